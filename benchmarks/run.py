"""Benchmarks of esoarm's engines, in one command; writes docs/benchmarks.md.

    python benchmarks/run.py            # everything (~15 min on 2 cores)
    python benchmarks/run.py --quick    # small sizes, a smoke test (numbers not meaningful)

Canonical workload: ``esoarm sweep test-1 --vary observer.eps=geom:0.03:0.3:100
--seeds 20`` -- 2,000 runs of 20 s at a 1 ms RK4 step (40 M RK4 steps).  The
exact engine (default) and the fast engine (``--engine fast``) are measured
against

(c) ``benchmarks/loop.c``, a straightforward single-threaded C implementation of
    the same loop, built with ``gcc -O3`` here and fed the very same inputs;
(a) a plain-Python loop with the same semantics (esoarm's reference engine),
    a subset timed and extrapolated;
(b) python-control ``input_output_response`` on the continuous-time closed loop,
    a subset timed and extrapolated.

Every ratio is measured in one run, engine and C loop back to back (rounds of
C, exact, fast), because the machine may be shared: the load average is
recorded.  Also: cold (empty caches) and warm whole commands, start-up
(``esoarm --help``, a one-run sweep), throughput against the number of runs
(1 to 10⁵, plotted), peak memory, and a 1,000,000-run metrics-only sweep.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
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
PLOT = ROOT / "docs" / "img" / "throughput.png"
VARY = "observer.eps=geom:0.03:0.3:100"
SWEEP_ARGS = ["sweep", "test-1", "--vary", VARY, "--seeds", "20"]
N_RUNS = 2000


def esoarm_cmd() -> list[str]:
    exe = Path(sys.executable).with_name("esoarm")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("esoarm")
    return [found] if found else [sys.executable, "-m", "esoarm"]


def sh(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, check=False).stdout.strip()
    except OSError as exc:
        return f"({cmd[0]} unavailable: {exc})"


def kept_sections() -> str:
    """Sections of docs/benchmarks.md written by other benchmark scripts, kept on rewrite.

    A script owns the text between ``<!-- begin:NAME -->`` and ``<!-- end:NAME -->``
    (e.g. ``benchmarks/bench_arms.py``).
    """
    import re

    old = DOC.read_text(encoding="utf-8") if DOC.exists() else ""
    blocks = re.findall(r"<!-- begin:[\w-]+ -->.*?<!-- end:[\w-]+ -->\n?", old, re.S)
    return "".join("\n" + b if b.endswith("\n") else "\n" + b + "\n" for b in blocks)


def replace_section(text: str, section: str) -> str:
    """``text`` with its ``<!-- begin:NAME -->`` … ``<!-- end:NAME -->`` block replaced by
    ``section`` (a block of the same NAME), or with ``section`` appended."""
    import re

    found = re.match(r"<!-- begin:([\w-]+) -->", section)
    if found is None:
        raise ValueError("a section starts with its begin marker")
    name = found.group(1)
    pattern = re.compile(rf"<!-- begin:{name} -->.*?<!-- end:{name} -->\n?", re.S)
    if pattern.search(text):
        return pattern.sub(lambda _: section, text, count=1)
    return text.rstrip("\n") + "\n\n" + section


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


#: The environment of the commands timed warm: Python may cache bytecode (as after
#: ``pip install``) even where PYTHONDONTWRITEBYTECODE is set (a sandbox, a CI).
WARM_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


#: GNU time reports the peak resident memory of the command it starts (its ``%M``).
GNU_TIME = "/usr/bin/time"


def run_proc(cmd: list[str], env: dict[str, str] | None = None,
             cpu: list[float] | None = None, memory: bool = False) -> tuple[float, float]:
    """Run a command; return (wall time [s], peak resident memory [MiB] or nan).

    With ``cpu``, the process's CPU time (user + system) [s] is appended to it.  Without
    ``env``, the command runs in :data:`WARM_ENV`.  With ``memory``, the command runs under
    GNU time, which forks it from its own small process and reports its peak resident
    memory: read from this process's ``wait4``, the peak would include this (large)
    process's own, which Linux hands on through ``vfork`` + ``exec``.  Without ``memory`` or
    without GNU time, the memory is nan.
    """
    wrap = memory and os.path.exists(GNU_TIME)
    full = [GNU_TIME, "-f", "esoarm-bench-maxrss %M", *cmd] if wrap else cmd
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(full, env=WARM_ENV if env is None else env,
                                stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        text = err.read().decode(errors="replace")
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {text[-2000:]}")
    if cpu is not None:
        cpu.append(usage.ru_utime + usage.ru_stime)
    peak = float("nan")
    for line in text.splitlines():
        if line.startswith("esoarm-bench-maxrss "):
            peak = int(line.split()[1]) / 1024.0  # KiB
    return wall, peak


def sweep_cmd(points: int, seeds: int, engine: str, out: Path | None = None) -> list[str]:
    vary = f"observer.eps=geom:0.03:0.3:{points}" if points > 1 else "observer.eps=0.09"
    cmd = [*esoarm_cmd(), "sweep", "test-1", "--vary", vary, "--seeds", str(seeds),
           "--engine", engine]
    return [*cmd, "--out", str(out)] if out else cmd


def split_runs(runs: int) -> tuple[int, int]:
    """(points, seeds) with points × seeds = runs, 20 seeds where possible."""
    seeds = min(runs, 20)
    return runs // seeds, seeds


# ---------------------------------------------------------------------------
# the C loop


class CLoop:
    """benchmarks/loop.c built here, fed the canonical inputs (runs cycled for other sizes)."""

    def __init__(self, grid, work: Path) -> None:  # type: ignore[no-untyped-def]
        from esoarm.engines import batch

        self.work = work
        self.exe = work / "loop"
        subprocess.run(["gcc", "-O3", "-o", str(self.exe), str(HERE / "loop.c"), "-lm"],
                       check=True)
        self.runs = [(i, s) for i in range(len(grid.points)) for s in grid.seeds]
        pack = batch._pack(list(grid.points), self.runs)
        # loop.c's layout: theta0, sigma, q, h, ts, b0 | rig[8] | obs[21] | ctl[6] (the kinds'
        # vectors without their CODE in element 0)
        fpar = np.column_stack([pack.x0[:, 0], pack.fpar, pack.b0[:, 0]])
        pts = np.hstack([fpar, pack.pp[:, 1:9], pack.op[:, 1:22], pack.cp[:, 1:7]])
        assert pts.shape[1] == 41
        pts.astype("<f8").tofile(work / "points.f64")
        pack.ipar[:, :4].astype("<i8").tofile(work / "ipoints.i64")
        pack.refs.astype("<f8").tofile(work / "refs.f64")
        pack.noises.astype("<f8").tofile(work / "noises.f64")
        self.pairs = np.column_stack([pack.run_point, pack.run_noise]).astype("<i8")
        self.dims = [str(len(pts)), str(pack.refs.shape[0]), str(pack.noises.shape[0]),
                     str(pack.refs.shape[2])]

    def time(self, runs: int | None = None) -> float:
        """Loop time [s] (timer inside the C program) of ``runs`` runs (default all)."""
        n = len(self.pairs) if runs is None else runs
        self.pairs[np.arange(n) % len(self.pairs)].tofile(self.work / "runs.i64")
        out = subprocess.run([str(self.exe), str(self.work), *self.dims[:3], str(n),
                              self.dims[3]], check=True, capture_output=True, text=True).stdout
        return float(out.strip())

    def metrics(self) -> np.ndarray:
        return np.fromfile(self.work / "metrics_c.f64").reshape(-1, 4)


# ---------------------------------------------------------------------------
# measurements


def canonical_grid(extra: tuple[str, ...] = ()):  # type: ignore[no-untyped-def]
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.sweep import build_grid

    return build_grid(load_scenario("test-1", list(extra)), [VARY], seeds=20)


def bench_canonical(c: CLoop, work: Path, rounds: int,
                    cold: bool = True) -> dict:  # type: ignore[type-arg]
    """Rounds of (C loop, exact command, fast command), back to back; cold runs first."""
    out = work / "sweep.csv"
    cold_exact = cold_fast = float("nan")
    if cold:
        cold_env = dict(os.environ, NUMBA_CACHE_DIR=str(work / "cold-numba"),
                        ESOARM_CACHE_DIR=str(work / "cold-esoarm"))
        cold_exact, _ = run_proc(sweep_cmd(100, 20, "exact", out), cold_env)
        shutil.rmtree(work / "cold-numba", ignore_errors=True)
        cold_fast, _ = run_proc(sweep_cmd(100, 20, "fast", out), cold_env)
    res: dict = {"c": [], "exact": [], "fast": [], "cold_exact": cold_exact,  # type: ignore[type-arg]
                 "cold_fast": cold_fast, "load": []}
    run_proc(sweep_cmd(100, 20, "exact", out))  # warm both caches: the numba kernels
    run_proc(sweep_cmd(100, 20, "fast", out))  # and the C kernel
    for _ in range(rounds):
        res["load"].append(os.getloadavg()[0])
        res["c"].append(c.time())
        res["exact"].append(run_proc(sweep_cmd(100, 20, "exact", out))[0])
        res["fast"].append(run_proc(sweep_cmd(100, 20, "fast", out))[0])
    rows = len(out.read_text().splitlines()) - 1
    assert rows == N_RUNS, rows
    res["ratio_exact"] = [ci / e for ci, e in zip(res["c"], res["exact"], strict=True)]
    res["ratio_fast"] = [ci / f for ci, f in zip(res["c"], res["fast"], strict=True)]
    return res


def bench_inprocess(grid, c: CLoop, quick: bool) -> dict:  # type: ignore[type-arg, no-untyped-def]
    """Engines in this process (no start-up): all threads and one thread, CPU time per run."""
    from esoarm.engines import batch, fast

    pts, seeds = list(grid.points), grid.seeds
    batch.run_metrics(pts[:1], seeds=[0])  # every kernel timed below loaded (or compiled)
    batch.run_metrics(pts[:1], seeds=[0], blocked=False)  # first, not inside the timing
    fast.run_metrics(pts[:1], seeds=[0])
    out: dict = {}  # type: ignore[type-arg]
    t0 = time.perf_counter()
    exact = batch.run_metrics(pts, seeds=seeds).values
    out["exact_all"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    quick_vals = fast.run_metrics(pts, seeds=seeds).values
    out["fast_all"] = time.perf_counter() - t0
    sub = pts[:: (10 if not quick else 50)]
    n_sub = len(sub) * len(seeds)
    runners = {"exact": batch.run_metrics, "fast": fast.run_metrics,
               "unblocked": lambda *a, **k: batch.run_metrics(*a, blocked=False, **k)}
    for name, fn in runners.items():
        c0 = time.process_time()
        fn(sub, seeds=seeds, workers=1)
        out[f"{name}_cpu_per_run"] = (time.process_time() - c0) / n_sub
    out["scalar_c_cpu_per_run"] = scalar_block_c(sub, seeds, c.work)
    c0 = time.process_time()
    out["c_per_run_sub"] = c.time(n_sub) / n_sub
    c.time()  # all runs: the C loop's metrics against the exact engine's
    out["c_vs_exact_rel"] = float(np.max(np.abs(c.metrics()[:, :3] - exact[:, :3])
                                         / np.abs(exact[:, :3])))
    del c0
    rel = np.abs(quick_vals - exact) / np.maximum(np.abs(exact), 1e-300)
    out["fast_rel_quantized"] = float(rel[:, :5].max())
    out["fast_differing_quantized"] = int((rel[:, :5] > 1e-9).any(axis=1).sum())
    g0 = canonical_grid(("sensor.resolution_deg=0",))
    e0 = batch.run_metrics(list(g0.points), seeds=g0.seeds).values
    f0 = fast.run_metrics(list(g0.points), seeds=g0.seeds).values
    with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 where both are 0 (nan: skipped)
        rel0 = np.abs(f0 - e0) / np.abs(e0)
    out["fast_rel_unquantized"] = float(np.nanmax(rel0[:, :5]))
    out["diverged"] = (int(exact[:, -1].sum()), int(quick_vals[:, -1].sum()))
    return out


def scalar_block_c(points, seeds, work: Path) -> float:  # type: ignore[no-untyped-def]
    """CPU time per run of the fast engine's C block loop built *without* -ffast-math.

    The same block structure (runs innermost) calling scalar libm, as the exact
    engine must: how much the block order alone gains in C on this CPU.
    """
    import ctypes

    from esoarm.engines import batch, fast

    src = Path(fast.__file__).with_name("_fast_kernel.c")
    obj, lib = work / "scalar.o", work / "scalar.so"
    subprocess.run(["gcc", "-O3", "-fno-math-errno", "-fPIC", "-c", str(src), "-o", str(obj)],
                   check=True)
    subprocess.run(["gcc", "-shared", str(obj), "-o", str(lib), "-lm"], check=True)
    kernel = fast._bind(ctypes.CDLL(str(lib)))
    runs = [(i, int(s)) for i in range(len(points)) for s in seeds]
    pack = batch._pack(list(points), runs)
    c0 = time.process_time()
    fast._run_pack(kernel, pack, 1)
    return (time.process_time() - c0) / len(runs)


def bench_python(grid, n: int) -> dict:  # type: ignore[type-arg, no-untyped-def]
    """(a) the plain-Python reference loop on n runs, extrapolated; bit identity of exact."""
    from esoarm.engines import batch
    from esoarm.engines.simulation import prepare, run_reference

    idx = np.linspace(0, len(grid.points) - 1, n).astype(int)
    scns = [grid.points[i].with_overrides({"sensor.seed": int(k % len(grid.seeds))})
            for k, i in enumerate(idx)]
    t0 = time.perf_counter()
    refs = [run_reference(s, prepare(s)) for s in scns]
    per_run = (time.perf_counter() - t0) / n
    exact = batch.run_metrics(scns).values
    same = all(exact[i, 0] == r.metrics["rms_error"] and exact[i, 1] == r.metrics["rms_u"]
               and exact[i, 2] == r.metrics["max_abs_error"] for i, r in enumerate(refs))
    return {"per_run": per_run, "subset": n, "extrapolated": per_run * N_RUNS,
            "bit_identical": same}


def bench_control(grid, n: int) -> dict:  # type: ignore[type-arg, no-untyped-def]
    """(b) python-control input_output_response, continuous-time loop, n runs, extrapolated."""
    import control as ct
    from bench_models import continuous_loop

    from esoarm.reference import evaluate_reference

    times, rms = [], []
    idx = np.linspace(0, len(grid.points) - 1, n).astype(int)
    for i in idx:
        scn = grid.points[i]
        sys_ = continuous_loop(scn)
        t = np.arange(scn.n_samples) * scn.sample_time
        t0 = time.perf_counter()
        resp = ct.input_output_response(sys_, t, 0.0, [scn.rig.theta0, 0, scn.rig.theta0, 0, 0])
        times.append(time.perf_counter() - t0)
        theta_ref = evaluate_reference(scn.reference, t)[0]
        rms.append(float(np.sqrt(np.mean((resp.outputs - theta_ref) ** 2))))
    per_run = float(np.mean(times))
    return {"per_run": per_run, "subset": n, "extrapolated": per_run * N_RUNS,
            "eps": [float(grid.points[i].observer.eps) for i in idx], "rms_error": rms}


def bench_startup(reps: int) -> dict:  # type: ignore[type-arg]
    """esoarm --help, --version, a one-run sweep (both engines), warm: median of reps (and best).

    The commands take turns (help, version, exact, fast, help, ...) so that a slow stretch
    of the machine falls on all of them.
    """
    out: dict = {}  # type: ignore[type-arg]
    cmds = {"python": [sys.executable, "-c", "pass"],  # the bare interpreter: a yardstick
            "help": [*esoarm_cmd(), "--help"], "version": [*esoarm_cmd(), "--version"],
            "one_exact": sweep_cmd(1, 1, "exact"), "one_fast": sweep_cmd(1, 1, "fast")}
    for cmd in cmds.values():  # warm the caches
        run_proc(cmd)
    walls: dict[str, list[float]] = {name: [] for name in cmds}
    cpus: dict[str, list[float]] = {name: [] for name in cmds}
    for _ in range(reps):
        for name, cmd in cmds.items():
            walls[name].append(run_proc(cmd, cpu=cpus[name])[0])
    for name in cmds:
        out[name] = float(np.median(walls[name]))
        out[f"{name}_best"] = min(walls[name])
        out[f"{name}_cpu"] = float(np.median(cpus[name]))
    out["reps"] = reps
    code = "import time; t = time.perf_counter(); import esoarm.cli; print(time.perf_counter() - t)"
    out["import_cli"] = float(np.median([float(sh([sys.executable, "-c", code]) or "nan")
                                         for _ in range(reps)]))
    return out


#: The arms' sweep: 200 runs of 20 s at 200 Hz (20 observer bandwidths x 10 seeds).
ARM_VARY = ["--vary", "observer.eps=geom:0.01:0.05:20", "--seeds", "10", "--set", "duration=20"]
LEVER_AT_200 = ["sweep", "test-1", "--vary", "observer.eps=geom:0.03:0.3:20", "--seeds", "10",
                "--set", "duration=20", "--set", "sensor.rate_hz=200"]


def _ur5_scenario(work: Path) -> Path | None:
    """A 6-dof UR5 scenario (example-robot-data's URDF, 200 Hz), if that package is installed."""
    from importlib import metadata

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    urdf = Path(str(dist.locate_file(
        "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")))
    if not urdf.is_file():
        return None
    path = work / "ur5.toml"
    path.write_text(f'''name = "ur5"
duration = 20.0
[plant]
kind = "urdf"
file = "{urdf}"
payload_mass = 1.0
payload_offset = [0.0, 0.0, 0.05]
[sensor]
rate_hz = 200.0
[observer]
eps = 0.02
[controller]
kind = "computed-torque"
k1 = 20.0
k2 = 100.0
[actuator]
torque_limit = 150.0
[reference]
kind = "range"
fraction = 0.15
''', encoding="utf-8")
    return path


def bench_arms(work: Path, rounds: int, quick: bool) -> dict:  # type: ignore[type-arg]
    """Arms' sweeps (two-link, a 6-dof UR5) against the lever arm's at 200 Hz, whole commands.

    Each round runs the two-link sweep then the lever arm's, back to back (the ratio is
    per round); the UR5 sweep and Pinocchio's own loop (``tests/reference_arm.py`` with
    ``pinocchio.aba``, one run timed and extrapolated to 200 runs on every core) once.
    """
    sys.path.insert(0, str(HERE))
    from bench_arms import _plain_run, plain_loop_missing, plain_params

    from esoarm.scenario import load_scenario

    vary = ARM_VARY if not quick else [*ARM_VARY[:-1], "duration=2"]
    lever = LEVER_AT_200 if not quick else [*LEVER_AT_200[:-3], "duration=2", *LEVER_AT_200[-2:]]
    arm_cmd = [*esoarm_cmd(), "sweep", "two-link", *vary]
    lever_cmd = [*esoarm_cmd(), *lever]
    run_proc(arm_cmd)  # compile / load the kernels of both once
    run_proc(lever_cmd)
    out: dict = {"arm": [], "lever": [], "ratio": [], "arm_cpu": [],  # type: ignore[type-arg]
                 "lever_cpu": [], "cpu_ratio": [], "load_before": load(),
                 "arm_cmd": " ".join(["esoarm", "sweep", "two-link", *vary]),
                 "lever_cmd": " ".join(["esoarm", *lever])}
    for _ in range(rounds):
        a = run_proc(arm_cmd, cpu=out["arm_cpu"])[0]
        b = run_proc(lever_cmd, cpu=out["lever_cpu"])[0]
        out["arm"].append(a)
        out["lever"].append(b)
        out["ratio"].append(a / b)
        out["cpu_ratio"].append(out["arm_cpu"][-1] / out["lever_cpu"][-1])
        print(f"  round: two-link {a:.2f} s ({out['arm_cpu'][-1]:.2f} s CPU), lever {b:.2f} s "
              f"({out['lever_cpu'][-1]:.2f} s CPU): {a / b:.2f}x, load {load()}", flush=True)
    ur5 = _ur5_scenario(work)
    if ur5 is not None:
        ur5_cmd = [*esoarm_cmd(), "sweep", str(ur5), *vary]
        run_proc(ur5_cmd)
        cpu: list[float] = []
        out["ur5"] = run_proc(ur5_cmd, cpu=cpu)[0]
        out["ur5_cpu"] = cpu[0]
        out["ur5_cmd"] = " ".join(["esoarm", "sweep", "ur5.toml", *vary])
    missing = plain_loop_missing()  # the baseline lives in the source checkout's tests/
    if missing is None:
        scn = load_scenario("two-link", [vary[-1]])
        one = _plain_run(plain_params(scn))
        out["pinocchio_one"] = one
        out["pinocchio_200"] = one * 200 / (os.cpu_count() or 1)
    else:
        print(f"  Pinocchio's own loop not timed: {missing}", flush=True)
        out["pinocchio_skip"] = missing
    out["load_after"] = load()
    return out


def bench_first_reproduce() -> dict:  # type: ignore[type-arg]
    """The first ``esoarm reproduce`` after ``pip install .`` into a new venv (empty caches).

    As ``benchmarks/bench_first_reproduce.py``: this checkout installed (not editable)
    with its dependencies into a new virtual environment, so numba's cache beside the
    installed sources is empty and every kernel the command needs is compiled.
    """
    from bench_first_reproduce import clean_env, install, reproduce

    with tempfile.TemporaryDirectory(prefix="esoarm-first-") as tmp:
        t0 = time.perf_counter()
        bindir = install(ROOT, Path(tmp) / "venv")
        installed = time.perf_counter() - t0
        compiled_c = any((Path(tmp) / "venv").glob(
            "lib/python*/site-packages/esoarm/plants/_elementary*.so"))
        before = load()
        wall, cpu, status = reproduce(bindir, Path(tmp) / "out", clean_env())
        after = load()
    if status != 0:
        raise RuntimeError(f"the first esoarm reproduce failed (exit {status})")
    return {"wall": wall, "cpu": cpu, "load_before": before, "load_after": after,
            "install": installed, "c_extension": compiled_c}


def bench_scaling(c: CLoop, sizes: list[int], c_max: int) -> dict:  # type: ignore[type-arg]
    """Whole commands (and the C loop) against the number of runs; peak memory of each."""
    res: dict = {"runs": sizes, "exact": [], "fast": [], "c": [], "c_measured": [],  # type: ignore[type-arg]
                 "rss_exact": [], "rss_fast": []}
    per_run_c = None
    for n in sizes:
        points, seeds = split_runs(n)
        for engine in ("exact", "fast"):
            wall, rss = run_proc(sweep_cmd(points, seeds, engine), memory=True)
            res[engine].append(wall)
            res[f"rss_{engine}"].append(rss)
        if n <= c_max:
            t = c.time(n)
            per_run_c = t / n
            res["c"].append(t)
            res["c_measured"].append(True)
        else:
            assert per_run_c is not None
            res["c"].append(per_run_c * n)
            res["c_measured"].append(False)
        print(f"  {n:>7} runs: exact {res['exact'][-1]:.2f} s, fast {res['fast'][-1]:.2f} s, "
              f"C {res['c'][-1]:.2f} s", flush=True)
    return res


def bench_million(work: Path, runs: int) -> dict:  # type: ignore[type-arg]
    """A metrics-only sweep of ``runs`` runs with the fast engine, written to CSV."""
    out = work / "million.csv"
    points, seeds = split_runs(runs)
    wall, rss = run_proc(sweep_cmd(points, seeds, "fast", out), memory=True)
    with out.open() as fh:
        rows = sum(1 for _ in fh) - 1
    return {"runs": runs, "seconds": wall, "peak_mib": rss, "rows": rows}


def bench_tune() -> list[dict]:  # type: ignore[type-arg]
    """What ``esoarm tune`` finds for ε on the twin, for several prices w of control."""
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.tune import DEFAULT_OBJECTIVE, Objective, parse_bound, tune

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


# ---------------------------------------------------------------------------


def machine_info() -> dict[str, str]:
    import control
    import numba

    lscpu = sh(["lscpu"])
    cpu = next((line.split(":", 1)[1].strip() for line in lscpu.splitlines()
                if line.startswith("Model name")), platform.machine())
    try:
        import pinocchio
        pin_version = str(pinocchio.__version__)
    except ImportError:
        pin_version = "not installed"
    return {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "cpu": cpu,
        "pinocchio": pin_version,
        "load_before": load(),
        "lscpu": lscpu,
        "nproc": sh(["nproc"]),
        "free": sh(["free", "-h"]),
        "gcc": sh(["gcc", "--version"]).splitlines()[0],
        "numpy": np.__version__,
        "numba": numba.__version__,
        "control": control.__version__,
        "python": platform.python_version(),
        "vector_isa": " ".join(sorted({w for w in Path("/proc/cpuinfo").read_text().split()
                                       if w.startswith("avx")})) if Path("/proc/cpuinfo").exists()
        else "?",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="small sizes only: a smoke test of this script (for CI)")
    parser.add_argument("--no-doc", action="store_true", help="do not write docs/benchmarks.md")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of C / exact / fast")
    parser.add_argument("--max-runs", type=int, default=100_000,
                        help="largest sweep of the throughput curve (powers of 10 up to it)")
    parser.add_argument("--big", type=int, default=1_000_000,
                        help="runs of the large metrics-only sweep (memory)")
    parser.add_argument("--only-arms", action="store_true",
                        help="only the arms' sweeps: rewrites only their section of the page")
    parser.add_argument("--only-side-by-side", action="store_true",
                        help="only start-up and warm rounds of C, exact and fast on the "
                             "canonical sweep (printed; the page is not written)")
    args = parser.parse_args()
    if args.only_side_by_side:
        with tempfile.TemporaryDirectory(prefix="esoarm-bench-") as tmp:
            print(f"load {load()}", flush=True)
            print(bench_startup(2 if args.quick else 3), flush=True)
            print(bench_canonical(CLoop(canonical_grid(), Path(tmp)), Path(tmp),
                                  1 if args.quick else args.rounds, cold=False))
            print(f"load {load()}", flush=True)
        return
    from bench_doc import arms_section, plot_scaling, write_doc

    command = " ".join(["python benchmarks/run.py", *sys.argv[1:]])
    if args.only_arms:
        machine = machine_info()
        with tempfile.TemporaryDirectory(prefix="esoarm-bench-") as tmp:
            print(f"load {load()}", flush=True)
            arms = bench_arms(Path(tmp), 1 if args.quick else args.rounds, args.quick)
        print(arms)
        section = arms_section(arms, machine, command)
        print(section)
        if not args.no_doc:
            old = DOC.read_text(encoding="utf-8") if DOC.exists() else "# Benchmarks\n"
            DOC.write_text(replace_section(old, section), encoding="utf-8")
            print(f"wrote the arms section of {DOC}")
        return

    machine = machine_info()
    m: dict = {"quick": args.quick, "command": command}  # type: ignore[type-arg]
    grid = canonical_grid()
    top = 100 if args.quick else args.max_runs
    sizes = [10**i for i in range(7) if 10**i <= top]
    steps = [
        ("start-up", lambda: bench_startup(3 if args.quick else 11)),
        ("canonical sweep: C, exact, fast (rounds)",
         lambda: bench_canonical(c, work, 1 if args.quick else args.rounds)),
        ("in-process engines", lambda: bench_inprocess(grid, c, args.quick)),
        ("plain Python", lambda: bench_python(grid, 2 if args.quick else 10)),
        ("python-control", lambda: bench_control(grid, 1 if args.quick else 3)),
        ("throughput against runs", lambda: bench_scaling(c, sizes, 100 if args.quick
                                                          else 10_000)),
        ("arms: two-link and UR5 sweeps against the lever arm's at 200 Hz",
         lambda: bench_arms(work, 1 if args.quick else args.rounds, args.quick)),
    ]
    if not args.quick:
        steps += [(f"{args.big:,}-run sweep", lambda: bench_million(work, args.big)),
                  ("tuning study", bench_tune),
                  ("first esoarm reproduce after pip install . (new venv)",
                   bench_first_reproduce)]
    names = ["startup", "canonical", "inproc", "python", "control", "scaling", "arms", "million",
             "tune", "first"]
    with tempfile.TemporaryDirectory(prefix="esoarm-bench-") as tmp:
        work = Path(tmp)
        c = CLoop(grid, work)
        for key, (label, fn) in zip(names, steps, strict=False):
            print(f"{label} ...", flush=True)
            m[key] = fn()
            if key not in ("scaling", "tune"):
                print(f"  {m[key]}", flush=True)
    machine["load_after"] = load()
    machine["self_peak_mib"] = f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f}"
    text = write_doc(m, machine)
    if args.no_doc:
        print(text)
        return
    plot_scaling(m["scaling"], PLOT)
    DOC.write_text(replace_section(text + kept_sections(),
                                   arms_section(m["arms"], machine, command)), encoding="utf-8")
    print(f"wrote {DOC} and {PLOT}")


if __name__ == "__main__":
    main()
