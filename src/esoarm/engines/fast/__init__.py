"""Opt-in fast engine: blocks of runs on a vectorized C kernel (``--engine fast``).

The exact engine (:mod:`esoarm.engines.batch`) is bit-identical to the reference
engine and stays the default.  This engine trades the last bits for speed: it
advances a block of 64 runs together, runs as the innermost loop, and lets the
C compiler turn that loop into SIMD code that calls glibc's vector ``tanh``
and ``cos`` (libmvec; AVX-512 does 8 runs per instruction).  The kernel,
``_fast_kernel.c`` beside this module, is compiled on first use with the
system C compiler (``$CC``, else ``cc`` or ``gcc``) and cached under
``$ESOARM_CACHE_DIR`` (default ``~/.cache/esoarm``).

Agreement with the exact engine
    Relative difference ≤ 1e-9 on every metric wherever no quantization
    boundary is crossed (tested with ``sensor.resolution_deg = 0``).  With a
    quantizing encoder a round-off difference in θ can, rarely, put a
    measurement on the other side of a quantization step; that run then
    differs by about what one encoder count changes (tested and documented in
    the benchmarks page).  Gear backlash is a switch of the same sort: with a
    high-gain observer the loop can chatter in the gap and the metrics become
    round-off-sensitive (the exact engine itself moves by up to ~8 % when θ0
    moves by 1e-15 rad); the fast engine then differs by as much.  Runs that
    diverge are re-run on the exact engine, so their partial metrics are the
    exact engine's.

What it supports
    Every scenario the exact engine runs except those :func:`unsupported`
    names (a run that needs the exact engine is reported, never silently
    approximated): the lever arm with the linear ESO and the FLC, no motor
    (``actuator.pwm_bits``, coloured noise, gear backlash, ``rig.backlash_deg``, hard end
    stops, ``rig.end_stops``, the gate ``actuator.stop_gate``,
    ``actuator.observer_sees = "commanded"``, a cogging torque, ``rig.cogging``, and a learned
    feedforward table, ``controller.feedforward_map``, are modelled).
    It computes every metric of :data:`esoarm.engines.metrics.METRICS`.

Without a working C compiler the fast engine is unavailable: :func:`run_metrics`
warns once and runs the exact engine instead (same numbers, slower).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from esoarm._limits import STREAM_SAMPLES
from esoarm.controllers import flc as _ctl
from esoarm.engines import packing as _packing
from esoarm.engines.metrics import METRICS, MetricsTable, NoiseCache, _chunked_metrics, _renumbered
from esoarm.engines.simulation import DIVERGENCE_LIMIT
from esoarm.kinds import hook, kinds_of
from esoarm.observers import linear as _obs
from esoarm.plants import actuator as _act
from esoarm.plants import lever_arm as _rig
from esoarm.scenario import Scenario

__all__ = [
    "FastEngineUnavailable",
    "FastEngineWarning",
    "available",
    "run_metrics",
    "unsupported",
]

_SOURCE = Path(__file__).with_name("_fast_kernel.c")
_LANES = 64
#: Runs per chunk handed to the kernel threads (memory is O(chunk · N)).
DEFAULT_CHUNK = 2048

# per-lane parameter rows, in the order of the C enum
_PAR_NAMES = (
    "theta0", "sigma", "q", "b0", "inertia", "gcoef", "fc", "vs", "visc", "lag",
    "beta1", "beta2", "beta3", *(f"phi{i}" for i in range(9)), *(f"gamma{i}" for i in range(3)),
    *(f"gain{i}" for i in range(3)), "k1", "k2", "i0", "cgcoef", "limit", "pwm",
    "alpha", "jm", "kgear", "cgear", "sees", "gate", "stop_lo", "stop_hi",
    "cog_a", "cog_n", "cog_p", "ff_n",
)
_NPAR = len(_PAR_NAMES)
_NOUT = 10
#: Columns of :data:`esoarm.engines.metrics.METRICS` this engine computes (all of them).
COMPUTED: tuple[int, ...] = tuple(range(len(METRICS)))


class FastEngineUnavailable(RuntimeError):
    """The fast engine's C kernel could not be built or loaded here."""


class FastEngineWarning(UserWarning):
    """The fast engine fell back to the exact engine."""


# ---------------------------------------------------------------------------
# building and loading the kernel

_LIB: ctypes.CDLL | None = None
_LIB_ERROR: str | None = None
_LIB_LOCK = threading.Lock()

# tried in order: vector transcendentals for this CPU, then without -march,
# then a plain build (no libmvec: still blocked, scalar libm)
_FLAG_SETS = (
    (["-O3", "-march=native", "-mprefer-vector-width=512", "-ffast-math", "-fopenmp-simd"],
     ["-lmvec", "-lm"]),
    (["-O3", "-march=native", "-ffast-math", "-fopenmp-simd"], ["-lmvec", "-lm"]),
    (["-O3", "-ffast-math", "-fopenmp-simd"], ["-lmvec", "-lm"]),
    (["-O3", "-fno-math-errno"], ["-lm"]),
)


def _compiler() -> str | None:
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    return None


def _cpu_flags() -> str:
    """The CPU's feature flags: a kernel built with -march=native is only reused on a
    CPU with the same instruction sets (a shared home directory may span machines)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith(("flags", "Features")):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


def cache_dir() -> Path:
    """Where built kernels are kept: ``$ESOARM_CACHE_DIR``, else ``~/.cache/esoarm`` if
    writable, else a directory of the user's in the temporary directory
    (:func:`esoarm._cache.cache_dir`).

    Returns
    -------
    Path
        The cache directory (the built kernels are ``fast-kernel-<stamp>.so`` in it).
    """
    from esoarm._cache import cache_dir as esoarm_cache

    return esoarm_cache()


def _build(cc: str) -> Path:
    source = _SOURCE.read_bytes()
    version = subprocess.run([cc, "--version"], capture_output=True, text=True,
                             check=False).stdout.splitlines()[:1]
    errors = []
    for cflags, libs in _FLAG_SETS:
        stamp = hashlib.sha256(
            source + repr((version, cflags, libs, os.uname().machine, _cpu_flags())).encode()
        ).hexdigest()[:16]
        target = cache_dir() / f"fast-kernel-{stamp}.so"
        if target.exists():
            return target
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
            obj, lib = Path(tmp) / "k.o", Path(tmp) / "k.so"
            # compiled with -ffast-math but linked without it: linking with it
            # would add crtfastmath.o, which switches the whole process to
            # flush-to-zero when the library is loaded
            steps = ([cc, *cflags, "-fPIC", "-c", str(_SOURCE), "-o", str(obj)],
                     [cc, "-shared", str(obj), "-o", str(lib), *libs])
            for cmd in steps:
                res = subprocess.run(cmd, capture_output=True, text=True, check=False)
                if res.returncode != 0:
                    errors.append(f"{' '.join(cmd[:3])} ...: {res.stderr.strip()[:300]}")
                    break
            else:
                try:
                    ctypes.CDLL(str(lib))  # loads here (e.g. libmvec present)?
                except OSError as exc:
                    errors.append(str(exc))
                    continue
                os.replace(lib, target)
                return target
    raise FastEngineUnavailable("the fast engine's C kernel did not build: " + "; ".join(errors))


def _bind(lib: ctypes.CDLL) -> ctypes.CDLL:
    """Declare the C signature of ``esoarm_fast_block`` on a loaded kernel."""
    fn = lib.esoarm_fast_block
    fn.restype = None
    i, n, d, p = ctypes.c_int, ctypes.c_long, ctypes.c_double, ctypes.c_void_p
    fn.argtypes = [i, n, n, n, i, i, i, i, i, i, i, n, p,  # lanes, N, substeps, delay, kind,
                   # comp, lag, gear, stops, cogging, table on, its width, the tables
                   d, d, d, d, d,  # h, Ts, disturbance amplitude and frequency, limit
                   p, p, n, p, p, p, p, p]  # par, refs, stride, offsets, noise, ..., out
    return lib


def load_kernel() -> ctypes.CDLL:
    """Build (first time only) and load the C kernel.

    Returns
    -------
    ctypes.CDLL
        The loaded kernel with ``esoarm_fast_block``'s C signature declared (one per
        process, shared by every caller).

    Raises
    ------
    FastEngineUnavailable
        No C compiler, or the build failed; the message says which.
    """
    global _LIB, _LIB_ERROR
    with _LIB_LOCK:
        if _LIB is not None:
            return _LIB
        if _LIB_ERROR is not None:
            raise FastEngineUnavailable(_LIB_ERROR)
        try:
            cc = _compiler()
            if cc is None:
                raise FastEngineUnavailable(
                    "the fast engine needs a C compiler (cc or gcc on PATH, or $CC)")
            lib = ctypes.CDLL(str(_build(cc)))
            if lib.esoarm_fast_lanes() != _LANES or lib.esoarm_fast_npar() != _NPAR:
                raise FastEngineUnavailable(
                    "the fast engine's C kernel does not match esoarm.fast (stale build)")
        except (FastEngineUnavailable, OSError) as exc:
            _LIB_ERROR = str(exc)
            raise FastEngineUnavailable(_LIB_ERROR) from None
        _bind(lib)
        _LIB = lib
        return lib


def available() -> bool:
    """Whether the fast engine can run here (builds the kernel if needed).

    Returns
    -------
    bool
        True if the C kernel builds and loads; False otherwise (no compiler, build failed).
    """
    try:
        load_kernel()
    except FastEngineUnavailable:
        return False
    return True


# ---------------------------------------------------------------------------
# what the fast engine runs


def unsupported(scn: Scenario) -> str | None:
    """Why ``scn`` needs the exact engine, or None if the fast engine runs it.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    str or None
        The setting the fast engine does not model (e.g. ``"a [motor] model"``), or None.
    """
    for section, module in zip(("plant", "observer", "controller"), kinds_of(scn), strict=True):
        if not hook(module, "FAST"):  # the kind does not declare FAST = True
            return f"{section}.kind = {module.KIND!r}"
    if getattr(scn.observer, "input_delay", 0):
        return "observer.input_delay > 0"
    if getattr(scn.observer, "delay_form", "input") == "model":
        return "observer.delay_form = 'model'"
    if getattr(scn, "motor", None) is not None:
        return "a [motor] model"
    kind = getattr(scn.rig.disturbance, "kind", "sine")
    if kind != "sine":
        return f"rig.disturbance.kind = {kind!r}"
    if getattr(scn.rig, "stiction", 0.0) != 0.0:
        return "rig.stiction > 0 (Stribeck friction)"
    return None


def _point_rows(pack: _packing._Pack) -> np.ndarray:
    """(P, NPAR) per-point parameter rows in the kernel's order."""
    # the kinds' vectors without their CODE in element 0
    f, rg, ob, ct = pack.fpar, _rig_rows(pack), pack.op[:, 1:], pack.cp[:, 1:]
    cols = [pack.x0[:, 0], f[:, _packing._SIGMA], f[:, _packing._Q], pack.b0[:, 0],
            rg[:, _rig.INERTIA], rg[:, _rig.GCOEF], rg[:, _rig.FC], rg[:, _rig.VS],
            rg[:, _rig.VISC], rg[:, _rig.LAG],
            ob[:, _obs.BETA1], ob[:, _obs.BETA2], ob[:, _obs.BETA3],
            *(ob[:, _obs.PHI + i] for i in range(9)), *(ob[:, _obs.GAMMA + i] for i in range(3)),
            *(ob[:, _obs.GAIN + i] for i in range(3)),
            ct[:, _ctl.K1], ct[:, _ctl.K2], ct[:, _ctl.I0], ct[:, _ctl.GCOEF], ct[:, _ctl.LIMIT],
            pack.ap[:, _act.PWM_LEVELS],
            rg[:, _rig.BACKLASH], rg[:, _rig.JM], rg[:, _rig.KGEAR], rg[:, _rig.CGEAR],
            # what the ESO is fed, the gate's band and the stops (∓1e30 without stops)
            pack.ap[:, _act.SEES], pack.ap[:, _act.GATE], pack.ap[:, _act.GATE_LO],
            pack.ap[:, _act.GATE_HI],
            # rig.cogging (A = 0: none) and the learned table's bin count (0: none)
            rg[:, _rig.COG_AMP], rg[:, _rig.COG_PERIODS], rg[:, _rig.COG_PHASE],
            _table_bins(pack)]
    out = np.column_stack(cols)
    assert out.shape[1] == _NPAR
    return out


def _rig_rows(pack: _packing._Pack) -> np.ndarray:
    """The rig vectors without their CODE, zero-padded to every entry (cogging, stops)."""
    rg = pack.pp[:, 1:]
    out = np.zeros((rg.shape[0], max(rg.shape[1], _rig.VECTOR_SIZE)))
    out[:, : rg.shape[1]] = rg
    return out


def _table_bins(pack: _packing._Pack) -> np.ndarray:
    """(P,) the learned table's bin count of each point (0: none)."""
    return np.array([float(_act.table_bins(row)) for row in pack.ap])


def _has_stops(a: np.ndarray) -> bool:
    """Whether actuator vector ``a`` carries rig.end_stops (∓1e30 stands for none)."""
    return bool(a[_act.GATE_LO] > -1e29 or a[_act.GATE_HI] < 1e29)


def _structure(pack: _packing._Pack, p: int, rgs: np.ndarray,
               bins: np.ndarray) -> tuple:  # type: ignore[type-arg]
    """What a block must share: sizes, steps, discretization, flags (lag, gear backlash,
    end stops, cogging, a learned table), disturbance."""
    ip, f, rg, ob, ct = pack.ipar[p], pack.fpar[p], rgs[p], pack.op[p, 1:], pack.cp[p, 1:]
    return (int(ip[_packing._N]), int(ip[_packing._NSUB]), int(ip[_packing._DELAY]),
            int(ob[_obs.DISC]), int(ct[_ctl.COMP]), int(rg[_rig.LAG] > 0.0),
            int(rg[_rig.BACKLASH] > 0.0), int(_has_stops(pack.ap[p])),
            int(rg[_rig.COG_AMP] != 0.0), int(bins[p] > 0.0),
            float(f[_packing._H]), float(f[_packing._TS]), float(rg[_rig.DAMP]),
            float(rg[_rig.DFREQ]))


def _run_pack(lib: ctypes.CDLL, pack: _packing._Pack, workers: int) -> np.ndarray:
    """Metrics rows (R, len(METRICS)) of one packed chunk."""
    nruns = len(pack.run_point)
    rows = _point_rows(pack)
    nmax = pack.refs.shape[2]
    refs = np.ascontiguousarray(pack.refs)
    noises = np.ascontiguousarray(pack.noises)
    groups: dict[tuple, list[int]] = {}  # type: ignore[type-arg]
    rgs, bins = _rig_rows(pack), _table_bins(pack)
    keys = [_structure(pack, p, rgs, bins) for p in range(len(rows))]
    for r in range(nruns):
        groups.setdefault(keys[pack.run_point[r]], []).append(r)
    blocks = []
    for key, members in groups.items():
        for i in range(0, len(members), _LANES):
            blocks.append((key, np.array(members[i : i + _LANES], dtype=np.int64)))
    raw = np.empty((nruns, _NOUT))

    def work(item: tuple) -> None:  # type: ignore[type-arg]
        (n, nsub, delay, kind, comp, lag_on, gear_on, stops_on, cog_on, ff_on, h, ts, damp,
         dfreq), runs = item
        lanes = np.resize(runs, _LANES)  # pad with repeats; their outputs are dropped
        pts = pack.run_point[lanes]
        par = np.ascontiguousarray(rows[pts].T)
        ref_off = (pack.ipar[pts, _packing._REFIDX] * 3 * nmax).astype(np.int64)
        noise_off = (pack.run_noise[lanes] * nmax).astype(np.int64)
        uhist = np.zeros((delay + 1) * _LANES)
        # each lane's table, row by row (the bins after FF_BINS in the actuator vector)
        nbins = bins[pts].astype(np.int64)
        ffmax = max(int(nbins.max()), 1)
        ff = np.zeros((_LANES, ffmax))
        for lane, (pt, nb) in enumerate(zip(pts, nbins, strict=True)):
            ff[lane, :nb] = pack.ap[pt, _act.FF_BINS + 1 : _act.FF_BINS + 1 + nb]
        out = np.empty((_NOUT, _LANES))
        lib.esoarm_fast_block(len(runs), n, nsub, delay, kind, comp, lag_on, gear_on, stops_on,
                              cog_on, ff_on, ffmax, ff.ctypes.data, h, ts,
                              damp, dfreq,
                              DIVERGENCE_LIMIT, par.ctypes.data, refs.ctypes.data, nmax,
                              ref_off.ctypes.data, noises.ctypes.data, noise_off.ctypes.data,
                              uhist.ctypes.data, out.ctypes.data)
        raw[runs] = out[:, : len(runs)].T

    if workers > 1 and len(blocks) > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(work, blocks))
    else:
        for b in blocks:
            work(b)
    res = np.full((nruns, len(METRICS)), np.nan)
    n_rows = raw[:, 8]
    col = METRICS.index
    res[:, col("rms_error")] = np.sqrt(raw[:, 0] / n_rows)
    res[:, col("rms_u")] = np.sqrt(raw[:, 1] / n_rows)
    res[:, col("max_abs_error")] = raw[:, 2]
    res[:, col("max_abs_u")] = raw[:, 3]
    res[:, col("rms_f_error")] = np.sqrt(raw[:, 4] / n_rows)
    res[:, col("rms_rate_error")] = np.sqrt(raw[:, 5] / n_rows)
    with np.errstate(invalid="ignore", divide="ignore"):
        res[:, col("rms_du")] = np.where(n_rows > 1, np.sqrt(raw[:, 6] / (n_rows - 1)), 0.0)
    res[:, col("saturated_fraction")] = raw[:, 7] / n_rows
    res[:, col("samples")] = n_rows
    res[:, col("diverged")] = raw[:, 9]
    return res


def _default_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


_warned = False


def run_metrics(
    points: Sequence[Scenario],
    seeds: Sequence[int] | None = None,
    *,
    workers: int | None = None,
    chunk: int = DEFAULT_CHUNK,
    progress: Callable[[int], None] | None = None,
    _noise_cache: NoiseCache | None = None,
) -> MetricsTable:
    """Fast counterpart of :func:`esoarm.engines.batch.run_metrics`: same arguments and table.

    Parameters
    ----------
    points : sequence of Scenario
        Validated scenarios; each must be one the fast engine supports.
    seeds : sequence of int, optional
        Noise seeds run at every point (seed fastest); default each point's own.
    workers : int, optional
        Threads (cores); default all this process may use.
    chunk : int
        Runs per packed chunk; memory is O(chunk · N).
    progress : callable, optional
        Called with the number of runs finished after each chunk.
    _noise_cache : NoiseCache, optional
        Internal: the noise sequences already drawn, shared with a caller that runs the
        same seeds again (a fresh cache by default).

    Returns
    -------
    MetricsTable
        One row per run (point-major, seed fastest), columns
        :data:`esoarm.engines.metrics.METRICS`; a run that diverged has the exact engine's
        partial metrics and ``diverged`` = 1.  Without a C compiler the exact engine's table,
        with a :class:`FastEngineWarning` (once per process).

    Raises
    ------
    ValueError
        A point needs the exact engine (the message names the setting).
    """
    global _warned
    for scn in points:
        why = unsupported(scn)
        if why is not None:
            raise ValueError(
                f"scenario '{scn.name}' has {why}, which the fast engine does not model; "
                "use the exact engine (--engine exact)")
    if any(scn.n_samples > STREAM_SAMPLES for scn in points):
        # a run this long keeps its whole log in the kernel's memory; the exact engine
        # streams it block by block (esoarm.engines.stream), in constant memory
        from esoarm.engines import batch as _batch
        from esoarm.engines.stream import with_long_runs

        return with_long_runs(_batch.run_metrics, points, seeds, workers=workers, chunk=chunk,
                              progress=progress, _noise_cache=_noise_cache)
    try:
        lib = load_kernel()
    except FastEngineUnavailable as exc:
        if not _warned:
            warnings.warn(f"{exc}; running the exact engine instead", FastEngineWarning,
                          stacklevel=2)
            _warned = True
        from esoarm.engines import batch as _batch  # numba: only when falling back

        return _batch.run_metrics(points, seeds, workers=workers, chunk=chunk,
                                  progress=progress, _noise_cache=_noise_cache)
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    nthreads = workers or _default_workers()
    noise_cache = _noise_cache or NoiseCache()

    def run_chunk(part: list[tuple[int, int]]) -> np.ndarray:
        used, local = _renumbered(part)
        pack = _packing._pack([points[pi] for pi in used], local, noise_cache)
        res = _run_pack(lib, pack, nthreads)
        bad = np.flatnonzero(res[:, METRICS.index("diverged")] != 0.0)
        if len(bad):  # diverged: the exact engine gives the partial metrics
            again = [points[part[i][0]].with_overrides({"sensor.seed": part[i][1]}) for i in bad]
            from esoarm.engines import batch as _batch

            res[bad] = _batch.run_metrics(again, workers=workers).values
        return res

    return _chunked_metrics(points, seeds, chunk, progress, run_chunk)


if __name__ == "__main__":  # pragma: no cover - manual check: python -m esoarm.engines.fast
    print(load_kernel(), file=sys.stderr)
