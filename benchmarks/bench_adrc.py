"""The ADRC forms, tunings and add-ons measured on the twin: the tables of docs/adrc.md.

    python benchmarks/bench_adrc.py [--seeds N] [--quick]

Prints markdown: (1) the half-gain observer against the bandwidth tuning on test-1 with
0.5° of encoder noise (RMS error, RMS Δu, and the noise budget's RMS Δu), every
discretization; (2) the largest transport delay test-1 holds (RMS error ≤ 2× the delay-free
run) for the paper's ESO, the ESO fed the delayed input and its predictor, at ε = 0.05 and
0.03 s at 50 Hz and at 1 kHz; (3) the forms side by side on test-1 and test-2 (the PID alone
and with the ESO's compensation among them).  Batch engine, seeded; nothing is timed.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from esoarm.scenario import load_scenario
from esoarm.studies.adrc.compare import FORMS, compare, delay_tolerance


def half_gain(seeds: list[int], eps_list: list[float]) -> str:
    from esoarm.studies.frequency.noise import noise_budget

    lines = ["| discretization | ε [s] | tuning | RMS error [rad] | RMS Δu [N·m] "
             "| budget RMS Δu [N·m] |", "|---|---|---|---|---|---|"]
    for disc in ("euler", "zoh", "current"):
        for eps in eps_list:
            for tuning in ("bandwidth", "half-gain"):
                over = {"sensor.noise_deg": 0.5, "observer.eps": eps,
                        "observer.discretization": disc, "observer.tuning": tuning}
                (r,) = compare("test-1", ["eso+flc"], seeds, over)
                budget = noise_budget(load_scenario("test-1", over)).rms_du
                lines.append(f"| {disc} | {eps:g} | {tuning} | {r.rms_error:.5f} | "
                             f"{r.rms_du:.4f} | {budget:.4f} |")
    return "\n".join(lines)


def equal_tracking(seeds: list[int]) -> str:
    """RMS Δu of half-gain at the RMS error of the bandwidth tuning at ε = 0.05 s (interpolated
    over ε)."""
    out = ["| discretization | bandwidth ε = 0.05 s: RMS error, RMS Δu | half-gain at that "
           "RMS error: ε, RMS Δu | Δu saved |", "|---|---|---|---|"]
    grid = [0.02, 0.025, 0.03, 0.035, 0.04, 0.045, 0.05, 0.06]
    for disc in ("euler", "zoh", "current"):
        base = {"sensor.noise_deg": 0.5, "observer.discretization": disc}
        (ref,) = compare("test-1", ["eso+flc"], seeds, {**base, "observer.eps": 0.05})
        errs, dus, ok_eps = [], [], []
        for eps in grid:
            if disc == "euler" and 0.02 / eps >= 1.0:
                continue
            (r,) = compare("test-1", ["half-gain"], seeds, {**base, "observer.eps": eps})
            if math.isfinite(r.rms_error):
                errs.append(r.rms_error)
                dus.append(r.rms_du)
                ok_eps.append(eps)
        order = np.argsort(errs)
        e_s, d_s, x_s = (np.array(errs)[order], np.array(dus)[order],
                         np.array(ok_eps)[order])
        if not e_s[0] <= ref.rms_error <= e_s[-1]:
            out.append(f"| {disc} | {ref.rms_error:.5f}, {ref.rms_du:.4f} | outside the "
                       f"grid ({e_s[0]:.5f} … {e_s[-1]:.5f}) | — |")
            continue
        du = float(np.interp(ref.rms_error, e_s, d_s))
        eps = float(np.interp(ref.rms_error, e_s, x_s))
        out.append(f"| {disc} | {ref.rms_error:.5f}, {ref.rms_du:.4f} | {eps:.3f}, {du:.4f} | "
                   f"{100 * (1 - du / ref.rms_du):.0f} % |")
    return "\n".join(out)


def delays(seeds: list[int], quick: bool) -> str:
    lines = ["| rate, ε | delay-free RMS error [rad] | paper's ESO | ESO fed u_{k−N} | "
             "predictor | predictor, reference N ahead |", "|---|---|---|---|---|---|"]
    cases = [(50.0, 0.05, list(range(0, 16))), (50.0, 0.03, list(range(0, 16))),
             (1000.0, 0.05, [0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 120, 140, 160, 200]),
             (1000.0, 0.03, [0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 120, 140, 160, 200])]
    if quick:
        cases = cases[:1]
    forms = ["eso+flc", "delay-input", "delay-predictor", "delay-predictor+preview"]
    for rate, eps, ds in cases:
        scn = load_scenario("test-1", {"sensor.rate_hz": rate, "observer.eps": eps})
        yard, held, _ = delay_tolerance(scn, forms, ds, seeds)
        ms = 1000.0 / rate

        def cell(d: int, ms: float = ms) -> str:
            return "none" if d < 0 else f"{d} ({d * ms:g} ms)"

        lines.append(f"| {rate:g} Hz, {eps:g} s | {yard:.5f} | {cell(held['eso+flc'])} | "
                     f"{cell(held['delay-input'])} | {cell(held['delay-predictor'])} | "
                     f"{cell(held['delay-predictor+preview'])} |")
    return "\n".join(lines)


def forms_table(seeds: list[int]) -> str:
    names = [f for f in FORMS if f not in ("delay-input", "delay-predictor")]
    lines = ["| form | test-1 RMS error [rad] | test-1 RMS Δu [N·m] | test-2 RMS error [rad] "
             "| test-2 RMS Δu [N·m] |", "|---|---|---|---|---|"]
    res = {s: compare(s, names, seeds) for s in ("test-1", "test-2")}
    for i, f in enumerate(names):
        a, b = res["test-1"][i], res["test-2"][i]
        lines.append(f"| {f} | {a.rms_error:.5f} | {a.rms_du:.4f} | {b.rms_error:.5f} | "
                     f"{b.rms_du:.4f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--quick", action="store_true", help="one delay case, two seeds")
    ap.add_argument("--only", choices=["half-gain", "delay", "forms"], default=None)
    args = ap.parse_args()
    seeds = list(range(2 if args.quick else args.seeds))
    if args.only in (None, "half-gain"):
        print("### Half-gain against bandwidth (test-1, 0.5° noise)\n")
        print(half_gain(seeds, [0.03, 0.05, 0.09]))
        print("\n### At equal tracking\n")
        print(equal_tracking(seeds))
    if args.only in (None, "delay"):
        print("\n### Largest transport delay held (RMS error ≤ 2× delay-free)\n")
        print(delays(seeds[:2], args.quick))
    if args.only in (None, "forms"):
        print("\n### The forms side by side\n")
        print(forms_table(seeds))


if __name__ == "__main__":
    main()
