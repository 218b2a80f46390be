"""The log of a closed-loop run and every metric computed from it, in one place.

This module imports neither numba nor the compiled engines, so code that only
handles metrics (sweep tables, tuning objectives) and small sweeps start
quickly (:func:`esoarm.engines.simulation.reference_metrics` runs a few runs on the
reference engine).

Every engine writes the same log, one block of :data:`LOG_ROWS` per joint and
one column per sample (:func:`esoarm.engines.loop.closed_loop`); the
time-series CSV shows :data:`SERIES_COLUMNS`.  Metrics (:data:`METRICS`) are
defined here once and evaluated two ways that give identical numbers: with
NumPy on arrays (:func:`series_metrics`: a run's result, the rig loop, the
reproduction) and compiled inside the batch kernels (:func:`log_metrics`),
which sums in NumPy's pairwise order so that not even the last bit differs
(tested).

Metrics over the samples logged (k = 0 … N−1, or up to the sample at which a
run diverged):

``rms_error`` [rad]        sqrt(mean(e_k²)), e_k = θ(t_k) − θd(t_k)
``rms_u`` [N·m]            sqrt(mean(u_k²))
``max_abs_error`` [rad]    max |e_k|
``max_abs_u`` [N·m]        max |u_k|
``rms_f_error`` [rad/s²]   sqrt(mean((ẑ3_k − f_k)²)), the perturbation estimate's error
``rms_rate_error`` [rad/s] sqrt(mean((ẑ2_k − θ̇(t_k))²)), the rate estimate's error
``rms_du`` [N·m]           sqrt(mean((u_k − u_{k−1})²)), k ≥ 1: control roughness (0 for one sample)
``saturated_fraction``     share of samples whose command hit ±torque_limit
``samples``                samples logged
``diverged``               1.0 if the run left the finite range, else 0.0
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm._jit import jitable
from esoarm.plants.noise import NoiseModel, draws
from esoarm.plants.sensor import noise_sequence

if TYPE_CHECKING:
    from esoarm.contract import Units
    from esoarm.scenario import Scenario

__all__ = ["LOG_ROWS", "METRICS", "METRIC_QUANTITY", "SERIES_COLUMNS", "MetricsTable",
           "NoiseCache", "combine_joints", "log_metrics", "metric_units", "series_metrics"]

#: Rows of the engine log per joint (joint j occupies rows j·len(LOG_ROWS) …).
LOG_ROWS: tuple[str, ...] = ("theta", "theta_ref", "error", "u", "z1", "z2", "z3", "f_true",
                             "y", "saturated", "omega")
TH, REF, ERR, U, Z1, Z2, Z3, F, Y, SAT, OM = range(len(LOG_ROWS))
NROW = len(LOG_ROWS)

#: Time-series CSV columns, SI units: the first nine fixed, then the measured
#: angle y [rad] and the saturation flag (1: the command hit ±torque_limit).
SERIES_COLUMNS: tuple[str, ...] = ("t", "theta", "theta_ref", "error", "u", "z1", "z2", "z3",
                                   "f_true", "y", "saturated")

#: Metric names, in the column order of the batch engine's tables.
METRICS: tuple[str, ...] = (
    "rms_error", "rms_u", "max_abs_error", "max_abs_u", "rms_f_error", "rms_rate_error",
    "rms_du", "saturated_fraction", "samples", "diverged",
)
NMETRIC = len(METRICS)

#: The quantity (a field of :class:`esoarm.contract.Units`) each metric is measured in;
#: "" for a plain number.
METRIC_QUANTITY: dict[str, str] = {
    "rms_error": "position", "rms_u": "force", "max_abs_error": "position",
    "max_abs_u": "force", "rms_f_error": "acceleration", "rms_rate_error": "velocity",
    "rms_du": "force", "saturated_fraction": "", "samples": "", "diverged": "",
}


def metric_units(units: Units) -> dict[str, str]:
    """The unit of every metric of :data:`METRICS` for a plant's units ("" for a number).

    Parameters
    ----------
    units : Units
        The plant's units (:func:`esoarm.kinds.units`).

    Returns
    -------
    dict of str to str
        Metric name to unit, e.g. ``rms_error`` to "rad" (rotary) or "m" (prismatic).

    Examples
    --------
    >>> from esoarm.contract import PRISMATIC_UNITS
    >>> metric_units(PRISMATIC_UNITS)["rms_u"]
    'N'
    """
    return {name: getattr(units, q) if q else "" for name, q in METRIC_QUANTITY.items()}

# how :func:`combine_joints` combines each column over the joints (compiled twin: joints_metrics)
_RMS_COLUMNS = tuple(i for i, name in enumerate(METRICS) if name.startswith("rms_"))
_MAX_COLUMNS = tuple(i for i, name in enumerate(METRICS)
                     if name.startswith("max_") or name == "diverged")
_SAMPLES = METRICS.index("samples")


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def series_metrics(error: np.ndarray, u: np.ndarray, *, z: np.ndarray | None = None,
                   f_true: np.ndarray | None = None, omega: np.ndarray | None = None,
                   saturated: np.ndarray | None = None,
                   diverged: bool = False) -> dict[str, float]:
    """Every metric of :data:`METRICS` from a run's arrays (NaN where an input is missing).

    Parameters
    ----------
    error, u : ndarray (N,)
        Tracking error [rad] and applied command [N·m] per sample.
    z : ndarray (N, 3), optional
        Estimates ẑ_k (angle, rate, perturbation).
    f_true, omega : ndarray (N,), optional
        True perturbation [rad/s²] and rate [rad/s].
    saturated : ndarray (N,), optional
        1.0 where the command hit the limit.
    diverged : bool
        The run left the finite range.

    Returns
    -------
    dict of str to float
        Every name of :data:`METRICS`: rms_error, max_abs_error [rad]; rms_u, max_abs_u,
        rms_du [N·m]; rms_f_error [rad/s²]; rms_rate_error [rad/s]; saturated_fraction in
        [0, 1]; samples N; diverged 0 or 1.  NaN where an input is missing (all but samples
        and diverged for N = 0).

    Examples
    --------
    >>> import numpy as np
    >>> m = series_metrics(np.array([0.3, -0.4]), np.array([1.0, 1.0]))
    >>> round(m["rms_error"], 6), m["max_abs_error"], m["rms_du"], m["samples"]
    (0.353553, 0.4, 0.0, 2.0)
    """
    nan = math.nan
    n = len(error)
    out = dict.fromkeys(METRICS, nan)
    out["samples"] = float(n)
    out["diverged"] = 1.0 if diverged else 0.0
    if n == 0:
        return out
    out["rms_error"] = _rms(error)
    out["rms_u"] = _rms(u)
    out["max_abs_error"] = float(np.max(np.abs(error)))
    out["max_abs_u"] = float(np.max(np.abs(u)))
    if z is not None and f_true is not None:
        out["rms_f_error"] = _rms(z[:, 2] - f_true)
    if z is not None and omega is not None:
        out["rms_rate_error"] = _rms(z[:, 1] - omega)
    out["rms_du"] = _rms(np.diff(u)) if n > 1 else 0.0
    if saturated is not None:
        out["saturated_fraction"] = float(np.mean(saturated))
    return out


def combine_joints(joints: list[dict[str, float]]) -> dict[str, float]:
    """Metrics of an arm over every joint and sample, from each joint's :func:`series_metrics`.

    Every joint has the same samples, so an RMS over all of them is the root of
    the joints' mean squares, a maximum the largest joint maximum, a fraction
    the joints' mean.  One joint: its metrics unchanged.

    Parameters
    ----------
    joints : list of dict of str to float
        One :func:`series_metrics` dict per joint (same samples).

    Returns
    -------
    dict of str to float
        The arm's metrics, same names and units; ``diverged`` 1 if any joint diverged.

    Examples
    --------
    >>> m = combine_joints([{n: 3.0 for n in METRICS}, {n: 4.0 for n in METRICS}])
    >>> m["rms_error"], m["max_abs_u"], m["saturated_fraction"]
    (3.5355339059327378, 4.0, 3.5)
    """
    if len(joints) == 1:
        return dict(joints[0])
    out: dict[str, float] = {}
    for name in METRICS:
        values = np.array([m[name] for m in joints])
        if name.startswith("rms_"):
            out[name] = float(np.sqrt(np.mean(values**2)))
        elif name.startswith("max_") or name == "diverged":
            out[name] = float(np.max(values))
        elif name == "samples":
            out[name] = float(values[0])
        else:
            out[name] = float(np.mean(values))
    return out


# ---------------------------------------------------------------------------
# compiled evaluation (batch kernels): the same numbers, bit for bit


@jitable
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:
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
    total: float = res
    return total


@jitable
def pairwise_sum(a: np.ndarray, n: int) -> float:
    """Sum of a[:n] in NumPy's pairwise order (bit-identical to ``np.add.reduce``).

    NumPy splits a block of n > 128 values at n2 = n//2 rounded down to a
    multiple of 8 and adds the two halves' sums; blocks of ≤ 128 values use 8
    interleaved accumulators.  Written with an explicit stack (no recursion).

    Parameters
    ----------
    a : ndarray
        The values (float64); only ``a[:n]`` is read.
    n : int
        Number of values summed (n ≥ 0).

    Returns
    -------
    float
        The sum, the same bits as ``np.add.reduce(a[:n])``.
    """
    # stack of (lo, n, partial sum of the left half, state) frames
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


@jitable
def _rms_of(scratch: np.ndarray, n: int) -> float:
    return math.sqrt(pairwise_sum(scratch, n) / n)


@jitable
def _max_abs(x: np.ndarray, n: int) -> float:
    # np.max propagates NaN; so does this
    m: float = abs(x[0])
    for i in range(1, n):
        v: float = abs(x[i])
        if v > m or v != v:
            m = v
            if v != v:
                return v
    return m


@jitable
def log_metrics(log: np.ndarray, rows: int, diverged: bool, out: np.ndarray) -> None:
    """:data:`METRICS` of joint 0 of an engine log with ``rows`` samples, into ``out``.

    The compiled twin of :func:`series_metrics` (same numbers, bit for bit).

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ rows)
        An engine log (:data:`LOG_ROWS`); joint 0's rows are read.
    rows : int
        Samples logged (columns 0 … rows−1), ≥ 1.
    diverged : bool
        The run left the finite range.
    out : ndarray, shape (len(METRICS),)
        Output: the metrics in :data:`METRICS` order and units, written in place.
    """
    scratch = np.empty(max(rows, 1))
    e, u = log[ERR], log[U]
    for k in range(rows):
        scratch[k] = e[k] * e[k]
    out[0] = _rms_of(scratch, rows)
    for k in range(rows):
        scratch[k] = u[k] * u[k]
    out[1] = _rms_of(scratch, rows)
    out[2] = _max_abs(e, rows)
    out[3] = _max_abs(u, rows)
    for k in range(rows):
        d = log[Z3, k] - log[F, k]
        scratch[k] = d * d
    out[4] = _rms_of(scratch, rows)
    for k in range(rows):
        d = log[Z2, k] - log[OM, k]
        scratch[k] = d * d
    out[5] = _rms_of(scratch, rows)
    if rows > 1:
        for k in range(rows - 1):
            d = u[k + 1] - u[k]
            scratch[k] = d * d
        out[6] = _rms_of(scratch, rows - 1)
    else:
        out[6] = 0.0
    for k in range(rows):
        scratch[k] = log[SAT, k]
    out[7] = pairwise_sum(scratch, rows) / rows
    out[8] = rows
    out[9] = 1.0 if diverged else 0.0


@jitable
def joints_metrics(log: np.ndarray, nj: int, rows: int, diverged: bool, out: np.ndarray) -> None:
    """:data:`METRICS` over the ``nj`` joints of an engine log, into ``out``.

    The compiled twin of :func:`combine_joints` of each joint's :func:`series_metrics`
    (same numbers, bit for bit): each joint's metrics by :func:`log_metrics`, then RMS
    over joints as the root of the mean square (NumPy's summation order), maxima
    the largest, the saturated fraction the mean.  One joint: :func:`log_metrics`.

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·nj, ≥ rows)
        An engine log (:data:`LOG_ROWS` per joint).
    nj : int
        Number of joints, ≥ 1.
    rows : int
        Samples logged (columns 0 … rows−1), ≥ 1.
    diverged : bool
        The run left the finite range.
    out : ndarray, shape (len(METRICS),)
        Output: the metrics in :data:`METRICS` order and units, written in place.
    """
    if nj == 1:
        log_metrics(log, rows, diverged, out)
        return
    each = np.empty((nj, out.shape[0]))
    for j in range(nj):
        log_metrics(log[j * NROW:(j + 1) * NROW], rows, diverged, each[j])
    column = np.empty(nj)
    for c in range(out.shape[0]):
        for j in range(nj):
            column[j] = each[j, c]
        if c in _RMS_COLUMNS:
            for j in range(nj):
                column[j] = column[j] * column[j]
            out[c] = math.sqrt(pairwise_sum(column, nj) / nj)
        elif c in _MAX_COLUMNS:
            out[c] = _max_abs(column, nj)  # maxima are >= 0 (and NaN propagates)
        elif c == _SAMPLES:
            out[c] = column[0]
        else:
            out[c] = pairwise_sum(column, nj) / nj


def metrics_dict(values: np.ndarray) -> dict[str, Any]:
    """One row of :data:`METRICS` values as a dict.

    Parameters
    ----------
    values : ndarray, shape (len(METRICS),)
        The metrics in :data:`METRICS` order.

    Returns
    -------
    dict of str to float
        Name to value (units as :func:`series_metrics`).
    """
    return {name: float(v) for name, v in zip(METRICS, values, strict=True)}


# ---------------------------------------------------------------------------
# tables of many runs


@dataclass(frozen=True)
class MetricsTable:
    """Metrics of many runs: ``values[i]`` is run i, columns :data:`METRICS`.

    Attributes
    ----------
    values : ndarray, shape (R, len(METRICS))
        One row per run, in run order.
    """

    values: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """One metric for every run (see :data:`METRICS` for names and units).

        Parameters
        ----------
        name : str
            A name of :data:`METRICS`.

        Returns
        -------
        ndarray, shape (R,)
            The metric of each run, in run order (a view of :attr:`values`).

        Raises
        ------
        ValueError
            ``name`` is not a metric.
        """
        return self.values[:, METRICS.index(name)]

    def row(self, i: int) -> dict[str, float]:
        """Metrics of run ``i`` as a dict.

        Parameters
        ----------
        i : int
            Run index (row).

        Returns
        -------
        dict of str to float
            Name to value (units as :func:`series_metrics`).
        """
        return {name: float(v) for name, v in zip(METRICS, self.values[i], strict=True)}

    def __len__(self) -> int:
        return int(self.values.shape[0])


#: A run of a table: (index of its point, noise seed).
Run = tuple[int, int]


def _chunked_metrics(points: Sequence[Scenario], seeds: Sequence[int] | None, chunk: int,
                     progress: Callable[[int], None] | None,
                     run_chunk: Callable[[list[Run]], np.ndarray]) -> MetricsTable:
    """Both engines' ``run_metrics``: every point × every seed (point-major; None: each point
    with its own ``sensor.seed``), ``chunk`` runs at a time through ``run_chunk`` (a chunk's
    runs -> their rows of :data:`METRICS`), ``progress`` after each chunk."""
    if seeds is None:
        runs = [(i, scn.sensor.seed) for i, scn in enumerate(points)]
    else:
        runs = [(i, int(s)) for i in range(len(points)) for s in seeds]
    out = np.empty((len(runs), NMETRIC))
    for start in range(0, len(runs), chunk):
        part = runs[start : start + chunk]
        out[start : start + len(part)] = run_chunk(part)
        if progress is not None:
            progress(len(part))
    return MetricsTable(out)


def _renumbered(runs: Sequence[Run]) -> tuple[list[int], list[Run]]:
    """The points ``runs`` use (ascending), and the runs with those points numbered 0, 1, …."""
    used = sorted({pi for pi, _ in runs})
    local = {pi: j for j, pi in enumerate(used)}
    return used, [(local[pi], s) for pi, s in runs]


class NoiseCache:
    """Noise sequences, drawn once per (seed, N, noise model) (the sensor noise of a run)."""

    def __init__(self) -> None:
        self._store: dict[tuple[Any, ...], np.ndarray] = {}

    def get(self, seed: int, n: int, noise_deg: float, model: NoiseModel | None = None,
            joints: int = 1) -> tuple[tuple[Any, ...], np.ndarray]:
        """(key, sequence) of a seed; runs without noise share one zero sequence.

        Parameters
        ----------
        seed : int
            The sensor's noise seed.
        n : int
            Length of the sequence (samples · joints).
        noise_deg : float
            Noise standard deviation [deg]; 0 gives the shared zero sequence (white model).
        model : NoiseModel, optional
            The measurement disturbance (:func:`esoarm.plants.noise.noise_model`); None or a
            white model: the standard-normal draws of
            :func:`esoarm.plants.sensor.noise_sequence`.
        joints : int
            Number of joints (a coloured model has one process per joint).

        Returns
        -------
        tuple
            ``(key, sequence)`` (key ``(seed, n)``, ``(-1, n)`` without noise, longer for a
            coloured model); the sequence is cached, not to be modified
            (:func:`esoarm.plants.noise.draws`).
        """
        extra = None if model is None else model.key
        if extra is None:
            key: tuple[Any, ...] = (seed, n) if noise_deg > 0 else (-1, n)
            if key not in self._store:
                self._store[key] = noise_sequence(seed, n, noise_deg)
        else:
            assert model is not None
            key = (seed, n, joints, *extra)
            if key not in self._store:
                self._store[key] = draws(model, seed, n, joints)
        return key, self._store[key]
