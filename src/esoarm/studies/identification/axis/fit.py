"""Output-error fit of an axis (plant kind "axis"), started from IDIM-LS.

The model is the axis plant's own RK4 step (:func:`esoarm.plants.axis.axis_rk4_step`)
driven by the logged force/torque, simulated over *segments* of the log with each
segment's initial position and velocity estimated (multiple shooting without
continuity constraints, as the lever arm's fit).  The parameters are those of
the IDIM-LS estimate it starts from -- θ = (M, Fv, Fc, offset), or with the
viscous friction split by direction (M, Fv+, Fv−, Fc, offset), and G for a
rotary axis with gravity -- fitted as multiples of a scale taken from the data --
the IDIM-LS estimate (or ten of its HAC standard errors, whichever is larger) --
so the fit does not depend on the unit system: a log in N and m and the same log
in kN and mm give the same answer.  The only bounds are physical (M > 0, Fv ≥ 0,
Fc ≥ 0); a value that ends at one is reported with the bound's name.

Intervals: the Newey-West sandwich (:func:`esoarm.studies.identification.idim.hac_covariance`)
on the fit's Jacobian, the residual's memory setting the bandwidth -- the
residual of a fit on real data is far from white, and (JᵀJ)⁻¹σ̂² would be
several times too narrow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from esoarm.engines.batch import cover_with_physics_stamp  # registers the physics with numba
from esoarm.plants.axis import axis_rk4_step
from esoarm.studies.identification.idim import (
    IdimResult,
    filtered_derivatives,
    hac_bandwidth,
    hac_covariance,
)

cover_with_physics_stamp(__file__)

__all__ = ["OE_NAMES", "OeResult", "axis_vector", "fit_axis_oe", "segment_bounds",
           "simulate_axis_segments"]

#: Names of the fitted parameters of a symmetric axis without gravity.
OE_NAMES = ("mass", "viscous_friction", "coulomb_friction", "offset")


def axis_vector(names: tuple[str, ...], theta: np.ndarray) -> np.ndarray:
    """The simulation's parameters (M, Fv+, Fv−, Fc+, Fc−, offset, G) from IDIM-LS ones.

    ``names`` are an IDIM-LS estimate's (:data:`esoarm.studies.identification.idim.NAMES`
    or ``NAMES_ASYMMETRIC``); a parameter not among them is 0.
    """
    v = dict(zip(names, (float(t) for t in theta), strict=True))
    fv = v.get("viscous_friction", 0.0)
    fc = v.get("coulomb_friction", 0.0)
    return np.array([v["mass"], v.get("viscous_friction_pos", fv),
                     v.get("viscous_friction_neg", fv), fc, fc, v.get("offset", 0.0),
                     v.get("gravity", 0.0)])


@njit(cache=True)
def simulate_axis_segments(out, full, vs, lag, u, seg_start, seg_len, x0, h,  # pragma: no cover
                           nsub):
    """Simulated position into ``out`` for every segment (see the module docstring).

    ``full`` = (M, Fv+, Fv−, Fc+, Fc−, offset, G) (:func:`axis_vector`), smoothing
    ``vs``, lag T; segment s starts at ``seg_start[s]`` from (x0[2s], x0[2s+1]); the
    force ``u[k]`` is held over sample k.
    """
    ax = (full[0], full[1], full[2], full[3], full[4], full[5], full[6], vs, lag)
    for s in range(len(seg_start)):
        k0 = seg_start[s]
        q = x0[2 * s]
        v = x0[2 * s + 1]
        tau = u[k0 - 1] if k0 > 0 else u[0]
        for j in range(seg_len[s]):
            k = k0 + j
            out[k] = q
            for _ in range(nsub):
                q, v, tau = axis_rk4_step(q, v, tau, u[k], h, ax)
            if not math.isfinite(q):
                for m in range(k + 1, k0 + seg_len[s]):
                    out[m] = math.inf
                break


@dataclass(frozen=True)
class OeResult:
    """An output-error fit.

    Attributes
    ----------
    names : tuple of str
        The fitted parameters (those of the IDIM-LS start, in its order).
    values, ci95_half : ndarray
        θ̂ and the half-widths of their HAC 95 % intervals.
    at_bound : tuple of str
        "" or the name of the physical bound a value ended at, per parameter.
    residual_rms : float
        RMS of the position residual [m or rad].
    fit_percent : float
        100·(1 − ‖y − ŷ‖/‖y − ȳ‖) [%].
    bandwidth : int
        Newey-West bandwidth [samples].
    max_autocorrelation : float
        Largest |ρ| of the residual at lags 1 … 20.
    segment_s : float
        Segment length [s].
    converged : bool
        The solver's verdict.
    residual : ndarray
        y − ŷ.
    """

    names: tuple[str, ...]
    values: np.ndarray
    ci95_half: np.ndarray
    at_bound: tuple[str, ...]
    residual_rms: float
    fit_percent: float
    bandwidth: int
    max_autocorrelation: float
    segment_s: float
    converged: bool
    residual: np.ndarray


def segment_bounds(n: int, length: int) -> tuple[np.ndarray, np.ndarray]:
    count = max(1, n // length)
    starts = length * np.arange(count)
    lens = np.full(count, length)
    lens[-1] = n - starts[-1]
    return starts.astype(np.int64), lens.astype(np.int64)


def fit_axis_oe(y: np.ndarray, u: np.ndarray, ts: float, start: IdimResult, segment: float,
                vs: float = 1e-3, lag: float = 0.0, nsub: int = 1) -> OeResult:
    """Fit the axis to the position ``y`` under the force ``u`` (see the module).

    ``start`` is the IDIM-LS estimate of the same log (its parameters are the ones
    fitted; it is the starting point and the scale of each); ``segment`` [s] the
    simulation horizon.
    """
    from scipy.optimize import least_squares
    from scipy.sparse import lil_matrix

    n = len(y)
    seg_n = max(5, int(round(segment / ts)))
    seg_start, seg_len = segment_bounds(n, seg_n)
    nseg = len(seg_start)
    names = start.names
    p = len(names)
    theta0 = np.array([start.value(k) for k in names])
    se = np.array([start.se_hac[start.names.index(k)] for k in names])
    scale = np.maximum(np.abs(theta0), 10.0 * se)
    scale[scale == 0.0] = 1.0
    q, dq, _ = filtered_derivatives(y, ts, 0.1 / ts)
    x0 = np.empty(2 * nseg)
    x0[0::2] = q[seg_start]
    x0[1::2] = dq[seg_start]
    pos_scale = max(float(np.std(y)), 1e-300)
    vel_scale = max(float(np.std(dq)), 1e-300)
    state_scale = np.tile([pos_scale, vel_scale], nseg)
    h = ts / nsub
    out = np.empty(n)

    def unpack(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return z[:p] * scale, z[p:] * state_scale

    def residual(z: np.ndarray) -> np.ndarray:
        theta, states = unpack(z)
        simulate_axis_segments(out, axis_vector(names, theta), vs, lag, u, seg_start, seg_len,
                               states, h, nsub)
        r = (y - out) / pos_scale
        return np.where(np.isfinite(r), r, 1e6)

    sparsity = lil_matrix((n, p + 2 * nseg), dtype=int)
    sparsity[:, :p] = 1
    for s in range(nseg):
        rows = slice(int(seg_start[s]), int(seg_start[s] + seg_len[s]))
        sparsity[rows, p + 2 * s] = 1
        sparsity[rows, p + 1 + 2 * s] = 1
    lower = np.full(p + 2 * nseg, -np.inf)
    # physical: M > 0, friction ≥ 0 (no scale in them)
    bound_names = {"mass": "mass > 0", "viscous_friction": "viscous friction ≥ 0",
                   "viscous_friction_pos": "viscous friction (q̇ > 0) ≥ 0",
                   "viscous_friction_neg": "viscous friction (q̇ < 0) ≥ 0",
                   "coulomb_friction": "Coulomb friction ≥ 0"}
    for i, name in enumerate(names):
        if name in bound_names:
            lower[i] = 1e-9 if name == "mass" else 0.0
    z0 = np.concatenate([theta0 / scale, x0 / state_scale])
    z0[:p] = np.where(np.isfinite(lower[:p]), np.maximum(z0[:p], lower[:p] + 1e-6), z0[:p])
    sol = least_squares(residual, z0, jac_sparsity=sparsity, bounds=(lower, np.inf),
                        x_scale=1.0, method="trf", xtol=1e-10, ftol=1e-10, max_nfev=200)
    theta, _states = unpack(sol.x)
    r = residual(sol.x) * pos_scale
    jac = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
    jac = jac * pos_scale  # d(residual in position units)/d(z)
    # the residual's memory, and at least one segment: within a segment the residual of a
    # simulation is one correlated curve (its initial state errors carry through it)
    lags = min(max(hac_bandwidth(r), seg_n), n // 4)
    # the physical columns with each segment's initial states profiled out (Frisch-Waugh:
    # the physical block of the full sandwich, at a fraction of its cost)
    jp = jac[:, :p].copy()
    for s in range(nseg):
        rows = slice(int(seg_start[s]), int(seg_start[s] + seg_len[s]))
        js = jac[rows, p + 2 * s: p + 2 + 2 * s]
        jp[rows] -= js @ np.linalg.lstsq(js, jac[rows, :p], rcond=None)[0]
    cov = hac_covariance(jp, r, lags)
    half = 1.96 * np.sqrt(np.maximum(np.diag(cov), 0.0)) * scale
    at_bound = tuple(bound_names.get(names[i], "") if sol.active_mask[i] != 0 else ""
                     for i in range(p))
    rc = r - r.mean()
    denom = float(rc @ rc) or 1.0
    rho = max(abs(float(rc[:-k] @ rc[k:]) / denom) for k in range(1, 21))
    fit = float(100.0 * (1.0 - np.linalg.norm(r) / np.linalg.norm(y - y.mean())))
    return OeResult(names, theta, half, at_bound, float(np.sqrt(np.mean(r**2))), fit, lags, rho,
                    seg_n * ts, bool(sol.success), r)
