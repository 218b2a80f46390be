"""How honest are ``identify``'s AR noise estimates?  Synthetic residuals, seeded.

    python benchmarks/bench_noise_ar.py [--datasets N]

Each dataset is 2000 samples of AR noise (0.3° RMS) cut into segments of 100 samples, each
with its offset and slope fitted away (what the identification's initial angle and rate do),
and an independent input.  Reported, per truth: how often the verdict calls it sensor noise
(each test has a 5 % false-rejection level), the mean of the whiteness and input
portmanteau statistics against their χ² means, the chosen orders, and the coverage of the
95 % intervals of φ1 and of the RMS; for comparison the mean Yule-Walker φ1 of the same
residuals (biased by the segments' fit).  Prints one line per truth; nothing is timed.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from esoarm.plants.noise import NoiseModel, draws
from esoarm.studies.identification.residual.noise_ar import SegmentResidual, fit_ar, segment_verdict


def _segments(w: np.ndarray, seed: int, n: int = 100) -> list[SegmentResidual]:
    t = np.arange(n) * 0.02
    x = np.stack([np.ones(n), t], axis=1)
    u = np.random.default_rng(10_000 + seed).standard_normal(len(w))
    out = []
    for s in range(len(w) // n):
        ws = w[s * n:(s + 1) * n]
        out.append(SegmentResidual(ws - x @ np.linalg.lstsq(x, ws, rcond=None)[0], x,
                                   u[s * n:(s + 1) * n], np.arange(n)))
    return out


def run(phi: tuple[float, ...], datasets: int) -> str:
    """One truth: the line of statistics over ``datasets`` seeded datasets."""
    sensor = white_q = input_q = cover_phi = cover_std = 0
    orders: list[int] = []
    yw: list[float] = []
    for seed in range(100, 100 + datasets):
        w = draws(NoiseModel(math.radians(0.3), phi, 0.0, 10.0, 0.05, 0.02), seed, 2000)
        if not phi:
            w = w * math.radians(0.3)
        segs = _segments(w, seed)
        d = segment_verdict(segs).to_dict()
        sensor += bool(d["sensor_noise"])
        white_q += d["innovation_autocorrelation_chi2"]
        input_q += d["input_cross_correlation_chi2"]
        orders.append(int(d["order"]))
        if phi and d["order"]:
            lo, hi = d["noise_ar_ci95"][0]
            cover_phi += lo <= phi[0] <= hi
        lo, hi = d["noise_std_ci95_deg"]
        cover_std += lo <= 0.3 <= hi
        r = np.concatenate([s.r for s in segs])
        yw.append(fit_ar(r, max(1, len(phi))).phi[0] if phi else 0.0)
    n = datasets
    return (f"AR{list(phi)}: sensor noise {sensor}/{n}; whiteness Q mean {white_q / n:.1f} "
            f"(χ² mean {20 - len(phi)}), input Q mean {input_q / n:.1f} (χ² mean 20); orders "
            f"{np.bincount(orders).tolist()}; φ1 interval covers {cover_phi}/{n}, RMS interval "
            f"covers {cover_std}/{n}; Yule-Walker φ1 mean {np.mean(yw):.3f}")


def main(argv: list[str] | None = None) -> None:
    """Print the statistics for white, AR(1) 0.7 and AR(2) (1.2, −0.5) noise."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--datasets", type=int, default=40)
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    for phi in [(), (0.7,), (1.2, -0.5)]:
        print(run(phi, args.datasets), flush=True)


if __name__ == "__main__":
    main()
