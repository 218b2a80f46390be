"""Observer kind ``"nonlinear"``: Han's nonlinear extended state observer (fal-ESO).

The ESO of eq. 8 with the innovation e = y − z1 injected linearly into the first
equation and through Han's nonlinear gain function into the second and third:

    ż1 = z2 + β1 e
    ż2 = z3 + b0 u + β2 fal(e, α2, δ)
    ż3 = β3 fal(e, α3, δ)

    fal(e, α, δ) = e / δ^(1−α)          for |e| ≤ δ
                 = |e|^α · sign(e)       otherwise

with β1, β2, β3 the gains of Theorem 1 for the free parameter ε (poles of the
linear part at −1/ε).  α < 1 gives small errors a higher gain and large errors
a lower one (δ, the linear zone around zero, keeps the gain finite); with
α2 = α3 = 1, fal(e) = e and the observer *is* the linear ESO, bit for bit.

Discretizations (``discretization``), each the linear ESO's with the two
nonlinear injections replaced by fal of the innovation:

``"euler"``
    z⁺ = z + Ts·(right side above).
``"zoh"``
    z⁺ = Φ z + Γ u + (Lp1 e, Lp2 fal(e, α2, δ), Lp3 fal(e, α3, δ)).
``"current"``
    ẑ = z + (Lc1 e, Lc2 fal(e, α2, δ), Lc3 fal(e, α3, δ)), z⁺ = Φ ẑ + Γ u.

Φ, Γ and the gains Lp, Lc are the linear design's (:mod:`esoarm.observers.linear`),
so they place the poles of the *linearized* error dynamics (α = 1); with α < 1
the gains act on fal(e) instead of e, as Han's continuous observer does.  All
three are defined for any α and δ; the stability of the nonlinear discrete
error dynamics is not guaranteed by the pole placement (Han's fal-ESO is
usually run with a small Ts·β), which is why the linear ESO stays the default.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field, field_validator

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, ObserverLinearization, PlantDesign, Vector, read_only
from esoarm.observers.linear import B0 as _B0
from esoarm.observers.linear import (
    BETA1,
    BETA2,
    BETA3,
    CURRENT,
    DISC,
    EULER,
    GAIN,
    GAMMA,
    PHI,
    VECTOR_SIZE,
    ZOH,
    design_observer,
    discrete_linearization,
    observer_warnings,
)
from esoarm.observers.linear import TS as _TS

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "Params", "advance", "design", "estimate", "fal",
           "initialize", "label", "linearization", "predict", "state_size", "summary",
           "warnings"]

KIND = "nonlinear"
CODE = 1
JIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "nonlinear.c"

# the linear ESO's vector, then α2, α3, δ
ALPHA2, ALPHA3, DELTA = VECTOR_SIZE, VECTOR_SIZE + 1, VECTOR_SIZE + 2


class Params(Section):
    """``[observer]`` of kind "nonlinear": Han's fal-ESO (gains from ε as for eq. 8)."""

    kind: Literal["nonlinear"] = Field(
        "nonlinear", description="observer kind (the registered kinds: esoarm.kinds)")
    eps: float = Field(
        0.09, gt=0, description="free parameter ε; linear-part poles at −1/ε",
        json_schema_extra=unit("s"),
    )
    discretization: Literal["euler", "zoh", "current"] = Field(
        "euler", description='"euler" | "zoh" | "current" (the linear ESO\'s, with fal)'
    )
    alpha: list[float] = Field(
        default_factory=lambda: [0.5, 0.25],
        description="[α2, α3]: exponents of fal in the 2nd and 3rd equations, 0 < α ≤ 1 "
        "(1: linear)", json_schema_extra=unit("1"),
    )
    delta: float = Field(
        0.1, gt=0, description="δ: half-width of fal's linear zone around e = 0",
        json_schema_extra=unit("rad"),
    )

    @field_validator("alpha")
    @classmethod
    def _two_exponents(cls, value: list[float]) -> list[float]:
        if len(value) != 2:
            raise ValueError(f"needs two exponents [α2, α3], got {len(value)}")
        for a in value:
            if not (math.isfinite(a) and 0.0 < a <= 1.0):
                raise ValueError(f"each α must be in (0, 1], got {a!r}")
        return value


@jitable
def fal(e: float, alpha: float, delta: float) -> float:
    """Han's fal(e, α, δ): e/δ^(1−α) for |e| ≤ δ, else |e|^α·sign(e); fal = e for α = 1.

    Parameters
    ----------
    e : float
        The innovation e = y − z1 [rad].
    alpha : float
        Exponent α in (0, 1] [1].
    delta : float
        Half-width δ > 0 of the linear zone [rad].

    Returns
    -------
    float
        fal(e, α, δ), with the sign of e (odd in e).

    Examples
    --------
    >>> fal(0.04, 0.5, 0.01)  # |e| > δ: sqrt(0.04)
    0.2
    >>> fal(-0.005, 0.5, 0.01) == -0.005 / 0.01 ** 0.5
    True
    >>> fal(0.3, 1.0, 0.01)
    0.3
    """
    if abs(e) <= delta:
        linear: float = e / delta ** (1.0 - alpha)  # float ** float: Any to mypy
        return linear
    return math.copysign(abs(e) ** alpha, e)


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, the linear ESO's vector for ε and the discretization at Ts, α2, α3, δ).

    One design for every joint (a URDF arm's joints all have b0 = 1: its observers' input is
    already an acceleration), b0 from the plant's nominal model.  State: 3 per joint.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[observer]`` table).
    plant : PlantDesign
        The plant's design (n joints, nominal input gains b0 [1/(kg·m²)]).
    ts : float
        Sample period Ts [s].

    Returns
    -------
    ComponentDesign
        (CODE, the 21-float linear vector, α2, α3, δ [rad]), 3 states per joint.

    Raises
    ------
    ValueError
        If the joints' b0 differ (one design serves every joint).
    """
    obs = scn.observer
    if not isinstance(obs, Params):  # pragma: no cover - the registry dispatches by kind
        raise TypeError("not a nonlinear observer table")
    b0 = np.asarray(plant.b0, dtype=float)
    if np.any(b0 != b0[0]):
        raise ValueError("the nonlinear ESO kind uses one b0 for every joint, and the joints' "
                         f"b0 differ ({', '.join(f'{b:g}' for b in b0)})")
    lin = design_observer(obs.eps, ts, float(b0[0]), obs.discretization)
    vec = np.concatenate([[float(CODE)], lin.vector, [obs.alpha[0], obs.alpha[1], obs.delta]])
    return ComponentDesign(read_only(vec), 3 * plant.n_joints)


@jitable
def _estimate1(z1: float, z2: float, z3: float, y: float,
               obs: Vector) -> tuple[float, float, float]:
    if obs[DISC] == CURRENT:
        e = y - z1
        d = obs[DELTA]
        return (z1 + obs[GAIN] * e, z2 + obs[GAIN + 1] * fal(e, obs[ALPHA2], d),
                z3 + obs[GAIN + 2] * fal(e, obs[ALPHA3], d))
    return z1, z2, z3


@jitable
def _advance1(z1: float, z2: float, z3: float, zh1: float, zh2: float, zh3: float, y: float,
              u: float, obs: Vector) -> tuple[float, float, float]:
    kind = obs[DISC]
    if kind == EULER:
        ts = obs[_TS]
        e = y - z1
        f2 = fal(e, obs[ALPHA2], obs[DELTA])
        f3 = fal(e, obs[ALPHA3], obs[DELTA])
        d1 = z2 + obs[BETA1] * e
        d2 = z3 + obs[_B0] * u + obs[BETA2] * f2
        d3 = obs[BETA3] * f3
        return z1 + ts * d1, z2 + ts * d2, z3 + ts * d3
    if kind == ZOH:
        e = y - z1
        n1 = obs[PHI] * z1 + obs[PHI + 1] * z2 + obs[PHI + 2] * z3 + obs[GAMMA] * u
        n2 = obs[PHI + 3] * z1 + obs[PHI + 4] * z2 + obs[PHI + 5] * z3 + obs[GAMMA + 1] * u
        n3 = obs[PHI + 6] * z1 + obs[PHI + 7] * z2 + obs[PHI + 8] * z3 + obs[GAMMA + 2] * u
        return (n1 + obs[GAIN] * e, n2 + obs[GAIN + 1] * fal(e, obs[ALPHA2], obs[DELTA]),
                n3 + obs[GAIN + 2] * fal(e, obs[ALPHA3], obs[DELTA]))
    # "current": prediction z⁺ = Φ ẑ + Γ u
    n1 = obs[PHI] * zh1 + obs[PHI + 1] * zh2 + obs[PHI + 2] * zh3 + obs[GAMMA] * u
    n2 = obs[PHI + 3] * zh1 + obs[PHI + 4] * zh2 + obs[PHI + 5] * zh3 + obs[GAMMA + 1] * u
    n3 = obs[PHI + 6] * zh1 + obs[PHI + 7] * zh2 + obs[PHI + 8] * zh3 + obs[GAMMA + 2] * u
    return n1, n2, n3


@jitable
def initialize(z: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """Initial state z_0 = (y_0, 0, 0) per joint.

    Parameters
    ----------
    z : ndarray, shape (3n,)
        Observer state, set in place to z_0.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        the linear ESO's vector, α2, α3, δ (unused here).
    """
    for j in range(len(y)):
        z[3 * j] = y[j]
        z[3 * j + 1] = 0.0
        z[3 * j + 2] = 0.0


@jitable
def predict(z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray) -> None:
    """A lost sample: the measurement the observer expects at t_k, ẑ1 = z1 per joint, into ``y``.

    Parameters
    ----------
    z : ndarray, shape (3n,)
        Observer state z_k (not changed).
    zhat : ndarray, shape (3n,)
        The previous estimate ẑ_{k−1} (unused: z1 is the angle predicted for t_k).
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE.
    y : ndarray, shape (n,)
        Output: the predicted angle(s) [rad]; the estimate and update then see zero
        innovation.
    """
    for j in range(len(y)):
        y[j] = z[3 * j]


def state_size(params: Params) -> int:
    """States per joint: 3 (angle, rate, total perturbation).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    int
        3.
    """
    return 3


@jitable
def estimate(z: np.ndarray, y: np.ndarray, p: Vector, zhat: np.ndarray) -> None:
    """Estimate ẑ_k for the controller (the state, or its fal-correction for "current").

    Parameters
    ----------
    z : ndarray, shape (3n,)
        Observer state z_k (joint j in ``z[3j:3j+3]``); not changed.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        the linear ESO's vector, α2, α3, δ.
    zhat : ndarray, shape (3n,)
        Output: the estimate ẑ_k, angle [rad], rate [rad/s] and total perturbation
        [rad/s²] of joint j in ``zhat[3j:3j+3]``, written in place.
        The perturbation is f = θ̈ − b0·u (eq. 7): what accelerates θ besides the input.
    """
    obs = p[1:]
    for j in range(len(y)):
        i = 3 * j
        zhat[i], zhat[i + 1], zhat[i + 2] = _estimate1(z[i], z[i + 1], z[i + 2], y[j], obs)


@jitable
def advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray, p: Vector) -> None:
    """z_{k+1} in place from z_k, ẑ_k, y_k and the applied u_k.

    Parameters
    ----------
    z : ndarray, shape (3n,)
        Observer state z_k, updated in place to z_{k+1}.
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k from :func:`estimate` (used by "current").
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    u : ndarray, shape (n,)
        The observer input u_k as applied (the saturated command [N·m] on the lever arm),
        entering as b0·u [rad/s²].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        the linear ESO's vector, α2, α3, δ.
    """
    obs = p[1:]
    for j in range(len(y)):
        i = 3 * j
        z[i], z[i + 1], z[i + 2] = _advance1(z[i], z[i + 1], z[i + 2], zhat[i], zhat[i + 1],
                                             zhat[i + 2], y[j], u[j], obs)


# ---------------------------------------------------------------------------
# what the rest of esoarm asks the kind


def label(params: Params) -> str:
    """The observer in titles: ``euler nonlinear ESO``.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"{params.discretization} nonlinear ESO"


def summary(params: Params) -> str:
    """One line on the settings: ``ε = 0.09 s (euler)``.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        ε [s] and the discretization.
    """
    return f"ε = {params.eps:g} s ({params.discretization})"


def warnings(params: Params, ts: float) -> list[str]:
    """The linear ESO's warnings for ε and the discretization at Ts [s] (its linear part).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.
    ts : float
        Sample period Ts [s].

    Returns
    -------
    list of str
        One-line warnings, empty when the design is fine.
    """
    return observer_warnings(params.eps, ts, params.discretization)


def linearization(params: Params, ts: float, b0: float) -> ObserverLinearization:
    """The fal-ESO in fal's linear zone |y − z1| ≤ δ, where fal(e, α, δ) = δ^(α−1) e.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].

    Returns
    -------
    ObserverLinearization
        Its pole is the spectral radius of P (the poles are no longer a triple).
    """
    d = design_observer(params.eps, ts, b0, params.discretization)
    slopes = np.array([1.0, params.delta ** (params.alpha[0] - 1.0),
                       params.delta ** (params.alpha[1] - 1.0)])
    lin = discrete_linearization(d, d.gain * slopes, 0.0,
                                 "fal-ESO (its linear zone |e| ≤ δ)")
    pole = float(np.max(np.abs(np.linalg.eigvals(lin.p))))
    return ObserverLinearization(lin.p, lin.q, lin.gamma, lin.hz, lin.hy, pole, lin.eps,
                                 lin.discretization, lin.label)
