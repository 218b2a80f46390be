"""The model-based predictor for issue 33's 2× delay goal on test-1 (measurements).

    python benchmarks/bench_model_predictor.py [--seeds 14,15,16,17] [--update docs/adrc.md]

The goal (as in ``bench_predictor.py``): test-1 holds twice the transport delay the paper's ESO
holds (RMS error ≤ 2× the paper's ESO without delay) at equal ε, at 50 Hz and 1 kHz, ε = 0.05
and 0.03 s.  Every design is told the delay (``observer.input_delay`` =
``actuator.delay_samples`` = N) and sees the reference N samples ahead.

The design measured here, ``observer.delay_form = "model"`` as shipped
(:mod:`esoarm.observers.linear`), a Smith predictor built on the nominal model:

- the ESO is *model-assisted*: the exact held-input ("current") ESO of ε with the nominal
  model's acceleration m(θ, θ̇) = −(G(θ) + Fc tanh(θ̇/vs) + Fv θ̇)/I0 added to b0·u_{k−N} as a
  known input, so that ẑ3 estimates only what the model leaves (the sine disturbance, the
  inertia error, the friction the model misses); G is the plant's nominal gravity (what the FLC's
  ``compensation = "model"`` uses), Fc and Fv the friction the user gives
  (``observer.model_coulomb``, ``observer.model_viscous``; here identified on the twin);
- the predictor propagates (θ̂, θ̇̂) over the N samples with the same model, the N commands
  already sent and ẑ3 held, and hands the FLC θ̂, θ̇̂ at t_{k+N} and the perturbation
  ẑ3 + m(θ̂_{k+N}, θ̇̂_{k+N}) there: a velocity reversal inside the horizon is predicted
  with its friction step instead of being learned N samples late.

The model's smoothing velocity vs = 0.05 rad/s (``observer.model_friction_velocity``) (five
times the twin's 0.01) was chosen on seeds 0-1 (1 kHz ε = 0.05 and 50 Hz ε = 0.03): with the
twin's own 0.01 an over-estimated Fc (1.5×) drives a limit cycle. The rows with Fc × 0, 0.5 and
1.5 measure how much the design relies on knowing the friction; one row adds Stribeck stiction
the model lacks; one row judges the design against its own delay-free RMS error instead of the
paper's ESO's. Seeds 0-1 chose the design, 2-9 were looked at; the table is on the seeds given
(14-17 were declared held out before their first run).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
from doc_block import write_block

from esoarm.engines.simulation import prepare
from esoarm.scenario import Scenario, load_scenario
from esoarm.studies.adrc.compare import _scenario, form_keys

sys.path.insert(0, str(Path(__file__).parent))
from bench_predictor import held_by, paper_holds, simulate_one, tracking_rms  # noqa: E402

HELD = (14, 15, 16, 17)
CASES = [(50.0, 0.05), (50.0, 0.03), (1000.0, 0.05), (1000.0, 0.03)]
#: the model's tanh smoothing velocity [rad/s] (chosen on seeds 0-1, see the module docstring;
#: the default of observer.model_friction_velocity)
MODEL_VS = 0.05
#: the seed of the identification experiment (none of the table's)
IDENT_SEED = 18


def identified_friction(seed: int = IDENT_SEED) -> tuple[float, float]:
    """(Fc [N·m], Fv [N·m·s/rad]) as a user gets them: ``esoarm excite`` on test-1's twin
    (its own seed, none of the table's) and ``esoarm identify --json``."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "excite.csv"
        subprocess.run([sys.executable, "-m", "esoarm", "excite", "test-1", "--twin", "--set",
                        f"sensor.seed={seed}", "--log", str(log)], check=True,
                       capture_output=True)
        out = subprocess.run([sys.executable, "-m", "esoarm", "identify", str(log), "--json"],
                             check=True, capture_output=True, text=True).stdout
    phys = json.loads(out)["physical"]
    return phys["coulomb_friction"]["value"], phys["viscous_friction"]["value"]


def rms_error(scn: Scenario, delay: int, seeds: tuple[int, ...], fc: float, fv: float,
              vs: float = MODEL_VS, told: bool = True) -> float:
    """Mean RMS of θ − θd over ``seeds`` with ``delay_form = "model"``; inf if one diverged.

    ``told = False``: the observer is not told the delay (``input_delay = 0``) and the
    reference is not previewed: the model-assisted ESO alone, as the paper's ESO is run.
    """
    theta_ref = np.asarray(prepare(scn).theta_ref).ravel()
    out = []
    for seed in seeds:
        form = form_keys("delay-predictor+preview", scn, delay) if told else {
            "actuator.delay_samples": delay}
        point = _scenario(scn, {**form,
                                "observer.discretization": "current",
                                "observer.delay_form": "model", "observer.model_coulomb": fc,
                                "observer.model_viscous": fv,
                                "observer.model_friction_velocity": vs, "sensor.seed": seed})
        e = tracking_rms(partial(simulate_one, point), theta_ref)
        if not math.isfinite(e):
            return math.inf
        out.append(e)
    return float(np.mean(out))


def _rms_at(scn: Scenario, seeds: tuple[int, ...], fc: float, fv: float, vs: float, told: bool,
            delay: int) -> float:
    return rms_error(scn, delay, seeds, fc, fv, vs, told)


#: row label -> (Fc scale, model vs [rad/s], twin overrides, own yardstick, told the delay)
ROWS: dict[str, tuple[float, float, dict, bool, bool]] = {
    "Fc, Fv identified": (1.0, MODEL_VS, {}, False, True),
    "Fc × 0.5": (0.5, MODEL_VS, {}, False, True),
    "Fc × 1.5": (1.5, MODEL_VS, {}, False, True),
    "Fc = 0 (gravity and viscous only)": (0.0, MODEL_VS, {}, False, True),
    "identified, vs = 0.01 rad/s (the twin's)": (1.0, 0.01, {}, False, True),
    "identified, on a twin with Stribeck stiction 0.02 N·m (not in the model)":
        (1.0, MODEL_VS, {"rig.stiction": 0.02}, False, True),
    "identified, against its own delay-free RMS": (1.0, MODEL_VS, {}, True, True),
    "identified, the ESO not told the delay (input_delay = 0, no preview)":
        (1.0, MODEL_VS, {}, False, False),
}


def table(cases: list[tuple[float, float]], seeds: tuple[int, ...],
          friction: tuple[float, float]) -> str:
    """One row per model, one column per case: the largest delay held and the RMS errors."""
    fc, fv = friction
    cols, yards, papers = [], [], []
    cells: dict[str, list[str]] = {r: [] for r in ROWS}
    for rate, eps in cases:
        base = {"sensor.rate_hz": rate, "observer.eps": eps}
        scn = load_scenario("test-1", base)
        fine = rate <= 50.0
        yard, paper = paper_holds(scn, seeds, fine)
        goal = 2 * paper
        cols.append(f"{rate:g} Hz, ε = {eps} s")
        yards.append(f"{yard:.5f} ({2.0 * yard:.5f})")
        papers.append(f"{paper} (goal {goal})")
        for name, (fcs, vs, over, own, told) in ROWS.items():
            t = time.perf_counter()
            twin = load_scenario("test-1", {**base, **over}) if over else scn
            limit = 2.0 * (paper_holds(twin, seeds, fine)[0] if over else yard)
            if own:
                limit = 2.0 * rms_error(twin, 0, seeds, fcs * fc, fv, vs)
            if fine:
                delays = list(range(1, 17))
            elif own or not told:
                delays = list(range(10, 201, 10))
            else:
                delays = [goal // 2, goal, round(1.25 * goal)]
            held, seen = held_by(partial(_rms_at, twin, seeds, fcs * fc, fv, vs, told), limit,
                                 delays)
            text = (f"{held}" if held else f"< {delays[0]}") + (" ✓" if held >= goal else " ✗")
            shown = seen if not fine else [(d, e) for d, e in seen if d == goal]
            if own:
                shown = [(0, limit / 2.0)] + seen[-2:]
            elif not told and not fine:
                shown = seen[-2:]
            if shown:
                text += " (" + ", ".join(f"{d}: {e:.4f}" for d, e in shown) + ")"
            if over or own:
                text += f", limit {limit:.4f}"
            cells[name].append(text)
            print(f"<!-- {rate:g} Hz, ε {eps}: {name} {time.perf_counter() - t:.0f} s -->",
                  flush=True)
    lines = ["| friction model | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols),
             "| delay-free RMS of the paper's ESO [rad] (2× limit) | " + " | ".join(yards) + " |",
             "| the paper's ESO holds | " + " | ".join(papers) + " |"]
    lines += [f"| {name} | " + " | ".join(cells[name]) + " |" for name in ROWS]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default=",".join(map(str, HELD)),
                    help="sensor seeds (default: the held-out 14-17)")
    ap.add_argument("--quick", action="store_true", help="50 Hz only (a smoke run)")
    ap.add_argument("--update", default=None, metavar="MD",
                    help="write the table between the markers in this file")
    args = ap.parse_args()
    seeds = tuple(int(s) for s in args.seeds.split(","))
    t0 = time.perf_counter()
    fc, fv = identified_friction()
    text = (f"The largest delay held with `delay_form = \"model\"` on seeds "
            f"{', '.join(map(str, seeds))} (the reference previewed N samples; ✓ the goal, 2× "
            "the paper's ESO's delay; 50 Hz searched 1..16, 1 kHz at half the goal, the goal "
            "and 1.25× it; RMS error [rad] in brackets, at the goal at 50 Hz). The friction "
            f"identified on the twin (`esoarm excite test-1 --twin --set sensor.seed={IDENT_SEED}`"
            f", `esoarm identify --json`): Fc = {fc:.5f} N·m, Fv = {fv:.5f} N·m·s/rad (the twin "
            "has 0.05 and 0.01):\n\n" + table(CASES[:2] if args.quick else CASES, seeds, (fc, fv))
            + f"\n\n<!-- {time.perf_counter() - t0:.0f} s -->\n")
    print(text)
    if args.update:
        write_block(Path(args.update), "bench_model_predictor:table", text)
        print(f"wrote the table into {args.update}")


if __name__ == "__main__":
    main()
