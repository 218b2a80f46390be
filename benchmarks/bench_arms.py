"""Benchmarks of URDF arms on the reference engine (issue 14), in one command; prints its table.

The arms' section of docs/benchmarks.md (the compiled engine, against the lever
arm at the same rate) is written by ``python benchmarks/run.py --only-arms``;
this script keeps the reference engine's numbers and the plain Pinocchio loop
(``plain_params``, ``_plain_run``) that run.py reuses.

    python benchmarks/bench_arms.py                 # one 20 s run + a 1,000-run sweep
    python benchmarks/bench_arms.py --sweep-duration 20   # the sweep's runs at full length

Workloads, both on the built-in ``two-link`` scenario (200 Hz, 1 ms RK4 step):

(a) one 20 s run (4,000 samples, 20,000 RK4 steps, 80,000 ABA calls):
    ``esoarm simulate two-link`` (the reference engine, the only engine that can
    call Pinocchio) against a plain-Python Pinocchio loop doing the same work
    (``tests/reference_arm.py`` with ``dynamics = "aba"``: per RK4 stage one
    ``pinocchio.aba`` and NumPy friction, per sample CRBA + solve for the
    controller and per-joint Euler ESOs);
(b) a 1,000-run sweep ``esoarm sweep two-link --vary observer.eps=geom:0.005:0.1:100
    --seeds 10`` (runs in worker processes, one per core), against the plain
    loop run in the same number of processes on a subset, extrapolated.

Numbers depend on the machine and on whatever else runs on it: the load
average is recorded.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
BEGIN, END = "<!-- begin:arms-reference -->", "<!-- end:arms-reference -->"
SWEEP = ["--vary", "observer.eps=geom:0.005:0.1:100", "--seeds", "10"]


#: The plain Pinocchio loop: the tests' independent reference for the arms, reused here as
#: the baseline (it is in the source checkout, not in the installed package).
PLAIN_LOOP = ROOT / "tests" / "reference_arm.py"


def plain_loop_missing() -> str | None:
    """Why the plain Pinocchio loop cannot run here (None when it can).

    The benchmarks need no ``tests/``: without it (or without Pinocchio) only this
    baseline is skipped, and the page says so.
    """
    if not PLAIN_LOOP.is_file():
        return f"{PLAIN_LOOP.relative_to(ROOT)} is not in this checkout"
    if importlib.util.find_spec("pinocchio") is None:
        return "pinocchio is not installed (pip install 'esoarm[arms]')"
    return None


def _plain_module():
    spec = importlib.util.spec_from_file_location("reference_arm", PLAIN_LOOP)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def plain_params(scn) -> dict:
    """The plain loop's parameters for an esoarm two-link scenario."""
    from esoarm.engines.simulation import prepare

    inp = prepare(scn, draw_noise=False)
    n = inp.plant.n_joints
    refs = inp.refs
    ref = tuple(np.column_stack([refs[3 * j + i] for j in range(n)]) for i in range(3))
    p, r = scn.plant, scn.rig
    return {"urdf": p.file, "g": p.g, "payload_mass": p.payload_mass,
            "payload_offset": tuple(p.payload_offset), "inertia_scale": r.inertia_scale,
            "coulomb": r.coulomb_friction, "vs": r.friction_velocity,
            "viscous": r.viscous_friction, "d_amp": r.disturbance.amplitude,
            "d_freq": r.disturbance.frequency, "rate_hz": scn.sensor.rate_hz, "step": r.step,
            "duration": scn.duration, "noise_deg": scn.sensor.noise_deg,
            "resolution_deg": scn.sensor.resolution_deg, "seed": scn.sensor.seed,
            "eps": scn.observer.eps, "k1": scn.controller.k1, "k2": scn.controller.k2,
            "torque_limit": scn.actuator.torque_limit,
            "compensation": scn.controller.compensation, "reference": ref, "dynamics": "aba"}


def _plain_run(params: dict) -> float:
    module = _plain_module()
    t0 = time.perf_counter()
    module.run_plain(params)
    return time.perf_counter() - t0


def esoarm_cmd() -> list[str]:
    """This interpreter's esoarm (not whichever ``esoarm`` is first on PATH)."""
    return [sys.executable, "-m", "esoarm"]


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweep-duration", type=float, default=2.0,
                    help="duration [s] of each sweep run (default 2: the sweep is 1,000 runs "
                    "of 400 samples; 20 for full-length runs)")
    ap.add_argument("--plain-subset", type=int, default=8,
                    help="plain-loop sweep runs actually timed (then extrapolated)")
    args = ap.parse_args()

    missing = plain_loop_missing()
    if missing is not None:
        raise SystemExit(f"bench_arms.py compares esoarm with the plain Pinocchio loop: {missing}")
    import pinocchio

    from esoarm import __version__
    from esoarm.engines.simulation import simulate
    from esoarm.scenario import load_scenario

    load_before = load()
    cores = os.cpu_count() or 1
    scn = load_scenario("two-link")
    # (a) one run: esoarm (warm: numba helpers compiled and cached by a first run)
    simulate(scn, warn=False)
    esoarm_times = []
    for _ in range(3):
        t0 = time.perf_counter()
        res = simulate(scn, warn=False)
        esoarm_times.append(time.perf_counter() - t0)
    params = plain_params(scn)
    plain_times = [_plain_run(params) for _ in range(3)]
    plain_out = _plain_module().run_plain(params)
    plain_rms = float(np.sqrt(np.mean(plain_out["error"] ** 2)))
    t_one, t_plain = min(esoarm_times), min(plain_times)
    print(f"one run: esoarm {t_one:.2f} s, plain Pinocchio loop {t_plain:.2f} s")

    # (b) the 1,000-run sweep through the CLI (processes)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sweep.csv"
        cmd = [*esoarm_cmd(), "sweep", "two-link", *SWEEP, "--set",
               f"duration={args.sweep_duration!r}", "--out", str(out)]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        t_sweep = time.perf_counter() - t0
        if done.returncode != 0:
            raise SystemExit(f"sweep failed: {done.stderr.strip()}")
        n_runs = sum(1 for _ in out.open()) - 1
    print(f"sweep: {n_runs} runs in {t_sweep:.1f} s")
    short = load_scenario("two-link", [f"duration={args.sweep_duration!r}"])
    eps_grid = np.geomspace(0.005, 0.1, args.plain_subset)
    subset = [plain_params(short.with_overrides({"observer.eps": float(e)})) for e in eps_grid]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=cores) as pool:
        list(pool.map(_plain_run, subset))
    t_plain_subset = time.perf_counter() - t0
    t_plain_sweep = t_plain_subset * n_runs / len(subset)
    print(f"plain loop sweep (extrapolated from {len(subset)}): {t_plain_sweep:.0f} s")

    rows = [
        ("one 20 s run (4,000 samples, 20,000 RK4 steps)", f"{t_one:.2f} s",
         f"{t_plain:.2f} s", f"{t_plain / t_one:.1f}×"),
        (f"sweep: {n_runs} runs of {args.sweep_duration:g} s, {cores} processes",
         f"{t_sweep:.0f} s ({n_runs / t_sweep:.1f} runs/s)",
         f"{t_plain_sweep:.0f} s (extrapolated from {len(subset)} runs)",
         f"{t_plain_sweep / t_sweep:.1f}×"),
    ]
    lines = [
        BEGIN,
        "## URDF arms",
        "",
        "Measured by `python benchmarks/bench_arms.py` (printed, not written to the docs). "
        "`esoarm simulate` runs an arm on the reference engine (Pinocchio); `sweep` runs it "
        "on the compiled engine. The baseline is the computed-torque loop a Pinocchio user "
        "writes in plain Python (`tests/reference_arm.py`, `dynamics = \"aba\"`).",
        "",
        f"- when: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; machine: "
        f"{platform.processor() or platform.machine()}, {cores} cores; load average before / "
        f"after: {load_before} / {load()}",
        *([f"- the cores were shared with other work (load average ≈ "
            f"{os.getloadavg()[0]:.0f} on {cores} cores): absolute times are several times an "
            "idle machine's; the ratios, measured back to back, are the point"]
          if os.getloadavg()[0] > 1.5 * cores else []),
        f"- esoarm {__version__}, Pinocchio {pinocchio.__version__}, numpy {np.__version__}, "
        f"python {platform.python_version()}",
        f"- two-link, 20 s: RMS tracking error {res.rms_error:.4f} rad (esoarm) and "
        f"{plain_rms:.4f} rad (plain loop, Euler ESOs as esoarm's default)",
        "",
        "| workload | esoarm | plain-Python Pinocchio loop | speed-up |",
        "|---|---|---|---|",
        *(f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows),
        "",
        f"One run: best of 3 (esoarm {', '.join(f'{t:.2f}' for t in esoarm_times)} s; plain "
        f"{', '.join(f'{t:.2f}' for t in plain_times)} s). Sweep: "
        f"`esoarm sweep two-link {' '.join(SWEEP)} --set duration={args.sweep_duration:g}` "
        "wall time including start-up.",
        END,
    ]
    print("\n".join(lines[1:-1]))  # printed only: docs/benchmarks.md's arms section is
    # written by `python benchmarks/run.py --only-arms` (the compiled engine's arms)

if __name__ == "__main__":
    main()
