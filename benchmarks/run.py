"""Benchmarks of esoarm's compiled batch engine (issue 3), in one command.

    python benchmarks/run.py            # everything, writes docs/benchmarks.md
    python benchmarks/run.py --quick    # skip the 100,000-run memory sweep

Canonical workload: ``esoarm sweep test-1 --vary observer.eps=geom:0.03:0.3:100
--seeds 20`` -- 2,000 runs of 20 s at a 1 ms RK4 step (40 M RK4 steps).  Measured
in one run, on one machine, against

(a) a plain-Python loop with the same semantics (esoarm's reference engine,
    ``run_reference``): a subset of the runs is timed and extrapolated;
(b) python-control ``input_output_response`` on the continuous-time closed loop
    (plant + eq. 8 ESO + FLC, no sampling, noise or quantization): a subset,
    extrapolated;
(c) ``benchmarks/loop.c``, a straightforward single-threaded C implementation of
    the SPEC §2 loop, built with ``gcc -O3`` here, fed the very same inputs.

Plus one compiled run against one C run, the first-call compile time, and the
peak memory of a 100,000-run metrics-only sweep.  Numbers depend on the
machine and on whatever else runs on it: the load average is recorded.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
DOC = ROOT / "docs" / "benchmarks.md"
SWEEP_ARGS = ["sweep", "test-1", "--vary", "observer.eps=geom:0.03:0.3:100", "--seeds", "20"]
BIG_ARGS = ["sweep", "test-1", "--vary", "observer.eps=geom:0.03:0.3:1000", "--seeds", "100"]
N_RUNS = 2000


def esoarm_cmd() -> list[str]:
    exe = shutil.which("esoarm")
    return [exe] if exe else [sys.executable, "-c", "from esoarm.cli import main; main()"]


def sh(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, check=False).stdout.strip()
    except OSError as exc:
        return f"({cmd[0]} unavailable: {exc})"


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def timed(cmd: list[str], env: dict[str, str] | None = None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


# ---------------------------------------------------------------------------


def canonical_grid():  # type: ignore[no-untyped-def]
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweep import build_grid

    return build_grid(load_scenario("test-1"), ["observer.eps=geom:0.03:0.3:100"], seeds=20)


def bench_c(grid, work: Path) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Build loop.c, feed it the canonical workload, time it, compare its metrics."""
    from esoarm.engines import batch

    exe = work / "loop"
    subprocess.run(["gcc", "-O3", "-o", str(exe), str(HERE / "loop.c"), "-lm"], check=True)
    runs = [(i, s) for i in range(len(grid.points)) for s in grid.seeds]
    pack = batch._pack(list(grid.points), runs)
    pts = np.hstack([pack.fpar, pack.rig, pack.obs, pack.ctl])
    assert pts.shape[1] == 41
    pts.astype("<f8").tofile(work / "points.f64")
    pack.ipar.astype("<i8").tofile(work / "ipoints.i64")
    pack.refs.astype("<f8").tofile(work / "refs.f64")
    pack.noises.astype("<f8").tofile(work / "noises.f64")
    np.column_stack([pack.run_point, pack.run_noise]).astype("<i8").tofile(work / "runs.i64")
    dims = [str(len(pts)), str(pack.refs.shape[0]), str(pack.noises.shape[0]), str(len(runs)),
            str(pack.refs.shape[2])]
    loop_times, walls = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        out = subprocess.run([str(exe), str(work), *dims], check=True, capture_output=True,
                             text=True).stdout
        walls.append(time.perf_counter() - t0)
        loop_times.append(float(out.strip()))
    c_metrics = np.fromfile(work / "metrics_c.f64").reshape(len(runs), 4)
    ours = batch.run_metrics(grid.points, seeds=grid.seeds).values
    rel = np.abs(c_metrics[:, :3] - ours[:, :3]) / np.abs(ours[:, :3])
    # one run alone
    np.array([[0, 0]], dtype="<i8").tofile(work / "runs.i64")
    one = []
    for _ in range(5):
        out = subprocess.run([str(exe), str(work), dims[0], dims[1], dims[2], "1", dims[4]],
                             check=True, capture_output=True, text=True).stdout
        one.append(float(out.strip()))
    return {"loop": min(loop_times), "wall": min(walls), "max_rel_diff": float(rel.max()),
            "one_run": min(one), "diverged_c": float(c_metrics[:, 3].sum()),
            "diverged_ours": float(ours[:, -1].sum())}


def bench_sweep_cli(work: Path) -> dict[str, float]:
    """The whole command, process start included (warm numba cache, and cold once)."""
    out = work / "sweep.csv"
    cmd = [*esoarm_cmd(), *SWEEP_ARGS, "--out", str(out)]
    cold_env = dict(os.environ, NUMBA_CACHE_DIR=str(work / "cold-cache"))
    cold = timed(cmd, cold_env)  # compiles the metrics kernel into an empty cache
    warm = [timed(cmd) for _ in range(3)]
    start = [timed([*esoarm_cmd(), "--version"]) for _ in range(3)]
    rows = len(out.read_text().splitlines()) - 1
    assert rows == N_RUNS, rows
    return {"warm": min(warm), "warm_all": warm, "cold": cold, "cli_start": min(start)}


def bench_inprocess(grid) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Kernel throughput in this process: all threads and one thread; one run alone."""
    from esoarm.engines import batch
    from esoarm.scenario import load_scenario

    batch.run_metrics(grid.points[:1], seeds=[0])  # warm (cached) kernel
    t_all = []
    for _ in range(2):
        t0 = time.perf_counter()
        batch.run_metrics(grid.points, seeds=grid.seeds)
        t_all.append(time.perf_counter() - t0)
    sub = grid.points[::10]  # 10 points × 20 seeds = 200 runs on one thread
    t0 = time.perf_counter()
    batch.run_metrics(sub, seeds=grid.seeds, workers=1)
    per_run_1t = (time.perf_counter() - t0) / (len(sub) * len(grid.seeds))
    scn = load_scenario("test-1")
    one = []
    for _ in range(20):
        t0 = time.perf_counter()
        batch.run_metrics([scn], workers=1)
        one.append(time.perf_counter() - t0)
    series = []
    for _ in range(10):
        t0 = time.perf_counter()
        batch.simulate_many([scn], workers=1)
        series.append(time.perf_counter() - t0)
    return {"all_threads": min(t_all), "per_run_1thread": per_run_1t, "one_run": min(one),
            "one_run_series": min(series)}


def bench_python(grid, n: int = 10) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """(a) the plain-Python reference loop on n runs, extrapolated to the sweep."""
    from esoarm.engines.simulation import prepare, run_reference

    idx = np.linspace(0, len(grid.points) - 1, n).astype(int)
    t0 = time.perf_counter()
    for k, i in enumerate(idx):
        scn = grid.points[i].with_overrides({"sensor.seed": int(k % len(grid.seeds))})
        run_reference(scn, prepare(scn))
    per_run = (time.perf_counter() - t0) / n
    return {"per_run": per_run, "subset": n, "extrapolated": per_run * N_RUNS}


def _continuous_loop(scn):  # type: ignore[no-untyped-def]
    """The continuous-time closed loop as a python-control nonlinear system.

    States (θ, θ̇, z1, z2, z3): the rig of SPEC §2 (no lag), the eq. 8 ESO fed
    y = θ, and the saturated FLC -- built from esoarm's own physics functions.
    """
    import control as ct

    from esoarm.controllers.flc import FLCParams, flc_control
    from esoarm.observers.linear import continuous_gains, eso_rhs
    from esoarm.plants.lever_arm import RigParams, rig_acceleration
    from esoarm.plants.model import input_gain
    from esoarm.reference import evaluate_reference

    rig = RigParams.from_scenario(scn).vector
    ctl = FLCParams.from_scenario(scn).vector
    b0 = input_gain(scn.plant.inertia)
    beta = continuous_gains(scn.observer.eps)
    ref = scn.reference

    def update(t, x, u, params):  # type: ignore[no-untyped-def]
        r, dr, ddr = (float(v[0]) for v in evaluate_reference(ref, t))
        uc = flc_control(x[2], x[3], x[4], r, dr, ddr, ctl)
        acc = rig_acceleration(x[0], x[1], uc, t, rig)
        return [x[1], acc, *eso_rhs(x[2], x[3], x[4], x[0], uc, b0, *beta)]

    return ct.nlsys(update, lambda t, x, u, params: x[0], states=5, inputs=0, outputs=1,
                    name="closed_loop")


def bench_control(grid, n: int = 3) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """(b) python-control input_output_response, continuous-time loop, n runs, extrapolated."""
    import control as ct

    from esoarm.reference import evaluate_reference

    times = []
    rms = []
    idx = np.linspace(0, len(grid.points) - 1, n).astype(int)
    for i in idx:
        scn = grid.points[i]
        sys_ = _continuous_loop(scn)
        t = np.arange(scn.n_samples) * scn.sample_time
        t0 = time.perf_counter()
        resp = ct.input_output_response(sys_, t, 0.0, [scn.rig.theta0, 0, scn.rig.theta0, 0, 0])
        times.append(time.perf_counter() - t0)
        theta_ref = evaluate_reference(scn.reference, t)[0]
        rms.append(float(np.sqrt(np.mean((resp.outputs - theta_ref) ** 2))))
    per_run = float(np.mean(times))
    return {"per_run": per_run, "subset": n, "extrapolated": per_run * N_RUNS,
            "eps": [float(grid.points[i].observer.eps) for i in idx], "rms_error": rms}


def bench_tune() -> list[dict]:  # type: ignore[type-arg]
    """What ``esoarm tune`` finds for ε on the twin, for several prices w of control."""
    from esoarm.scenario import load_scenario
    from esoarm.studies.tune import DEFAULT_OBJECTIVE, Objective, parse_bound, tune

    out = []
    cases = [("test-1", 0.1, ()), ("test-1", 1.0, ()), ("test-1", 10.0, ()), ("test-2", 1.0, ()),
             ("test-1", 1.0, ("rig.inertia_scale=0.8:1.2", "rig.coulomb_friction=0:0.1"))]
    for name, w, robust in cases:
        base = load_scenario(name)
        t0 = time.perf_counter()
        res = tune(base, [parse_bound("observer.eps=0.02:0.3", base)],
                   objective=Objective(DEFAULT_OBJECTIVE, w), seeds=5,
                   robust=[parse_bound(r, base, "--robust") for r in robust], samples=8)
        out.append({"scenario": name, "w": w, "robust": ", ".join(robust) or "none",
                    "eps": res.best["observer.eps"], "metrics": res.best_metrics,
                    "baseline": res.baseline, "runs": res.runs,
                    "seconds": time.perf_counter() - t0})
    return out


def bench_memory(work: Path) -> dict[str, float]:
    """Peak resident memory of a 100,000-run metrics-only sweep (its own process)."""
    out = work / "big.csv"
    wrapper = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
               "subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
               "print(time.perf_counter() - t, "
               "resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    res = subprocess.run([sys.executable, "-c", wrapper, *esoarm_cmd(), *BIG_ARGS, "--out",
                          str(out)], check=True, capture_output=True, text=True).stdout.split()
    rows = len(out.read_text().splitlines()) - 1
    return {"seconds": float(res[0]), "peak_mib": int(res[1]) / 1024.0, "rows": rows}


# ---------------------------------------------------------------------------


def verdict(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def write_doc(m: dict, machine: dict[str, str]) -> str:  # type: ignore[type-arg]
    c, cli, inp, py, pc = m["c"], m["cli"], m["inproc"], m["python"], m["control"]
    mem = m.get("memory")
    thr = {
        "esoarm sweep (whole command, warm cache)": N_RUNS / cli["warm"],
        "esoarm sweep (whole command, cold: compiles first)": N_RUNS / cli["cold"],
        "batch engine in-process, all threads (no start-up)": N_RUNS / inp["all_threads"],
        "batch engine in-process, 1 thread": 1.0 / inp["per_run_1thread"],
        "(c) C gcc -O3, single thread (loop only)": N_RUNS / c["loop"],
        "(c) C gcc -O3, single thread (process incl. input files)": N_RUNS / c["wall"],
        "(a) plain Python reference loop (extrapolated)": 1.0 / py["per_run"],
        "(b) python-control input_output_response (extrapolated)": 1.0 / pc["per_run"],
    }
    g_c = cli["warm"] and (N_RUNS / cli["warm"]) / (N_RUNS / c["loop"])
    g_py = py["extrapolated"] / cli["warm"]
    g_pc = pc["extrapolated"] / cli["warm"]
    one_ratio = inp["one_run"] / c["one_run"]
    lines = [
        "# Benchmarks",
        "",
        "Generated by `python benchmarks/run.py` (the numbers below are measured by that "
        "script in one run; rerun it to refresh this page). Issue 3 sets the goals.",
        "",
        "## Machine",
        "",
        f"- when: {machine['date']}",
        f"- load average before / after: {machine['load_before']} / {machine['load_after']} "
        "(other processes on this shared machine take CPU time too; a load above ~0.1 means "
        "the two cores were not ours alone)",
        f"- python {platform.python_version()}, numpy {machine['numpy']}, numba "
        f"{machine['numba']}, python-control {machine['control']}, {machine['gcc']}",
        "",
        "`nproc`: " + machine["nproc"],
        "",
        "```text",
        machine["lscpu"],
        "```",
        "",
        "```text",
        machine["free"],
        "```",
        "",
        "## Canonical workload",
        "",
        "`esoarm sweep test-1 --vary observer.eps=geom:0.03:0.3:100 --seeds 20` — 2,000 runs "
        "of 20 s, 1 ms RK4 step, 50 Hz sampling: 40 M RK4 steps.",
        "",
        "| engine | runs/s | time for 2,000 runs [s] | how measured |",
        "|---|---:|---:|---|",
    ]
    how = {
        "esoarm sweep (whole command, warm cache)": "wall time of the CLI process, best of 3, "
                                                    "CSV written",
        "esoarm sweep (whole command, cold: compiles first)": "same, empty NUMBA_CACHE_DIR",
        "batch engine in-process, all threads (no start-up)": "`run_metrics`, best of 2",
        "batch engine in-process, 1 thread": "200 runs, extrapolated",
        "(c) C gcc -O3, single thread (loop only)": "timer inside the C program, best of 3",
        "(c) C gcc -O3, single thread (process incl. input files)": "process wall time",
        "(a) plain Python reference loop (extrapolated)": f"{py['subset']} runs timed",
        "(b) python-control input_output_response (extrapolated)": f"{pc['subset']} runs timed "
        "(RK45, continuous time)",
    }
    for name, rate in thr.items():
        lines.append(f"| {name} | {rate:,.0f} | {N_RUNS / rate:,.2f} | {how[name]} |")
    lines += [
        "",
        f"- C and the batch engine agree: largest relative difference of rms_error, rms_u, "
        f"max_abs_error over the 2,000 runs = {c['max_rel_diff']:.1e} (C sums sequentially, "
        "NumPy pairwise); diverged runs: C "
        f"{c['diverged_c']:.0f}, esoarm {c['diverged_ours']:.0f}.",
        f"- python-control solves the continuous-time loop (no sampling, noise or "
        f"quantization), so its numbers differ by design: RMS error "
        f"{', '.join(f'{e:.4f}' for e in pc['rms_error'])} rad at ε = "
        f"{', '.join(f'{e:.3g}' for e in pc['eps'])} s.",
        f"- process start of `esoarm --version`: {cli['cli_start']:.2f} s; warm sweep runs: "
        f"{', '.join(f'{x:.2f}' for x in cli['warm_all'])} s.",
        "",
        "## One run",
        "",
        "| | time [ms] |",
        "|---|---:|",
        f"| batch engine, one run, metrics only, 1 thread (best of 20) | "
        f"{inp['one_run'] * 1e3:.2f} |",
        f"| batch engine, one run, full time series (best of 10) | "
        f"{inp['one_run_series'] * 1e3:.2f} |",
        f"| C gcc -O3, one run (best of 5) | {c['one_run'] * 1e3:.2f} |",
        f"| C gcc -O3, per run in the 2,000-run loop | {c['loop'] / N_RUNS * 1e3:.2f} |",
        f"| batch engine, per run on 1 thread in a 200-run batch | "
        f"{inp['per_run_1thread'] * 1e3:.2f} |",
        "",
        "## Memory",
        "",
    ]
    if mem:
        lines += [
            f"`esoarm {' '.join(BIG_ARGS)} --out big.csv` (100,000 runs, metrics only): "
            f"peak resident memory {mem['peak_mib']:.0f} MiB, {mem['seconds']:.0f} s, "
            f"{mem['rows']:,} rows written.",
            "",
        ]
    else:
        lines += ["Not measured in this run (`--quick`).", ""]
    lines += [
        "## Goals of issue 3",
        "",
        "| goal | measured | verdict |",
        "|---|---|---|",
        f"| whole sweep command ≥ 2× the throughput of (c) | {g_c:.2f}× | {verdict(g_c >= 2)} |",
        f"| whole sweep command > 1,000× (a) | {g_py:,.0f}× | {verdict(g_py > 1000)} |",
        f"| (for reference) whole sweep command vs (b) | {g_pc:,.0f}× | — |",
        f"| one compiled run within 2× of one C run | {one_ratio:.2f}× | "
        f"{verdict(one_ratio <= 2)} |",
    ]
    if mem:
        lines.append(f"| 100,000-run metrics-only sweep < 1 GiB | {mem['peak_mib']:.0f} MiB | "
                     f"{verdict(mem['peak_mib'] < 1024)} |")
    lines += ["", "## Reading the numbers", "", *m["notes"], ""]
    if m.get("tune"):
        lines += [
            "## What `esoarm tune` finds for ε on the twin",
            "",
            "`tune(..., --vary observer.eps=0.02:0.3, --seeds 5)`, objective "
            "`rms_error + w*rms_u`, differential evolution (seed 0); the paper chose ε = 0.09 s.",
            "",
            "| scenario | w [rad/(N·m)] | robust samples over | best ε [s] | RMS error [rad] | "
            "RMS u [N·m] | at ε = 0.09: RMS error, RMS u | runs | time [s] |",
            "|---|---:|---|---:|---:|---:|---|---:|---:|",
        ]
        for t in m["tune"]:
            b, base = t["metrics"], t["baseline"]
            lines.append(
                f"| {t['scenario']} | {t['w']:g} | {t['robust']} | {t['eps']:.3f} | "
                f"{b['rms_error']:.4f} | {b['rms_u']:.4f} | {base['rms_error']:.4f}, "
                f"{base['rms_u']:.4f} | {t['runs']:,} | {t['seconds']:.1f} |")
        lines.append("")
    return "\n".join(lines)


def notes(m: dict) -> list[str]:  # type: ignore[type-arg]
    c, cli, inp, py = m["c"], m["cli"], m["inproc"], m["python"]
    per_c = c["loop"] / N_RUNS
    per_nb = inp["per_run_1thread"]
    best_case = N_RUNS * per_nb / 2 + cli["cli_start"]
    return [
        f"- Per run on one core the compiled engine takes {per_nb * 1e3:.2f} ms and the C loop "
        f"{per_c * 1e3:.2f} ms ({per_nb / per_c:.2f}×): both spend their time in libm "
        "(4 `tanh`, 4 `cos`, 4 `sin` per RK4 step) and in the same arithmetic, which has to be "
        "evaluated in the same order for the results to stay bit-identical with the reference "
        "engine (no fast-math, no vectorized transcendental functions).",
        f"- On 2 cores the best the whole command can do is therefore about half the "
        f"single-core time plus the process start: ≈ {best_case:.1f} s, against "
        f"{c['loop']:.1f} s for C, i.e. at most ≈ {c['loop'] / best_case:.2f}× C. The ≥ 2× goal "
        "would need the engine to beat C per core, which the bit-identity requirement rules "
        "out here.",
        f"- The > 1,000× goal over plain Python needs the 2,000 runs in under "
        f"{py['extrapolated'] / 1000:.2f} s including process start; the plain-Python loop is "
        f"{py['per_run'] * 1e3:.0f} ms per run (simple float arithmetic, which CPython runs "
        "comparatively fast), so the attainable ratio on 2 cores is about "
        f"{py['per_run'] / (per_nb / 2):.0f}× for the kernel alone.",
        "- Start-up: importing numpy/numba/pydantic and loading the cached kernels is included "
        "in the whole-command times; the first run after installation also compiles the "
        "kernel (the 'cold' row).",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 100,000-run sweep")
    parser.add_argument("--no-doc", action="store_true", help="do not write docs/benchmarks.md")
    args = parser.parse_args()
    import control
    import numba

    machine = {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "load_before": load(),
        "lscpu": sh(["lscpu"]),
        "nproc": sh(["nproc"]),
        "free": sh(["free", "-h"]),
        "gcc": sh(["gcc", "--version"]).splitlines()[0],
        "numpy": np.__version__,
        "numba": numba.__version__,
        "control": control.__version__,
    }
    m: dict = {}  # type: ignore[type-arg]
    grid = canonical_grid()
    with tempfile.TemporaryDirectory(prefix="esoarm-bench-") as tmp:
        work = Path(tmp)
        print("C baseline ...", flush=True)
        m["c"] = bench_c(grid, work)
        print(m["c"], flush=True)
        print("esoarm sweep command ...", flush=True)
        m["cli"] = bench_sweep_cli(work)
        print(m["cli"], flush=True)
        print("in-process engine ...", flush=True)
        m["inproc"] = bench_inprocess(grid)
        print(m["inproc"], flush=True)
        print("plain Python ...", flush=True)
        m["python"] = bench_python(grid)
        print(m["python"], flush=True)
        print("python-control ...", flush=True)
        m["control"] = bench_control(grid)
        print(m["control"], flush=True)
        print("tuning study ...", flush=True)
        m["tune"] = bench_tune()
        print([(t["scenario"], t["w"], t["eps"]) for t in m["tune"]], flush=True)
        if not args.quick:
            print("100,000-run sweep (memory) ...", flush=True)
            m["memory"] = bench_memory(work)
            print(m["memory"], flush=True)
    machine["load_after"] = load()
    m["notes"] = notes(m)
    text = write_doc(m, machine)
    if not args.no_doc:
        DOC.parent.mkdir(parents=True, exist_ok=True)
        DOC.write_text(text, encoding="utf-8")
        print(f"wrote {DOC}")
    else:
        print(text)


if __name__ == "__main__":
    main()
