"""Predictor variants tried for the 2× delay goal on test-1 (experiments, not shipped forms).

    python benchmarks/bench_predictor.py [--quick]

The shipped predictor (``observer.delay_form = "predictor"``, :func:`esoarm.observers.linear.
eso_predict`) hands the controller the angle and rate predicted N samples ahead from the
ESO's estimate ẑ_k and the N commands sent, f̂ held; with the reference previewed N samples
(the moves started N·Ts earlier, the error measured against the reference itself:
``delay-predictor+preview`` of :mod:`esoarm.studies.adrc.compare`).  The variants below
change only that prediction.  Each runs on the reference engine with the linear ESO's
``estimate`` wrapped (the kernels are not touched), means over seeds 0-1, the transport delay
``actuator.delay_samples`` = ``observer.input_delay`` = N:

- ``held``: the shipped prediction (checks the wrapper: the batch engine's numbers);
- ``trend``: f̂ extrapolated with its slope over the last 2N samples, in the prediction and
  in the perturbation the FLC cancels (f̂ + N·Ts·ḟ̂);
- ``filtered``: ẑ2 and ẑ3 low-passed (first order, τ = 0.75·N·Ts) before they are
  extrapolated: the prediction N·Ts·ẑ2 + … amplifies the rate estimate's noise;
- ``both``: ẑ2, ẑ3 low-passed with τ = 0.3·N·Ts, then f̂'s slope over 2N samples (of the
  low-passed f̂) extrapolated as in ``trend`` (tried last, after the others: tuned on
  these very runs);
- ``partial``: the state predicted only N/2 samples ahead.

The table: the largest N whose RMS error stays ≤ 2× the paper's ESO without delay, at
50 Hz searched sample by sample (0..12), at 1 kHz evaluated at the paper's ESO's delay × 1,
1.5 and 2 (the 2× goal) only: the reference engine with the Python wrapper takes ~10-25 s
per 20 s run there.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

import numpy as np

import esoarm.observers.linear as lin
from esoarm.engines.simulation import SimulationDiverged, prepare, simulate
from esoarm.scenario import Scenario, load_scenario
from esoarm.studies.adrc.compare import _scenario, form_keys

Predict = Callable[[float, float, float, np.ndarray, int, np.ndarray, dict], tuple]


def _held(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
    h1, h2 = lin.eso_predict(h1, h2, h3, z, 3, nd, obs)
    return h1, h2, h3


def _trend(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
    ts, b0 = obs[lin.TS], obs[lin.B0]
    hist = st.setdefault("hist", [])
    hist.append(h3)
    m = 2 * nd
    slope = (hist[-1] - hist[-1 - m]) / (m * ts) if len(hist) > m else 0.0
    half = 0.5 * ts * ts
    for i in range(nd):
        acc = h3 + slope * (i + 0.5) * ts + b0 * z[3 + i]
        h1 = h1 + ts * h2 + half * acc
        h2 = h2 + ts * acc
    return h1, h2, h3 + slope * nd * ts


def _filtered(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
    ts = obs[lin.TS]
    a = ts / (0.75 * nd * ts + ts)
    st["h2"] = h2 if "h2" not in st else st["h2"] + a * (h2 - st["h2"])
    st["h3"] = h3 if "h3" not in st else st["h3"] + a * (h3 - st["h3"])
    g1, g2 = lin.eso_predict(h1, st["h2"], st["h3"], z, 3, nd, obs)
    return g1, g2, h3


def _both(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
    ts, b0 = obs[lin.TS], obs[lin.B0]
    a = ts / (0.3 * nd * ts + ts)
    st["h2"] = h2 if "h2" not in st else st["h2"] + a * (h2 - st["h2"])
    st["h3"] = h3 if "h3" not in st else st["h3"] + a * (h3 - st["h3"])
    hist = st.setdefault("hist", [])
    hist.append(st["h3"])
    m = 2 * nd
    slope = (hist[-1] - hist[-1 - m]) / (m * ts) if len(hist) > m else 0.0
    g2, half = st["h2"], 0.5 * ts * ts
    for i in range(nd):
        acc = st["h3"] + slope * (i + 0.5) * ts + b0 * z[3 + i]
        h1 = h1 + ts * g2 + half * acc
        g2 = g2 + ts * acc
    return h1, g2, h3 + slope * nd * ts


def _partial(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
    h1, h2 = lin.eso_predict(h1, h2, h3, z, 3, nd // 2, obs)
    return h1, h2, h3


VARIANTS: dict[str, Predict] = {"held": _held, "trend": _trend, "filtered": _filtered,
                                "both": _both, "partial": _partial}


def rms_error(scn: Scenario, variant: str, delay: int, seeds: tuple[int, ...] = (0, 1)) -> float:
    """Mean RMS of θ − θd over ``seeds`` with ``variant``'s prediction at ``delay`` samples."""
    predict = VARIANTS[variant]
    original = lin.estimate
    st: dict = {}

    def estimate(z, y, p, zhat):  # type: ignore[no-untyped-def]
        obs = p[1:]
        h1, h2, h3 = lin.eso_estimate(z[0], z[1], z[2], y[0], obs)
        nd = int(obs[lin.DELAY])
        if nd > 0 and obs[lin.FORM] == 1.0:
            h1, h2, h3 = predict(h1, h2, h3, z, nd, obs, st)
        zhat[0], zhat[1], zhat[2] = h1, h2, h3

    theta_ref = np.asarray(prepare(scn).theta_ref).ravel()
    out = []
    lin.estimate = estimate  # the reference engine looks the step up by module attribute
    try:
        for seed in seeds:
            st.clear()
            point = _scenario(scn, {**form_keys("delay-predictor+preview", scn, delay),
                                    "sensor.seed": seed})
            try:
                res = simulate(point, warn=False)
            except SimulationDiverged:
                out.append(math.inf)
                continue
            th = np.asarray(res.theta).ravel()
            out.append(float(np.sqrt(np.mean((th - theta_ref[:len(th)]) ** 2))))
    finally:
        lin.estimate = original
    return float(np.mean(out))


def prediction_error(scn: Scenario, delay: int, seed: int = 0) -> tuple[float, float]:
    """RMS [rad] of the ESO's angle ẑ1 − θ and of the shipped prediction θ̂(k+N) − θ(k+N).

    The twin's angle at the sample N later is the truth the prediction aims at (the first
    second left out: the observer's start).
    """
    rec: list[tuple[float, float]] = []

    def predict(h1, h2, h3, z, nd, obs, st):  # type: ignore[no-untyped-def]
        g1, g2 = lin.eso_predict(h1, h2, h3, z, 3, nd, obs)
        rec.append((h1, g1))
        return g1, g2, h3

    VARIANTS["_record"] = predict
    try:
        original = lin.estimate
        point = _scenario(scn, {**form_keys("delay-predictor+preview", scn, delay),
                                "sensor.seed": seed})

        def estimate(z, y, p, zhat):  # type: ignore[no-untyped-def]
            obs = p[1:]
            h1, h2, h3 = lin.eso_estimate(z[0], z[1], z[2], y[0], obs)
            h1, h2, h3 = predict(h1, h2, h3, z, int(obs[lin.DELAY]), obs, {})
            zhat[0], zhat[1], zhat[2] = h1, h2, h3

        lin.estimate = estimate
        try:
            res = simulate(point, warn=False)
        finally:
            lin.estimate = original
    finally:
        del VARIANTS["_record"]
    th = np.asarray(res.theta).ravel()
    r = np.asarray(rec)[:len(th)]
    skip = int(scn.sensor.rate_hz)
    cur = r[skip:, 0] - th[skip:]
    pred = r[skip:-delay, 1] - th[skip + delay:]
    return float(np.sqrt(np.mean(cur ** 2))), float(np.sqrt(np.mean(pred ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="50 Hz only")
    args = ap.parse_args()
    # (rate, eps, the paper's ESO's largest delay from bench_adrc.py --only delay, yard)
    cases = [(50.0, 0.05, 4), (50.0, 0.03, 3), (1000.0, 0.05, 80), (1000.0, 0.03, 60)]
    if args.quick:
        cases = cases[:2]
    base = load_scenario("test-1", {"observer.eps": 0.05})
    for label, keys in (("test-1", {}), ("no sensor noise or quantization",
                                         {"sensor.noise_deg": 0.0, "sensor.resolution_deg": 0.0})):
        cur, pred = prediction_error(_scenario(base, keys), 4)
        print(f"50 Hz, ε = 0.05 s, N = 4, {label}: RMS of ẑ1 − θ {1e3 * cur:.2f} mrad, of the "
              f"predicted angle − θ(k+N) {1e3 * pred:.2f} mrad")
    print()
    print("| rate, ε | delay-free RMS [rad] (2× limit) | paper's ESO holds | "
          + " | ".join(VARIANTS) + " |")
    print("|---|---|---|" + "---|" * len(VARIANTS))
    for rate, eps, paper in cases:
        scn = load_scenario("test-1", {"sensor.rate_hz": rate, "observer.eps": eps})
        from esoarm.studies.adrc.compare import delay_tolerance

        yard, _, _ = delay_tolerance(scn, [], [0], [0, 1])
        limit = 2.0 * yard
        cells = []
        for v in VARIANTS:
            if rate <= 50.0:
                held = 0
                for d in range(1, 13):
                    if rms_error(scn, v, d) > limit:
                        break
                    held = d
                cells.append(f"{held}")
            else:
                parts = []
                for d in (paper, round(1.5 * paper / 10) * 10, 2 * paper):
                    e = rms_error(scn, v, d)
                    parts.append(f"{d}: {e:.4f}{'' if e <= limit else ' ✗'}")
                cells.append(", ".join(parts))
            print(f"<!-- {rate:g} Hz ε {eps}: {v} done -->", flush=True)
        print(f"| {rate:g} Hz, {eps} s | {yard:.5f} ({limit:.5f}) | {paper} | "
              + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
