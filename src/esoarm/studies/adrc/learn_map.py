"""A learned position-periodic perturbation: ẑ3 binned over the angle into a feedforward table.

The ESO's perturbation estimate ẑ3 [rad/s²] holds everything the nominal model
θ̈ = b0·u leaves out.  The part that repeats with the arm's angle -- cogging of the
motor, gear eccentricity, an error of the gravity model -- is learned from one logged
run by averaging ẑ3 in N bins over [0, 2π): bin i collects the samples whose estimated
angle ẑ1 lies nearest the node θ_i = 2π i / N (modulo 2π).  The table m_i is then
written into the scenario as ``controller.feedforward_map``; the next run adds
−I0·m(ẑ1) (interpolated linearly between the nodes, :func:`esoarm.plants.actuator.feedforward`)
to the drive, and its ESO, fed the command without it, is left to estimate only
what the table misses: a slower observer (larger ε) tracks as well.

Samples are averaged regardless of the rate and the time, so a perturbation that
depends on those (friction, the sine disturbance d(t), the inertia error times the
acceleration) averages out only as far as the run visits each angle with both signs
of rate and at many times; the bins the run never visits are reported, and set to 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["LearnedMap", "eps_at_error", "learn_map", "learned_from_run", "map_at",
           "rms_errors", "with_map"]


@dataclass(frozen=True)
class LearnedMap:
    """A feedforward table learned from a run.

    Attributes
    ----------
    table : ndarray, shape (N,)
        m_i [rad/s²] at θ_i = 2π i / N (the previous table added, if one was given).
    counts : ndarray of int, shape (N,)
        Samples averaged into each bin (0: a bin the run never visited, its value kept
        from the previous table or 0).
    """

    table: np.ndarray
    counts: np.ndarray

    @property
    def visited(self) -> int:
        """Number of bins with at least one sample."""
        return int(np.count_nonzero(self.counts))


def learn_map(z1: np.ndarray, z3: np.ndarray, bins: int, *, skip: int = 0,
              previous: np.ndarray | list[float] | None = None) -> LearnedMap:
    """Bin the perturbation estimate ẑ3 over the estimated angle ẑ1.

    Parameters
    ----------
    z1 : ndarray, shape (K,)
        Estimated angle ẑ1 per sample [rad] (any range; taken modulo 2π).
    z3 : ndarray, shape (K,)
        Perturbation estimate ẑ3 per sample [rad/s²] (what the ESO saw: with a table in the
        run, the residual the table left).
    bins : int
        N ≥ 2, the number of nodes over [0, 2π).
    skip : int
        Leading samples to leave out (the observer's transient).
    previous : ndarray or list of float, shape (N,), optional
        The table the run was made with: the residual learned is added to it.

    Returns
    -------
    LearnedMap
        The table [rad/s²] and the samples per bin.

    Raises
    ------
    ValueError
        Bins below 2, arrays of different lengths, non-finite values, or a previous table
        of another length.
    """
    if bins < 2:
        raise ValueError(f"--bins: {bins}; need at least 2")
    z1 = np.asarray(z1, dtype=float)[skip:]
    z3 = np.asarray(z3, dtype=float)[skip:]
    if z1.shape != z3.shape or z1.ndim != 1:
        raise ValueError("z1 and z3 must be 1-D arrays of one length")
    if not (np.all(np.isfinite(z1)) and np.all(np.isfinite(z3))):
        raise ValueError("z1 or z3 holds a non-finite value")
    base = np.zeros(bins) if previous is None else np.asarray(previous, dtype=float)
    if base.shape != (bins,):
        raise ValueError(f"the scenario's controller.feedforward_map has {base.size} values, "
                         f"not --bins {bins}; learn with --bins {base.size}")
    idx = np.rint(z1 / (2.0 * math.pi) * bins).astype(np.int64) % bins
    counts = np.bincount(idx, minlength=bins)
    sums = np.bincount(idx, weights=z3, minlength=bins)
    mean = np.divide(sums, counts, out=np.zeros(bins), where=counts > 0)
    return LearnedMap(base + mean, counts)


def map_at(table: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """The table interpolated linearly at ``angle`` [rad], periodic over 2π (the drive's rule).

    Parameters
    ----------
    table : ndarray, shape (N,)
        m_i at θ_i = 2π i / N.
    angle : float or ndarray
        Angle(s) [rad].

    Returns
    -------
    ndarray
        m(θ) in the table's units.
    """
    t = np.asarray(table, dtype=float)
    n = t.size
    nodes = np.arange(n + 1) * (2.0 * math.pi / n)
    return np.interp(np.mod(angle, 2.0 * math.pi), nodes, np.append(t, t[0]))


def learned_from_run(scn: Scenario, bins: int, skip: float = 1.0) -> LearnedMap:
    """Run ``scn`` on the reference engine and learn its table from ẑ (as ``esoarm learn-map``).

    Parameters
    ----------
    scn : Scenario
        The scenario of the learning run (its own ``controller.feedforward_map``, if any, is
        the previous table).
    bins : int
        N nodes over [0, 2π).
    skip : float
        Seconds at the start left out [s].

    Returns
    -------
    LearnedMap
        The table [rad/s²] and the samples per bin.
    """
    from esoarm.engines.simulation import prepare, run_reference

    r = run_reference(scn, prepare(scn))
    first = int((r.t < r.t[0] + skip).sum())
    previous = list(getattr(scn.controller, "feedforward_map", [])) or None
    return learn_map(r.z[:, 0], r.z[:, 2], bins, skip=first, previous=previous)


def with_map(scn: Scenario, table: np.ndarray) -> Scenario:
    """``scn`` with ``controller.feedforward_map`` set to ``table`` [rad/s²].

    Parameters
    ----------
    scn : Scenario
        The scenario to copy (left unchanged).
    table : ndarray, shape (N,)
        The learned perturbation m(θ_i) at θ_i = 2π i/N [rad/s²].

    Returns
    -------
    Scenario
        A copy whose ``controller.feedforward_map`` is ``table`` (as floats), validated.
    """
    return scn.with_overrides({"controller.feedforward_map": [float(v) for v in table]})


def rms_errors(scn: Scenario, eps: list[float], seeds: list[int]) -> np.ndarray:
    """Mean RMS tracking error [rad] over ``seeds`` at each ε [s] (reference engine).

    Parameters
    ----------
    scn : Scenario
        The scenario (with or without a table).
    eps : list of float
        Observer ε values [s].
    seeds : list of int
        ``sensor.seed`` values.

    Returns
    -------
    ndarray, shape (len(eps),)
        Mean RMS error [rad] per ε.
    """
    from esoarm.engines.simulation import prepare, run_reference

    out = np.empty(len(eps))
    for i, e in enumerate(eps):
        vals = []
        for s in seeds:
            point = scn.with_overrides({"observer.eps": e, "sensor.seed": s})
            vals.append(run_reference(point, prepare(point)).metrics["rms_error"])
        out[i] = float(np.mean(vals))
    return out


def eps_at_error(eps: list[float], errors: np.ndarray, target: float) -> float | None:
    """The largest ε [s] whose RMS error, interpolated linearly over ``eps``, is ≤ ``target``.

    Parameters
    ----------
    eps : list of float
        Increasing ε values [s].
    errors : ndarray
        RMS error [rad] at each.
    target : float
        The RMS error to hold [rad].

    Returns
    -------
    float or None
        ε [s]; None if even the smallest ε misses the target (no extrapolation beyond
        the last ε either: then the last ε is returned and the caller says "≥").
    """
    if errors[0] > target:
        return None
    for i in range(1, len(eps)):
        if errors[i] > target:
            a, b = errors[i - 1], errors[i]
            return float(eps[i - 1] + (target - a) / (b - a) * (eps[i] - eps[i - 1]))
    return float(eps[-1])
