"""The actuator between controller and plant: saturation, optional motor, transport delay.

Shared by every plant kind and every engine (reference, batch, the emulated
device and the real-time loop), so "what reaches the plant" is written once:

1. the controller's command is saturated to ±torque_limit (:func:`saturate`);
2. without a ``[motor]`` table the actuator is an ideal torque source: the
   plant is driven by the command itself.  With one, the host turns the
   torque into a PWM duty with the estimated rate (back-EMF compensation,
   :func:`esoarm.plants.motor.torque_to_duty`); the torque the host believes
   it applies, :func:`esoarm.plants.motor.duty_to_torque`, is what the
   observer is updated with and what is logged as ``u``; the plant is driven
   by the duty's rate-independent torque :func:`esoarm.plants.motor.source_torque`
   and the motor's back-EMF damping (N·Kt)²/R, which the actuator supplies
   (:func:`back_emf_damping`) to every plant kind that declares ``MOTOR = True``
   and that kind's design adds to its viscous friction.  A plant kind without
   ``MOTOR = True`` refuses a ``[motor]`` table (:func:`motor_refused`, from its
   ``check``);
   Without a motor, ``actuator.pwm_bits`` = b > 0 is a PWM drive of b bits, sign and
   magnitude (a direction pin and a duty, e.g. Arduino ``analogWrite``, b = 8): the torque
   is rounded to the nearest of the M = 2^b − 1 levels per sign, u_drive = L·rint(M·u/L)/M
   (L = torque_limit, round half to even, as the motor's duty); the host knows its duty, so
   the rounded torque is also what is logged and observed;
3. the drive is delayed by ``delay_samples`` (0 before the first command) and
   held over [t_k, t_{k+1}) (:func:`delayed_input`); the actuator lag, a plant
   state, is integrated by the plant kind.

The actuator vector ``a`` is (torque_limit, motor flag, motor block of
:class:`esoarm.plants.motor.MotorParams`, PWM levels M).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from esoarm._jit import jitable
from esoarm.contract import Vector, read_only
from esoarm.plants.motor import MotorParams, duty_to_torque, source_torque, torque_to_duty

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["FF_BINS", "SEES", "actuate", "actuate_with_table", "actuator_vector", "gated",
           "table_bins",
           "back_emf_damping", "delayed_input", "feedforward", "motor_of", "motor_refused",
           "saturate"]

LIMIT, MOTOR, MOTOR_BLOCK = 0, 1, 2
#: PWM levels per sign, 2^pwm_bits − 1 (0: an ideal torque source), after the motor block.
PWM_LEVELS = 6
#: What the observer is fed (``actuator.observer_sees``): 0.0 the applied (saturated)
#: command, 1.0 the controller's command before saturation (the paper's ESO).
SEES = 7
SEES_APPLIED, SEES_COMMANDED = 0.0, 1.0
#: The ESO's gate at an end stop (``actuator.stop_gate``): its band [rad] (0: none), then
#: the rig's lower and upper stop [rad] (``rig.end_stops``; ∓1e30 without stops).
GATE, GATE_LO, GATE_HI = 8, 9, 10
VECTOR_SIZE = 11
#: With a learned feedforward table (``controller.feedforward_map``): its number of bins N
#: at FF_BINS, then the N feedforward torques −I0·m_i [N·m] at θ_i = 2π i / N.
FF_BINS = 11


def motor_of(scn: Scenario) -> MotorParams | None:
    """The motor of the actuator: the scenario's ``[motor]`` table, or None (a torque source).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    MotorParams or None
        Supply [V], resistance [Ω], torque constant [N·m/A], gear ratio, PWM range, deadband.
    """
    return MotorParams.from_scenario(scn)


def back_emf_damping(scn: Scenario) -> float | None:
    """The motor's back-EMF damping at the joint, (N·Kt)²/R [N·m·s/rad], or None without one.

    What a plant kind with ``MOTOR = True`` adds to its viscous friction in its
    design, so that driving it with :func:`esoarm.plants.motor.source_torque`
    of the duty integrates the motor law τ = (N·Kt·Vs/R)·d − ((N·Kt)²/R)·ω.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    float or None
        (N·Kt)²/R [N·m·s/rad], None without a ``[motor]`` table.
    """
    motor = motor_of(scn)
    return None if motor is None else motor.damping


def motor_refused(scn: Scenario, kind: str) -> str | None:
    """The one-line refusal of a ``[motor]`` table by plant kind ``kind`` (None without one).

    For the ``check`` of a plant kind that does not declare ``MOTOR = True``: its
    design would not take the motor's back-EMF damping, and the host's back-EMF
    compensation would then drive the plant with torque nobody models.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.
    kind : str
        The plant kind's tag (``plant.kind``).

    Returns
    -------
    str or None
        The message naming the key, or None if the scenario has no ``[motor]`` table.
    """
    if scn.motor is None:
        return None
    return (f"key 'motor': plant.kind = '{kind}' does not model a motor (its design takes no "
            "back-EMF damping); remove the [motor] table (plant kinds with a motor: "
            "those declaring MOTOR = True, e.g. 'lever-arm', 'axis')")


def actuator_vector(scn: Scenario) -> np.ndarray:
    """(torque_limit, 1.0 with a motor else 0.0, motor block or zeros, PWM levels), read-only.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    ndarray
        The actuator vector ``a`` of :func:`actuate` (:data:`VECTOR_SIZE` values).
    """
    vec = np.zeros(VECTOR_SIZE)
    vec[LIMIT] = scn.actuator.torque_limit
    motor = motor_of(scn)
    if motor is not None:
        vec[MOTOR] = 1.0
        vec[MOTOR_BLOCK:PWM_LEVELS] = motor.block
    bits = getattr(scn.actuator, "pwm_bits", 0)
    if bits > 0:
        vec[PWM_LEVELS] = float(2**bits - 1)
    if getattr(scn.actuator, "observer_sees", "applied") == "commanded":
        vec[SEES] = SEES_COMMANDED
    stops = getattr(scn.rig, "end_stops", [])
    vec[GATE] = getattr(scn.actuator, "stop_gate", 0.0) if stops else 0.0
    vec[GATE_LO] = min(stops) if stops else -1e30
    vec[GATE_HI] = max(stops) if stops else 1e30
    table = getattr(scn.controller, "feedforward_map", None)
    if table:
        # −I0·m(θ): the map is in the units of ẑ3 [rad/s²], the nominal I0 = 1/b0 makes it
        # a torque (the FLC's u = I0 (α − β̂) with the map's part of β̂)
        i0 = scn.plant.inertia
        vec = np.concatenate([vec, [float(len(table))], [-i0 * m for m in table]])
    return read_only(vec)


@jitable
def table_bins(a: Vector) -> int:
    """The learned feedforward table's number of bins N in actuator vector ``a`` (0: none).

    Parameters
    ----------
    a : ndarray
        :func:`actuator_vector` (a vector of :data:`VECTOR_SIZE` values, or a table's
        zero-padded row, has none).

    Returns
    -------
    int
        N, the table's values being ``a[FF_BINS + 1 : FF_BINS + 1 + N]``.

    Examples
    --------
    >>> table_bins(np.zeros(VECTOR_SIZE)), table_bins(np.r_[np.zeros(VECTOR_SIZE), 2.0, 1, 2])
    (0, 2)
    """
    if len(a) <= FF_BINS:
        return 0
    return int(a[FF_BINS])


@jitable
def feedforward(angle: float, a: Vector) -> float:
    """The learned feedforward torque at angle θ̂ [N·m]: the table −I0·m linearly interpolated.

    The table's N values sit at θ_i = 2π i / N, i = 0 … N − 1, and wrap around
    (position-periodic); without a table (a vector of :data:`VECTOR_SIZE` values) 0.

    Parameters
    ----------
    angle : float
        Estimated arm angle ẑ1 [rad] (any value; taken modulo 2π).
    a : ndarray
        :func:`actuator_vector`.

    Returns
    -------
    float
        The feedforward torque [N·m], added to the drive (not to the command the observer is
        fed: the ESO then estimates the perturbation the table leaves).

    Examples
    --------
    >>> a = np.array([2.0, 0, 0, 0, 0, 0, 0, 0, 0, -1e30, 1e30, 4.0, 1.0, 2.0, 3.0, 4.0])
    >>> float(feedforward(0.0, a)), float(feedforward(np.pi / 4, a))
    (1.0, 1.5)
    """
    n = table_bins(a)
    if n == 0:  # no table (or one zero-padded away)
        return 0.0
    x = angle / (2.0 * np.pi) * n
    x = x - n * np.floor(x / n)  # in [0, n)
    i = int(np.floor(x))
    if i >= n:  # round-off at the top
        i = n - 1
    frac = x - i
    j = i + 1 if i + 1 < n else 0
    return float((1.0 - frac) * a[FF_BINS + 1 + i] + frac * a[FF_BINS + 1 + j])


@jitable
def saturate(u: float, limit: float) -> float:
    """Clip u to ±limit [N·m]; NaN passes through so faults stay visible.

    Parameters
    ----------
    u : float
        Torque command [N·m], positive in the direction of positive θ.
    limit : float
        Torque limit [N·m], ≥ 0.

    Returns
    -------
    float
        u clipped to [−limit, limit] [N·m] (NaN if u is NaN).

    Examples
    --------
    >>> saturate(3.0, 2.0), saturate(-3.0, 2.0), saturate(1.5, 2.0)
    (2.0, -2.0, 1.5)
    """
    if u > limit:
        return limit
    if u < -limit:
        return -limit
    return u


@jitable
def actuate(u: float, rate: float, a: Vector) -> tuple[float, float, float]:
    """The saturated command u [N·m] through the actuator.

    Parameters
    ----------
    u : float
        Saturated torque command [N·m].
    rate : float
        Estimated joint rate ẑ2 [rad/s] (for the motor's back-EMF compensation).
    a : ndarray
        :func:`actuator_vector`.

    Returns
    -------
    (u_host, drive, duty) : (float, float, float)
        The torque the host applies as far as it knows [N·m] (logged, fed to
        the observer), the torque driving the plant [N·m], and the PWM duty
        [counts] (NaN without a motor or a PWM resolution).
    """
    if a[MOTOR] == 0.0:
        if len(a) > PWM_LEVELS and a[PWM_LEVELS] > 0.0:  # a PWM drive without a motor model
            levels = a[PWM_LEVELS]
            duty = float(np.rint(u / a[LIMIT] * levels))
            torque = a[LIMIT] * duty / levels
            return torque, torque, duty
        return u, u, np.nan
    m = a[MOTOR_BLOCK:]
    duty = torque_to_duty(u, rate, m)
    return duty_to_torque(duty, rate, m), source_torque(duty, m), duty


@jitable
def gated(y: float, u: float, a: Vector) -> bool:
    """The ESO's b0·u term gated: the arm at an end stop and the command pushing into it.

    While the rig holds the arm at a stop, θ̈ = 0 whatever u: an ESO fed u estimates
    ẑ3 → −b0·u (the stop's reaction), which the FLC's −I0·ẑ3 turns into still more torque
    into the stop, and which it must unlearn when the arm leaves (a bump).  Fed 0 instead,
    ẑ3 stays with what acts besides the command.

    Parameters
    ----------
    y : float
        Measured angle y_k [rad].
    u : float
        The command the observer would be fed [N·m].
    a : ndarray
        :func:`actuator_vector` (the band and the stops).

    Returns
    -------
    bool
        True: feed the observer 0 this sample.

    Examples
    --------
    >>> a = np.array([2.0, 0, 0, 0, 0, 0, 0, 0, 0.01, -1.0, 1.0])
    >>> [bool(gated(y, u, a)) for y, u in ((0.995, 0.5), (0.995, -0.5), (0.5, 0.5))]
    [True, False, False]
    """
    if len(a) <= GATE_HI:  # an observer's own stepper: an actuator of its limit alone
        return False
    band = a[GATE]
    if band <= 0.0:
        return False
    return (y >= a[GATE_HI] - band and u > 0.0) or (y <= a[GATE_LO] + band and u < 0.0)


@jitable
def actuate_with_table(u: float, rate: float, angle: float,
                       a: Vector) -> tuple[float, float, float]:
    """:func:`actuate`, with a learned table's torque in the drive (not in the host's torque).

    The host's torque (what the observer is fed) is that of u alone; the drive and the duty
    are those of sat(u − I0·m(θ̂)): the table reaches the plant through the same actuator
    (with a motor, one duty for both), and the ESO estimates what the table leaves.
    Without a table it is :func:`actuate`.

    Parameters
    ----------
    u : float
        Saturated torque command [N·m].
    rate : float
        Estimated joint rate ẑ2 [rad/s] (the motor's back-EMF compensation).
    angle : float
        Estimated angle ẑ1 [rad] (the table's argument).
    a : ndarray
        :func:`actuator_vector`.

    Returns
    -------
    (u_host, drive, duty) : (float, float, float)
        As :func:`actuate`; drive and duty with the table.
    """
    u_host, drive, duty = actuate(u, rate, a)
    if table_bins(a) > 0:
        _, drive, duty = actuate(saturate(u + feedforward(angle, a), a[LIMIT]), rate, a)
    return u_host, drive, duty


@jitable
def delayed_input(hist: np.ndarray, k: int, delay: int, drive: np.ndarray,
                  applied: np.ndarray) -> None:
    """Record sample k's drive and select the input applied over [t_k, t_{k+1}).

    ``hist`` holds the drives of samples 0 … k (n per sample); ``applied``
    receives the drive of sample k − delay, or 0 before the first command.

    Parameters
    ----------
    hist : ndarray
        History of drives [N·m], at least (k + 1)·n long; written at ``hist[k*n:(k+1)*n]``.
    k : int
        Index of the current sample, ≥ 0.
    delay : int
        Transport delay [samples], ≥ 0.
    drive : ndarray, shape (n,)
        Drive of sample k per joint [N·m] (the actuator's torque to the plant).
    applied : ndarray, shape (n,)
        Output, overwritten: the drive held over [t_k, t_{k+1}) [N·m].
    """
    n = len(drive)
    for j in range(n):
        hist[k * n + j] = drive[j]
        applied[j] = hist[(k - delay) * n + j] if k >= delay else 0.0
