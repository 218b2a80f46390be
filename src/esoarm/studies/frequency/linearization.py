"""The sampled-data loop linearized at an operating angle, as discrete LTI systems.

The loop of a scenario is linearized at an operating angle θ0 and written as
discrete linear time-invariant systems at the sample period Ts, so that a
control engineer can read margins, sensitivities and bandwidths, and carry on
in python-control (:func:`to_control`).

Plant (sample-to-sample, exact)
    The rig's dynamics, linearized at θ = θ0, θ̇ = 0, with the true inertia
    I = inertia_scale · I0:

        I δθ̈ = δτ + gcoef · sin θ0 · δθ − c · δθ̇,      (G(θ) ≈ G(θ0) − gcoef sin θ0 δθ)

    gravity G(θ) = gcoef cos θ (eq. 4) becomes a spring about θ0 (gcoef =
    (m1 l1 − m2 l2) g).  Friction ``c`` depends on the ``friction`` choice,
    because the rig's Coulomb term Fc tanh(θ̇/vs) is not smooth at rest:

    - ``"viscous"`` (default): c = b, the Coulomb term excluded.  While the arm
      moves (|θ̇| ≫ vs) the Coulomb torque is a bounded input disturbance that
      the ESO estimates, not a damping; this is the least damped, conservative
      model.
    - ``"slope"``: c = b + (Fc + Fst)/vs, the slope of the friction curve
      (Fc + Fst e^{−(θ̇/vst)²}) tanh(θ̇/vs) at zero speed (small motions about
      rest; with the defaults c = 5.01 N·m·s/rad, a strongly damped arm).
    - ``"none"``: c = 0, a frictionless arm.

    The actuator lag T adds the state τ (τ̇ = (u − τ)/T); the command is held
    over each sample (zero-order hold) and delayed by ``delay_samples``·Ts;
    the plant is discretized exactly (matrix exponential), so its frequency
    response is that of the sampled-data loop at the samples.  Noise,
    quantization and the saturation ±torque_limit are left out (linear model).

Motor (a scenario's ``[motor]`` table, :mod:`esoarm.plants.motor`)
    The motor is a torque source (N·Kt·Vs/R)·d plus the back-EMF damping
    Dm = (N·Kt)²/R, and the host asks for the duty d = (u + Dm ẑ2)/(N·Kt·Vs/R)
    (back-EMF compensation with the estimated rate).  Its linear part is in
    the loop, as the simulators run it (:func:`esoarm.plants.actuator.actuate`):

    - the plant's damping is c + Dm (for every ``friction`` choice: the
      back-EMF is not friction), its input the motor's source torque;
    - the torque that drives the plant is u + Dm ẑ2 (the compensation), while
      the observer is updated with u, the torque the host believes it applies
      (equal to u but for the nonlinear parts below), so the controller's
      output row gains −Dm on ẑ2 and its state update keeps u.

    Left out (nonlinear): the driver's deadband and the host's
    pre-compensation of it, which cancel but for the PWM rounding; the PWM
    quantization to whole duty counts (a step of N·Kt·Vs/(R·(1 − δ)·pwm_max)
    at the arm); the supply-voltage saturation |d| ≤ 1 (|u + Dm ẑ2| ≤ N·Kt·Vs/R).

Controller (one discrete LTI system)
    The ESO of the scenario's discretization and the FLC, with the reference
    set to zero (deviation from the operating point), in the negative-feedback
    convention τ_k = −K(z) y_k (τ the torque that drives the plant):

        ẑ_k = (I − M C) z_k + M y_k              (M = Lc for "current", else 0)
        z_{k+1} = P z_k + Q y_k + Γ u_k           (the observer update)
        u_k = −I0 (k2 ẑ1 + k1 ẑ2 + β̂),  β̂ = ẑ3 ("eso") or −gcoef sin θ0 ẑ1/I0 ("model")
        τ_k = u_k + Dm ẑ2_k                       (Dm = 0 without a motor)

    The ESO is linear for every discretization, so this is exact for the
    controller; only the plant is linearized.  The nonlinear ESO (observer kind
    ``"nonlinear"``) injects fal(e, α, δ) of the innovation e, which is linear
    for |e| ≤ δ with slope δ^(α−1): its 2nd and 3rd gains are scaled by that
    slope, which is exact for innovations within ±δ (larger ones are outside a
    linear analysis).

Supported: the lever-arm plant kind with the FLC controller kind and every
observer kind that gives its linear model (``linearization``, see
:mod:`esoarm.contract`); other kinds are refused (:class:`~esoarm.scenario.ScenarioError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq

from esoarm.contract import ObserverLinearization
from esoarm.kinds import can, hook, kinds_of
from esoarm.plants.actuator import motor_of
from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import Scenario, ScenarioError, load_scenario

__all__ = [
    "FRICTION_MODELS",
    "ControlLoop",
    "LinearLoop",
    "closed_loop_matrix",
    "closed_loop_radius",
    "controller_matrices",
    "critical_delay",
    "eso_closed_forms",
    "freqresp",
    "linearize",
    "loop_scenario",
    "motor_damping",
    "observer_model",
    "observer_system",
    "perturbation_estimate",
    "sampled_plant",
    "to_control",
]

FRICTION_MODELS = ("viscous", "slope", "none")

Matrices = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _require_control() -> Any:
    try:
        import control
    except ImportError:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "the frequency-domain analysis needs python-control: "
            "pip install 'esoarm[analyze]'") from None
    return control


# ---------------------------------------------------------------------------
# the linear model as plain matrices


def _load(scenario: Scenario | str | Path, overrides: dict | list[str] | None) -> Scenario:
    if isinstance(scenario, Scenario) and not overrides:
        return loop_scenario(scenario)
    return loop_scenario(load_scenario(scenario, overrides))


def loop_scenario(scn: Scenario) -> Scenario:
    """The scenario whose loop this linearization models: ``scn`` itself, or, for a
    controller kind without ``FLC_LAW`` that declares ``flc_equivalent`` (the linear ADRC
    forms adrc-tf and adrc-error), the FLC with the linear ESO that closes the same
    feedback loop y → u (:func:`esoarm.controllers.common.flc_equivalent`).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    Scenario
        ``scn``, or its equivalent (the scenario's plant, rig, sensor and actuator kept).
    """
    if can(scn, "FLC_LAW"):
        return scn
    equivalent = hook(kinds_of(scn)[2], "flc_equivalent")
    return scn if equivalent is None else scn.with_overrides(equivalent(scn.controller))


def motor_damping(scn: Scenario) -> float:
    """The motor's back-EMF damping (N·Kt)²/R at the arm [N·m·s/rad]; 0 without ``[motor]``.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario with the FLC.

    Returns
    -------
    float
    """
    motor = motor_of(scn)
    return 0.0 if motor is None else motor.damping


def continuous_plant(scn: Scenario, theta0: float, friction: str = "viscous"
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rig linearized at (θ0, 0): (A, B, C), input the applied torque [N·m], output θ [rad].

    States (δθ, δθ̇) or, with an actuator lag T > 0, (δθ, δθ̇, δτ).  With a
    ``[motor]`` table the back-EMF damping :func:`motor_damping` is added to the
    friction's, and the input is the motor's source torque.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario with the FLC.
    theta0 : float
        Operating angle [rad].
    friction : {"viscous", "slope", "none"}
        Friction in the linear plant (module docstring).

    Returns
    -------
    tuple of ndarray
        (A, B, C).

    Raises
    ------
    ValueError
        An unknown friction model.
    """
    if friction not in FRICTION_MODELS:
        raise ValueError(f"friction must be one of {', '.join(FRICTION_MODELS)}; got {friction!r}")
    p, r = scn.plant, scn.rig
    inertia = r.inertia_scale * p.inertia
    gcoef = gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g)
    spring = gcoef * math.sin(theta0)  # −∂G/∂θ at θ0 [N·m/rad]
    damping = {"viscous": r.viscous_friction,
               "slope": r.viscous_friction
               + (r.coulomb_friction + r.stiction) / r.friction_velocity,
               "none": 0.0}[friction] + motor_damping(scn)
    lag = scn.actuator.lag
    if lag > 0:
        a = np.array([[0.0, 1.0, 0.0],
                      [spring / inertia, -damping / inertia, 1.0 / inertia],
                      [0.0, 0.0, -1.0 / lag]])
        b = np.array([[0.0], [0.0], [1.0 / lag]])
    else:
        a = np.array([[0.0, 1.0], [spring / inertia, -damping / inertia]])
        b = np.array([[0.0], [1.0 / inertia]])
    c = np.zeros((1, a.shape[0]))
    c[0, 0] = 1.0
    return a, b, c


def _zoh(a: np.ndarray, b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{At}, ∫0^t e^{As} ds B) from one block matrix exponential (Van Loan)."""
    n, m = b.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n] = a * t
    block[:n, n:] = b * t
    e = expm(block)
    return e[:n, :n], e[:n, n:]


def sampled_plant(scn: Scenario, theta0: float, friction: str = "viscous",
                  extra_delay: float = 0.0) -> Matrices:
    """The linearized rig seen from the controller: ZOH, delay, sampling at Ts.

    The input u_k [N·m] is delayed by τ = delay_samples·Ts + ``extra_delay``
    [s] (any τ ≥ 0, not only whole samples: the modified z-transform), held
    over each sample, and θ is sampled at t_k.  With τ = m Ts + δ, 0 ≤ δ < Ts:

        x_{k+1} = Φ x_k + Γ0 u_{k−m} + Γ1 u_{k−m−1},
        Φ = e^{A Ts},  Γ0 = ∫0^{Ts−δ} e^{As} ds B,  Γ1 = e^{A (Ts−δ)} ∫0^δ e^{As} ds B,

    the past inputs held in a shift register.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario with the FLC.
    theta0 : float
        Operating angle [rad].
    friction : {"viscous", "slope", "none"}
        Friction in the linear plant (module docstring).
    extra_delay : float
        Input delay [s] added to ``actuator.delay_samples``·Ts.

    Returns
    -------
    Matrices
        (A, B, C, D) with D = 0.

    Raises
    ------
    ValueError
        A delay that is negative or not finite.
    """
    ts = scn.sample_time
    a, b, c = continuous_plant(scn, theta0, friction)
    tau = scn.actuator.delay_samples * ts + float(extra_delay)
    if not (tau >= 0 and math.isfinite(tau)):
        raise ValueError(f"the input delay must be finite and >= 0, got {tau!r} s")
    m = int(math.floor(tau / ts + 1e-12))
    delta = tau - m * ts
    if delta < 1e-12 * ts:
        delta = 0.0
    phi, _ = _zoh(a, b, ts)
    if delta == 0.0:
        _, gam0 = _zoh(a, b, ts)
        gam1 = None
    else:
        ea, gam0 = _zoh(a, b, ts - delta)
        _, g_delta = _zoh(a, b, delta)
        gam1 = ea @ g_delta
    n = a.shape[0]
    nreg = m + (1 if gam1 is not None else 0)  # u_{k−1} … u_{k−nreg}
    size = n + nreg
    ad = np.zeros((size, size))
    bd = np.zeros((size, 1))
    ad[:n, :n] = phi
    # shift register r_i = u_{k−i}, i = 1 … nreg
    if nreg:
        bd[n, 0] = 1.0
        for i in range(1, nreg):
            ad[n + i, n + i - 1] = 1.0

    def feed(gain: np.ndarray, lag: int) -> None:  # the plant takes u_{k−lag}
        if lag == 0:
            bd[:n] += gain
        else:
            ad[:n, n + lag - 1:n + lag] += gain

    feed(gam0, m)
    if gam1 is not None:
        feed(gam1, m + 1)
    cd = np.zeros((1, size))
    cd[:, :n] = c
    return ad, bd, cd, np.zeros((1, 1))


def _reduced_gains(scn: Scenario, theta0: float) -> np.ndarray:
    """Row Kr with δu = −Kr δẑ: the FLC (eq. 14-16) about θ0 with zero reference."""
    p, ctl = scn.plant, scn.controller
    i0 = p.inertia
    if ctl.compensation == "eso":
        return i0 * np.array([ctl.k2, ctl.k1, 1.0])
    gcoef = gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g)
    # β̂ = −G(ẑ1)/I0  →  δβ̂ = gcoef sin θ0 δẑ1 / I0
    return i0 * np.array([ctl.k2 + gcoef * math.sin(theta0) / i0, ctl.k1, 0.0])


def check_supported(scn: Scenario) -> None:
    """Refuse, in one line, a scenario whose kinds this linearization does not model.

    Parameters
    ----------
    scn : Scenario
        A scenario.

    Raises
    ------
    ScenarioError
        One line naming the key whose kind is not modelled.
    """
    if not can(scn, "RIG"):  # what the plant kind declares
        raise ScenarioError(
            f"plant.kind: the frequency-domain analysis models the lever arm (one joint), not "
            f"'{scn.plant.kind}'; simulate, sweep and tune run it")
    scn = loop_scenario(scn)  # a linear ADRC form: its FLC equivalent
    if not can(scn, "FLC_LAW"):  # what the controller kind declares
        raise ScenarioError(
            f"controller.kind: the frequency-domain analysis models the feedback-linearizing "
            f"law of eq. 14-16 (a controller kind with FLC_LAW or flc_equivalent), not "
            f"'{scn.controller.kind}'; "
            "simulate, sweep and tune run it")
    observer_linearization(scn)  # refuses an observer kind without one


def observer_linearization(scn: Scenario) -> ObserverLinearization:
    """The observer kind's linear model at the scenario's Ts (its ``linearization``).

    Raises
    ------
    ScenarioError
        The kind declares none (not modelled): one line naming ``observer.kind``.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    ObserverLinearization
        (P, Q, Γ, Hz, Hy) of the kind at the scenario's Ts.
    """
    kind = kinds_of(scn).observer
    lin = hook(kind, "linearization")
    if lin is None:
        raise ScenarioError(
            f"observer.kind: the frequency-domain analysis has no linear model of observer "
            f"kind '{kind.KIND}' (the kind declares none); simulate, sweep and tune run it")
    model: ObserverLinearization = lin(scn.observer, scn.sample_time, 1.0 / scn.plant.inertia)
    return model


def observer_matrices(scn: Scenario) -> tuple[np.ndarray, ...]:
    """A 3-state observer of the scenario as z⁺ = P z + Q y + Γ u, ẑ = (I − M C) z + M y.

    From the observer kind (:func:`observer_linearization`); for the nonlinear ESO, the loop
    for innovations |y − z1| ≤ δ (fal's linear zone).  Any kind: :func:`observer_model`.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    tuple of ndarray
        (P, Q, Γ, M), shapes (3,3), (3,1), (3,1), (3,1).
    """
    lin = observer_linearization(scn)
    return lin.p, lin.q, lin.gamma, lin.hy


def observer_model(scn: Scenario) -> tuple[np.ndarray, ...]:
    """Any observer kind as z⁺ = P z + Q y + Γ u, ẑ = Hz z + Hy y (one joint).

    The kind's ``linearization`` (:func:`observer_linearization`; the ESOs: Hz = I − M C,
    Hy = M).

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    tuple of ndarray
        (P, Q, Γ, Hz, Hy); Hz has 3 rows.
    """
    lin = observer_linearization(scn)
    return lin.p, lin.q, lin.gamma, lin.hz, lin.hy


def observer_system(scn: Scenario) -> Matrices:
    """The observer alone: inputs (y [rad], u [N·m]), outputs ẑ = (ẑ1, ẑ2, ẑ3).

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    Matrices
        (A, B, C, D) of the observer.
    """
    pmat, qmat, gam, hz, hy = observer_model(scn)
    return (pmat, np.hstack([qmat, gam]), hz, np.hstack([hy, np.zeros((3, 1))]))


def controller_matrices(scn: Scenario, theta0: float) -> Matrices:
    """ESO + FLC (+ the motor's back-EMF compensation) as K(z): input y [rad], output −τ [N·m].

    τ = u + Dm ẑ2 drives the plant (τ = u without a motor); the observer is
    updated with u (module docstring).

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario with the FLC.
    theta0 : float
        Operating angle [rad].

    Returns
    -------
    Matrices
        (A, B, C, D) of K(z).
    """
    pmat, qmat, gam, zhat_z, zhat_y = observer_model(scn)  # ẑ = zhat_z z + zhat_y y
    kr = _reduced_gains(scn, theta0).reshape(1, 3)
    ck = kr @ zhat_z
    dk = kr @ zhat_y
    # u = −(ck z + dk y) updates the observer; −τ = −u − Dm ẑ2 is the output
    ko = kr - motor_damping(scn) * np.array([[0.0, 1.0, 0.0]])
    return pmat - gam @ ck, qmat - gam @ dk, ko @ zhat_z, ko @ zhat_y


def _series(first: Matrices, second: Matrices) -> Matrices:
    """second ∘ first for SISO state-space systems (states: first, then second)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    n1, n2 = a1.shape[0], a2.shape[0]
    a = np.zeros((n1 + n2, n1 + n2))
    a[:n1, :n1] = a1
    a[n1:, :n1] = b2 @ c1
    a[n1:, n1:] = a2
    b = np.vstack([b1, b2 @ d1])
    c = np.hstack([d2 @ c1, c2])
    return a, b, c, d2 @ d1


def closed_loop_matrix(plant: Matrices, controller: Matrices, gain: float = 1.0) -> np.ndarray:
    """State matrix of the loop u = −gain · K y closed around the plant (D_plant = 0).

    Parameters
    ----------
    plant : Matrices
        The sampled plant (A, B, C, D), input u [N·m], output θ [rad].
    controller : Matrices
        K(z), input y [rad], output −τ [N·m].
    gain : float
        The loop gain the controller is scaled by.

    Returns
    -------
    ndarray
        The closed loop's state matrix (plant states first).

    Raises
    ------
    ValueError
        A plant with a direct feedthrough.
    """
    ap, bp, cp, dp = plant
    ak, bk, ck, dk = controller
    if np.any(dp):
        raise ValueError("the plant must be strictly proper")
    n_p, n_k = ap.shape[0], ak.shape[0]
    a = np.zeros((n_p + n_k, n_p + n_k))
    a[:n_p, :n_p] = ap - gain * bp @ dk @ cp
    a[:n_p, n_p:] = -gain * bp @ ck
    a[n_p:, :n_p] = bk @ cp
    a[n_p:, n_p:] = ak
    return a


def closed_loop_radius(plant: Matrices, controller: Matrices, gain: float = 1.0) -> float:
    """Spectral radius of the closed loop (< 1: stable, = 1: marginally stable).

    Parameters
    ----------
    plant : Matrices
        The sampled plant (A, B, C, D), input u [N·m], output θ [rad].
    controller : Matrices
        K(z), input y [rad], output −τ [N·m].
    gain : float
        The loop gain the controller is scaled by.

    Returns
    -------
    float
    """
    return float(np.max(np.abs(np.linalg.eigvals(closed_loop_matrix(plant, controller, gain)))))


@dataclass(frozen=True)
class LinearLoop:
    """The linearized sampled-data loop as plain matrices (A, B, C, D), dt = Ts.

    Attributes
    ----------
    plant : tuple
        τ_k [N·m] → θ_k [rad] (ZOH, lag, delay; τ = u without a motor).
    controller : tuple
        y_k [rad] → −τ_k [N·m] (negative-feedback convention).
    loop : tuple
        Controller after plant: the loop broken at the plant input.
    observer : tuple
        (y_k, u_k) → ẑ_k.
    ts, theta0 : float
        Sample period [s], operating angle [rad].
    friction : str
        Friction model of the linearization (module docstring).
    motor_damping : float
        Back-EMF damping (N·Kt)²/R in the loop [N·m·s/rad]; 0 without a motor.
    """

    plant: Matrices
    controller: Matrices
    loop: Matrices
    observer: Matrices
    ts: float
    theta0: float
    friction: str
    motor_damping: float = 0.0

    def response(self, which: str, w: np.ndarray) -> np.ndarray:
        """Frequency response of ``plant``, ``controller`` or ``loop`` at w [rad/s].

        Parameters
        ----------
        which : {"plant", "controller", "loop"}
            The system.
        w : ndarray
            Frequencies [rad/s].

        Returns
        -------
        ndarray of complex
            The response at z = e^{jωTs}.
        """
        return freqresp(getattr(self, which), np.exp(1j * np.asarray(w) * self.ts))


def linearize(scenario: Scenario | str | Path, overrides: dict | list[str] | None = None, *,
              theta0: float | None = None, friction: str = "viscous") -> LinearLoop:
    """The loop of a scenario as matrices; see the module docstring.

    Parameters
    ----------
    scenario : Scenario, str or Path
        A scenario, a built-in name or a TOML file.
    overrides : dict or list of str, optional
        Overrides of its keys.
    theta0 : float, optional
        Operating angle [rad]; default ``rig.theta0``.
    friction : {"viscous", "slope", "none"}
        Friction in the linear plant (module docstring).

    Returns
    -------
    LinearLoop
        The sampled plant, the controller, the loop and the observer as matrices.
    """
    scn = _load(scenario, overrides)
    check_supported(scn)
    th = scn.rig.theta0 if theta0 is None else float(theta0)
    plant = sampled_plant(scn, th, friction)
    ctl = controller_matrices(scn, th)
    return LinearLoop(plant, ctl, _series(plant, ctl), observer_system(scn), scn.sample_time,
                      th, friction, motor_damping(scn))


def freqresp(sys: Matrices, z: np.ndarray) -> np.ndarray:
    """C (zI − A)⁻¹ B + D at the points z (first input, first output).

    Parameters
    ----------
    sys : Matrices
        (A, B, C, D) of a discrete system.
    z : ndarray of complex
        The points.

    Returns
    -------
    ndarray of complex
        The response, shaped like ``z``.
    """
    a, b, c, d = sys
    z = np.atleast_1d(np.asarray(z, dtype=complex))
    n = a.shape[0]
    # one batched solve: (z_i I − A) x_i = B for every point at once
    mats = z.reshape(-1, 1, 1) * np.eye(n) - a
    rhs = np.broadcast_to(b[:, :1].astype(complex), (z.size, n, 1))
    x = np.linalg.solve(mats, rhs)[..., 0]
    return (x @ c[0] + d[0, 0]).reshape(z.shape)


# ---------------------------------------------------------------------------
# python-control objects


@dataclass(frozen=True)
class ControlLoop:
    """The loop as python-control ``StateSpace`` systems (discrete, dt = Ts).

    Attributes
    ----------
    plant : control.StateSpace
        u [N·m] → θ [rad]; with a ``[motor]`` the input is the motor's source
        torque τ = u + (N·Kt)²/R·ẑ2 and the back-EMF damping is in the plant.
    controller : control.StateSpace
        y [rad] → −u [N·m]: the ESO + FLC with the negative-feedback sign, u = −K y
        (with a motor, −τ: the host's back-EMF compensation included).
    loop : control.StateSpace
        ``controller * plant``, broken at the plant input; ``control.feedback(loop, 1)``
        is the closed loop (complementary sensitivity at the plant input).
    observer : control.StateSpace
        Inputs (y, u), outputs (ẑ1, ẑ2, ẑ3).
    theta0 : float
        Operating angle [rad].
    friction : str
    """

    plant: Any
    controller: Any
    loop: Any
    observer: Any
    theta0: float
    friction: str


def to_control(scenario: Scenario | str | Path = "test-1",
               overrides: dict | list[str] | None = None, *, theta0: float | None = None,
               friction: str = "viscous") -> ControlLoop:
    """The linearized loop as python-control systems (needs ``esoarm[analyze]``).

    Example
    -------
    >>> import control
    >>> from esoarm.analysis import to_control
    >>> sys = to_control("test-1", {"observer.eps": 0.05})
    >>> gm, pm, *_ = control.stability_margins(sys.loop)
    >>> cl = control.feedback(sys.loop, 1)          # closed loop at the plant input
    >>> bool(max(abs(cl.poles())) < 1)
    True

    Parameters
    ----------
    scenario, overrides, theta0, friction
        As for :func:`linearize`.

    Returns
    -------
    ControlLoop
        The plant, the controller, the loop and the observer as ``control.StateSpace``.
    """
    control = _require_control()
    lin = linearize(scenario, overrides, theta0=theta0, friction=friction)
    ts = lin.ts

    def ss(m: Matrices, inputs: Any = None, outputs: Any = None, name: str = "") -> Any:
        return control.ss(*m, ts, inputs=inputs, outputs=outputs, name=name)

    return ControlLoop(
        plant=ss(lin.plant, "u", "theta", "plant"),
        controller=ss(lin.controller, "y", "-u", "controller"),
        loop=ss(lin.loop, "u", "-u", "loop"),
        observer=ss(lin.observer, ["y", "u"], ["z1", "z2", "z3"], "eso"),
        theta0=lin.theta0,
        friction=lin.friction,
    )


def perturbation_estimate(scn: Scenario) -> Matrices:
    """The ESO's perturbation estimate: f [rad/s², held over each sample] → ẑ3 [rad/s²].

    f drives the sampled double integrator θ̈ = f (u = 0); Theorem 1's
    continuous ESO gives ẑ3/f = (1/ε)³/(s + 1/ε)³.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    Matrices
        (A, B, C, D) from f to ẑ3.
    """
    ts = scn.sample_time
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    phi, gam = _zoh(a, np.array([[0.0], [1.0]]), ts)
    integrator = (phi, gam, np.array([[1.0, 0.0]]), np.zeros((1, 1)))
    oa, ob, oc, od = observer_system(scn)
    z3_of_y = (oa, ob[:, :1], oc[2:3], od[2:3, :1])
    return _series(integrator, z3_of_y)


def eso_closed_forms(eps: float, b0: float, s: np.ndarray) -> dict[str, np.ndarray]:
    """Theorem 1's continuous ESO transfer functions at s [1/s], a = 1/ε, D = (s + a)³.

    ``zi_y``: ẑi/y, ``zi_u``: ẑi/u (u [N·m]), ``f``: ẑ3/f = a³/D::

        ẑ1 = [(3a s² + 3a² s + a³) y + b0 s u] / D
        ẑ2 = [(3a² s² + a³ s) y + b0 (s² + 3a s) u] / D
        ẑ3 = a³ (s² y − b0 u) / D

    Parameters
    ----------
    eps : float
        ε [s].
    b0 : float
        The input gain b0 [1/(kg·m²)].
    s : ndarray of complex
        The points [1/s].

    Returns
    -------
    dict of str to ndarray
        The transfer functions above by name, each shaped like ``s``.
    """
    a = 1.0 / eps
    s = np.asarray(s, dtype=complex)
    den = (s + a) ** 3
    return {
        "z1_y": (3 * a * s**2 + 3 * a**2 * s + a**3) / den, "z1_u": b0 * s / den,
        "z2_y": (3 * a**2 * s**2 + a**3 * s) / den, "z2_u": b0 * (s**2 + 3 * a * s) / den,
        "z3_y": a**3 * s**2 / den, "z3_u": -(a**3) * b0 / den,
        "f": a**3 / den,
    }


def critical_delay(scn: Scenario, theta0: float, friction: str = "viscous",
                   upper: float | None = None, tol: float = 1e-7) -> float:
    """Smallest extra input delay [s] that makes the sampled-data loop marginally stable.

    A direct test, independent of frequency responses: the plant with an
    extra (fractional) delay is rediscretized exactly (:func:`sampled_plant`)
    and the closed loop's spectral radius is bisected to 1.  ``nan`` if the
    loop is unstable without extra delay or still stable at ``upper``
    (default 2 s).

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario with the FLC.
    theta0 : float
        Operating angle [rad].
    friction : {"viscous", "slope", "none"}
        Friction in the linear plant (module docstring).
    upper : float, optional
        The largest delay tried [s] (default 2 s).
    tol : float
        The bisection's tolerance [s].

    Returns
    -------
    float
        The delay margin [s], or nan (see above).
    """
    ctl = controller_matrices(scn, theta0)

    def radius(tau: float) -> float:
        return closed_loop_radius(sampled_plant(scn, theta0, friction, tau), ctl) - 1.0

    if radius(0.0) >= 0:
        return math.nan
    hi = 2.0 if upper is None else upper
    grid = np.linspace(0.0, hi, 401)
    prev = 0.0
    for x in grid[1:]:
        if radius(x) >= 0:
            return float(brentq(radius, prev, x, xtol=tol))
        prev = x
    return math.nan
