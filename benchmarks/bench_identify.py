"""Benchmark of ``esoarm identify``: time to fit a 60 s log at 50 Hz.

Run:  python benchmarks/bench_identify.py [--out docs/benchmarks-identify.md]

For each twin in :data:`CASES` (non-default parameters; one with an actuator
lag and a transport delay, which the fit has to find by trying delays and
testing the lag):

1. A 60 s identification experiment (the default ``esoarm excite`` plan) is
   recorded on the twin.
2. ``identify`` fits it (default options: delay search 0 … 2, lag test, 25 %
   kept for validation), three times after one warm-up run (numba's compiled
   kernels come from the on-disk cache after the first run); median and max,
   and the number of simulations of the log the fit ran.
3. The whole command line, ``esoarm identify LOG --json``, in a new process
   (interpreter start, imports, cached kernel load, fit, validation), once.

Results are written as Markdown with the machine they ran on and its load.
Nothing here is a test: numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

import numpy as np

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import load_scenario
from esoarm.studies.identification import fit as identify_fit
from esoarm.studies.identification.data import read_ident_log
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.identify import IdentResult, identify

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_rig import machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BASE = ["rig.inertia_scale=1.25", "rig.coulomb_friction=0.08", "rig.viscous_friction=0.02",
        "sensor.seed=4"]
#: name -> true twin (overrides of test-1); the fit starts from test-1 as it is.
CASES = {
    "friction": BASE,
    "lag and delay": [*BASE, "actuator.lag=0.03", "actuator.delay_samples=1"],
}


TIME_HEAD = ("| twin | `identify()` in-process, median of 3 (max) [s] | "
             "`esoarm identify LOG --json`, new process [s] | simulations of the log |\n"
             "|---|---|---|---|")
FOUND_HEAD = ("| twin | `rig.inertia_scale` | `rig.coulomb_friction` [N·m] | `actuator.lag` [s] | "
              "delay [samples] | iterations of the final fit | validation fit [%] |\n"
              "|---|---|---|---|---|---|---|")


class _Count:
    """Counts the simulations of the log (one per parameter set) while installed."""

    def __init__(self) -> None:
        self.n = 0
        self._one, self._many = identify_fit.simulate_segments, identify_fit.simulate_columns

        def one(*args):  # type: ignore[no-untyped-def]
            self.n += 1
            return self._one(*args)

        def many(outs, *args):  # type: ignore[no-untyped-def]
            self.n += outs.shape[0]
            return self._many(outs, *args)

        identify_fit.simulate_segments, identify_fit.simulate_columns = one, many

    def close(self) -> None:
        identify_fit.simulate_segments, identify_fit.simulate_columns = self._one, self._many


def run_case(sets: list[str], tmp: Path) -> dict:
    """Record the experiment on the twin ``sets`` and time the fit (see the module)."""
    log_path = tmp / "excite.csv"
    excite_twin(load_scenario("test-1", sets), ExcitationPlan(), log_path)
    scn = load_scenario("test-1")
    log = read_ident_log(log_path, scn.actuator.torque_limit)
    identify(scn, [log])  # warm-up (compiles or loads the kernels)
    times: list[float] = []
    res: IdentResult | None = None
    counter = _Count()
    try:
        for _ in range(3):
            counter.n = 0
            t0 = time.perf_counter()
            res = identify(scn, [log])
            times.append(time.perf_counter() - t0)
    finally:
        counter.close()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", "from esoarm.cli import main; main()",
                           "identify", str(log_path), "--json"], capture_output=True,
                          text=True, check=True)
    cli = time.perf_counter() - t0
    assert res is not None and proc.stdout
    return {"times": times, "cli": cli, "res": res, "simulations": counter.n}


def _estimate(res: IdentResult, key: str, digits: int = 4) -> str:
    e = res.estimates[key]
    return (f"{e.value:.{digits}g} ({e.ci95[0]:.{digits}g} … {e.ci95[1]:.{digits}g})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "benchmarks-identify.md"))
    args = parser.parse_args()
    load_before = os.getloadavg()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, sets in CASES.items():
            results[name] = run_case(sets, Path(tmp))
    load_after = os.getloadavg()
    rows = "\n".join(
        f"| {name} | {np.median(r['times']):.2f} ({max(r['times']):.2f}) | {r['cli']:.2f} | "
        f"{r['simulations']} |" for name, r in results.items())
    found = "\n".join(
        f"| {name} | {_estimate(r['res'], 'rig.inertia_scale')} | "
        f"{_estimate(r['res'], 'rig.coulomb_friction', 3)} | "
        f"{_estimate(r['res'], 'actuator.lag', 3)} | "
        f"{r['res'].value('actuator.delay_samples'):g} | {r['res'].iterations} | "
        f"{r['res'].validation['fit_percent']:.2f} |" for name, r in results.items())
    text = f"""# Identification benchmark

Measured with `python benchmarks/bench_identify.py` on {date.today().isoformat()}.

Machine: {machine()}.
Load average (1, 5, 15 min) before: {", ".join(f"{x:.2f}" for x in load_before)}; after:
{", ".join(f"{x:.2f}" for x in load_after)} (other work on the machine slows every number
here; the fit runs its simulations on all cores).

A 60 s experiment at 50 Hz (3000 samples, the default `esoarm excite` plan) on two twins of
test-1 with `rig.inertia_scale = 1.25`, `rig.coulomb_friction = 0.08`,
`rig.viscous_friction = 0.02` -- *friction* as such, *lag and delay* with
`actuator.lag = 0.03` s and `actuator.delay_samples = 1` as well -- fitted with the default
options of `esoarm identify` from test-1's values (delay 0 … 2 samples tried, the lag
tested, the last 25 % kept for validation).

{TIME_HEAD}
{rows}

What the fits found (95 % intervals in brackets; the truth is 1.25, 0.08 N·m, and 0 or
0.03 s with 0 or 1 sample of delay):

{FOUND_HEAD}
{found}
"""
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
