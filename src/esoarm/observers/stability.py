"""Analysis helpers: observer gains and poles, stability checks, Theorem 1 and 2 bounds.

Everything here is computed from the same designs the simulators run
(:func:`esoarm.observers.linear.design_observer`), so an analysis cannot drift from
the code it describes.

Observer (paper eq. 8-10, Theorem 1)
    The continuous ESO with β = (3/ε, 3/ε², 1/ε³) has the estimation-error
    matrix A − βC of eq. 10, characteristic polynomial (s + 1/ε)³.  Each
    discretization (step 5 of the sampled-data loop) has its own error recursion
    z̃⁺ = M z̃ (:func:`esoarm.observers.linear.discrete_error_matrix`): "euler" puts
    the triple pole at 1 − Ts/ε, "zoh" and "current" at e^{−Ts/ε}.

Estimation-error bound (eq. 11-12)
    z̃̇ = (A − βC) z̃ + B γ with B = (0, 0, 1) and γ = ḟ.  The impulse
    responses from γ to the three error components are 1/(s+a)³,
    (s + 3a)/(s+a)³ and (s² + 3as + 3a²)/(s+a)³ with a = 1/ε; all three are
    sums of non-negative terms, so their L1 norms equal their DC gains and the
    steady-state error obeys, component by component,

        |z̃| ≤ sup|γ| · (ε³, 3ε², 3ε)

    which is the quantitative form of Theorem 1 used by
    :func:`theorem1_bound`.

Tracking-error bound (eq. 17-20, Theorem 2)
    ë + k1 ė + k2 e = κ with |κ| ≤ μ.  The paper concludes |e| → μ/k2.  For
    the LTI system the rigorous steady-state bound is μ·‖h‖₁, h the impulse
    response of 1/(s² + k1 s + k2).  For k1² ≥ 4 k2 (real poles, the paper's
    Δ ≥ 0 cases, and our defaults k1 = 10, k2 = 25 which are critically
    damped) h ≥ 0 and ‖h‖₁ = 1/k2, so μ/k2 is exact.  For k1² < 4 k2 the
    bound grows by coth(π σ / (2 ω_d)) (σ = k1/2, ω_d = √(k2 − σ²)); see
    :func:`tracking_l1_gain`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from esoarm.observers.linear import (
    DISCRETIZATIONS,
    continuous_error_matrix,
    continuous_gains,
    design_observer,
    discrete_error_matrix,
    discrete_error_poles,
    observer_warnings,
    pole_damping,
)
from esoarm.plants.model import gravity_coefficient, gravity_torque, input_gain

if TYPE_CHECKING:
    from esoarm.result import SimResult

__all__ = [
    "CONTINUOUS",
    "ObserverAnalysis",
    "analyze_observer",
    "characteristic_polynomial",
    "error_matrix",
    "estimation_error",
    "observer_gains",
    "observer_poles",
    "observer_warnings",
    "pole_damping",
    "theorem1_bound",
    "theorem2_bound",
    "tracking_l1_gain",
]


#: The continuous observer of eq. 8 (Theorem 1), besides the sampled-data discretizations.
CONTINUOUS = "continuous"


def _check_disc(discretization: str) -> None:
    if discretization != CONTINUOUS and discretization not in DISCRETIZATIONS:
        allowed = ", ".join((CONTINUOUS, *DISCRETIZATIONS))
        raise ValueError(f"discretization must be one of {allowed}; got {discretization!r}")


def _check_ts(ts: float | None, discretization: str) -> float:
    if discretization == CONTINUOUS:
        return 0.0
    if ts is None or not ts > 0 or not math.isfinite(ts):
        raise ValueError(f"ts must be a finite number > 0 for '{discretization}', got {ts!r}")
    return float(ts)


def observer_gains(
    eps: float, ts: float | None = None, discretization: str = CONTINUOUS, b0: float = 1.0
) -> np.ndarray:
    """Observer gains for ε, continuous (Theorem 1) or for a discretization.

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s]; design error poles at −1/ε [1/s].
    ts : float, optional
        Sample period Ts [s]; required unless ``discretization = "continuous"``.
    discretization : {"continuous", "euler", "zoh", "current"}
        "continuous": β = (3/ε, 3/ε², 1/ε³) of Theorem 1 [1/s, 1/s², 1/s³].
        "euler": Ts·β (the update z⁺ = z + Ts·(eq. 8)).  "zoh": Lp of the
        predictive form, poles of Φ − Lp C at e^{−Ts/ε}.  "current": Lc of
        the current-estimator form, poles of Φ − Lc C Φ at e^{−Ts/ε}
        (the sampled-data loop, step 5).  The discrete gains are dimensionless, 1/s, 1/s².
    b0 : float
        Input gain 1/I0 [1/(kg·m²)]; the gains do not depend on it.

    Returns
    -------
    ndarray, shape (3,)
    """
    _check_disc(discretization)
    if discretization == CONTINUOUS:
        return np.array(continuous_gains(eps))
    ts = _check_ts(ts, discretization)
    return np.array(design_observer(eps, ts, b0, discretization).gain)


def error_matrix(eps: float, ts: float | None = None, discretization: str = CONTINUOUS
                 ) -> np.ndarray:
    """Estimation-error matrix: A − βC (eq. 10) or the discrete recursion matrix.

    "euler": I + Ts (A − βC); "zoh": Φ − Lp C; "current": Φ − Lc C Φ.

    Parameters
    ----------
    eps : float
        Observer time constant ε > 0 [s].
    ts : float, optional
        Sample period Ts > 0 [s]; needed by the discrete forms.
    discretization : str
        ``"continuous"`` (the default), ``"euler"``, ``"zoh"`` or ``"current"``.

    Returns
    -------
    ndarray, shape (3, 3)
        The matrix whose eigenvalues are the estimation-error poles.
    """
    _check_disc(discretization)
    if discretization == CONTINUOUS:
        return continuous_error_matrix(eps)
    return discrete_error_matrix(eps, _check_ts(ts, discretization), discretization)


def observer_poles(eps: float, ts: float | None = None, discretization: str = CONTINUOUS
                   ) -> np.ndarray:
    """Design error poles (triple): −1/ε [1/s] continuous, else in the z-plane.

    These are the exact values the gains are designed for ("euler":
    1 − Ts/ε; "zoh"/"current": e^{−Ts/ε}).  Eigenvalues computed numerically
    from :func:`error_matrix` agree only to about ∛(machine ε) because the
    pole is triple; compare :func:`characteristic_polynomial` instead.

    Parameters
    ----------
    eps : float
        Observer time constant ε > 0 [s].
    ts : float, optional
        Sample period Ts > 0 [s]; needed by the discrete forms.
    discretization : str
        ``"continuous"`` (the default), ``"euler"``, ``"zoh"`` or ``"current"``.

    Returns
    -------
    ndarray, shape (3,)
        The triple pole, s-plane [1/s] or z-plane.

    Examples
    --------
    >>> observer_poles(0.1).tolist(), observer_poles(0.1, 0.02, "euler").tolist()
    ([-10.0, -10.0, -10.0], [0.8, 0.8, 0.8])
    """
    _check_disc(discretization)
    if discretization == CONTINUOUS:
        if not eps > 0:
            raise ValueError(f"eps must be > 0, got {eps!r}")
        return np.full(3, -1.0 / eps)
    return discrete_error_poles(eps, _check_ts(ts, discretization), discretization)


def characteristic_polynomial(matrix: np.ndarray) -> np.ndarray:
    """Monic characteristic polynomial of a 3×3 matrix, highest power first.

    Computed from traces and the determinant (Faddeev–LeVerrier), which is
    well conditioned for repeated eigenvalues, unlike ``np.poly`` of the
    eigenvalues.

    Parameters
    ----------
    matrix : ndarray, shape (3, 3)
        Any square matrix of order 3.

    Returns
    -------
    ndarray, shape (4,)
        Coefficients [1, c2, c1, c0] of λ³ + c2 λ² + c1 λ + c0.
    """
    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3):
        raise ValueError(f"expected a 3×3 matrix, got shape {m.shape}")
    tr = np.trace(m)
    tr2 = np.trace(m @ m)
    return np.array([1.0, -tr, 0.5 * (tr * tr - tr2), -np.linalg.det(m)])


@dataclass(frozen=True)
class ObserverAnalysis:
    """Gains, error dynamics and stability of one ESO design.

    Attributes
    ----------
    eps : float
        Free parameter ε [s].
    ts : float
        Sample period Ts [s] (0 for "continuous").
    discretization : str
        "continuous", "euler", "zoh" or "current".
    gains : ndarray (3,)
        See :func:`observer_gains`.
    error_matrix : ndarray (3, 3)
        See :func:`error_matrix`.
    poles : ndarray (3,)
        Design error poles (s-plane for continuous, z-plane otherwise).
    spectral_radius : float
        max |pole| (discrete); for continuous, max Re(pole) [1/s].
    damping : float
        Damping ratio ζ of the poles (see :func:`pole_damping`).
    stable : bool
        Discrete: radius < 1; continuous: Re < 0.
    ts_over_eps : float
        Ts/ε (0 for continuous).
    """

    eps: float
    ts: float
    discretization: str
    gains: np.ndarray
    error_matrix: np.ndarray
    poles: np.ndarray
    spectral_radius: float
    damping: float
    stable: bool
    ts_over_eps: float


def analyze_observer(eps: float, ts: float | None = None, discretization: str = CONTINUOUS,
                     b0: float = 1.0) -> ObserverAnalysis:
    """Gains, error matrix, poles, damping and stability of an ESO design.

    Parameters
    ----------
    eps : float
        Observer time constant ε > 0 [s].
    ts : float, optional
        Sample period Ts > 0 [s]; needed by the discrete forms.
    discretization : str
        ``"continuous"`` (the default), ``"euler"``, ``"zoh"`` or ``"current"``.
    b0 : float
        Nominal input gain b0 [1/(kg·m²)] of the observer model.

    Returns
    -------
    ObserverAnalysis
        The record of gains, matrix, poles, damping ratio and a stability verdict.
    """
    poles = observer_poles(eps, ts, discretization)
    gains = observer_gains(eps, ts, discretization, b0)
    mat = error_matrix(eps, ts, discretization)
    if discretization == CONTINUOUS:
        radius = float(np.max(poles.real))
        stable = radius < 0.0
        zeta = pole_damping(poles[0])
        ratio = 0.0
        ts_val = 0.0
    else:
        ts_val = float(ts)  # type: ignore[arg-type]
        radius = float(np.max(np.abs(poles)))
        stable = radius < 1.0
        zeta = pole_damping(poles[0], ts_val)
        ratio = ts_val / eps
    return ObserverAnalysis(eps, ts_val, discretization, gains, mat, poles, radius, zeta,
                            stable, ratio)


# ---------------------------------------------------------------------------
# Theorem 1 and Theorem 2


def theorem1_bound(eps: float, gamma_max: float) -> np.ndarray:
    """Steady-state bound on the estimation error |z̃| of the continuous ESO.

    From eq. 11-12 with z̃̇ = (A − βC) z̃ + B γ, B = (0, 0, 1):
    |z̃_i(t)| ≤ sup|γ| · ‖h_i‖₁ once e^{(A−βC) t} z̃(0) has decayed, and the
    L1 norms are exactly (ε³, 3ε², 3ε) (module docstring).

    Parameters
    ----------
    eps : float
        Free parameter ε [s].
    gamma_max : float
        sup |γ| = sup |ḟ| [rad/s³], γ the derivative of the total
        perturbation (eq. 7).

    Returns
    -------
    ndarray (3,)
        Bounds on |θ − z1| [rad], |θ̇ − z2| [rad/s], |f − z3| [rad/s²].
    """
    if not eps > 0:
        raise ValueError(f"eps must be > 0, got {eps!r}")
    return abs(gamma_max) * np.array([eps**3, 3.0 * eps**2, 3.0 * eps])


def tracking_l1_gain(k1: float, k2: float) -> float:
    """L1 norm of the impulse response of 1/(s² + k1 s + k2) (eq. 17).

    The exact steady-state gain from sup|κ| to sup|e|: 1/k2 when
    k1² ≥ 4 k2 (the paper's μ/k2, eq. 20); coth(π σ / (2 ω_d)) / k2 with
    σ = k1/2, ω_d = √(k2 − σ²) when the error dynamics are underdamped.

    Parameters
    ----------
    k1 : float
        Error-rate gain > 0 [1/s].
    k2 : float
        Error gain > 0 [1/s²].

    Returns
    -------
    float
        The gain [s²]: sup|e| ≤ gain · sup|κ| in steady state.

    Examples
    --------
    >>> tracking_l1_gain(10.0, 25.0)  # critically damped: 1/k2
    0.04
    """
    if not (k1 > 0 and k2 > 0):
        raise ValueError(f"k1 and k2 must be > 0, got {k1!r}, {k2!r}")
    sigma = 0.5 * k1
    disc = k2 - sigma * sigma
    if disc <= 0.0:
        return 1.0 / k2
    wd = math.sqrt(disc)
    return 1.0 / (k2 * math.tanh(math.pi * sigma / (2.0 * wd)))


def theorem2_bound(kappa: np.ndarray | float, k2: float, k1: float | None = None) -> float:
    """Steady-state tracking-error bound μ/k2 of Theorem 2 (eq. 18-20).

    Parameters
    ----------
    kappa : array_like or float
        Estimation error κ of eq. 17 (e.g. from :func:`estimation_error`)
        [rad/s²]; μ = max |κ|.
    k2 : float
        Error gain [1/s²].
    k1 : float, optional
        Error-rate gain [1/s].  When given, the rigorous bound
        μ · :func:`tracking_l1_gain` (k1, k2) is returned, which equals μ/k2
        for k1² ≥ 4 k2 and is larger when the error dynamics are underdamped
        (the paper's μ/k2 is then not a bound).

    Returns
    -------
    float
        Bound on lim sup |e| [rad].
    """
    mu = float(np.max(np.abs(np.asarray(kappa, dtype=float))))
    if k1 is None:
        if not k2 > 0:
            raise ValueError(f"k2 must be > 0, got {k2!r}")
        return mu / k2
    return mu * tracking_l1_gain(k1, k2)


def estimation_error(result: SimResult) -> np.ndarray:
    """The estimation error κ_k of eq. 17 at each sample of a simulated run.

    With u = I0 (α − β̂) unsaturated and θ̈ = f + b0 u (f the true total
    perturbation, :attr:`SimResult.f_true`), the tracking error obeys
    ë + k1 ė + k2 e = κ with

        κ = (f − β̂) + k1 (θ̇ − ẑ2) + k2 (θ − ẑ1)

    β̂ = ẑ3 for "eso" compensation, −G(ẑ1)/I0 for "model".  This is exact
    for the continuous loop; in the sampled loop it holds at the samples
    while u is held, so compare with Theorem 2 at sample rates well above
    the closed-loop bandwidth.  Samples where u is saturated break the
    premise; check ``abs(result.u) < torque_limit``.

    Parameters
    ----------
    result : SimResult

    Returns
    -------
    ndarray (N,)
        κ_k [rad/s²].
    """
    scn = result.scenario
    from esoarm.kinds import can

    if not can(scn, "FLC_LAW"):  # what the controller kind declares
        raise ValueError(f"κ (eq. 17) is defined for the FLC's law, not for controller.kind = "
                         f"{scn.controller.kind!r}")
    k1, k2 = scn.controller.k1, scn.controller.k2
    z1, z2, z3 = result.z[:, 0], result.z[:, 1], result.z[:, 2]
    if scn.controller.compensation == "eso":
        beta_hat = z3
    else:
        p = scn.plant
        gcoef = gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g)
        beta_hat = -np.array([gravity_torque(v, gcoef) for v in z1]) * input_gain(p.inertia)
    kappa: np.ndarray = ((result.f_true - beta_hat) + k1 * (result.omega - z2)
                         + k2 * (result.theta - z1))
    return kappa
