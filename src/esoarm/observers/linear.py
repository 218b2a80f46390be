"""Observer kind ``"linear"``: the paper's extended state observer (ESO), eq. 8.

Continuous observer (eq. 8), y = θ measured, b0 = 1/I0:

    ż1 = z2 + β1 (y − z1)
    ż2 = z3 + b0 u + β2 (y − z1)
    ż3 = β3 (y − z1)

Theorem 1: β1 = 3/ε, β2 = 3/ε², β3 = 1/ε³ put all three error poles at −1/ε.

Tunings (``tuning``): ``"bandwidth"`` (the above: Gao's bandwidth parametrization, every
discretization's gain placing the triple pole) or ``"half-gain"`` (G. Herbst, "Half-gain tuning
for active disturbance rejection control", arXiv:2003.03986; discrete time: Herbst & Hempel,
Control Eng. Practice 2025): the same gain vector halved (β/2 for "euler", Lp/2, Lc/2), which
passes less measurement noise at the same ε; pyadrc's ``half_gain=(False, True)`` is "current"
with Lc/2 (tested to round-off).

Input delay (``input_delay`` = N samples, ``delay_form``): the ESO is fed the command of N
samples ago, u_{k−N} (0 before the first), the drive the rig applies over [t_k, t_{k+1}) when
its transport delay is N samples (``actuator.delay_samples``), so the perturbation estimate no
longer holds b0·(u_{k−N} − u_k).  ``delay_form = "predictor"`` also hands the controller the
estimate predicted N samples ahead with the exact held-input model of the triple integrator and
the N commands already sent, θ̂ and θ̇̂ at t_{k+N} (f̂ held), a Smith predictor in the
observer.  The state then holds, after the 3 per joint, the N last commands of each joint.
The prediction assumes the exact held-input model: on an ESO of that model ("zoh",
"current") the nominal loop keeps the FLC's poles for every N (the separation principle);
the Euler ESO's estimation error depends on u, and its loop loses damping as N grows
(unstable from N = 9 at ε = 0.03 s, 50 Hz; docs/adrc.md, "A delay-aware ESO").
``delay_form = "model"`` (the one-joint lever arm) adds the nominal model's acceleration
m(θ, θ̇) = −(G(θ) + Fc tanh(θ̇/vs) + Fv θ̇)/I0 (the plant's gravity, the ``model_*`` friction)
to b0·u_{k−N} as a known input of the ESO, and predicts with it (:func:`model_predict`): the
controller gets θ̂, θ̇̂ and ẑ3 + m at t_{k+N}, a friction step inside the horizon included
(docs/adrc.md, "The model-based predictor").  Its block carries the model after the form.

The semantics: step 5 of the sampled-data loop (docs/semantics.md).  Three discretizations, selected
by name:

``"euler"``
    The paper's fixed-step implementation: z⁺ = z + Ts·(right side of eq. 8).
    Error poles at 1 − Ts/ε; unstable once Ts/ε ≥ 2.
``"zoh"``
    Exact discrete model of the extended plant under a held u (predictive
    form): z⁺ = Φ z + Γ u + Lp (y − z1), poles of Φ − Lp C at e^{−Ts/ε}.
``"current"``
    Exact model, current-estimator form: the prediction z = Φ ẑ⁻ + Γ u⁻ is
    corrected with the newest sample before the control is computed,
    ẑ = z + Lc (y − z1), poles of Φ − Lc C Φ at e^{−Ts/ε}.

The per-sample step is split in two plain functions shared by every engine:
:func:`eso_estimate` gives the estimate ẑ_k the controller may use at t_k, and
:func:`eso_advance` gives z_{k+1}.  Their parameters are packed in one float
vector (:attr:`ESODesign.vector`) so that compiled batch kernels can hold one
row per run.

As a kind (see :mod:`esoarm.contract`): :class:`Params` is the ``[observer]``
table, :func:`design` gives (CODE, :attr:`ESODesign.vector`), and
:func:`initialize`, :func:`estimate` and :func:`advance` are the array-valued
step functions (one 3-state ESO per joint) every engine calls.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Literal, cast

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, joint_values, show_joint_values, unit
from esoarm.contract import ComponentDesign, ObserverLinearization, PlantDesign, Vector, read_only
from esoarm.plants.elementary import cos, tanh

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = [
    "CODE",
    "check",
    "predict",
    "state_size",
    "FAST",
    "JIT",
    "KIND",
    "Params",
    "advance",
    "design",
    "estimate",
    "initialize",
    "label",
    "linearization",
    "summary",
    "warnings",
    "DISCRETIZATIONS",
    "TUNINGS",
    "delayed_linearization",
    "eso_predict",
    "ESODesign",
    "ExtendedStateObserver",
    "continuous_error_matrix",
    "continuous_gains",
    "design_observer",
    "discrete_error_matrix",
    "discrete_error_poles",
    "eso_advance",
    "eso_estimate",
    "eso_rhs",
    "extended_plant",
    "observer_warnings",
    "pole_damping",
]

Discretization = Literal["euler", "zoh", "current"]
DISCRETIZATIONS: tuple[str, ...] = ("euler", "zoh", "current")
TUNINGS: tuple[str, ...] = ("bandwidth", "half-gain")
DELAY_FORMS: tuple[str, ...] = ("input", "predictor", "model")
#: the largest ``input_delay`` [samples]
MAX_INPUT_DELAY = 200

# Layout of the packed observer vector (see ESODesign.vector).
DISC, TS, B0, BETA1, BETA2, BETA3 = 0, 1, 2, 3, 4, 5
PHI = 6  # 9 entries, row-major
GAMMA = 15  # 3 entries
GAIN = 18  # 3 entries: Lp ("zoh") or Lc ("current"); Ts·β for "euler" (information only)
VECTOR_SIZE = 21
EULER, ZOH, CURRENT = 0, 1, 2
# The kind's block per joint: ESODesign.vector, then the input delay N [samples] and the form
# (0 "input": the ESO fed u_{k−N}; 1 "predictor": the estimate also predicted N samples ahead).
DELAY, FORM = 21, 22
BLOCK_SIZE = 23
FORM_INPUT, FORM_PREDICTOR, FORM_MODEL = 0.0, 1.0, 2.0
# delay_form = "model" (one joint only) appends the nominal model to the block: gravity's
# (m1 l1 − m2 l2) g [N·m], Coulomb Fc [N·m], its tanh velocity vs [rad/s], viscous Fv [N·m·s/rad]
M_GCOEF, M_FC, M_VS, M_FV = 23, 24, 25, 26
MODEL_BLOCK_SIZE = 27

KIND = "linear"
CODE = 0
JIT = True
#: The fast engine's C kernel models this observer (every discretization).
FAST = True
#: Linear for sensor noise: the noise budget predicts its chatter (``analyze --bandwidth``).
NOISE_BUDGET = True
#: The reference the bandwidth criterion is stated against (the paper's observer).
BASELINE = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "linear.c"


class Params(Section):
    """``[observer]`` of kind "linear": the ESO of eq. 8 (Theorem 1 gains)."""

    kind: Literal["linear"] = Field(
        "linear", description="observer kind (the registered kinds: esoarm.kinds)")
    eps: Annotated[float, Field(gt=0)] | list[Annotated[float, Field(gt=0)]] = Field(
        0.09, description="free parameter ε; observer poles at −1/ε (an arm: one number for "
        "every joint, or one per joint)", json_schema_extra=unit("s"),
    )
    discretization: Literal["euler", "zoh", "current"] = Field(
        "euler", description='"euler" (paper) | "zoh" | "current"'
    )
    tuning: Literal["bandwidth", "half-gain"] = Field(
        "bandwidth", description='"bandwidth": the triple pole at −1/ε (Theorem 1) | '
        '"half-gain": that gain vector halved (Herbst), less noise at the same ε')
    input_delay: int = Field(
        0, ge=0, le=MAX_INPUT_DELAY, description="the ESO is fed the command of this many "
        "samples ago (the rig's transport delay, actuator.delay_samples)",
        json_schema_extra=unit("samples"))
    delay_form: Literal["input", "predictor", "model"] = Field(
        "input", description='with input_delay > 0: "input": the ESO fed u_{k−N} | '
        '"predictor": also the estimate predicted N samples ahead (a Smith predictor) | '
        '"model": the ESO and the prediction add the nominal model (the plant\'s gravity, '
        'the model_* friction), a lever arm only')
    model_coulomb: float = Field(
        0.0, ge=0, description='with delay_form = "model": the Coulomb friction Fc the '
        "model assumes (e.g. identified)", json_schema_extra=unit("N·m"))
    model_viscous: float = Field(
        0.0, ge=0, description='with delay_form = "model": the viscous friction Fv the '
        "model assumes", json_schema_extra=unit("N·m·s/rad"))
    model_friction_velocity: float = Field(
        0.05, gt=0, description='with delay_form = "model": the model\'s Coulomb friction '
        "is Fc·tanh(θ̇/vs); a vs wider than the rig's keeps an over-estimated Fc from a limit "
        "cycle", json_schema_extra=unit("rad/s"))


def continuous_gains(eps: float) -> tuple[float, float, float]:
    """Observer gains of Theorem 1: (β1, β2, β3) = (3/ε, 3/ε², 1/ε³).

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s]; all three error poles at −1/ε [1/s].

    Returns
    -------
    tuple of float
        β1 = 3/ε [1/s], β2 = 3/ε² [1/s²], β3 = 1/ε³ [1/s³].

    Raises
    ------
    ValueError
        If ε is not positive.

    Examples
    --------
    >>> continuous_gains(0.5)
    (6.0, 12.0, 8.0)
    """
    if not eps > 0:
        raise ValueError(f"eps must be > 0, got {eps!r}")
    return 3.0 / eps, 3.0 / eps**2, 1.0 / eps**3


def extended_plant(b0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The extended plant of eq. 7 as (A, B, C): x = (θ, θ̇, f), u [N·m].

    Parameters
    ----------
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].

    Returns
    -------
    tuple of ndarray
        A, shape (3, 3) (the triple integrator); B = (0, b0, 0); C = (1, 0, 0), so that
        ẋ = A x + B u, y = C x with the state (θ [rad], θ̇ [rad/s], f [rad/s²]).
    """
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    b = np.array([0.0, b0, 0.0])
    c = np.array([1.0, 0.0, 0.0])
    return a, b, c


def continuous_error_matrix(eps: float) -> np.ndarray:
    """The estimation-error matrix of eq. 10, A − βC; eigenvalues all −1/ε.

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s].

    Returns
    -------
    ndarray, shape (3, 3)
        A − βC: −β1 [1/s], −β2 [1/s²], −β3 [1/s³] in the first column, the shift
        (ones above the diagonal) elsewhere; β the gains of Theorem 1.
    """
    b1, b2, b3 = continuous_gains(eps)
    return np.array([[-b1, 1.0, 0.0], [-b2, 0.0, 1.0], [-b3, 0.0, 0.0]])


def _zoh_matrices(ts: float, b0: float) -> tuple[np.ndarray, np.ndarray]:
    # Closed form of Φ = e^{A Ts}, Γ = ∫0^Ts e^{A s} ds B for the triple integrator.
    phi = np.array([[1.0, ts, ts * ts / 2.0], [0.0, 1.0, ts], [0.0, 0.0, 1.0]])
    gamma = b0 * np.array([ts * ts / 2.0, ts, 0.0])
    return phi, gamma


def _ackermann_observer(phi: np.ndarray, c_row: np.ndarray, pole: float) -> np.ndarray:
    """Gain L with eig(Φ − L c_row) = {pole, pole, pole} (Ackermann's formula)."""
    n = phi.shape[0]
    obs = np.vstack([c_row @ np.linalg.matrix_power(phi, i) for i in range(n)])
    char = np.linalg.matrix_power(phi - pole * np.eye(n), n)
    e_last = np.zeros(n)
    e_last[-1] = 1.0
    return char @ np.linalg.solve(obs, e_last)


@dataclass(frozen=True)
class ESODesign:
    """A discretized ESO: everything :func:`eso_advance` needs, for one ε and Ts.

    Attributes
    ----------
    discretization : {"euler", "zoh", "current"}
    eps : float
        Free parameter ε [s].
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].
    beta : ndarray, shape (3,)
        Continuous gains (3/ε, 3/ε², 1/ε³).
    phi, gamma : ndarray
        Discrete extended plant (exact ZOH; for "euler", I + Ts·A and Ts·B).
    gain : ndarray, shape (3,)
        Lp ("zoh"), Lc ("current"), or Ts·β ("euler"); halved by "half-gain".
    tuning : {"bandwidth", "half-gain"}
        The observer tuning.
    """

    discretization: Discretization
    eps: float
    ts: float
    b0: float
    beta: np.ndarray
    phi: np.ndarray
    gamma: np.ndarray
    gain: np.ndarray
    vector: np.ndarray = field(repr=False)
    tuning: str = "bandwidth"

    @property
    def error_matrix(self) -> np.ndarray:
        """Matrix of the discrete estimation-error recursion."""
        if self.tuning != "bandwidth":
            c_row = np.array([1.0, 0.0, 0.0])
            if self.discretization == "current":
                return self.phi - np.outer(self.gain, c_row @ self.phi)
            return self.phi - np.outer(self.gain, c_row)
        return discrete_error_matrix(self.eps, self.ts, self.discretization)

    @property
    def poles(self) -> np.ndarray:
        """Error poles in the z-plane (the triple pole of "bandwidth"; "half-gain": the
        eigenvalues of :attr:`error_matrix`, largest modulus first)."""
        if self.tuning != "bandwidth":
            ev = np.linalg.eigvals(self.error_matrix)
            return ev[np.argsort(-np.abs(ev))]
        return discrete_error_poles(self.eps, self.ts, self.discretization)


def design_observer(eps: float, ts: float, b0: float, discretization: str = "euler",
                    tuning: str = "bandwidth") -> ESODesign:
    """Discretize the ESO of eq. 8 for sample period ``ts``.

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s] (Theorem 1).
    ts : float
        Sample period Ts > 0 [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].
    discretization : {"euler", "zoh", "current"}
        See the module docstring and the sampled-data loop, step 5.
    tuning : {"bandwidth", "half-gain"}
        "half-gain": the gain vector of "bandwidth" halved (β/2 for "euler", Lp/2, Lc/2).

    Returns
    -------
    ESODesign
        Gains, discrete matrices and the packed :attr:`ESODesign.vector` (read-only).

    Raises
    ------
    ValueError
        If ``discretization`` or ``tuning`` is unknown, or ``ts`` or ``eps`` is not positive.
    """
    if discretization not in DISCRETIZATIONS:
        raise ValueError(
            f"discretization must be one of {', '.join(DISCRETIZATIONS)}; got {discretization!r}"
        )
    if tuning not in TUNINGS:
        raise ValueError(f"tuning must be one of {', '.join(TUNINGS)}; got {tuning!r}")
    if not ts > 0:
        raise ValueError(f"ts must be > 0, got {ts!r}")
    beta = np.array(continuous_gains(eps))
    scale = 0.5 if tuning == "half-gain" else 1.0
    beta = scale * beta
    c_row = np.array([1.0, 0.0, 0.0])
    if discretization == "euler":
        a, b, _ = extended_plant(b0)
        phi = np.eye(3) + ts * a
        gamma = ts * b
        gain = ts * beta
        kind = EULER
    else:
        phi, gamma = _zoh_matrices(ts, b0)
        pole = math.exp(-ts / eps)
        if discretization == "zoh":
            gain = scale * _ackermann_observer(phi, c_row, pole)
            kind = ZOH
        else:
            # Φ − Lc C Φ: an observer for the pair (Φ, CΦ)
            gain = scale * _ackermann_observer(phi, c_row @ phi, pole)
            kind = CURRENT
    vec = np.zeros(VECTOR_SIZE)
    vec[DISC] = kind
    vec[TS] = ts
    vec[B0] = b0
    vec[BETA1 : BETA3 + 1] = beta
    vec[PHI : PHI + 9] = phi.ravel()
    vec[GAMMA : GAMMA + 3] = gamma
    vec[GAIN : GAIN + 3] = gain
    for arr in (beta, phi, gamma, gain, vec):
        arr.setflags(write=False)
    return ESODesign(cast(Discretization, discretization), eps, ts, b0, beta, phi, gamma, gain,
                     vec, tuning)


def discrete_error_matrix(eps: float, ts: float, discretization: str) -> np.ndarray:
    """Matrix M of the estimation-error recursion z̃⁺ = M z̃ (γ = 0).

    "euler": I + Ts (A − βC); "zoh": Φ − Lp C; "current": Φ − Lc C Φ.

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s].
    ts : float
        Sample period Ts > 0 [s].
    discretization : {"euler", "zoh", "current"}
        The discretization (module docstring).

    Returns
    -------
    ndarray, shape (3, 3)
        M (dimensionless in the z-plane: its eigenvalues are the error poles).
    """
    d = design_observer(eps, ts, 1.0, discretization)
    c_row = np.array([[1.0, 0.0, 0.0]])
    if discretization == "euler":
        return np.eye(3) + ts * continuous_error_matrix(eps)
    if discretization == "zoh":
        return d.phi - np.outer(d.gain, c_row) @ np.eye(3)
    return d.phi - np.outer(d.gain, c_row @ d.phi)


def discrete_error_poles(eps: float, ts: float, discretization: str) -> np.ndarray:
    """Design error poles (z-plane, triple) of a discretized ESO.

    "euler": 1 − Ts/ε (stable only while Ts/ε < 2); "zoh" and "current":
    e^{−Ts/ε}, the exact image of the continuous poles −1/ε.

    Parameters
    ----------
    eps : float
        Free parameter ε > 0 [s].
    ts : float
        Sample period Ts [s].
    discretization : {"euler", "zoh", "current"}
        The discretization (module docstring).

    Returns
    -------
    ndarray, shape (3,)
        The triple pole, three times.

    Raises
    ------
    ValueError
        If ``discretization`` is unknown.

    Examples
    --------
    >>> discrete_error_poles(0.1, 0.05, "euler")
    array([0.5, 0.5, 0.5])
    """
    if discretization == "euler":
        p = 1.0 - ts / eps
    elif discretization in ("zoh", "current"):
        p = math.exp(-ts / eps)
    else:
        raise ValueError(f"discretization must be one of {', '.join(DISCRETIZATIONS)}")
    return np.full(3, p)


def pole_damping(pole: complex, ts: float | None = None) -> float:
    """Damping ratio ζ of a pole: s-plane if ``ts`` is None, else z-plane.

    A z-plane pole is mapped to s = ln(z)/Ts (principal branch); a negative
    real z-pole (ringing at the Nyquist frequency, Euler with Ts/ε > 1)
    gives ζ = −ln|z| / √(ln²|z| + π²) < 1.  ζ = 1 for a positive real pole
    and for z = 0 (deadbeat); ζ ≤ 0 on or outside the stability boundary.

    Parameters
    ----------
    pole : complex
        The pole, s-plane [1/s] when ``ts`` is None, else z-plane.
    ts : float, optional
        Sample period [s] of a z-plane pole.

    Returns
    -------
    float
        ζ (1 for a real stable pole; below 0 when unstable).
    """
    if ts is None:
        s = complex(pole)
    else:
        z = complex(pole)
        if z == 0:
            return 1.0
        s = cmath.log(z) / ts
    mag = abs(s)
    if mag == 0.0:
        return 0.0
    return -s.real / mag


def observer_warnings(eps: float, ts: float, discretization: str) -> list[str]:
    """One-line warnings when ε is too small for the sample period Ts.

    Parameters
    ----------
    eps : float
        Free parameter ε [s].
    ts : float
        Sample period Ts [s].
    discretization : {"euler", "zoh", "current"}

    Returns
    -------
    list of str
        Empty when the design is fine.  Checks, in order: the discrete error
        poles unstable (radius ≥ 1: "euler" with Ts/ε ≥ 2); Euler poles on
        the negative real axis (1 < Ts/ε < 2: estimates ring at the Nyquist
        frequency, damping ζ < 1); an observer faster than the samples
        support for the exact discretizations (ε < 2 Ts: noisy estimates).
    """
    poles = discrete_error_poles(eps, ts, discretization)
    radius = float(np.max(np.abs(poles)))
    ratio = ts / eps
    out: list[str] = []
    if not radius < 1.0:
        out.append(
            f"observer.eps = {eps:g} s with discretization '{discretization}' at Ts = {ts:g} s: "
            f"the discrete observer is unstable (pole radius {radius:.3g} >= 1); "
            f"use eps > {ts / 2:g} s or discretization 'zoh'/'current'"
        )
    elif discretization == "euler" and ratio > 1.0:
        out.append(
            f"observer.eps = {eps:g} s with Euler at Ts = {ts:g} s: Ts/eps = {ratio:.3g}"
            f" > 1 puts the observer poles on the negative real axis (damping "
            f"{pole_damping(poles[0], ts):.2g}, oscillating estimates)"
        )
    if eps < 2.0 * ts and discretization != "euler":
        out.append(
            f"observer.eps = {eps:g} s is below 2·Ts = {2 * ts:g} s: the observer is faster "
            "than the sample rate supports well; expect noisy estimates"
        )
    return out


# ---------------------------------------------------------------------------
# plain step functions, shared by every engine


@jitable
def eso_rhs(z1: float, z2: float, z3: float, y: float, u: float, b0: float, beta1: float,
            beta2: float, beta3: float) -> tuple[float, float, float]:
    """Right side of eq. 8 at (z, y, u): returns (ż1, ż2, ż3).

    Parameters
    ----------
    z1, z2, z3 : float
        Observer state: angle [rad], rate [rad/s], total perturbation [rad/s²].
    y : float
        Measured angle [rad]; the innovation is e = y − z1.
    u : float
        Observer input [N·m] (the command on the lever arm).
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].
    beta1, beta2, beta3 : float
        Gains β1 [1/s], β2 [1/s²], β3 [1/s³].

    Returns
    -------
    tuple of float
        (ż1 [rad/s], ż2 [rad/s²], ż3 [rad/s³]).
    """
    e = y - z1
    return z2 + beta1 * e, z3 + b0 * u + beta2 * e, beta3 * e


@jitable
def eso_estimate(z1: float, z2: float, z3: float, y: float,
                 obs: np.ndarray) -> tuple[float, float, float]:
    """Estimate ẑ_k available to the controller at t_k (the sampled-data loop, step 5).

    For "euler" and "zoh" this is the state itself; for "current" it is the
    prediction corrected with y_k: ẑ = z + Lc (y − z1).

    Parameters
    ----------
    z1, z2, z3 : float
        Observer state z_k: angle [rad], rate [rad/s], total perturbation [rad/s²].
    y : float
        Measured angle y_k [rad].
    obs : ndarray, shape (21,)
        :attr:`ESODesign.vector`.

    Returns
    -------
    tuple of float
        ẑ_k = (θ̂ [rad], θ̇̂ [rad/s], f̂ [rad/s²]).
    """
    if obs[DISC] == CURRENT:
        e = y - z1
        return z1 + obs[GAIN] * e, z2 + obs[GAIN + 1] * e, z3 + obs[GAIN + 2] * e
    return z1, z2, z3


@jitable
def eso_advance(z1: float, z2: float, z3: float, zh1: float, zh2: float, zh3: float, y: float,
                u: float, obs: np.ndarray) -> tuple[float, float, float]:
    """Observer state z_{k+1} from z_k, the estimate ẑ_k, y_k and u_k.

    Parameters
    ----------
    z1, z2, z3 : float
        Observer state z_k.
    zh1, zh2, zh3 : float
        Estimate ẑ_k from :func:`eso_estimate` (used by "current").
    y : float
        Measured angle y_k [rad].
    u : float
        Control u_k [N·m] (saturated, as commanded).
    obs : ndarray, shape (21,)
        :attr:`ESODesign.vector`.

    Returns
    -------
    tuple of float
        z_{k+1}: angle [rad], rate [rad/s], total perturbation [rad/s²].
    """
    kind = obs[DISC]
    if kind == EULER:
        ts = obs[TS]
        d1, d2, d3 = eso_rhs(z1, z2, z3, y, u, obs[B0], obs[BETA1], obs[BETA2], obs[BETA3])
        return z1 + ts * d1, z2 + ts * d2, z3 + ts * d3
    if kind == ZOH:
        # z⁺ = Φ z + Γ u + Lp (y − z1)
        e = y - z1
        n1 = obs[PHI] * z1 + obs[PHI + 1] * z2 + obs[PHI + 2] * z3 + obs[GAMMA] * u
        n2 = obs[PHI + 3] * z1 + obs[PHI + 4] * z2 + obs[PHI + 5] * z3 + obs[GAMMA + 1] * u
        n3 = obs[PHI + 6] * z1 + obs[PHI + 7] * z2 + obs[PHI + 8] * z3 + obs[GAMMA + 2] * u
        return n1 + obs[GAIN] * e, n2 + obs[GAIN + 1] * e, n3 + obs[GAIN + 2] * e
    # "current": prediction z⁺ = Φ ẑ + Γ u
    n1 = obs[PHI] * zh1 + obs[PHI + 1] * zh2 + obs[PHI + 2] * zh3 + obs[GAMMA] * u
    n2 = obs[PHI + 3] * zh1 + obs[PHI + 4] * zh2 + obs[PHI + 5] * zh3 + obs[GAMMA + 1] * u
    n3 = obs[PHI + 6] * zh1 + obs[PHI + 7] * zh2 + obs[PHI + 8] * zh3 + obs[GAMMA + 2] * u
    return n1, n2, n3


# ---------------------------------------------------------------------------
# the kind: design and array-valued step functions (one ESO per joint)


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, one block per joint) for the scenario's ε, discretization, tuning and delay.

    Joint j's ESO uses ε_j (one ε applies to every joint) and the plant's b0_j at
    Ts [s].  State: 3 per joint, then ``input_delay`` commands per joint.

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
        (CODE, per joint the 21-float :attr:`ESODesign.vector`, the input delay N [samples]
        and the form (0 "input", 1 "predictor", 2 "model", then the model's 4 entries)),
        (3 + N)·n states.

    Raises
    ------
    ValueError
        If ``observer.eps`` has not one entry per joint, or ``delay_form = "model"`` is set
        on a plant other than the one-joint lever arm.
    """
    n = plant.n_joints
    ob = scn.observer
    eps = ob.eps
    eps_j = list(eps) if isinstance(eps, list) else [eps] * n
    if len(eps_j) != n:
        raise ValueError(f"observer.eps has {len(eps_j)} entries for {n} joints")
    nd = int(getattr(ob, "input_delay", 0))
    form = DELAY_FORMS.index(getattr(ob, "delay_form", "input"))
    blocks = [np.concatenate([design_observer(e, ts, float(b0), ob.discretization,
                                              getattr(ob, "tuning", "bandwidth")).vector,
                              [float(nd), float(form)]])
              for e, b0 in zip(eps_j, plant.b0, strict=True)]
    if form == FORM_MODEL:
        blocks[0] = np.concatenate([blocks[0], nominal_model(scn, n)])
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], *blocks])), (3 + nd) * n)


def nominal_model(scn: Scenario, n_joints: int) -> np.ndarray:
    """The model of ``delay_form = "model"``: (gcoef [N·m], Fc [N·m], vs [rad/s], Fv [N·m·s/rad]).

    Gravity is the plant's nominal G(θ) = gcoef·cos θ (what the FLC's ``compensation =
    "model"`` cancels); the friction is the observer's ``model_*`` keys (the rig's is not
    read: the controller knows only what it is told).

    Parameters
    ----------
    scn : Scenario
        The validated scenario.
    n_joints : int
        The plant's joints (must be 1).

    Returns
    -------
    ndarray, shape (4,)

    Raises
    ------
    ValueError
        If the plant is not the one-joint lever arm (the model is its gravity).
    """
    from esoarm.plants.model import gravity_coefficient

    p = scn.plant
    if getattr(p, "kind", "") != "lever-arm" or n_joints != 1:
        raise ValueError(f"observer.delay_form = 'model' needs plant.kind = 'lever-arm' (its "
                         f"nominal gravity is the model); got plant.kind = "
                         f"'{getattr(p, 'kind', '?')}' with {n_joints} joint(s)")
    ob = scn.observer
    return np.array([gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g), ob.model_coulomb,
                     ob.model_friction_velocity, ob.model_viscous])


@jitable
def model_acceleration(theta: float, omega: float, obs: np.ndarray) -> float:
    """The nominal model's acceleration m(θ, θ̇) = −(G(θ) + Fc tanh(θ̇/vs) + Fv θ̇)/I0 [rad/s²].

    Parameters
    ----------
    theta, omega : float
        Angle [rad] and rate [rad/s].
    obs : ndarray
        The joint's block with the model (:data:`MODEL_BLOCK_SIZE` entries); I0 = 1/b0.

    Returns
    -------
    float
        m [rad/s²]: the acceleration the model predicts besides b0·u.
    """
    friction = obs[M_FC] * tanh(omega / obs[M_VS]) + obs[M_FV] * omega
    acc: float = -(obs[M_GCOEF] * cos(theta) + friction) * obs[B0]
    return acc


@jitable
def model_predict(h1: float, h2: float, h3: float, z: np.ndarray, base: int, nd: int,
                  obs: np.ndarray) -> tuple[float, float, float]:
    """θ̂, θ̇̂ and the total perturbation at t_{k+N} with the nominal model (``"model"``).

    The held-input steps of :func:`eso_predict` with the acceleration
    a_i = ẑ3 + b0 u_{k−N+i} + m(θ_i, θ̇_i) (:func:`model_acceleration`; ẑ3 is what the
    model leaves, held): a velocity reversal inside the horizon brings its friction step.

    Parameters
    ----------
    h1, h2, h3 : float
        The model-assisted estimate ẑ_k: angle [rad], rate [rad/s], residual [rad/s²].
    z : ndarray
        The observer state; ``z[base:base+nd]`` holds u_{k−N} … u_{k−1} [N·m].
    base, nd : int
        Where the commands start; the input delay N [samples].
    obs : ndarray
        The joint's block with the model.

    Returns
    -------
    tuple of float
        Angle [rad], rate [rad/s] and total perturbation ẑ3 + m [rad/s²] at t_{k+N}.
    """
    ts = obs[TS]
    b0 = obs[B0]
    half = 0.5 * ts * ts
    for i in range(nd):
        acc = h3 + b0 * z[base + i] + model_acceleration(h1, h2, obs)
        h1, h2 = h1 + ts * h2 + half * acc, h2 + ts * acc
    return h1, h2, h3 + model_acceleration(h1, h2, obs)


@jitable
def initialize(z: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """Initial state z_0 = (y_0, 0, 0) per joint from the first measurement y_0 [rad].

    The commands held for the input delay start at 0 (none sent yet).

    Parameters
    ----------
    z : ndarray, shape ((3 + N)·n,)
        Observer state, set in place to z_0.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        one block per joint (unused here).
    """
    for j in range(len(y)):
        z[3 * j] = y[j]
        z[3 * j + 1] = 0.0
        z[3 * j + 2] = 0.0
    for i in range(3 * len(y), len(z)):
        z[i] = 0.0


@jitable
def eso_predict(h1: float, h2: float, h3: float, z: np.ndarray, base: int, nd: int,
                obs: np.ndarray) -> tuple[float, float]:
    """θ̂, θ̇̂ at t_{k+N} from ẑ_k and the N commands sent, u_{k−N} … u_{k−1}.

    The exact model of the triple integrator under a held input, f̂ held:
    θ⁺ = θ + Ts θ̇ + Ts²/2 (f̂ + b0 u),  θ̇⁺ = θ̇ + Ts (f̂ + b0 u), whatever the
    discretization of the observer itself.

    Parameters
    ----------
    h1, h2, h3 : float
        The estimate ẑ_k: angle [rad], rate [rad/s], perturbation [rad/s²].
    z : ndarray
        The observer state; ``z[base:base+nd]`` holds u_{k−N} … u_{k−1} [N·m].
    base : int
        Where the joint's commands start in ``z``.
    nd : int
        The input delay N [samples].
    obs : ndarray
        The joint's block (:attr:`ESODesign.vector` first).

    Returns
    -------
    tuple of float
        Predicted angle [rad] and rate [rad/s] at t_{k+N}.
    """
    ts = obs[TS]
    b0 = obs[B0]
    half = 0.5 * ts * ts
    for i in range(nd):
        acc = h3 + b0 * z[base + i]
        h1 = h1 + ts * h2 + half * acc
        h2 = h2 + ts * acc
    return h1, h2


@jitable
def _delayed(z: np.ndarray, base: int, nd: int, u: float) -> float:
    """u_{k−N} from the commands held in ``z[base:base+nd]``; u_k appended (shifted in)."""
    if nd == 0:
        return u
    old: float = z[base]
    for i in range(nd - 1):
        z[base + i] = z[base + i + 1]
    z[base + nd - 1] = u
    return old


@jitable
def predict(z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray) -> None:
    """A lost sample: the measurement the observer expects at t_k, ẑ1 = z1 per joint, into ``y``.

    Parameters
    ----------
    z : ndarray, shape ((3 + N)·n,)
        Observer state z_k (not changed).
    zhat : ndarray
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
    """States per joint: 3 (angle, rate, total perturbation) and the commands held.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    int
        3 + ``input_delay`` (the N last commands held for the delayed input).
    """
    return 3 + int(params.input_delay)


@jitable
def estimate(z: np.ndarray, y: np.ndarray, p: np.ndarray, zhat: np.ndarray) -> None:
    """Estimate ẑ_k for the controller from z_k and y_k into ``zhat`` (:func:`eso_estimate`).

    With ``delay_form = "predictor"`` and N > 0, the angle and rate handed over are
    predicted N samples ahead (:func:`eso_predict`).  ``p`` holds one block per joint;
    the compiled kernels run one joint and hand ``p`` over as a tuple, which is sliced
    statically there.

    Parameters
    ----------
    z : ndarray, shape ((3 + N)·n,)
        Observer state z_k (joint j in ``z[3j:3j+3]``, its commands in
        ``z[3n + Nj : 3n + N(j+1)]``); not changed.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        one block per joint (:attr:`ESODesign.vector`, N, form).
    zhat : ndarray, shape ((3 + N)·n,)
        Output: the estimate ẑ_k, angle [rad], rate [rad/s] and total perturbation
        [rad/s²] of joint j in ``zhat[3j:3j+3]``, written in place.
        The perturbation is f = θ̈ − b0·u (eq. 7): what accelerates θ besides the input.
    """
    nj = len(y)
    if nj == 1:
        obs = p[1:]
        h1, h2, h3 = eso_estimate(z[0], z[1], z[2], y[0], obs)
        nd = int(obs[DELAY])
        if obs[FORM] == FORM_MODEL:
            h1, h2, h3 = model_predict(h1, h2, h3, z, 3, nd, obs)
        elif nd > 0 and obs[FORM] == FORM_PREDICTOR:
            h1, h2 = eso_predict(h1, h2, h3, z, 3, nd, obs)
        zhat[0], zhat[1], zhat[2] = h1, h2, h3
        return
    vec = np.asarray(p)
    for j in range(nj):
        i = 3 * j
        obs_j = vec[1 + BLOCK_SIZE * j:1 + BLOCK_SIZE * (j + 1)]
        h1, h2, h3 = eso_estimate(z[i], z[i + 1], z[i + 2], y[j], obs_j)
        nd = int(obs_j[DELAY])
        if nd > 0 and obs_j[FORM] == 1.0:
            h1, h2 = eso_predict(h1, h2, h3, z, 3 * nj + nd * j, nd, obs_j)
        zhat[i], zhat[i + 1], zhat[i + 2] = h1, h2, h3


@jitable
def advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray,
            p: np.ndarray) -> None:
    """z_{k+1} in place from z_k, ẑ_k, y_k and the input u_{k−N} (:func:`eso_advance`).

    ``u`` is the plant's observer input (the command for the lever arm); with an input
    delay N the ESO takes the one of N samples ago and keeps u_k for later.

    Parameters
    ----------
    z : ndarray, shape ((3 + N)·n,)
        Observer state z_k, updated in place to z_{k+1}.
    zhat : ndarray, shape ((3 + N)·n,)
        The estimate ẑ_k from :func:`estimate` (used by "current"; recomputed from z_k and
        y_k when it holds a prediction).
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    u : ndarray, shape (n,)
        The observer input u_k as applied (the saturated command [N·m] on the lever arm),
        entering as b0·u [rad/s²].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then
        one block per joint (:attr:`ESODesign.vector`, N, form).
    """
    nj = len(y)
    if nj == 1:
        obs = p[1:]
        nd = int(obs[DELAY])
        h1, h2, h3 = zhat[0], zhat[1], zhat[2]
        if (nd > 0 and obs[FORM] == FORM_PREDICTOR) or obs[FORM] == FORM_MODEL:
            h1, h2, h3 = eso_estimate(z[0], z[1], z[2], y[0], obs)
        ud = _delayed(z, 3, nd, u[0])
        if obs[FORM] == FORM_MODEL:
            # the model's acceleration enters as a known input: b0·(u + m(ẑ1, ẑ2)/b0)
            ud = ud + model_acceleration(h1, h2, obs) / obs[B0]
        z[0], z[1], z[2] = eso_advance(z[0], z[1], z[2], h1, h2, h3, y[0], ud, obs)
        return
    vec = np.asarray(p)
    for j in range(nj):
        i = 3 * j
        obs_j = vec[1 + BLOCK_SIZE * j:1 + BLOCK_SIZE * (j + 1)]
        nd = int(obs_j[DELAY])
        h1, h2, h3 = zhat[i], zhat[i + 1], zhat[i + 2]
        if nd > 0 and obs_j[FORM] == 1.0:
            h1, h2, h3 = eso_estimate(z[i], z[i + 1], z[i + 2], y[j], obs_j)
        ud = _delayed(z, 3 * nj + nd * j, nd, u[j])
        z[i], z[i + 1], z[i + 2] = eso_advance(z[i], z[i + 1], z[i + 2], h1, h2, h3, y[j], ud,
                                               obs_j)


def check(scn: Scenario) -> str | None:
    """The model form's plant: ``delay_form = "model"`` needs the one-joint lever arm.

    Parameters
    ----------
    scn : Scenario
        The scenario, valid key by key.

    Returns
    -------
    str or None
        One line naming ``observer.delay_form``, or None.
    """
    if getattr(scn.observer, "delay_form", "input") != "model":
        return None
    if getattr(scn.plant, "kind", "") != "lever-arm":
        return (f"key 'observer.delay_form': 'model' adds the lever arm's nominal gravity and the "
                f"observer.model_* friction; plant.kind = '{scn.plant.kind}' has no such model "
                "(use 'input' or 'predictor')")
    return None


def label(params: Params) -> str:
    """The observer in titles: its discretization ("euler"), the paper's ESO being the default.

    A half-gain tuning and an input delay are added (``zoh, half-gain, delay 2``).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        The discretization's name and any non-default tuning or delay.
    """
    out = str(params.discretization)
    if params.tuning != "bandwidth":
        out += f", {params.tuning}"
    if params.delay_form == "model":
        out += f", model predictor {params.input_delay}"
    elif params.input_delay:
        out += f", {'predictor' if params.delay_form == 'predictor' else 'delay'} " \
            f"{params.input_delay}"
    return out


def summary(params: Params) -> str:
    """One line on the settings: ``ε = 0.09 s (euler)``.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        ε [s] per joint, the discretization, and any non-default tuning or input delay.
    """
    return f"ε = {show_joint_values(params.eps)} s ({label(params)})"


def warnings(params: Params, ts: float) -> list[str]:
    """:func:`observer_warnings` of each ε of ``params`` (once each) at Ts [s].

    With the half-gain tuning the poles are those of the halved gains: an unstable
    design is reported from them.  The predictor on the Euler ESO is reported too (its
    nominal loop loses damping as the delay grows; tests/observers/test_delay_predictor.py).

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
    out: list[str] = []
    for eps in dict.fromkeys(joint_values(params.eps)):
        if params.tuning == "bandwidth":
            msgs = observer_warnings(eps, ts, params.discretization)
        else:
            radius = float(np.max(np.abs(design_observer(eps, ts, 1.0, params.discretization,
                                                         params.tuning).poles)))
            msgs = [] if radius < 1.0 else [
                f"observer.eps = {eps:g} s with tuning '{params.tuning}' and discretization "
                f"'{params.discretization}' at Ts = {ts:g} s: the discrete observer is unstable "
                f"(pole radius {radius:.3g} >= 1)"]
        out.extend(m for m in msgs if m not in out)
    if params.delay_form == "predictor" and params.input_delay and params.discretization == "euler":
        out.append("observer.delay_form = 'predictor' with discretization 'euler': the Euler "
                   "ESO's estimate depends on the command, so the predicted loop loses damping "
                   "as observer.input_delay grows (test-1 at 50 Hz, ε = 0.03 s: unstable from "
                   "9 samples); 'current' or 'zoh' keeps the controller's poles for any delay "
                   "(check with esoarm analyze)")
    if params.delay_form == "model" and params.discretization != "current":
        out.append(f"observer.delay_form = 'model' with discretization "
                   f"'{params.discretization}': it was measured on 'current' (docs/adrc.md, "
                   "\"The model-based predictor\")")
    if params.delay_form == "model" and params.model_coulomb == 0.0 \
            and params.model_viscous == 0.0:
        out.append("observer.delay_form = 'model' with model_coulomb = model_viscous = 0: the "
                   "model is gravity alone, which does not reach twice the delay on test-1")
    return out


def _one_eps(params: Params) -> float:
    values = joint_values(params.eps)
    if len(values) != 1:
        raise ValueError(f"observer.eps: the linear analysis takes one ε, got {len(values)}")
    return values[0]


def discrete_linearization(d: ESODesign, gain: np.ndarray, pole: float,
                           label: str) -> ObserverLinearization:
    """z⁺ = P z + Q y + Γ u, ẑ = Hz z + Hy y (Hz = I − M C, Hy = M) for the ESO ``d``.

    Parameters
    ----------
    d : ESODesign
        The design (Φ, Γ and the discretization).
    gain : ndarray, shape (3,)
        The injection gain (``d.gain``, or the nonlinear ESO's slopes times it).
    pole : float
        The slowest error pole reported (z-plane).
    label : str
        The observer's name in titles.

    Returns
    -------
    ObserverLinearization
    """
    c = np.array([[1.0, 0.0, 0.0]])
    g = np.asarray(gain, dtype=float).reshape(3, 1)
    gam = d.gamma.reshape(3, 1)
    if d.discretization == "current":
        # z⁺ = Φ ẑ + Γ u with ẑ = z + Lc (y − z1)
        mgain = g
        pmat = d.phi @ (np.eye(3) - mgain @ c)
        qmat = d.phi @ mgain
    else:
        # z⁺ = F z + Γ u + L (y − z1), F = Φ (zoh) or I + Ts A (euler), L = Lp or Ts β
        mgain = np.zeros((3, 1))
        pmat = d.phi - g @ c
        qmat = g
    return ObserverLinearization(pmat, qmat, gam, np.eye(3) - mgain @ c, mgain, pole, d.eps,
                                 d.discretization, label)


def delayed_linearization(lin: ObserverLinearization, ts: float, b0: float, nd: int,
                          predictor: bool) -> ObserverLinearization:
    """``lin`` fed the input of ``nd`` samples ago, its estimate predicted ahead if asked.

    The state grows by the commands held, h = (u_{k−N}, …, u_{k−1}):
    z⁺ = P z + Q y + Γ h1, h⁺ = (h2, …, hN, u); the predictor's estimate is
    Ψᴺ ẑ + Σ_i Ψ^{N−1−i} Γx h_i with Ψ, Γx the exact held-input model (:func:`eso_predict`).

    Parameters
    ----------
    lin : ObserverLinearization
        The observer without delay (3 states).
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].
    nd : int
        Input delay N [samples] (0 gives ``lin``).
    predictor : bool
        The estimate predicted N samples ahead.

    Returns
    -------
    ObserverLinearization
        3 + N states.
    """
    if nd == 0:
        return lin
    n = lin.p.shape[0]
    m = n + nd
    pmat = np.zeros((m, m))
    pmat[:n, :n] = lin.p
    pmat[:n, n:n + 1] = lin.gamma
    for i in range(nd - 1):
        pmat[n + i, n + i + 1] = 1.0
    qmat = np.vstack([lin.q, np.zeros((nd, 1))])
    gam = np.zeros((m, 1))
    gam[-1, 0] = 1.0
    hz = np.hstack([lin.hz, np.zeros((3, nd))])
    hy = lin.hy
    if predictor:
        psi, gx = _zoh_matrices(ts, b0)
        psi = psi.copy()
        psi[2, :] = (0.0, 0.0, 1.0)
        pn = np.linalg.matrix_power(psi, nd)
        hz = np.hstack([pn @ lin.hz] + [
            (np.linalg.matrix_power(psi, nd - 1 - i) @ gx).reshape(3, 1) for i in range(nd)])
        hy = pn @ lin.hy
    return ObserverLinearization(pmat, qmat, gam, hz, hy, lin.pole, lin.eps,
                                 lin.discretization, lin.label)


def linearization(params: Params, ts: float, b0: float) -> ObserverLinearization:
    """The ESO as a linear system for ``analyze`` (exact: the ESO is linear).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table (one ε).
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].

    Returns
    -------
    ObserverLinearization
        Its design pole is the slowest error pole of the discretization and tuning; with an
        input delay N, 3 + N states (:func:`delayed_linearization`).
    """
    if params.delay_form == "model":
        from esoarm.scenario.errors import ScenarioError

        raise ScenarioError("observer.delay_form = 'model': the frequency-domain analysis has "
                            "no linear model of it (its friction model is nonlinear in θ̇); "
                            "analyze the same scenario with delay_form = 'predictor'")
    d = design_observer(_one_eps(params), ts, b0, params.discretization, params.tuning)
    pole = float(np.max(np.abs(d.poles)))
    lin = discrete_linearization(d, d.gain, pole, "ESO")
    return delayed_linearization(lin, ts, b0, params.input_delay,
                                 params.delay_form == "predictor")


class ExtendedStateObserver:
    """Stateful ESO stepped one sample at a time (real-time loop, replay, notebooks).

    Per sample: ``zhat = eso.estimate(y)`` gives the estimate for the
    controller, then ``eso.update(u)`` advances with the applied command.
    Both call the same plain functions as the simulators.

    Parameters
    ----------
    design : ESODesign
        From :func:`design_observer`.
    y0 : float
        First measurement [rad]; initial state z_0 = (y0, 0, 0) (the sampled-data loop).
    """

    __slots__ = ("_obs", "_y", "design", "z", "zhat")

    def __init__(self, design: ESODesign, y0: float) -> None:
        self.design = design
        self._obs = design.vector
        self.z: tuple[float, float, float] = (float(y0), 0.0, 0.0)
        self.zhat: tuple[float, float, float] = self.z
        self._y = float(y0)

    def estimate(self, y: float) -> tuple[float, float, float]:
        """Take measurement y_k [rad]; return ẑ_k = (θ̂, θ̇̂, f̂).

        Parameters
        ----------
        y : float
            Measured angle y_k [rad].

        Returns
        -------
        tuple of float
            ẑ_k = (θ̂ [rad], θ̇̂ [rad/s], f̂ [rad/s²]), also kept as :attr:`zhat`.
        """
        self._y = y
        z1, z2, z3 = self.z
        self.zhat = eso_estimate(z1, z2, z3, y, self._obs)
        return self.zhat

    def update(self, u: float) -> tuple[float, float, float]:
        """Advance to z_{k+1} with the control u_k [N·m] computed from ẑ_k.

        Parameters
        ----------
        u : float
            The applied (saturated) control u_k [N·m].

        Returns
        -------
        tuple of float
            z_{k+1}: angle [rad], rate [rad/s], total perturbation [rad/s²], also kept as
            :attr:`z`.
        """
        z1, z2, z3 = self.z
        h1, h2, h3 = self.zhat
        self.z = eso_advance(z1, z2, z3, h1, h2, h3, self._y, u, self._obs)
        return self.z
