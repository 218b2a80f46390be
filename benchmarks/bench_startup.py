"""Start-up and fixed cost of ``esoarm sweep``: where the time outside the kernels goes.

    python benchmarks/bench_startup.py            # best of 5, prints Markdown tables
    python benchmarks/bench_startup.py --reps 10

Measures, warm (kernels built and cached, Python bytecode compiled as after
``pip install``), best of ``--reps``:

* the wall and CPU time of ``esoarm --help``, a one-run sweep on each engine and the
  canonical sweep (``--vary observer.eps=geom:0.03:0.3:100 --seeds 20``, 2,000 runs)
  on each engine;
* the same canonical sweep run in this process (:func:`esoarm.studies.sweeps.sweep.iter_sweep`,
  kernels already loaded): the whole command minus this is the command's fixed cost;
* the phases of that fixed cost, each timed in a fresh interpreter.

The machine may be shared: the load average is printed; take the best of several runs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from run import WARM_ENV as ENV  # noqa: E402 - bytecode cached, as after pip install
from run import esoarm_cmd, load, run_proc, sweep_cmd  # noqa: E402

#: Phases of a sweep's start-up, each timed in a fresh interpreter (cumulative steps).
PROBE = r"""
import sys, time
t0 = time.perf_counter()
marks = []
def mark(name):
    marks.append((name, time.perf_counter()))
import esoarm.cli, esoarm.cli.studies.sweep; mark("import esoarm.cli (click)")
from esoarm.scenario import load_scenario; mark("import esoarm.scenario (numpy, pydantic, kinds)")
from esoarm.studies.sweeps.sweep import build_grid; mark("import studies.sweep")
grid = build_grid(load_scenario("test-1"), ["observer.eps=geom:0.03:0.3:100"], 20)
mark("load test-1, build and check the grid (100 points)")
engine = sys.argv[1]
if engine == "exact":
    from esoarm.engines.simulation import reference_metrics
    mark("import engines.simulation (the reference engine)")
    reference_metrics(grid.points[:1], [0])
    mark("one 20 s run on the reference engine (a sweep of <= 3 runs)")
    import numba; mark("import numba")
    from esoarm.engines import batch; mark("import engines.batch (physics stamp, kernels)")
    from numba.core.registry import cpu_target
    cpu_target.target_context.refresh()
    mark("numba target refresh (its implementations; no scipy.linalg: esoarm._jit)")
    batch.run_metrics(grid.points[:1], seeds=[0, 1, 2, 3], workers=1)
    mark("load the cached kernel, one tiny call")
    assert "scipy.linalg" not in sys.modules
else:
    from esoarm.engines import fast; mark("import engines.fast")
    fast.load_kernel(); mark("locate and load the C kernel")
    fast.run_metrics(grid.points[:1], [0]); mark("one 20 s run on the C kernel")
pts = grid.points[0:100]; mark("build the 100 points again (per chunk)")
from esoarm.engines.packing import _pack
_pack(pts, [(i, s) for i in range(100) for s in range(20)]); mark("pack 2,000 runs (noise, refs)")
import rich.console, rich.table; mark("import rich (the summary table)")
prev = t0
for name, t in marks:
    print(f"{name}\t{t - prev:.4f}")
    prev = t
"""


def best(cmd: list[str], reps: int) -> tuple[float, float]:
    """Best wall time and best CPU time (user + system) [s] of ``cmd`` over ``reps`` runs."""
    run_proc(cmd, ENV)  # warm
    walls, cpu = [], []
    for _ in range(reps):
        walls.append(run_proc(cmd, ENV, cpu=cpu)[0])
    return min(walls), min(cpu)


def in_process(engine: str) -> float:
    """The canonical sweep in this process, kernels loaded first [s]."""
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.sweep import build_grid, iter_sweep

    grid = build_grid(load_scenario("test-1"), ["observer.eps=geom:0.03:0.3:100"], 20)
    small = build_grid(load_scenario("test-1"), ["observer.eps=0.09"], 4)
    for _ in iter_sweep(small, engine=engine):  # load the kernels
        pass
    t0 = time.perf_counter()
    for _ in iter_sweep(grid, engine=engine):
        pass
    return time.perf_counter() - t0


def phases(engine: str, reps: int) -> list[tuple[str, float]]:
    """Each phase's best time over ``reps`` fresh interpreters."""
    runs = []
    for _ in range(reps):
        out = subprocess.run([sys.executable, "-c", PROBE, engine], capture_output=True,
                             text=True, check=True, env=ENV).stdout
        runs.append([(a, float(b)) for a, b in (ln.split("\t") for ln in out.splitlines())])
    return [(name, min(r[i][1] for r in runs)) for i, (name, _) in enumerate(runs[0])]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=5, help="runs of each command (best kept)")
    args = parser.parse_args()
    print(f"load average before: {load()}\n")
    out = Path(os.environ.get("TMPDIR", "/tmp")) / f"esoarm-bench-startup-{os.getpid()}.csv"
    rows = [("`esoarm --help`", [*esoarm_cmd(), "--help"])]
    for engine in ("exact", "fast"):
        rows.append((f"one-run sweep, {engine}", sweep_cmd(1, 1, engine)))
    for engine in ("exact", "fast"):
        rows.append((f"canonical sweep (2,000 runs), {engine}", sweep_cmd(100, 20, engine, out)))
    print("| command (warm) | wall [s] | CPU [s] |\n|---|---:|---:|")
    whole = {}
    for label, cmd in rows:
        wall, cpu = best(cmd, args.reps)
        whole[label] = wall
        print(f"| {label} | {wall:.3f} | {cpu:.3f} |", flush=True)
    out.unlink(missing_ok=True)
    print("\n| engine | whole command [s] | sweep in-process [s] | fixed cost [s] |\n"
          "|---|---:|---:|---:|")
    for engine in ("exact", "fast"):
        inner = min(in_process(engine) for _ in range(max(1, args.reps // 2)))
        total = whole[f"canonical sweep (2,000 runs), {engine}"]
        print(f"| {engine} | {total:.3f} | {inner:.3f} | {total - inner:.3f} |", flush=True)
    t_py = min(run_proc([sys.executable, "-c", "pass"], ENV)[0] for _ in range(args.reps))
    for engine in ("exact", "fast"):
        print(f"\nPhases of the fixed cost, {engine} engine (best of {args.reps} fresh "
              "interpreters each):\n\n| phase | [s] |\n|---|---:|")
        print(f"| start the interpreter (`python -c pass`) | {t_py:.3f} |")
        for name, t in phases(engine, args.reps):
            print(f"| {name} | {t:.3f} |", flush=True)
    print(f"\nload average after: {load()}")


if __name__ == "__main__":
    main()
