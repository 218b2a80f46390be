"""Calibration of ``esoarm identify`` on seeded twins drawn over wide ranges.

Each rig is drawn by
:func:`esoarm.studies.identification.experiment.calibration.draw_rig` (the prior is
documented there), excited with ``esoarm excite test-1 --twin`` (the default plan) and
fitted with ``esoarm identify LOG --json`` as a user would run them, each a command of its
own. Rigs are sorted into recovered, refused, flagged and confidently wrong, and the
coverage of the written 95 % intervals is counted.

Seeds below ``HELD_OUT_START`` may have been looked at while the estimator was tuned; the
held-out seeds (from ``HELD_OUT_START`` on) were not, and are reported apart.  The held-out
range now is seeds 9,000,000 … 9,000,199, declared at 11:16 UTC on 2026-12-06 before any
run on them (seeds 7,000,000 … 7,000,199 and 8,000,000 … 8,000,119, held out for the frozen
commit 45e3d9f, are tuning data since the estimator was changed on their results; see
``calibration.HELD_OUT_START``).  ``--from-json`` takes several dumps and, like
``--range-note``, writes one table per million of seeds and one of them together.

Run: ``python benchmarks/bench_identify_calibration.py --rigs 200`` (writes
docs/benchmarks-identify-calibration.md; ``--tuning M`` adds M rigs of the tuning seeds;
``--jobs J`` runs J rigs at a time).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from esoarm.studies.identification.experiment.calibration import (
    HELD_OUT_START,
    RigOutcome,
    draw_rig,
    run_rig,
    summary,
    verdict_of,
)

ROOT = Path(__file__).resolve().parents[1]
GOALS = "confidently wrong ≤ 1 %, coverage of the written intervals ≥ 90 %, refused ≤ 25 %"


def _row(o: RigOutcome) -> str:
    t = o.rig.truth
    what = (f"{t['sensor.rate_hz']:g} Hz, I×{t['rig.inertia_scale']:.2f}, "
            f"Fc {t['rig.coulomb_friction']:.3f}, b {t['rig.viscous_friction']:.4f}, "
            f"Fst {t['rig.stiction']:.3f}, d {int(t['actuator.delay_samples'])}, "
            f"T {1000 * t['actuator.lag']:.0f} ms"
            + (f", backlash {t['rig.backlash_deg']:.2f}°" if t["rig.backlash_deg"] else "")
            + (f", AR φ {t['sensor.noise_ar_phi']:.2f}" if t["sensor.noise_ar_phi"] else "")
            + (f", vib {t['sensor.vibration_deg']:.2f}°" if t["sensor.vibration_deg"] else "")
            + (f", PWM {int(t['actuator.pwm_bits'])} bit" if t["actuator.pwm_bits"] else ""))
    if o.verdict in ("refused", "excite-failed"):  # (missed and wrong: the keys below)
        note = o.reason.replace("esoarm: failed: ", "").replace("|", "/")[:150]
    else:
        parts = []
        for key in o.missed + o.flagged:
            truth, v, lo, hi, w = o.params[key]
            parts.append(f"{key} {v:.4g} [{lo:.4g}, {hi:.4g}] truth {truth:.4g}"
                         + ("" if w else " (flagged)"))
        note = "; ".join(parts)
    return (f"| {o.rig.seed} | {what} | {o.stuck_share:.0%} | {o.verdict} | "
            f"{o.seconds:.1f} | {note} |")


def _table(title: str, outs: list[RigOutcome], note: str = "",
           rows: bool = True) -> list[str]:
    s = summary(outs)
    lines = [f"## {title}", "", *([note, ""] if note else []),
             f"**{s['rigs']:.0f} rigs; {s['recovered']:.0f} recovered "
             f"({s['recovered_percent']:.1f} %), {s['flagged']:.0f} flagged "
             f"({s['flagged_percent']:.1f} %), {s['refused']:.0f} refused "
             f"({s['refused_percent']:.1f} %), {s['missed']:.0f} missed near "
             f"({s['missed_percent']:.1f} %), {s['wrong']:.0f} confidently wrong "
             f"({s['wrong_percent']:.1f} %)** of the {s['identified']:.0f} that reached "
             "identify"
             + (f"; {s['excite-failed']:.0f} more where the default excitation itself stopped"
                if s["excite-failed"] else "")
             + f"; coverage of the {s['intervals_written']:.0f} written 95 % intervals "
             f"**{s['coverage_percent']:.1f} %**.", ""]
    exit0 = [o for o in outs if o.verdict in ("recovered", "flagged", "missed", "wrong")]
    literal = sum(o.verdict in ("missed", "wrong") for o in exit0)
    arm_only = sum(verdict_of({k: (o.rig.truth[k], *p[1:]) for k, p in o.params.items()})[0]
                   == "wrong" for o in exit0)
    ident = max(s["identified"], 1)
    lines += [f"Under the issue's literal rule (any written interval that misses, near or far): "
              f"{literal} of {s['identified']:.0f} ({100 * literal / ident:.1f} %). With a "
              "backlash rig's inertia judged against the arm's alone (the rule before "
              f"2026-12-06 08:00 UTC, see below): {arm_only} confidently wrong "
              f"({100 * arm_only / ident:.1f} %).", ""]
    secs = sorted(o.seconds for o in outs if o.seconds > 0)
    if secs:
        lines += [f"identify wall-clock per rig: median {secs[len(secs) // 2]:.1f} s, "
                  f"max {secs[-1]:.1f} s.", ""]
    if not rows:
        return lines
    lines += ["| seed | twin | stuck | verdict | identify [s] | what missed, or why refused |",
              "|---|---|---|---|---|---|"]
    lines += [_row(o) for o in outs]
    return lines + [""]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rigs", type=int, default=200, help="held-out rigs")
    ap.add_argument("--tuning", type=int, default=0, help="rigs from the tuning seeds 0 …")
    ap.add_argument("--tuning-start", type=int, default=0,
                    help="first tuning seed (default 0)")
    ap.add_argument("--held-start", type=int, default=HELD_OUT_START,
                    help="first held-out seed (default HELD_OUT_START); a later start lets two "
                    "processes split one range")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks-identify-calibration.md"))
    ap.add_argument("--json", dest="json_out", default="", help="also dump the outcomes")
    ap.add_argument("--from-json", dest="from_json", nargs="+", default=[],
                    help="write the page from --json dumps of earlier runs (nothing is run)")
    ap.add_argument("--note", default="", help="a sentence added under the page's header")
    ap.add_argument("--range-note", dest="range_notes", action="append", default=[],
                    metavar="START=TEXT", help="a sentence under the table of the seeds from "
                    "START to the next million (which commit, when, how it was declared)")
    args = ap.parse_args()
    if not args.from_json and (args.held_start < HELD_OUT_START
                               or args.tuning_start + args.tuning > HELD_OUT_START):
        ap.error(f"held-out seeds start at {HELD_OUT_START}; tuning seeds stay below it")
    range_notes: dict[int, str] = {}
    for item in args.range_notes:
        start_s, sep, text = item.partition("=")
        if not sep or not start_s.strip().isdigit():
            ap.error(f"--range-note {item!r}: expected START=TEXT (START a seed)")
        range_notes[int(start_s) // 1_000_000] = text.strip()
    seeds = [*range(args.tuning_start, args.tuning_start + args.tuning),
             *range(args.held_start, args.held_start + args.rigs)]
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    done: list[RigOutcome] = []
    lock = threading.Lock()
    start_utc = f"{datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M}"

    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True, check=False).stdout.strip()

    def write() -> None:  # after every rig: a run stopped early leaves its table
        outs = sorted(done, key=lambda o: o.rig.seed)
        elapsed = time.perf_counter() - t0
        tuning = [o for o in outs if o.rig.seed < HELD_OUT_START]
        held = [o for o in outs if o.rig.seed >= HELD_OUT_START]
        partial = (f" **{len(outs)} of the {len(seeds)} rigs asked for were done when this "
                   "page was written (the run was stopped or is still running).**"
                   if len(outs) < len(seeds) else "")
        lines = ["# Calibration of esoarm identify", "",
                 f"Measured with `python benchmarks/bench_identify_calibration.py --rigs "
                 f"{args.rigs}" + (f" --tuning {args.tuning}" if args.tuning else "")
                 + (f" --tuning-start {args.tuning_start}" if args.tuning_start else "")
                 + (f" --held-start {args.held_start}"
                    if args.held_start != HELD_OUT_START else "")
                 + (f" --jobs {args.jobs}" if args.jobs > 1 else "")
                 + f"` from {start_utc} UTC, commit {commit}, {platform.machine()} with "
                 f"{os.cpu_count()} cores, load average {load0:.1f} at the start; "
                 f"{elapsed / 60:.0f} min so far.{partial}"
                 + (f" {args.note}" if args.note else ""), "",
                 "Each rig is a twin of test-1 drawn from the prior of "
                 "`esoarm.studies.identification.experiment.calibration` (inertia 0.5-2×, "
                 "viscous friction 0.1-10×, Coulomb friction 0 to 1.5× the excitation's 0.2 N·m "
                 "RMS, stiction, backlash, white and coloured encoder noise, vibration, lag, "
                 "delay 0-3 samples, PWM resolution, gravity offset, 50 Hz to 1 kHz), excited with "
                 "`esoarm excite test-1 --twin` (the default plan; above 200 Hz shortened to "
                 "12000 samples) and fitted with `esoarm identify LOG --json --set "
                 "sensor.rate_hz=… --set sensor.resolution_deg=…` (what a user knows of the "
                 "encoder). *Recovered*: exit 0 and every judged truth inside its written "
                 "interval. *Flagged*: exit 0, a truth outside its interval, and that "
                 "parameter named in words (interval withheld, poorly determined, at a bound). "
                 "*Refused*: exit 1 or 2 with the reason. *Confidently wrong*: a written "
                 "interval that misses the truth far: beyond its 99.9 % extension "
                 "(3.29/1.96 × its half-width on the truth's side; the delay by any sample). "
                 "*Missed near*: written intervals that miss only inside that extension (with "
                 "eight 95 % intervals a third of an exact estimator's answers have one); they "
                 "count against the coverage. The noise σ is judged only on rigs whose "
                 "noise is white (no AR, vibration, backlash). With backlash the inertia is "
                 "judged as the rigid drive train's: the arm's plus the twin's motor side "
                 "(rig.motor_inertia, 1e-3 kg·m², which a rigid gear does not have) over "
                 "plant.inertia, the inertia a rigid model sees and identify writes "
                 "(`calibration.Rig.judged_truth`); the rigs' truth column shows the arm's. "
                 "The stuck column is the share "
                 "of samples where the true arm moved less than 1e-4 rad. A rig whose "
                 "default excitation itself stopped (`esoarm excite` refused, e.g. at the "
                 "angle limit) is counted apart: identify never saw it.", "",
                 f"Goals (issue 30, on the held-out seeds): {GOALS}.", ""]
        if args.from_json:  # the run's own facts are in --note, not this re-render's
            names = ", ".join(Path(f).name for f in args.from_json)
            lines[2] = f"Written from {names}, the dumps of runs: {args.note}"
        if range_notes or args.from_json:  # one table per million of seeds, then together
            groups = sorted({o.rig.seed // 1_000_000 for o in outs})
            for g in groups:
                part = [o for o in outs if o.rig.seed // 1_000_000 == g]
                lines += _table(f"Seeds {part[0].rig.seed:,} … {part[-1].rig.seed:,}", part,
                                range_notes.get(g, ""))
            if len(groups) > 1:
                lines += _table("All of the ranges above together", outs,
                                "The sum of the tables above (each range's own estimator "
                                "and freeze is said under its table).", rows=False)
        else:
            lines += _table(f"Held-out seeds ({HELD_OUT_START} …)", held)
            if tuning:
                lines += _table("Tuning seeds (below the held-out ones): looked at while the "
                                "estimator was changed", tuning)
        Path(args.out).write_text("\n".join(lines), encoding="utf-8")
        if args.json_out:
            Path(args.json_out).write_text(json.dumps(
                [{"seed": o.rig.seed, "verdict": o.verdict, "exit": o.exit_code,
                  "reason": o.reason, "missed": o.missed, "flagged": o.flagged,
                  "seconds": o.seconds, "stuck": o.stuck_share, "truth": o.rig.truth,
                  "params": o.params} for o in outs], indent=1), encoding="utf-8")

    def one(seed: int) -> RigOutcome:
        o = run_rig(draw_rig(seed))
        with lock:
            done.append(o)
            print(f"[{len(done)}/{len(seeds)}] seed {seed}: {o.verdict} {o.seconds:.1f} s "
                  f"{o.reason[:100]}{' '.join(o.missed)}", flush=True)
            write()
        return o

    if args.from_json:
        from esoarm.studies.identification.experiment.calibration import from_json

        for dump in args.from_json:
            done.extend(from_json(json.loads(Path(dump).read_text(encoding="utf-8"))))
        args.json_out = ""
        write()
        return
    with ThreadPoolExecutor(max(1, args.jobs)) as pool:
        outs = list(pool.map(one, seeds))
    held = [o for o in outs if o.rig.seed >= HELD_OUT_START]
    tuning = [o for o in outs if o.rig.seed < HELD_OUT_START]
    print(json.dumps({"held_out": summary(held) if held else None,
                      "tuning": summary(tuning) if tuning else None,
                      "minutes": (time.perf_counter() - t0) / 60}, indent=1))

if __name__ == "__main__":
    main()
