"""Compiled batch engine: many closed-loop runs at once, the reference engine's numbers exactly.

The kernels here run :func:`esoarm.engines.loop.closed_loop` -- the one
sample loop, also run as plain Python by the reference engine -- compiled
with numba and in parallel over runs (``prange``) on all cores, with the
registry's dispatch functions (:mod:`esoarm.kinds`) as step functions.  Both
engines therefore give the same numbers (the tests require bit-for-bit
equality on every kind, discretization, noise, quantization, lag, delay,
motor, saturation and compensation setting).  The exception is a URDF arm:
the reference engine calls Pinocchio, the kernels the compiled rigid body of
:mod:`esoarm.plants.arms.rigid_body` (``COMPILED_EXACT = False``), equal to rounding
(the tests hold every metric within
:data:`esoarm.plants.arms.compiled.ENGINE_TOLERANCE`).  A point whose kinds do
not compile (``JIT = False``) is run by the reference engine in worker processes.

The kinds' parameter vectors reach the kernels as tuples (they live in
registers) when they fit :data:`~esoarm.engines.packing.VECTOR_WIDTH`; longer
ones -- an arm's carry its packed models -- as arrays: the kernels are written
once and compiled for each way (:class:`VectorsAs`), the arrays' the first time
such a point is run.

Two modes:

* :func:`simulate_many` keeps the full time series and returns
  :class:`~esoarm.result.SimResult` objects (used by ``esoarm reproduce``);
* :func:`run_metrics` keeps only the metrics of each run (one row of
  :data:`METRICS` per run), for sweeps of any size: work is done in chunks of
  runs, each run keeps one scratch log while it runs, and the noise of a
  seed is drawn once and shared by every run that uses it.

Metrics come from :func:`esoarm.engines.metrics.joints_metrics`, which sums in NumPy's
pairwise order, so they are identical to the reference engine's
(:func:`esoarm.engines.metrics.series_metrics`), not merely close.

The kernels are compiled on first use and cached on disk (``cache=True``); the
cache is keyed on the source of this module *and* of every physics module it
calls (see :func:`_physics_stamp`), so editing the physics never leaves a
stale compiled kernel behind.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import (
    NativeValue,
    intrinsic,
    models,
    overload,
    register_model,
    typeof_impl,
    unbox,
)

from esoarm import _jit
from esoarm import kinds as _kinds
from esoarm.engines import loop as _loop
from esoarm.engines.loop import closed_loop, closed_loop_block
from esoarm.engines.metrics import (
    METRICS,
    NMETRIC,
    NROW,
    MetricsTable,
    NoiseCache,
    _chunked_metrics,
    _renumbered,
    joints_metrics,
)
from esoarm.engines.packing import (  # packing needs no numba (the fast engine uses it alone)
    _DELAY,
    _H,
    _N,
    _NC,
    _NJ,
    _NSUB,
    _NZ,
    _Q,
    _REFIDX,
    _SIGMA,
    _TS,
    VECTOR_WIDTH,  # noqa: F401 - re-exported
    _Pack,
    _pack,
    _stack,  # noqa: F401 - re-exported
)
from esoarm.engines.sample import Designs, Sampling, Steps
from esoarm.engines.simulation import (
    SimulationDiverged,
    diverged_message,
    prepare,
    run_reference,
)
from esoarm.result import SimResult
from esoarm.scenario import Scenario

_jit.register_all()  # the physics above becomes callable from the kernels below


@intrinsic
def _unreferenced(typingctx: Any, a: Any) -> Any:  # pragma: no cover - compiled
    """The array ``a`` without its memory's reference count (a NULL meminfo): handing it on,
    or taking views of it, then costs no atomic operation.  The memory stays ``a``'s owner's."""
    if not isinstance(a, types.Array):
        return None

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        src = context.make_array(sig.args[0])(context, builder, value=args[0])
        out = context.make_array(sig.return_type)(context, builder)
        out.meminfo = cgutils.get_null_value(out.meminfo.type)  # type: ignore[no-untyped-call]
        out.parent = cgutils.get_null_value(out.parent.type)  # type: ignore[no-untyped-call]
        out.nitems = src.nitems
        out.itemsize = src.itemsize
        out.data = src.data
        out.shape = src.shape
        out.strides = src.strides
        return out._getvalue()

    return a(a), codegen


@overload(_loop.borrowed)
def _borrowed_compiled(a):  # pragma: no cover - compiled
    """:func:`esoarm.engines.loop.borrowed` in the kernels: arrays unreferenced, else as is."""
    if isinstance(a, types.Array):
        return lambda a: _unreferenced(a)  # type: ignore[call-arg]
    return lambda a: a


@overload(_loop.keep_alive)
def _keep_alive_compiled(owner):  # pragma: no cover - compiled
    """:func:`esoarm.engines.loop.keep_alive` in the kernels: a use of ``owner``, no code."""
    return lambda owner: None

__all__ = [
    "METRICS",
    "MetricsTable",
    "compile_kernels",
    "run_metrics",
    "simulate_many",
]

#: Runs of one grid point the metrics kernel advances together.
BLOCK = 64
#: Upper bound on the logs of one block [bytes] (fewer runs per block for long runs).
BLOCK_BYTES = 32 * 2**20
#: Runs per chunk in metrics mode (bounds memory; one progress tick per chunk).
DEFAULT_CHUNK = 2048
#: Up to this many compiled runs, :func:`run_metrics` runs them through the time-series
#: kernel (:func:`_run`, the one :func:`simulate_many` uses) and takes the metrics from
#: the logs with NumPy (:func:`esoarm.engines.metrics.series_metrics`, the same bits):
#: a handful of runs gains little from the blocked kernel, which is a second compiled copy
#: of the sample loop (39 s of CPU to compile, load 3; ``esoarm reproduce`` then compiles
#: only :func:`_run`).
SERIES_RUNS = 64


# ---------------------------------------------------------------------------
# cache keyed on the physics sources as well as this file

_PHYSICS_DIRS = ("engines", "plants", "observers", "controllers")
_PHYSICS_FILES = ("kinds.py", "contract.py", "_jit.py")


def _physics_files() -> list[Path]:
    """Every source file the kernels may compile: the kinds, the loop, the metrics, the
    physics folders with their sub-packages (the URDF arms' ``plants/arms``)."""
    root = Path(__file__).resolve().parent.parent
    files = [root / name for name in _PHYSICS_FILES]
    for folder in _PHYSICS_DIRS:
        files.extend(sorted((root / folder).rglob("*.py")))
    return files


def _physics_stamp() -> str:
    """Hash of every source file the kernels may compile (:func:`_physics_files`)."""
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for path in _physics_files():
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


#: Source files whose numba kernels are cached under the physics stamp (this one, and any
#: module that calls :func:`cover_with_physics_stamp`).
_COVERED_FILES: set[str] = {os.path.realpath(__file__)}


def cover_with_physics_stamp(path: str) -> None:
    """Key the on-disk cache of the numba kernels defined in ``path`` on the physics too.

    For modules outside the engines whose kernels call the physics functions
    (e.g. the identification's segment simulator); call before the first use.

    Parameters
    ----------
    path : str
        The module's source file (its ``__file__``).
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
        class Locator(base):  # type: ignore[misc]
            def get_source_stamp(self) -> str:
                extra = _kinds.registry_stamp()  # '' for the package's own kinds
                only = _kinds.compiled_selection()  # '' for every compiled kind
                return (f"{super().get_source_stamp()}-{stamp}" + (f"-{extra}" if extra else "")
                        + (f"-only-{only}" if only else ""))

            def get_cache_path(self) -> str:
                # kinds registered at run time: their kernels apart from the package's own;
                # kernels compiled for some kinds only (esoarm.kinds.compile_only) apart too
                extra = _kinds.registry_stamp()
                only = _kinds.compiled_selection()
                path = super().get_cache_path()
                path = os.path.join(path, f"kinds-{extra}") if extra else path
                return os.path.join(path, f"only-{only}") if only else path

            @classmethod
            def from_function(cls, py_func: Any, py_file: str) -> Any:
                if os.path.realpath(py_file) not in _COVERED_FILES:
                    return None
                return super().from_function(py_func, py_file)

        Locator.__name__ = Locator.__qualname__ = f"EsoarmPhysics{base.__name__.lstrip('_')}"
        return Locator

    ours = [make(b) for b in bases if b is not None]
    classes = [c for c in impl._locator_classes if not c.__name__.startswith("EsoarmPhysics")]
    impl._locator_classes = ours + classes


_install_cache_locator()


def _drop_compiled_kernels() -> None:
    """After the dispatch changed (a kind (un)registered, :func:`esoarm.kinds.compile_only`):
    recompile every kernel with the new dispatch.

    Each kernel's on-disk cache is looked up again (a registry with kinds added at
    run time has its own cache directory, :func:`esoarm.kinds.registry_stamp`).
    """
    for value in list(globals().values()):
        if isinstance(value, numba.core.registry.CPUDispatcher):
            value._reset_overloads()  # type: ignore[attr-defined]  # numba internal
            if type(getattr(value, "_cache", None)).__name__ != "NullCache":
                value.enable_caching()


_kinds.on_dispatch_change(_drop_compiled_kernels)


def _cover(points: Sequence[Scenario]) -> None:
    """Widen the compiled kinds to every kind if a compiled point's kinds are not among them
    (:func:`esoarm.kinds.compile_only`; the dispatch would refuse its CODE)."""
    if not all(_kinds.covers(k) for k in map(_kinds.kinds_of, points) if k.jit):
        _kinds.compile_only(None)


# ---------------------------------------------------------------------------
# compiled kernels


class VectorsAs:
    """How the kernels hand the kinds' parameter vectors to the step functions: as tuples
    (``wide = False``: in registers, no loads, no reference counting in the inner loops;
    each within :data:`~esoarm.engines.packing.VECTOR_WIDTH`) or as the arrays themselves
    (``wide = True``: a URDF arm's carry its rigid-body models).  The kernels are written
    once; numba compiles them for each way (:class:`_VectorsAsType`) a point needs."""

    def __init__(self, wide: bool) -> None:
        self.wide = wide


#: The two ways: every vector within VECTOR_WIDTH, and the rest (:attr:`_Pack.wide`).
TUPLES, ARRAYS = VectorsAs(False), VectorsAs(True)


class _VectorsAsType(types.Type):
    """numba's type of a :class:`VectorsAs`: the way is in the type, the value is empty."""

    def __init__(self, wide: bool) -> None:
        self.wide = wide
        super().__init__(name=f"VectorsAs({'arrays' if wide else 'tuples'})")


@typeof_impl.register(VectorsAs)
def _typeof_vectors_as(val, c):  # pragma: no cover - typing
    return _VectorsAsType(val.wide)


register_model(_VectorsAsType)(models.OpaqueModel)


@unbox(_VectorsAsType)  # type: ignore[no-untyped-call]
def _unbox_vectors_as(typ, obj, c):  # pragma: no cover - compiled
    return NativeValue(c.context.get_dummy_value())  # type: ignore[no-untyped-call]


def _vectors(how: VectorsAs, pp: Any, op: Any, cp: Any,
             ap: Any) -> tuple[Any, ...]:  # pragma: no cover - the kernels use the overload
    """The plant's, observer's, controller's and actuator's vectors as ``how`` says."""
    raise NotImplementedError


@overload(_vectors)
def _vectors_compiled(how, pp, op, cp, ap):  # pragma: no cover - compiled
    if how.wide:
        return lambda how, pp, op, cp, ap: (pp, op, cp, ap)
    return lambda how, pp, op, cp, ap: (_tuple16(pp), _tuple32(op), _tuple16(cp), _tuple16(ap))


def _loaded(kernel: Any, how: VectorsAs) -> bool:
    """``kernel`` is compiled (or loaded from the disk cache) in this process for ``how``."""
    kind = numba.typeof(how)  # type: ignore[no-untyped-call]
    return any(sig and sig[0] == kind for sig in kernel.overloads)


@njit(cache=True, error_model="numpy")
def _tuple16(a):  # pragma: no cover - compiled
    return (a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12],
            a[13], a[14], a[15])


@njit(cache=True, error_model="numpy")
def _tuple32(a):  # pragma: no cover - compiled
    return (a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12],
            a[13], a[14], a[15], a[16], a[17], a[18], a[19], a[20], a[21], a[22], a[23], a[24],
            a[25], a[26], a[27], a[28], a[29], a[30], a[31])


@njit(cache=True, error_model="numpy")
def _records(how, n, fpar, ipar, b0, pp, op, cp, ap):  # pragma: no cover - compiled
    """The records of the sample functions for one point, with the registry's dispatch.

    The parameter vectors are handed over as ``how`` says (:class:`VectorsAs`; the
    physics indexes tuples exactly like arrays).
    """
    sg = Sampling(n, fpar[_TS], fpar[_H], ipar[_NSUB], ipar[_DELAY], fpar[_SIGMA], fpar[_Q])
    vp, vo, vc, va = _vectors(how, pp, op, cp, ap)
    d = Designs(b0, vp, vo, vc, va, ipar[_NZ], ipar[_NC])
    s = Steps(_kinds.plant_advance, _kinds.plant_advance_block, _kinds.plant_acceleration,
              _kinds.plant_observer_input, _kinds.observer_initialize, _kinds.observer_estimate,
              _kinds.observer_advance, _kinds.controller_initialize, _kinds.controller_control)
    return sg, d, s


@njit(cache=True, nogil=True, error_model="numpy")
def _run(how, log, n, x0, noise, fpar, ipar, ref, b0, pp, op, cp,
         ap):  # pragma: no cover - compiled
    """One run of :func:`closed_loop` with the registry's dispatch functions.

    Without the GIL: :func:`simulate_many` calls it from several threads.
    """
    x = x0.copy()
    sg, d, s = _records(how, n, fpar, ipar, b0, pp, op, cp, ap)
    return closed_loop(log, x, noise, ref, sg, d, s)


@njit(cache=True, error_model="numpy")
def _run_block(how, logs, rows, n, xs, noises, fpar, ipar, ref, b0, pp, op, cp,
               ap):  # pragma: no cover - compiled
    """A block of runs of one point through :func:`closed_loop_block` (records as in _run)."""
    sg, d, s = _records(how, n, fpar, ipar, b0, pp, op, cp, ap)
    closed_loop_block(logs, rows, xs, noises, ref, sg, d, s)


@njit(cache=True, parallel=True, error_model="numpy")
def _metrics_kernel(how, run_point, run_noise, fpar, ipar, x0, b0, pp, op, cp, ap, refs, noises,
                    out):  # pragma: no cover - compiled
    """The metrics of each run (one at a time, in parallel over the runs) into ``out``."""
    nmax = refs.shape[2]
    for r in prange(run_point.shape[0]):
        p = run_point[r]
        n = ipar[p, _N]
        nj = ipar[p, _NJ]
        log = np.empty((NROW * nj, nmax))
        status = _run(how, log, n, x0[p], noises[run_noise[r]], fpar[p], ipar[p],
                      refs[ipar[p, _REFIDX]], b0[p, :nj], pp[p], op[p], cp[p], ap[p])
        joints_metrics(log, nj, abs(status), status < 0, out[r])


@njit(cache=True, parallel=True, error_model="numpy")
def _blocked_metrics_kernel(how, blk_point, blk_start, blk_len, run_noise, fpar, ipar, x0, b0,
                            pp, op, cp, ap, refs, noises, out):  # pragma: no cover - compiled
    """The metrics of each run, the runs of a block (:func:`_blocks`) advanced together."""
    for b in prange(blk_point.shape[0]):
        p = blk_point[b]
        r0 = blk_start[b]
        m = blk_len[b]
        n = ipar[p, _N]
        nj = ipar[p, _NJ]
        logs = np.empty((m, NROW * nj, max(n, 1)))
        xs = np.empty((m, x0.shape[1]))
        nz = np.empty((m, noises.shape[1]))
        for i in range(m):
            xs[i] = x0[p]
            nz[i] = noises[run_noise[r0 + i]]
        rows = np.empty(m, dtype=np.int64)
        _run_block(how, logs, rows, n, xs, nz, fpar[p], ipar[p], refs[ipar[p, _REFIDX]],
                   b0[p, :nj], pp[p], op[p], cp[p], ap[p])
        for i in range(m):
            joints_metrics(logs[i], nj, abs(rows[i]), rows[i] < 0, out[r0 + i])


@njit(cache=True, parallel=True, error_model="numpy")
def _series_kernel(how, run_point, run_noise, fpar, ipar, x0, b0, pp, op, cp, ap, refs, noises,
                   logs, rows_out):  # pragma: no cover - compiled
    """:func:`_series_runs` as a parallel kernel over the runs (run for the arrays only)."""
    for r in prange(run_point.shape[0]):
        p = run_point[r]
        nj = ipar[p, _NJ]
        rows_out[r] = _run(how, logs[r], ipar[p, _N], x0[p], noises[run_noise[r]], fpar[p],
                           ipar[p], refs[ipar[p, _REFIDX]], b0[p, :nj], pp[p], op[p],
                           cp[p], ap[p])


def _blocks(run_point: np.ndarray, ipar: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cut the runs (point-major) into blocks of consecutive runs of one grid point.

    At most :data:`BLOCK` runs per block, fewer for long runs so that a block's
    logs stay within :data:`BLOCK_BYTES`.
    """
    starts, lens, pts = [], [], []
    r, total = 0, len(run_point)
    while r < total:
        p = int(run_point[r])
        per_run = 8 * NROW * max(int(ipar[p, _NJ]), 1) * max(int(ipar[p, _N]), 1)
        cap = max(1, min(BLOCK, BLOCK_BYTES // per_run))
        stop = r + 1
        while stop < total and run_point[stop] == p and stop - r < cap:
            stop += 1
        starts.append(r)
        lens.append(stop - r)
        pts.append(p)
        r = stop
    return (np.array(pts, dtype=np.int64), np.array(starts, dtype=np.int64),
            np.array(lens, dtype=np.int64))


def _series_runs(pack: _Pack, logs: np.ndarray, rows: np.ndarray, workers: int | None) -> None:
    """Each run of ``pack`` through :func:`_run` into ``logs[r]``, ``rows[r]``, on threads.

    Not a parallel (``prange``) kernel: that would be a second compiled copy of the
    whole sample loop, which a first ``esoarm reproduce`` after installation compiled
    on top of :func:`_run` (63 s of its 231 s of compiling, load 14); ``_run``
    releases the GIL, so the threads share the cores the same way.
    """
    how = ARRAYS if pack.wide else TUPLES

    def one(r: int) -> None:
        p = pack.run_point[r]
        nj = pack.ipar[p, _NJ]
        rows[r] = _run(how, logs[r], pack.ipar[p, _N], pack.x0[p],
                       pack.noises[pack.run_noise[r]],
                       pack.fpar[p], pack.ipar[p], pack.refs[pack.ipar[p, _REFIDX]],
                       pack.b0[p, :nj], pack.pp[p], pack.op[p], pack.cp[p], pack.ap[p])

    runs = len(pack.run_point)
    threads = min(workers or numba.get_num_threads(), runs)
    if threads <= 1:
        for r in range(runs):
            one(r)
        return
    with ThreadPoolExecutor(max_workers=threads) as pool:
        list(pool.map(one, range(runs)))


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
    blocked: bool = True,
    series: bool | None = None,
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
    blocked : bool
        Advance the runs of a grid point together, in blocks of up to :data:`BLOCK`
        (:func:`~esoarm.engines.loop.closed_loop_block`: the same numbers, faster);
        False runs them one at a time (kept for comparison in the benchmarks).
    series : bool, optional
        Run through the time-series kernel and take the metrics with NumPy (the same
        numbers; no second compiled copy of the sample loop to build or load).  Default:
        for calls of at most :data:`SERIES_RUNS` runs, with ``blocked``, unless this process
        has the blocked kernel loaded already.  Points whose parameter vectors are arrays
        (URDF arms) always use the metrics kernels.
    _noise_cache : NoiseCache, optional
        Internal: the noise sequences already drawn, shared with a caller that runs the
        same seeds again (a fresh cache by default).

    Returns
    -------
    MetricsTable
        One row per run, columns :data:`METRICS`.  Diverged runs are rows with
        ``diverged = 1`` (they do not raise).
    """
    noise_cache = _noise_cache or NoiseCache()
    compiled = [_kinds.kinds_of(scn).jit for scn in points]
    _cover(points)
    if series is None:  # (a sweep's last, small chunk: the blocked kernel is loaded already)
        nruns = len(points) * (1 if seeds is None else len(seeds))
        series = (blocked and nruns <= SERIES_RUNS
                  and not _loaded(_blocked_metrics_kernel, TUPLES))
    def run_chunk(part: list[tuple[int, int]]) -> np.ndarray:
        res = np.empty((len(part), NMETRIC))
        jit_idx = [i for i, (pi, _) in enumerate(part) if compiled[pi]]
        py_idx = [i for i, (pi, _) in enumerate(part) if not compiled[pi]]
        if jit_idx:
            res[jit_idx] = _compiled_metrics(points, [part[i] for i in jit_idx], noise_cache,
                                             series, blocked, workers)
        if py_idx:
            jobs = [points[part[i][0]].with_overrides({"sensor.seed": part[i][1]})
                    for i in py_idx]
            res[py_idx] = _python_metrics(jobs, workers)
        return res

    with _threads(workers):
        return _chunked_metrics(points, seeds, chunk, progress, run_chunk)


def _compiled_metrics(points: Sequence[Scenario], runs: list[tuple[int, int]],
                      noise_cache: NoiseCache, series: bool, blocked: bool,
                      workers: int | None) -> np.ndarray:
    """Metrics rows of ``runs`` ((point index, seed), every point's kinds compiled).

    Through the time-series kernel (``series``), the blocked metrics kernel, or the
    one-run-at-a-time metrics kernel; vectors as tuples or arrays as the points need.
    """
    used, local = _renumbered(runs)
    pack = _pack([points[pi] for pi in used], local, noise_cache)
    res = np.empty((len(runs), NMETRIC))
    how = ARRAYS if pack.wide else TUPLES
    if series and not pack.wide:
        _series_metrics(pack, [points[pi] for pi, _ in runs], res, workers)
    elif blocked:
        blk = _blocks(pack.run_point, pack.ipar)
        _blocked_metrics_kernel(how, *blk, *pack.args()[1:], res)  # type: ignore[call-arg]
    else:
        _metrics_kernel(how, *pack.args(), res)  # type: ignore[call-arg]
    return res


def _series_metrics(pack: _Pack, scenarios: list[Scenario], out: np.ndarray,
                    workers: int | None) -> None:
    """Metrics of the runs of ``pack`` (run r of ``scenarios[r]``) into ``out``, through
    :func:`_run` and :meth:`esoarm.result.SimResult.from_log` (see :data:`SERIES_RUNS`)."""
    nmax = pack.refs.shape[2]
    runs = len(pack.run_point)
    logs = np.empty((runs, NROW * int(pack.ipar[:, _NJ].max()), nmax))
    rows = np.empty(runs, dtype=np.int64)  # rows logged, < 0: diverged
    _series_runs(pack, logs, rows, workers)
    for r, scn in enumerate(scenarios):
        k = abs(int(rows[r]))
        t = np.arange(k) * scn.sample_time
        nj = NROW * int(pack.ipar[pack.run_point[r], _NJ])
        result = SimResult.from_log(scn, t, logs[r, :nj, :k], diverged=bool(rows[r] < 0))
        out[r] = [result.metrics[name] for name in METRICS]


def _reference_metrics(scn: Scenario) -> np.ndarray:
    """:data:`METRICS` of one run by the reference engine (a diverged run does not raise)."""
    try:
        result = run_reference(scn, prepare(scn))
    except SimulationDiverged as exc:
        result = exc.result
    return np.array([result.metrics[name] for name in METRICS])


def _python_metrics(scenarios: list[Scenario], workers: int | None) -> np.ndarray:
    """Metrics of runs whose kinds do not compile: the reference engine in worker processes."""
    procs = workers or os.cpu_count() or 1
    if procs == 1 or len(scenarios) == 1:
        return np.array([_reference_metrics(scn) for scn in scenarios])
    with ProcessPoolExecutor(max_workers=min(procs, len(scenarios))) as pool:
        return np.array(list(pool.map(_reference_metrics, scenarios)))


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
        Runs per kernel call (memory ≈ chunk · 11 · N · 8 bytes).

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
    _cover(scenarios)
    with _threads(workers):
        for start in range(0, len(scenarios), chunk):
            part = scenarios[start : start + chunk]
            if not all(_kinds.kinds_of(scn).jit for scn in part):
                results.extend(run_reference(scn, prepare(scn)) for scn in part)
                continue
            pack = _pack(part, [(i, scn.sensor.seed) for i, scn in enumerate(part)], noise_cache)
            nmax = pack.refs.shape[2]
            logs = np.empty((len(part), NROW * int(pack.ipar[:, _NJ].max()), nmax))
            rows = np.empty(len(part), dtype=np.int64)  # rows logged, < 0: diverged
            if pack.wide:
                _series_kernel(ARRAYS, *pack.args(), logs, rows)  # type: ignore[call-arg]
            else:
                _series_runs(pack, logs, rows, workers)
            for i, scn in enumerate(part):
                n = scn.n_samples
                k = abs(int(rows[i]))
                t = np.arange(n) * scn.sample_time
                result = SimResult.from_log(scn, t[:k], logs[i, :, :k], diverged=rows[i] < 0)
                if rows[i] < 0:
                    raise SimulationDiverged(
                        diverged_message(scn.name, float(t[k - 1]), k - 1, result), result)
                results.append(result)
    return results


def compile_kernels(series: bool = True, metrics: bool = True) -> None:
    """Compile (or load from the on-disk cache) the kernels ahead of use.

    Runs a 0.04 s default scenario through the chosen kernels (numba compiles them on
    first use, 30-90 s without a cache).

    Parameters
    ----------
    series : bool
        Compile the time-series kernel (:func:`simulate_many`).
    metrics : bool
        Compile the metrics kernel (:func:`run_metrics`).
    """
    scn = Scenario(duration=0.04)
    if series:
        simulate_many([scn], workers=1)
    if metrics:
        run_metrics([scn], workers=1)
