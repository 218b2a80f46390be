"""What the ESO is fed under a tight torque limit and at an end stop: the anti-windup tables
of docs/adrc.md.

    python benchmarks/bench_windup.py [--seeds N] [--only saturation|stop]

saturation
    test-1 with ``actuator.torque_limit`` lowered until the command saturates, each form
    run with ``actuator.observer_sees = "applied"`` (the saturated command, esoarm's
    default) and ``"commanded"`` (the command before saturation, the paper's ESO): mean
    over the seeds of the RMS error, the largest overshoot past a move's target (in the
    move's direction, until the next move starts) and the fraction of samples saturated.
stop
    test-1 with an end stop at 0.8 rad (``rig.end_stops = [-0.5, 0.8]``: the reference's
    1.0 rad is past it, so the arm is held there from about 2.5 s until the return move at
    10 s), without and with the ESO's gate (``actuator.stop_gate``): the largest |ẑ3| and
    |u| while held (4-10 s), and after the release (t ≥ 10 s) the RMS and largest error and
    the time the arm leaves the stop.

Reference engine, seeded; prints markdown.
"""

from __future__ import annotations

import argparse

import numpy as np

from esoarm.engines.simulation import simulate

LIMITS = [0.12, 0.1, 0.08]
FORMS = {"eso+flc": {}, "adrc-tf": {"controller.kind": "adrc-tf"},
         "adrc-error": {"controller.kind": "adrc-error"}}


def overshoot(t: np.ndarray, theta: np.ndarray, ref: np.ndarray) -> float:
    """Largest excursion past a move's target [rad], in the move's direction.

    Parameters
    ----------
    t : ndarray
        Sample times [s] (unused; the samples are in order).
    theta : ndarray
        True angle θ [rad].
    ref : ndarray
        Reference θd [rad]: rest-to-rest moves.

    Returns
    -------
    float
        max over the moves of max(0, sign(b − a)·(θ − b)) from the move's start to the next
        move's start, a → b the move.
    """
    moving = np.flatnonzero(np.diff(ref) != 0.0)
    if moving.size == 0:
        return 0.0
    starts = [int(moving[0])] + [int(b) for a, b in zip(moving[:-1], moving[1:],
                                                          strict=True) if b > a + 1]
    worst = 0.0
    for i, k0 in enumerate(starts):
        k1 = starts[i + 1] if i + 1 < len(starts) else len(ref)
        a = ref[k0]
        # the target: where the reference rests before the next move starts
        b = ref[k1 - 1]
        if b == a:
            continue
        worst = max(worst, float(np.max(np.sign(b - a) * (theta[k0:k1] - b))))
    return worst


def stop_table(seeds: list[int]) -> None:
    """The gate at an end stop: windup while held, the bump on release."""
    print(f"test-1 with an end stop at 0.8 rad, seeds {seeds[0]}-{seeds[-1]} (means)\n")
    print("| ESO's gate | max \\|ẑ3\\| held [rad/s²] | max \\|u\\| held [N·m] "
          "| RMS error after release [rad] | max error after release [rad] "
          "| leaves the stop at [s] |")
    print("|---|---|---|---|---|---|")
    for gate in (0.0, 0.01):
        rows = []
        for seed in seeds:
            tab = simulate("test-1", {"rig.end_stops": [-0.5, 0.8], "sensor.seed": seed,
                                      "actuator.stop_gate": gate}, warn=False).table()
            t, theta = tab[:, 0], tab[:, 1]
            held, after = (t > 4.0) & (t < 10.0), t >= 10.0
            leaves = t[after][np.argmax(theta[after] < 0.8)]
            rows.append((np.abs(tab[held, 7]).max(), np.abs(tab[held, 4]).max(),
                         np.sqrt(np.mean(tab[after, 3] ** 2)), np.abs(tab[after, 3]).max(),
                         leaves))
        m = np.mean(rows, axis=0)
        name = "none" if gate == 0.0 else f"stop_gate = {gate:g} rad"
        print(f"| {name} | {m[0]:.2f} | {m[1]:.3f} | {m[2]:.4f} | {m[3]:.3f} | {m[4]:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--only", choices=["saturation", "stop"])
    args = ap.parse_args()
    seeds = list(range(args.seeds))
    if args.only != "saturation":
        stop_table(seeds)
        if args.only == "stop":
            return
        print()
    print(f"test-1, seeds {seeds[0]}-{seeds[-1]} (means)\n")
    print("| form | torque_limit [N·m] | ESO fed | RMS error [rad] | overshoot [rad] "
          "| saturated |")
    print("|---|---|---|---|---|---|")
    for form, keys in FORMS.items():
        for limit in LIMITS:
            for sees in ("applied", "commanded"):
                rows = []
                for seed in seeds:
                    res = simulate("test-1", {**keys, "actuator.torque_limit": limit,
                                              "actuator.observer_sees": sees, "sensor.seed": seed},
                                   warn=False)
                    tab = res.table()
                    rows.append((res.metrics["rms_error"],
                                 overshoot(tab[:, 0], tab[:, 1], tab[:, 2]),
                                 float(np.mean(tab[:, 10]))))
                m = np.mean(rows, axis=0)
                print(f"| {form} | {limit:g} | {sees} | {m[0]:.5f} | {m[1]:.4f} | "
                      f"{m[2]:.1%} |")


if __name__ == "__main__":
    main()
