"""The learned feedforward table on the twin with cogging: the table of docs/adrc.md.

    python benchmarks/bench_learn_map.py [--seeds N] [--bins N]

test-1 (40 s) on a rig with a cogging torque A cos(nθ) (A = 0.08 N·m, n = 6 periods per
revolution, about 1/3 of the arm's gravity torque): one run at the scenario's ε learns the
table (``esoarm learn-map``'s rule), then every ε is run with and without it.  Prints
markdown: mean RMS error over the seeds at each ε, and the largest ε with the table that
tracks as well as ε = 0.05 s (and 0.03 s) without it.  Reference engine, seeded.
"""

from __future__ import annotations

import argparse

from esoarm.scenario import load_scenario
from esoarm.studies.adrc.learn_map import eps_at_error, learned_from_run, rms_errors, with_map

COGGING = {"duration": 40.0, "rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6}
EPS = [0.03, 0.05, 0.07, 0.09, 0.12, 0.15, 0.2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--bins", type=int, default=72)
    args = ap.parse_args()
    seeds = list(range(args.seeds))
    scn = load_scenario("test-1", COGGING)
    learned = learned_from_run(scn, args.bins)
    mapped = with_map(scn, learned.table)
    plain, ff = rms_errors(scn, EPS, seeds), rms_errors(mapped, EPS, seeds)
    print(f"Learned at ε = {scn.observer.eps:g} s: {args.bins} bins, {learned.visited} "
          f"visited; seeds {seeds[0]}-{seeds[-1]}\n")
    print("| ε [s] | RMS error, no table [rad] | RMS error, learned table [rad] |")
    print("|---|---|---|")
    for e, a, b in zip(EPS, plain, ff, strict=True):
        print(f"| {e:g} | {a:.5f} | {b:.5f} |")
    print("\n| without the table | its RMS error [rad] | ε with the table at that error [s] |")
    print("|---|---|---|")
    for e0 in (0.03, 0.05):
        target = float(plain[EPS.index(e0)])
        e1 = eps_at_error(EPS, ff, target)
        shown = "none" if e1 is None else (f"≥ {e1:g}" if e1 == EPS[-1] else f"{e1:.3f}")
        print(f"| ε = {e0:g} s | {target:.5f} | {shown} |")


if __name__ == "__main__":
    main()
