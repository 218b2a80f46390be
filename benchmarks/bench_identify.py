"""Benchmark of ``esoarm identify``: time to fit a 60 s log at 50 Hz.

Run:  python benchmarks/bench_identify.py [--out docs/benchmarks-identify.md]

1. A 60 s identification experiment (the default ``esoarm excite`` plan) is
   recorded on a twin with non-default parameters.
2. ``identify`` fits it (default options: delay search 0 … 2, lag test, 25 %
   kept for validation), three times after one warm-up run (numba's compiled
   kernel comes from the on-disk cache after the first run); median and max.
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
from esoarm.studies.excitation import ExcitationPlan
from esoarm.studies.identify import identify
from esoarm.studies.identify_data import read_ident_log

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_rig import machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TRUTH = ["rig.inertia_scale=1.25", "rig.coulomb_friction=0.08", "rig.viscous_friction=0.02",
         "sensor.seed=4"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "benchmarks-identify.md"))
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        log_path = Path(tmp) / "excite.csv"
        excite_twin(load_scenario("test-1", TRUTH), ExcitationPlan(), log_path)
        scn = load_scenario("test-1")
        log = read_ident_log(log_path, scn.actuator.torque_limit)
        identify(scn, [log])  # warm-up (compiles or loads the kernel)
        times, res = [], None
        for _ in range(3):
            t0 = time.perf_counter()
            res = identify(scn, [log])
            times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", "from esoarm.cli import main; main()",
                               "identify", str(log_path), "--json"], capture_output=True,
                              text=True, check=True)
        cli = time.perf_counter() - t0
    assert res is not None and proc.stdout
    load_after = os.getloadavg()[0]
    est = res.estimates
    text = f"""# Identification benchmark

Measured with `python benchmarks/bench_identify.py` on {date.today().isoformat()}.

Machine: {machine()}.
Load average (1 min) before / after: {load_before:.2f} / {load_after:.2f} (other work on the
machine slows every number here).

A 60 s experiment at 50 Hz (3000 samples, the default `esoarm excite` plan) on a twin with
`rig.inertia_scale = 1.25`, `rig.coulomb_friction = 0.08`, `rig.viscous_friction = 0.02`,
fitted with the default options of `esoarm identify` (delay 0 … 2 samples tried, the lag
tested, the last 25 % kept for validation).

| what | time [s] |
|---|---|
| `identify()` in-process, median of 3 (max) | {np.median(times):.2f} ({max(times):.2f}) |
| `esoarm identify LOG --json`, whole command in a new process | {cli:.2f} |

The fit found `rig.inertia_scale` = {est['rig.inertia_scale'].value:.4f}
(95 %: {est['rig.inertia_scale'].ci95[0]:.4f} … {est['rig.inertia_scale'].ci95[1]:.4f}),
`rig.coulomb_friction` = {est['rig.coulomb_friction'].value:.4f} N·m
({est['rig.coulomb_friction'].ci95[0]:.4f} … {est['rig.coulomb_friction'].ci95[1]:.4f}),
in {res.iterations} Levenberg-Marquardt iterations of the final fit; validation fit
{res.validation['fit_percent']:.2f} %.
"""
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
