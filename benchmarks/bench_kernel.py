"""The exact engine's kernel alone: CPU time and reference-count operations per run and sample.

Usage: ``python benchmarks/bench_kernel.py [--rounds 3]``.  Prints, for the canonical sweep's
grid (test-1, ε geometric over 100 points, 20 seeds) run on one thread by the blocked metrics
kernel (:func:`esoarm.engines.batch.run_metrics`):

* the CPU time per run [ms], best of ``--rounds``, with test-1's RK4 step (20 steps per
  sample) and with ``rig.step = 0.02`` (one step per sample: what the sample itself costs);
* the atomic reference-count increments and decrements the kernel performs per run and
  sample, counted by a copy of numba's runtime whose increment and decrement also count
  (in a child process: the counting runtime must be built before any kernel is loaded).

The kernels are compiled (or loaded from numba's cache) first, outside the timings.  Record
the machine load (printed) with every figure: other processes share the cores.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import subprocess
import sys
import time

EPS = "observer.eps=geom:0.03:0.3:100"


def grid(extra: list[str]):  # type: ignore[no-untyped-def]
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.sweep import build_grid

    return build_grid(load_scenario("test-1", extra), [EPS], seeds=20)


def cpu_per_run(extra: list[str], rounds: int) -> float:
    """Best CPU time per run [ms] of a quarter of the grid (500 runs), one thread."""
    from esoarm.engines import batch

    g = grid(extra)
    pts = list(g.points)[::4]
    batch.run_metrics(pts[:1], seeds=[0], workers=1)
    best = float("inf")
    for _ in range(rounds):
        c0 = time.process_time()
        batch.run_metrics(pts, seeds=g.seeds, workers=1)
        best = min(best, (time.process_time() - c0) / (len(pts) * len(g.seeds)) * 1e3)
    return best


def count_refcounts() -> None:
    """Child process: count the runtime's atomic increments/decrements per run and sample."""
    from llvmlite import ir
    from numba.core.runtime import nrtdynmod

    define = nrtdynmod._define_atomic_inc_dec

    def counting(module, op, ordering):  # type: ignore[no-untyped-def]
        fn = define(module, op, ordering)
        counter = ir.GlobalVariable(module, ir.IntType(64), name=f"bench_count_{op}")
        counter.initializer = ir.Constant(ir.IntType(64), 0)
        builder = ir.IRBuilder(fn.blocks[0])
        builder.position_at_start(fn.blocks[0])
        builder.store(builder.add(builder.load(counter), ir.Constant(ir.IntType(64), 1)),
                      counter)
        get = ir.Function(module, ir.FunctionType(ir.IntType(64), []), name=f"bench_get_{op}")
        b = ir.IRBuilder(get.append_basic_block())
        b.ret(b.load(counter))
        return fn

    nrtdynmod._define_atomic_inc_dec = counting
    from numba.core.runtime import nrt

    from esoarm.engines import batch

    g = grid([])
    pts = list(g.points)[::4]
    batch.run_metrics(pts[:1], seeds=[0], workers=1)
    lib = nrt.rtsys._library
    get = {op: ctypes.CFUNCTYPE(ctypes.c_int64)(lib.get_pointer_to_function(f"bench_get_{op}"))
           for op in ("add", "sub")}
    before = {op: f() for op, f in get.items()}
    batch.run_metrics(pts, seeds=g.seeds, workers=1)
    samples = len(pts) * len(g.seeds) * pts[0].n_samples
    inc, dec = ((get[op]() - before[op]) / samples for op in ("add", "sub"))
    print(f"{inc:.2f} {dec:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--count-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.count_child:
        count_refcounts()
        return
    print(f"load {os.getloadavg()[0]:.2f}", flush=True)
    full = cpu_per_run([], args.rounds)
    one = cpu_per_run(["rig.step=0.02"], args.rounds)
    out = subprocess.run([sys.executable, __file__, "--count-child"], check=True,
                         capture_output=True, text=True).stdout.split()
    print(f"CPU per run, one thread: {full:.3f} ms (20 RK4 steps per sample), "
          f"{one:.3f} ms (one RK4 step per sample)")
    print(f"reference-count increments per run-sample: {out[0]}, decrements: {out[1]}")
    print(f"load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
