"""Compiled batch engine: many closed-loop runs at once, SPEC §2 semantics exactly.

The per-sample loop here is the loop of :func:`esoarm.engines.simulation.run_reference`,
compiled with numba and run in parallel over runs (``prange``) on all cores.  It
calls the same plain physics functions -- :func:`~esoarm.plants.sensor.measure`,
:func:`~esoarm.observers.linear.eso_estimate` and :func:`~esoarm.observers.linear.eso_advance`
(eq. 8), :func:`~esoarm.controllers.flc.flc_control` (eq. 14-16),
:func:`~esoarm.plants.lever_arm.rig_acceleration`,
:func:`~esoarm.plants.lever_arm.applied_torque` and
:func:`~esoarm.plants.lever_arm.rig_advance` (RK4 of the rig) -- and the same divergence
rule (:data:`esoarm.engines.simulation.DIVERGENCE_LIMIT`), so both engines give the
same numbers (the tests require bit-for-bit equality on every discretization,
noise, quantization, lag, delay, saturation and compensation setting).

Two modes:

* :func:`simulate_many` keeps the full time series and returns
  :class:`~esoarm.result.SimResult` objects (used by ``esoarm reproduce``);
* :func:`run_metrics` keeps only the metrics of each run (one row of
  :data:`METRICS` per run), for sweeps of any size: work is done in chunks of
  runs, each run keeps one (9, N) scratch log while it runs, and the noise of a
  seed is drawn once and shared by every run that uses it.

Metrics are computed the way :func:`esoarm.result.compute_metrics` computes
them -- including NumPy's pairwise summation order -- so they are identical to
the reference engine's, not merely close.

The kernels are compiled on first use and cached on disk (``cache=True``); the
cache is keyed on the source of this module *and* of every physics module it
calls (see :class:`_PhysicsStampLocator`), so editing the physics never leaves
a stale compiled kernel behind.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

from esoarm import _jit
from esoarm.controllers import flc as _controller
from esoarm.controllers.flc import flc_control
from esoarm.engines.metrics import METRICS, MetricsTable, NoiseCache
from esoarm.engines.simulation import (
    SimulationDiverged,
    diverged_message,
    prepare,
    within_limits,
)
from esoarm.observers import linear as _observer
from esoarm.observers.linear import eso_advance, eso_estimate
from esoarm.plants import lever_arm as _rig
from esoarm.plants.lever_arm import applied_torque, rig_acceleration, rig_advance
from esoarm.plants.sensor import measure
from esoarm.result import SimResult
from esoarm.scenario import Scenario

_jit.register_all()  # the physics above becomes callable from the kernels below

__all__ = [
    "METRICS",
    "MetricsTable",
    "compile_kernels",
    "run_metrics",
    "simulate_many",
]

_NMETRIC = len(METRICS)

# rows of the (9, N) log: theta, theta_ref, error, u, z1, z2, z3, f_true, omega
_TH, _REF, _ERR, _U, _Z1, _Z2, _Z3, _F, _OM = range(9)
# point-parameter columns
_THETA0, _SIGMA, _Q, _H, _TS, _B0 = range(6)
_N, _NSUB, _DELAY, _REFIDX = range(4)

# _closed_loop unpacks the parameter vectors into tuples of these lengths
if (_rig.VECTOR_SIZE, _observer.VECTOR_SIZE, _controller.VECTOR_SIZE) != (10, 21, 6):
    raise ImportError(  # pragma: no cover - guards a core change
        "esoarm.engines.batch: the packed rig/observer/controller vectors changed size; "
        "update the tuple unpacking in esoarm.engines.batch._closed_loop"
    )

#: Runs per chunk in metrics mode (bounds memory; one progress tick per chunk).
DEFAULT_CHUNK = 2048


# ---------------------------------------------------------------------------
# cache keyed on the physics sources as well as this file

_PHYSICS_MODULES = ("engines/batch", "controllers/flc", "observers/linear", "plants/lever_arm",
                    "plants/sensor", "plants/model", "engines/simulation", "_jit")


def _physics_stamp() -> str:
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for name in _PHYSICS_MODULES:
        digest.update((root / f"{name}.py").read_bytes())
    return digest.hexdigest()


#: Source files whose numba kernels are cached under the physics stamp (this one, and any
#: module that calls :func:`cover_with_physics_stamp`).
_COVERED_FILES: set[str] = {os.path.realpath(__file__)}


def cover_with_physics_stamp(path: str) -> None:
    """Key the on-disk cache of the numba kernels defined in ``path`` on the physics too.

    For modules outside the engines whose kernels call the physics functions
    (e.g. the identification's segment simulator); call before the first use.
    """
    _COVERED_FILES.add(os.path.realpath(path))


def _install_cache_locator() -> None:
    """Key numba's on-disk cache of this module on every physics source file.

    numba invalidates a cached kernel only when the file defining the kernel
    changes; the physics it inlines lives in other modules.  This locator adds
    their content hash to the stamp.  It falls back silently to numba's own
    locators if numba's (internal) caching layout is not the expected one.
    """
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover
        return
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    def first(*names: str) -> type | None:
        return next((getattr(caching, n) for n in names if hasattr(caching, n)), None)

    # numba's own order: NUMBA_CACHE_DIR if set, else __pycache__ beside the
    # source, else the user-wide cache directory
    bases = [first("UserProvidedCacheLocator", "_UserProvidedCacheLocator"),
             first("InTreeCacheLocator", "_InTreeCacheLocator"),
             first("UserWideCacheLocator", "_UserWideCacheLocator")]
    if impl is None or None in bases or not hasattr(impl, "_locator_classes"):
        return  # pragma: no cover
    stamp = _physics_stamp()

    def make(base: type) -> type:
        class Locator(base):  # type: ignore[misc, valid-type]
            def get_source_stamp(self):  # type: ignore[no-untyped-def]
                return f"{super().get_source_stamp()}-{stamp}"

            @classmethod
            def from_function(cls, py_func, py_file):  # type: ignore[no-untyped-def]
                if os.path.realpath(py_file) not in _COVERED_FILES:
                    return None
                return super().from_function(py_func, py_file)

        Locator.__name__ = Locator.__qualname__ = f"EsoarmPhysics{base.__name__.lstrip('_')}"
        return Locator

    ours = [make(b) for b in bases if b is not None]
    classes = [c for c in impl._locator_classes if not c.__name__.startswith("EsoarmPhysics")]
    impl._locator_classes = ours + classes


_install_cache_locator()


# ---------------------------------------------------------------------------
# compiled kernels


@njit(cache=True)
def _closed_loop(log, n, theta0, noise, sigma, q, tref, dref, ddref, rig, obs, ctl, h, nsub,
                 delay, b0, ts):  # pragma: no cover - compiled
    """SPEC §2 loop of one run into ``log`` (9, ≥n).

    Returns the number of rows logged, negated if the run diverged (the last
    row logged is then the sample at which it left the finite range).

    Line for line the loop of :func:`esoarm.engines.simulation.run_reference`; the
    history of u_k for the transport delay is row ``_U`` of the log itself.
    """
    # the packed parameter vectors as tuples: the physics functions index them
    # exactly like arrays, but tuples live in registers (no reference counting)
    rig = (rig[0], rig[1], rig[2], rig[3], rig[4], rig[5], rig[6], rig[7], rig[8], rig[9])
    ctl = (ctl[0], ctl[1], ctl[2], ctl[3], ctl[4], ctl[5])
    obs = (obs[0], obs[1], obs[2], obs[3], obs[4], obs[5], obs[6], obs[7], obs[8], obs[9],
           obs[10], obs[11], obs[12], obs[13], obs[14], obs[15], obs[16], obs[17], obs[18],
           obs[19], obs[20])
    theta = theta0
    omega = 0.0
    tau = 0.0
    z1 = measure(theta0, noise[0], sigma, q)
    z2 = 0.0
    z3 = 0.0
    for k in range(n):
        tk = k * ts
        y = measure(theta, noise[k], sigma, q)
        ref = tref[k]
        h1, h2, h3 = eso_estimate(z1, z2, z3, y, obs)
        u = flc_control(h1, h2, h3, ref, dref[k], ddref[k], ctl)
        log[_U, k] = u
        u_applied = log[_U, k - delay] if k >= delay else 0.0
        acc = rig_acceleration(theta, omega, applied_torque(tau, u_applied, rig), tk, rig)
        log[_TH, k] = theta
        log[_REF, k] = ref
        log[_ERR, k] = theta - ref
        log[_Z1, k] = h1
        log[_Z2, k] = h2
        log[_Z3, k] = h3
        log[_F, k] = acc - b0 * u
        log[_OM, k] = omega
        if not within_limits(theta, h1, h2, h3, u):
            return -(k + 1)
        z1, z2, z3 = eso_advance(z1, z2, z3, h1, h2, h3, y, u, obs)
        theta, omega, tau = rig_advance(theta, omega, tau, u_applied, tk, h, nsub, rig)
    return n


@njit(cache=True)
def _pairwise_sum(a, n):  # pragma: no cover - compiled
    """Sum of a[:n] in NumPy's pairwise order (bit-identical to ``np.add.reduce``).

    NumPy splits a block of n > 128 values at n2 = n//2 rounded down to a
    multiple of 8 and adds the two halves' sums; blocks of ≤ 128 values use 8
    interleaved accumulators.  Written with an explicit stack (no recursion).
    """
    # stack of (lo, n, partial sum of the left half or nan, state) frames
    los = np.empty(64, dtype=np.int64)
    ns = np.empty(64, dtype=np.int64)
    left = np.empty(64)
    state = np.zeros(64, dtype=np.int64)  # 0: new, 1: left done
    top = 0
    los[0] = 0
    ns[0] = n
    state[0] = 0
    result = 0.0
    while top >= 0:
        lo = los[top]
        m = ns[top]
        if m <= 128:
            res = _block_sum(a, lo, m)
            top -= 1
            # hand the value to the parent frame
            while top >= 0:
                if state[top] == 0:
                    left[top] = res
                    state[top] = 1
                    n2 = ns[top] // 2
                    n2 -= n2 % 8
                    top += 1
                    los[top] = los[top - 1] + n2
                    ns[top] = ns[top - 1] - n2
                    state[top] = 0
                    break
                res = left[top] + res
                top -= 1
            else:
                result = res
            continue
        n2 = m // 2
        n2 -= n2 % 8
        top += 1
        los[top] = lo
        ns[top] = n2
        state[top] = 0
    return result


@njit(cache=True)
def _block_sum(a, lo, n):  # pragma: no cover - compiled
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        j = lo + i
        r0 += a[j]
        r1 += a[j + 1]
        r2 += a[j + 2]
        r3 += a[j + 3]
        r4 += a[j + 4]
        r5 += a[j + 5]
        r6 += a[j + 6]
        r7 += a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def _mean_square(x, n, scratch):  # pragma: no cover - compiled
    for i in range(n):
        scratch[i] = x[i] * x[i]
    return _pairwise_sum(scratch, n) / n


@njit(cache=True)
def _max_abs(x, n):  # pragma: no cover - compiled
    # np.max propagates NaN; so does this
    m = abs(x[0])
    for i in range(1, n):
        v = abs(x[i])
        if v > m or v != v:
            m = v
            if v != v:
                return v
    return m


@njit(cache=True, parallel=True)
def _metrics_kernel(run_point, run_noise, fpar, ipar, rig, obs, ctl, refs, noises,
                    out):  # pragma: no cover - compiled
    nmax = refs.shape[2]
    for r in prange(run_point.shape[0]):
        p = run_point[r]
        n = ipar[p, _N]
        ri = ipar[p, _REFIDX]
        log = np.empty((9, nmax))
        status = _closed_loop(log, n, fpar[p, _THETA0], noises[run_noise[r]], fpar[p, _SIGMA],
                            fpar[p, _Q], refs[ri, 0], refs[ri, 1], refs[ri, 2], rig[p], obs[p],
                            ctl[p], fpar[p, _H], ipar[p, _NSUB], ipar[p, _DELAY], fpar[p, _B0],
                            fpar[p, _TS])
        rows = abs(status)
        scratch = np.empty(rows)
        ferr = np.empty(rows)
        for k in range(rows):
            ferr[k] = log[_Z3, k] - log[_F, k]
        out[r, 0] = math.sqrt(_mean_square(log[_ERR], rows, scratch))
        out[r, 1] = math.sqrt(_mean_square(log[_U], rows, scratch))
        out[r, 2] = _max_abs(log[_ERR], rows)
        out[r, 3] = _max_abs(log[_U], rows)
        out[r, 4] = math.sqrt(_mean_square(ferr, rows, scratch))
        out[r, 5] = rows
        out[r, 6] = 1.0 if status < 0 else 0.0


@njit(cache=True, parallel=True)
def _series_kernel(run_point, run_noise, fpar, ipar, rig, obs, ctl, refs, noises, logs,
                   rows_out):  # pragma: no cover - compiled
    for r in prange(run_point.shape[0]):
        p = run_point[r]
        ri = ipar[p, _REFIDX]
        rows_out[r] = _closed_loop(logs[r], ipar[p, _N], fpar[p, _THETA0],
                                   noises[run_noise[r]], fpar[p, _SIGMA], fpar[p, _Q],
                                   refs[ri, 0], refs[ri, 1], refs[ri, 2], rig[p], obs[p], ctl[p],
                                   fpar[p, _H], ipar[p, _NSUB], ipar[p, _DELAY], fpar[p, _B0],
                                   fpar[p, _TS])


# ---------------------------------------------------------------------------
# packing scenarios into arrays


@dataclass
class _Pack:
    """Arrays for the kernels: P points, R runs (run -> point, run -> noise row)."""

    run_point: np.ndarray
    run_noise: np.ndarray
    fpar: np.ndarray
    ipar: np.ndarray
    rig: np.ndarray
    obs: np.ndarray
    ctl: np.ndarray
    refs: np.ndarray
    noises: np.ndarray

    def args(self) -> tuple[np.ndarray, ...]:
        return (self.run_point, self.run_noise, self.fpar, self.ipar, self.rig, self.obs,
                self.ctl, self.refs, self.noises)


def _point_arrays(scn: Scenario) -> tuple[np.ndarray, ...]:
    """(fpar, ipar-without-ref, rig, obs, ctl, ref arrays) of one scenario via prepare()."""
    inp = prepare(scn, draw_noise=False)  # noise is drawn once per seed (NoiseCache)
    fpar = np.array([inp.theta0, inp.sigma, inp.q, inp.h, scn.sample_time, inp.b0])
    ipar = np.array([len(inp.t), inp.nsub, inp.delay], dtype=np.int64)
    return fpar, ipar, inp.rig, inp.obs, inp.ctl, np.stack(
        [inp.theta_ref, inp.omega_ref, inp.accel_ref])


def _pack(points: Sequence[Scenario], runs: Sequence[tuple[int, int]],
          noise_cache: NoiseCache | None = None) -> _Pack:
    """Pack ``points`` and ``runs`` = [(point index, seed), ...] for the kernels."""
    noise_cache = noise_cache or NoiseCache()
    p = len(points)
    fpar = np.empty((p, 6))
    ipar = np.empty((p, 4), dtype=np.int64)
    rig = np.empty((p, _rig.VECTOR_SIZE))
    obs = np.empty((p, _observer.VECTOR_SIZE))
    ctl = np.empty((p, _controller.VECTOR_SIZE))
    ref_keys: dict[str, int] = {}
    ref_list: list[np.ndarray] = []
    for i, scn in enumerate(points):
        f, ip, rg, ob, ct, ref = _point_arrays(scn)
        fpar[i], ipar[i, :3], rig[i], obs[i], ctl[i] = f, ip, rg, ob, ct
        ref_key = f"{scn.sample_time!r}/{scn.n_samples}/{scn.reference.model_dump_json()}"
        if ref_key not in ref_keys:
            ref_keys[ref_key] = len(ref_list)
            ref_list.append(ref)
        ipar[i, _REFIDX] = ref_keys[ref_key]
    nmax = int(ipar[:, _N].max()) if p else 1
    refs = np.zeros((len(ref_list), 3, nmax))
    for i, ref in enumerate(ref_list):
        refs[i, :, : ref.shape[1]] = ref
    noise_rows: dict[tuple[int, int], int] = {}
    noise_list: list[np.ndarray] = []
    run_point = np.empty(len(runs), dtype=np.int64)
    run_noise = np.empty(len(runs), dtype=np.int64)
    for r, (pi, seed) in enumerate(runs):
        scn = points[pi]
        key, seq = noise_cache.get(seed, scn.n_samples, scn.sensor.noise_deg)
        if key not in noise_rows:
            noise_rows[key] = len(noise_list)
            noise_list.append(seq)
        run_point[r] = pi
        run_noise[r] = noise_rows[key]
    noises = np.zeros((max(len(noise_list), 1), nmax))
    for i, seq in enumerate(noise_list):
        noises[i, : len(seq)] = seq
    return _Pack(run_point, run_noise, fpar, ipar, rig, obs, ctl, refs, noises)


class _threads:
    """Context manager: run numba's parallel kernels on ``workers`` threads."""

    def __init__(self, workers: int | None) -> None:
        self.workers = workers
        self.saved = 0

    def __enter__(self) -> None:
        self.saved = numba.get_num_threads()
        if self.workers is not None:
            if self.workers < 1:
                raise ValueError(f"workers must be >= 1, got {self.workers}")
            numba.set_num_threads(min(self.workers, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]

    def __exit__(self, *exc: object) -> None:
        numba.set_num_threads(self.saved)


# ---------------------------------------------------------------------------
# public API


def run_metrics(
    points: Sequence[Scenario],
    seeds: Sequence[int] | None = None,
    *,
    workers: int | None = None,
    chunk: int = DEFAULT_CHUNK,
    progress: Callable[[int], None] | None = None,
    _noise_cache: NoiseCache | None = None,
) -> MetricsTable:
    """Run every point (× every seed) and keep only the metrics of each run.

    Parameters
    ----------
    points : sequence of Scenario
        Validated scenarios (e.g. the grid of a sweep).
    seeds : sequence of int, optional
        Noise seeds (``sensor.seed``) to run each point with; runs are ordered
        point-major, seed fastest.  Default: each point's own ``sensor.seed``.
    workers : int, optional
        Threads (cores) to use; default all of numba's threads.
    chunk : int
        Runs per kernel call; memory is O(chunk · N), not O(runs · N).
    progress : callable, optional
        Called with the number of runs finished after each chunk.

    Returns
    -------
    MetricsTable
        One row per run, columns :data:`METRICS`.  Diverged runs are rows with
        ``diverged = 1`` (they do not raise).
    """
    if seeds is None:
        runs = [(i, scn.sensor.seed) for i, scn in enumerate(points)]
    else:
        runs = [(i, int(s)) for i in range(len(points)) for s in seeds]
    out = np.empty((len(runs), _NMETRIC))
    noise_cache = _noise_cache or NoiseCache()
    with _threads(workers):
        for start in range(0, len(runs), chunk):
            part = runs[start : start + chunk]
            used = sorted({pi for pi, _ in part})
            local = {pi: j for j, pi in enumerate(used)}
            pack = _pack([points[pi] for pi in used], [(local[pi], s) for pi, s in part],
                         noise_cache)
            res = np.empty((len(part), _NMETRIC))
            _metrics_kernel(*pack.args(), res)  # type: ignore[call-arg]
            out[start : start + len(part)] = res
            if progress is not None:
                progress(len(part))
    return MetricsTable(out)


def simulate_many(
    scenarios: Sequence[Scenario],
    *,
    workers: int | None = None,
    chunk: int = 256,
) -> list[SimResult]:
    """Simulate scenarios with the compiled engine and keep their time series.

    The fast counterpart of calling :func:`esoarm.engines.simulation.simulate` on each
    scenario (no warnings are emitted here): same semantics, same numbers.

    Parameters
    ----------
    scenarios : sequence of Scenario
        Validated scenarios, each run with its own ``sensor.seed``.
    workers : int, optional
        Threads (cores) to use; default all.
    chunk : int
        Runs per kernel call (memory ≈ chunk · 9 · N · 8 bytes).

    Returns
    -------
    list of SimResult
        In the order of ``scenarios``.

    Raises
    ------
    SimulationDiverged
        For the first scenario (in order) whose run diverged, with its partial
        result and the reference engine's message.
    """
    results: list[SimResult] = []
    noise_cache = NoiseCache()
    scenarios = list(scenarios)
    with _threads(workers):
        for start in range(0, len(scenarios), chunk):
            part = scenarios[start : start + chunk]
            pack = _pack(part, [(i, scn.sensor.seed) for i, scn in enumerate(part)], noise_cache)
            nmax = pack.refs.shape[2]
            logs = np.empty((len(part), 9, nmax))
            rows = np.empty(len(part), dtype=np.int64)  # rows logged, < 0: diverged
            _series_kernel(*pack.args(), logs, rows)  # type: ignore[call-arg]
            for i, scn in enumerate(part):
                n = scn.n_samples
                k = abs(int(rows[i]))
                t = np.arange(n) * scn.sample_time
                log = logs[i, :8, :k].T.copy()
                result = SimResult.from_log(scn, t[:k], log, logs[i, _OM, :k].copy())
                if rows[i] < 0:
                    raise SimulationDiverged(diverged_message(scn.name, float(t[k - 1]), k - 1),
                                             result)
                results.append(result)
    return results


def compile_kernels(series: bool = True, metrics: bool = True) -> None:
    """Compile (or load from the on-disk cache) the kernels ahead of use."""
    scn = Scenario(duration=0.04)
    if series:
        simulate_many([scn], workers=1)
    if metrics:
        run_metrics([scn], workers=1)
