"""Plant kind ``"lever-arm"``: the paper's robotic lever arm and its digital twin.

    θ̈ = (τ − G(θ) − F(θ̇)) / I + d(t),     I = inertia_scale · I0
    F(θ̇) = (Fc + Fst exp(−(θ̇/vst)²)) tanh(θ̇/vs) + b θ̇      (Stribeck friction)
    τ̇ = (u_applied − τ) / T      (actuator lag T > 0; τ = u_applied when T = 0)
    d(t) = amplitude · sin(frequency · t)                  (paper eq. 6)
    τ_cog(θ) = A cos(n θ + φ)      (``rig.cogging``: cogging, gear eccentricity; added to τ)

Fst (``rig.stiction``, default 0) is the breakaway torque above Coulomb
friction, decaying over the Stribeck velocity vst; with Fst = 0 the friction is
exactly Fc tanh(θ̇/vs) + b θ̇ (bit for bit: Fc + 0·exp(…) = Fc).  tanh, exp
and the cos of G(θ) are :mod:`esoarm.plants.elementary`'s (plain arithmetic,
the same bits in every engine, vectorizable across a block of runs).

integrated with classical RK4 at a fixed step h, d evaluated at each stage
time.  The scalar functions take the rig parameters packed in one float vector
(:attr:`RigParams.vector`) so compiled batch kernels can hold one row per run.

As a kind (see :mod:`esoarm.contract`): :class:`Params` is the ``[plant]``
table (the nominal model of paper Table I, known to the controller),
:func:`design` builds the true rig from ``[plant]``, ``[rig]``, ``[actuator]``
and ``[motor]`` (one joint, state x = (θ, θ̇, τ)), and :func:`advance` and
:func:`acceleration` are the step functions every engine calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import PlantDesign, Vector, read_only
from esoarm.plants.actuator import back_emf_damping
from esoarm.plants.backlash import gear_torque
from esoarm.plants.elementary import cos, exp_neg, tanh
from esoarm.plants.model import gravity_coefficient, gravity_torque, input_gain

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["BACKLASH_MODEL", "CODE", "FAST", "JIT", "KIND", "MOTOR", "Params", "RIG", "RigParams",
           "acceleration", "advance", "geared_advance", "geared_derivative_at",
           "advance_block", "design", "observer_input", "rig_acceleration", "rig_advance",
           "rig_derivative", "rig_rk4_step"]

KIND = "lever-arm"
CODE = 0
JIT = True
#: The fast engine's C kernel models this plant.
FAST = True
#: Driven by the actuator's motor when the scenario has a ``[motor]`` table (its back-EMF
#: damping, :func:`esoarm.plants.actuator.back_emf_damping`, joins the viscous friction).
MOTOR = True
#: The one-joint rig of the serial protocol (run, emulate, excite, identify, analyze).
RIG = True
#: Models gear backlash (``rig.backlash_deg``, :mod:`esoarm.plants.backlash`).
BACKLASH_MODEL = True
#: Models a position-periodic torque (``rig.cogging``, :func:`cogging_torque`).
COGGING_MODEL = True
#: Models hard end stops (``rig.end_stops``, :func:`stopped_advance`).
END_STOPS_MODEL = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "lever_arm.c"


class Params(Section):
    """``[plant]``: the nominal lever-arm model known to the controller (paper Table I)."""

    kind: Literal["lever-arm"] = Field(
        "lever-arm", description='plant kind: "lever-arm" (the paper\'s rig, one joint)')
    m1: float = Field(0.5, gt=0, description="lumped mass 1", json_schema_extra=unit("kg"))
    m2: float = Field(0.55, gt=0, description="lumped mass 2", json_schema_extra=unit("kg"))
    l1: float = Field(0.15, gt=0, description="length of arm 1", json_schema_extra=unit("m"))
    l2: float = Field(0.14, gt=0, description="length of arm 2", json_schema_extra=unit("m"))
    inertia: float = Field(
        0.0225, gt=0, description="moment of inertia I0", json_schema_extra=unit("kg·m²")
    )
    g: float = Field(9.81, ge=0, description="gravity", json_schema_extra=unit("m/s²"))

INERTIA, GCOEF, FC, VS, VISC, DAMP, DFREQ, LAG, FST, VST = range(10)
#: Gear backlash (:mod:`esoarm.plants.backlash`): half-play α [rad], motor-side inertia Jm
#: [kg·m²], contact stiffness k [N·m/rad] and damping c [N·m·s/rad]; α = 0: a rigid gear.
BACKLASH, JM, KGEAR, CGEAR = range(10, 14)
#: Position-periodic torque τ_cog = A cos(n θ + φ) (``rig.cogging``): amplitude A [N·m],
#: periods per revolution n, phase φ [rad]; A = 0: none.
COG_AMP, COG_PERIODS, COG_PHASE = range(14, 17)
#: Hard end stops (``rig.end_stops``): lower and upper angle [rad]; only in a vector with
#: stops (then the cogging entries are there too, A = 0 for none).
STOP_LO, STOP_HI = 17, 18
VECTOR_SIZE = 19

#: Runs per vector in :func:`advance_block` (8 doubles: AVX-512; a multiple of AVX2's 4).
LANES = 8


@jitable
def disturbance(t: float, rig: Vector) -> float:
    """External disturbance d(t) = amplitude · sin(frequency · t) [rad/s²] (eq. 6).

    Parameters
    ----------
    t : float
        Time [s].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    float
        d(t) [rad/s²], added to θ̈.
    """
    return rig[DAMP] * math.sin(rig[DFREQ] * t)


@jitable
def cogging_torque(theta: float, amplitude: float, periods: float, phase: float) -> float:
    """Position-periodic torque on the arm τ_cog = A cos(n θ + φ) [N·m].

    Cogging of a permanent-magnet motor, gear eccentricity or a gravity-model error:
    a torque that repeats n times per revolution of the arm.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad].
    amplitude : float
        A [N·m], positive along increasing θ at n θ + φ = 0.
    periods : float
        n, periods per revolution [1].
    phase : float
        φ [rad].

    Returns
    -------
    float
        τ_cog [N·m] (the cos of :mod:`esoarm.plants.elementary`: same bits in every engine).

    Examples
    --------
    >>> float(cogging_torque(0.0, 0.1, 6.0, 0.0))
    0.1
    """
    return amplitude * cos(periods * theta + phase)


@jitable
def rig_acceleration_at(theta: float, omega: float, tau: float, d: float,
                        rig: Vector) -> float:
    """True angular acceleration θ̈ [rad/s²] given the disturbance value d = d(t) [rad/s²].

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Torque acting on the arm [N·m] (already lagged, see :func:`applied_torque`).
    d : float
        Disturbance d(t) [rad/s²].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    float
        θ̈ = (τ − G(θ) − F(θ̇))/I + d [rad/s²].
    """
    coulomb = rig[FC]
    if len(rig) > FST:  # a rig given without its Stribeck entries has Fst = 0 (see advance_block)
        # with Fst = 0 this is Fc bit for bit (Fc + 0·e^(−x²) is Fc)
        x = omega / rig[VST]
        coulomb = rig[FC] + rig[FST] * exp_neg(x * x)
    friction = coulomb * tanh(omega / rig[VS]) + rig[VISC] * omega
    torque = tau
    if len(rig) > COG_PHASE:  # a rig given with its cogging entries (see advance)
        torque = tau + cogging_torque(theta, rig[COG_AMP], rig[COG_PERIODS], rig[COG_PHASE])
    return (torque - gravity_torque(theta, rig[GCOEF]) - friction) / rig[INERTIA] + d


@jitable
def rig_acceleration(theta: float, omega: float, tau: float, t: float, rig: Vector) -> float:
    """True angular acceleration θ̈ [rad/s²] at angle θ, rate θ̇, torque τ, time t.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Torque acting on the arm [N·m].
    t : float
        Time [s] (for d(t)).
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    float
        θ̈ [rad/s²].

    Examples
    --------
    >>> rig = RigParams(0.02, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0).vector
    >>> float(rig_acceleration(0.0, 0.0, 0.1, 0.0, rig))
    5.0
    """
    return rig_acceleration_at(theta, omega, tau, disturbance(t, rig), rig)


@jitable
def rig_derivative_at(theta: float, omega: float, tau: float, u: float, d: float,
                      rig: Vector) -> tuple[float, float, float]:
    """Time derivative of the rig state (θ, θ̇, τ) under the input u [N·m], d(t) = d given.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Actuator lag state τ [N·m] (the torque on the arm when T > 0; unchanged when T = 0).
    u : float
        Applied input [N·m] (the lag's input when T > 0, else the torque itself).
    d : float
        Disturbance d(t) [rad/s²].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    (dtheta, domega, dtau) : (float, float, float)
        θ̇ [rad/s], θ̈ [rad/s²], τ̇ [N·m/s] (0 when T = 0).
    """
    lag = rig[LAG]
    lagged = lag > 0.0
    # selects, not branches: a compiled block of runs stays one vector loop
    torque = tau if lagged else u
    dtau = (u - tau) / lag if lagged else 0.0
    return omega, rig_acceleration_at(theta, omega, torque, d, rig), dtau


@jitable
def rig_derivative(theta: float, omega: float, tau: float, u: float, t: float,
                   rig: Vector) -> tuple[float, float, float]:
    """Time derivative of the rig state (θ, θ̇, τ) under the applied input u [N·m].

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Actuator lag state τ [N·m] (the torque on the arm when T > 0; unchanged when T = 0).
    u : float
        Applied input [N·m].
    t : float
        Time [s] (for d(t)).
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    (dtheta, domega, dtau) : (float, float, float)
        θ̇ [rad/s], θ̈ [rad/s²], τ̇ [N·m/s].
    """
    return rig_derivative_at(theta, omega, tau, u, disturbance(t, rig), rig)


@jitable
def rig_rk4_step_at(theta: float, omega: float, tau: float, u: float, d0: float, dhalf: float,
                    d1: float, h: float, rig: Vector) -> tuple[float, float, float]:
    """One RK4 step of length h [s] with u held, given d at the step's start, middle and end.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Actuator lag state τ [N·m] (the torque on the arm when T > 0; unchanged when T = 0).
    u : float
        Applied input [N·m], held over the step.
    d0 : float
        d(t) at the step's start [rad/s²].
    dhalf : float
        d(t + h/2) [rad/s²].
    d1 : float
        d(t + h) [rad/s²].
    h : float
        Step length [s].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    (theta, omega, tau) : (float, float, float)
        The rig state after the step(s) [rad, rad/s, N·m].
    """
    half = 0.5 * h
    a1, b1, c1 = rig_derivative_at(theta, omega, tau, u, d0, rig)
    a2, b2, c2 = rig_derivative_at(theta + half * a1, omega + half * b1, tau + half * c1, u,
                                   dhalf, rig)
    a3, b3, c3 = rig_derivative_at(theta + half * a2, omega + half * b2, tau + half * c2, u,
                                   dhalf, rig)
    a4, b4, c4 = rig_derivative_at(theta + h * a3, omega + h * b3, tau + h * c3, u, d1, rig)
    sixth = h / 6.0
    return (
        theta + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
        omega + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
        tau + sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4),
    )


@jitable
def rig_rk4_step(theta: float, omega: float, tau: float, u: float, t: float, h: float,
                 rig: Vector) -> tuple[float, float, float]:
    """One classical RK4 step of length h [s] from time t with u held.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Actuator lag state τ [N·m] (the torque on the arm when T > 0; unchanged when T = 0).
    u : float
        Applied input [N·m], held over the step.
    t : float
        Start of the step [s].
    h : float
        Step length [s].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    (theta, omega, tau) : (float, float, float)
        The rig state after the step(s) [rad, rad/s, N·m].
    """
    half = 0.5 * h
    return rig_rk4_step_at(theta, omega, tau, u, disturbance(t, rig),
                           disturbance(t + half, rig), disturbance(t + h, rig), h, rig)


@jitable
def rig_advance(theta: float, omega: float, tau: float, u: float, t0: float, h: float,
                nsub: int, rig: Vector) -> tuple[float, float, float]:
    """Integrate the rig over one sample: ``nsub`` RK4 steps of h from t0, u held.

    Parameters
    ----------
    theta : float
        Arm angle θ [rad], positive in the direction of positive torque.
    omega : float
        Arm rate θ̇ [rad/s]; friction opposes it.
    tau : float
        Actuator lag state τ [N·m] (the torque on the arm when T > 0; unchanged when T = 0).
    u : float
        Applied input [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = the sample time Ts).
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    (theta, omega, tau) : (float, float, float)
        The rig state after the step(s) [rad, rad/s, N·m].
    """
    for j in range(nsub):
        theta, omega, tau = rig_rk4_step(theta, omega, tau, u, t0 + j * h, h, rig)
    return theta, omega, tau


@jitable
def stop_held(theta: float, omega: float, acc: float, lower: float, upper: float) -> float:
    """The acceleration at an end stop: 0 while the arm rests on it and is pushed into it.

    Parameters
    ----------
    theta, omega : float
        Angle [rad] and rate [rad/s].
    acc : float
        The free acceleration θ̈ [rad/s²] (no stop).
    lower, upper : float
        The stops [rad].

    Returns
    -------
    float
        θ̈ [rad/s²].
    """
    if (theta >= upper and omega >= 0.0 and acc > 0.0) or (
            theta <= lower and omega <= 0.0 and acc < 0.0):
        return 0.0
    return acc


@jitable
def stopped_advance(theta: float, omega: float, tau: float, u: float, t0: float, h: float,
                    nsub: int, rig: Vector, lower: float,
                    upper: float) -> tuple[float, float, float]:
    """:func:`rig_advance` between hard end stops: an inelastic stop after every RK4 step.

    After each step an angle past a stop is set back onto it and a rate into it to zero
    (the arm stops dead and stays while pushed into the stop; pulled away it leaves).

    Parameters
    ----------
    theta, omega, tau : float
        State (θ [rad], θ̇ [rad/s], τ [N·m]).
    u : float
        Applied input [N·m], held.
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        RK4 steps.
    rig : ndarray or tuple of float
        The rig vector (:func:`rig_advance`).
    lower, upper : float
        The stops [rad].

    Returns
    -------
    (theta, omega, tau) : (float, float, float)
        The state after the sample.
    """
    for j in range(nsub):
        theta, omega, tau = rig_rk4_step(theta, omega, tau, u, t0 + j * h, h, rig)
        if theta >= upper:
            theta = upper
            omega = min(omega, 0.0)
        elif theta <= lower:
            theta = lower
            omega = max(omega, 0.0)
    return theta, omega, tau


@jitable
def applied_torque(tau: float, u: float, rig: Vector) -> float:
    """Torque acting on the arm: the lag state τ when T > 0, else u itself.

    Parameters
    ----------
    tau : float
        Actuator lag state τ [N·m].
    u : float
        Applied input [N·m].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s],
        b [N·m·s/rad], amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s]);
        the last two may be left off (Fst = 0).

    Returns
    -------
    float
        The torque on the arm [N·m].
    """
    if rig[LAG] > 0.0:
        return tau
    return u


@jitable
def geared_derivative_at(theta: float, omega: float, tau: float, theta_m: float,
                         omega_m: float, u: float, d: float,
                         rig: Vector) -> tuple[float, float, float, float, float]:
    """Time derivative of (θ, θ̇, τ, θm, θ̇m) with gear backlash (:mod:`esoarm.plants.backlash`).

    I θ̈ = τs − G(θ) − F(θ̇) + I d,  Jm θ̈m = τa − τs, τs the gear's dead-zone torque and τa
    the actuator's torque (the lag state τ when T > 0, else u).

    Parameters
    ----------
    theta, omega : float
        Arm angle θ [rad] and rate θ̇ [rad/s].
    tau : float
        Actuator lag state τ [N·m].
    theta_m, omega_m : float
        Motor-side angle θm [rad] and rate θ̇m [rad/s], at the arm.
    u : float
        Applied input [N·m].
    d : float
        Disturbance d(t) [rad/s²].
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (all 17 entries).

    Returns
    -------
    tuple of float
        θ̇ [rad/s], θ̈ [rad/s²], τ̇ [N·m/s], θ̇m [rad/s], θ̈m [rad/s²].
    """
    lag = rig[LAG]
    lagged = lag > 0.0
    torque = tau if lagged else u
    dtau = (u - tau) / lag if lagged else 0.0
    ts = gear_torque(theta_m - theta, omega_m - omega, rig[BACKLASH], rig[KGEAR], rig[CGEAR])
    return (omega, rig_acceleration_at(theta, omega, ts, d, rig), dtau, omega_m,
            (torque - ts) / rig[JM])


@jitable
def geared_advance(theta: float, omega: float, tau: float, theta_m: float, omega_m: float,
                   u: float, t0: float, h: float, nsub: int,
                   rig: Vector) -> tuple[float, float, float, float, float]:
    """``nsub`` classical RK4 steps of h [s] of :func:`geared_derivative_at`, u held.

    Parameters
    ----------
    theta, omega : float
        Arm angle θ [rad] and rate θ̇ [rad/s].
    tau : float
        Actuator lag state τ [N·m].
    theta_m, omega_m : float
        Motor-side angle θm [rad] and rate θ̇m [rad/s].
    u : float
        Applied input [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps.
    rig : ndarray or tuple of float
        The rig vector :attr:`RigParams.vector` (all 17 entries).

    Returns
    -------
    tuple of float
        (θ, θ̇, τ, θm, θ̇m) after the steps.
    """
    half = 0.5 * h
    sixth = h / 6.0
    x0, x1, x2, x3, x4 = theta, omega, tau, theta_m, omega_m
    for j in range(nsub):
        t = t0 + j * h
        d0 = disturbance(t, rig)
        dh = disturbance(t + half, rig)
        d1 = disturbance(t + h, rig)
        a0, a1, a2, a3, a4 = geared_derivative_at(x0, x1, x2, x3, x4, u, d0, rig)
        b0, b1, b2, b3, b4 = geared_derivative_at(x0 + half * a0, x1 + half * a1,
                                                  x2 + half * a2, x3 + half * a3,
                                                  x4 + half * a4, u, dh, rig)
        c0, c1, c2, c3, c4 = geared_derivative_at(x0 + half * b0, x1 + half * b1,
                                                  x2 + half * b2, x3 + half * b3,
                                                  x4 + half * b4, u, dh, rig)
        e0, e1, e2, e3, e4 = geared_derivative_at(x0 + h * c0, x1 + h * c1, x2 + h * c2,
                                                  x3 + h * c3, x4 + h * c4, u, d1, rig)
        x0 = x0 + sixth * (a0 + 2.0 * b0 + 2.0 * c0 + e0)
        x1 = x1 + sixth * (a1 + 2.0 * b1 + 2.0 * c1 + e1)
        x2 = x2 + sixth * (a2 + 2.0 * b2 + 2.0 * c2 + e2)
        x3 = x3 + sixth * (a3 + 2.0 * b3 + 2.0 * c3 + e3)
        x4 = x4 + sixth * (a4 + 2.0 * b4 + 2.0 * c4 + e4)
    return x0, x1, x2, x3, x4


@dataclass(frozen=True)
class RigParams:
    """Parameters of the true rig.

    Attributes
    ----------
    inertia : float
        True inertia I = inertia_scale · I0 [kg·m²].
    gcoef : float
        (m1 l1 − m2 l2) g [N·m].
    coulomb_friction : float
        Fc [N·m].
    friction_velocity : float
        vs [rad/s].
    viscous_friction : float
        b [N·m·s/rad].
    disturbance_amplitude : float
        [rad/s²].
    disturbance_frequency : float
        [rad/s].
    lag : float
        Actuator time constant T [s]; 0 for none.
    stiction : float
        Breakaway torque above Coulomb friction Fst [N·m]; 0 for none.
    stribeck_velocity : float
        Stribeck velocity vst [rad/s] over which the stiction decays.
    backlash : float
        Half the gear's play α [rad]; 0 for a rigid gear (:mod:`esoarm.plants.backlash`).
    motor_inertia : float
        Motor-side inertia Jm reflected to the arm [kg·m²] (with backlash).
    gear_stiffness : float
        Contact stiffness k [N·m/rad] (with backlash).
    gear_damping : float
        Contact damping c [N·m·s/rad] (with backlash).
    cogging_amplitude : float
        A of τ_cog = A cos(n θ + φ) [N·m]; 0 for none.
    cogging_periods : float
        n, periods per revolution [1].
    cogging_phase : float
        φ [rad].
    stop_lower, stop_upper : float
        Hard end stops [rad] (±inf: none).
    """

    inertia: float
    gcoef: float
    coulomb_friction: float
    friction_velocity: float
    viscous_friction: float
    disturbance_amplitude: float
    disturbance_frequency: float
    lag: float
    stiction: float = 0.0
    stribeck_velocity: float = 0.1
    backlash: float = 0.0
    motor_inertia: float = 1e-3
    gear_stiffness: float = 50.0
    gear_damping: float = 0.05
    cogging_amplitude: float = 0.0
    cogging_periods: float = 1.0
    cogging_phase: float = 0.0
    stop_lower: float = -math.inf
    stop_upper: float = math.inf

    @classmethod
    def from_scenario(cls, scn: Scenario) -> RigParams:
        """Rig parameters of a :class:`~esoarm.scenario.Scenario` (ideal torque source).

        Parameters
        ----------
        scn : Scenario
            A validated scenario with a lever-arm ``[plant]`` and its ``[rig]``.

        Returns
        -------
        RigParams
            The true rig (without the motor's back-EMF damping, see :func:`design`).
        """
        p, r = scn.plant, scn.rig
        return cls(
            inertia=r.inertia_scale * p.inertia,
            gcoef=gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g),
            coulomb_friction=r.coulomb_friction,
            friction_velocity=r.friction_velocity,
            viscous_friction=r.viscous_friction,
            disturbance_amplitude=r.disturbance.amplitude,
            disturbance_frequency=r.disturbance.frequency,
            lag=scn.actuator.lag,
            stiction=r.stiction,
            stribeck_velocity=r.stribeck_velocity,
            backlash=0.5 * math.radians(r.backlash_deg),
            motor_inertia=r.motor_inertia,
            gear_stiffness=r.gear_stiffness,
            gear_damping=r.gear_damping,
            cogging_amplitude=r.cogging.amplitude,
            cogging_periods=float(r.cogging.periods),
            cogging_phase=r.cogging.phase,
            stop_lower=min(r.end_stops) if r.end_stops else -math.inf,
            stop_upper=max(r.end_stops) if r.end_stops else math.inf,
        )

    @cached_property
    def vector(self) -> np.ndarray:
        """Packed float vector for the rig functions (computed once).

        Returns
        -------
        ndarray, shape (19,)
            Read-only (I [kg·m²], gcoef [N·m], Fc [N·m], vs [rad/s], b [N·m·s/rad],
            amplitude [rad/s²], frequency [rad/s], T [s], Fst [N·m], vst [rad/s],
            α [rad], Jm [kg·m²], k [N·m/rad], c [N·m·s/rad], cogging A [N·m], n, φ [rad],
            end stops lower, upper [rad] (±inf: none)).
        """
        vec = np.array(
            [
                self.inertia,
                self.gcoef,
                self.coulomb_friction,
                self.friction_velocity,
                self.viscous_friction,
                self.disturbance_amplitude,
                self.disturbance_frequency,
                self.lag,
                self.stiction,
                self.stribeck_velocity,
                self.backlash,
                self.motor_inertia,
                self.gear_stiffness,
                self.gear_damping,
                self.cogging_amplitude,
                self.cogging_periods,
                self.cogging_phase,
                self.stop_lower,
                self.stop_upper,
            ]
        )
        vec.setflags(write=False)
        return vec


# ---------------------------------------------------------------------------
# the kind: design and array-valued step functions


def design(scn: Scenario) -> PlantDesign:
    """The true rig of ``scn`` for the step functions.

    Parameters
    ----------
    scn : Scenario
        A validated scenario whose ``[plant]`` is of kind "lever-arm".

    Returns
    -------
    PlantDesign
        vector = (CODE, rig vector; its cogging entries only with cogging), x0 = (θ0 [rad],
        0, 0) — with backlash (θ0, 0, 0, θ0, 0), the motor side's angle and rate
        appended —, n_joints = 1, b0 = 1/I0 [1/(kg·m²)] (the nominal inertia, not the rig's).

    ``vector`` = (CODE, :attr:`RigParams.vector`); with a ``[motor]`` table the
    motor's back-EMF damping (N·Kt)²/R, which the actuator supplies
    (:func:`esoarm.plants.actuator.back_emf_damping`), is added to the viscous
    friction, so that driving the rig with the motor's rate-independent torque
    (:func:`esoarm.plants.motor.source_torque`) integrates the motor law.
    """
    rig = np.array(RigParams.from_scenario(scn).vector)
    if not scn.rig.end_stops:  # no stops: the vector without their entries
        rig = rig[:STOP_LO]
        if rig[COG_AMP] == 0.0:  # no cogging: without its entries (the kernels' width)
            rig = rig[:COG_AMP]
    damping = back_emf_damping(scn)
    if damping is not None:
        rig[VISC] += damping
    return PlantDesign(
        vector=read_only(np.concatenate([[float(CODE)], rig])),
        x0=read_only(np.array([scn.rig.theta0, 0.0, 0.0]
                              + ([scn.rig.theta0, 0.0] if scn.rig.backlash_deg > 0 else []))),
        n_joints=1,
        b0=read_only(np.array([input_gain(scn.plant.inertia)])),
    )


@jitable
def advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
            p: np.ndarray) -> None:
    """Integrate the state x = (θ, θ̇, τ) in place over one sample, input u[0] [N·m] held.

    ``nsub`` RK4 steps of h [s] from t0 [s] (:func:`rig_advance`); ``p`` is
    :attr:`PlantDesign.vector`.

    Parameters
    ----------
    x : ndarray, shape (3,) or (5,)
        State (θ [rad], θ̇ [rad/s], τ [N·m]), with backlash then (θm [rad], θ̇m [rad/s]),
        updated in place.
    u : ndarray, shape (1,)
        Applied torque [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s] (d(t) depends on it).
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = the sample time Ts).
    p : ndarray
        The design vector, p[0] = CODE, then :attr:`RigParams.vector`.
    """
    # the parameters as a tuple: compiled, they live in registers through the RK4 loop;
    # without a Stribeck term, the tuple without its entries skips e^(−x²) (same bits).
    # float(): in the interpreter (reference engine), Python floats are several times
    # quicker than NumPy scalars for the same IEEE operations; compiled, a no-op.
    th, om, ta, u0 = float(x[0]), float(x[1]), float(x[2]), float(u[0])
    if len(p) > 1 + BACKLASH and p[1 + BACKLASH] > 0.0:  # the two-mass drive train
        if len(p) > 1 + COG_PHASE:
            x[0], x[1], x[2], x[3], x[4] = geared_advance(th, om, ta, float(x[3]),
                                                          float(x[4]), u0, t0, h, nsub,
                                                          _full_rig(p))
        else:
            rig14 = (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]),
                     float(p[6]), float(p[7]), float(p[8]), float(p[9]), float(p[10]),
                     float(p[11]), float(p[12]), float(p[13]), float(p[14]))
            x[0], x[1], x[2], x[3], x[4] = geared_advance(th, om, ta, float(x[3]),
                                                          float(x[4]), u0, t0, h, nsub, rig14)
    elif len(p) > 1 + STOP_HI:  # end stops (and the cogging entries)
        x[0], x[1], x[2] = stopped_advance(th, om, ta, u0, t0, h, nsub, _full_rig(p),
                                           _entry(p, 1 + STOP_LO), _entry(p, 1 + STOP_HI))
    elif len(p) > 1 + COG_PHASE and p[1 + COG_AMP] != 0.0:  # cogging: the rig with its entries
        x[0], x[1], x[2] = rig_advance(th, om, ta, u0, t0, h, nsub, _full_rig(p))
    elif p[1 + FST] == 0.0:
        rig8 = (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]),
                float(p[6]), float(p[7]), float(p[8]))
        x[0], x[1], x[2] = rig_advance(th, om, ta, u0, t0, h, nsub, rig8)
    else:
        rig = (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]),
               float(p[6]), float(p[7]), float(p[8]), float(p[9]), float(p[10]))
        x[0], x[1], x[2] = rig_advance(th, om, ta, u0, t0, h, nsub, rig)


@jitable
def _full_rig(p: np.ndarray) -> tuple[float, ...]:
    """The whole rig vector of design vector ``p`` as a tuple (backlash and cogging entries)."""
    # the cogging entries by a run-time index: a design vector the compiled engine hands over
    # as a tuple zero-padded to its width (no cogging) still types (never called with it)
    k = 1 + COG_AMP
    return (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]), float(p[6]),
            float(p[7]), float(p[8]), float(p[9]), float(p[10]), float(p[11]), float(p[12]),
            float(p[13]), float(p[14]), _entry(p, k), _entry(p, k + 1), _entry(p, k + 2))


@jitable
def _entry(p: Vector, k: int) -> float:
    """``p[k]`` as a float, k a run-time index."""
    return float(p[k])


@jitable
def advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                  nsub: int, p: np.ndarray) -> None:
    """:func:`advance` for a block of runs sharing ``p``: run i is ``xs[i]``, ``us[i]``.

    The same RK4 steps as :func:`advance` on each run with ``live[i]`` true, the
    runs innermost; d(t), which depends on t only, is computed once per stage
    time for the whole block.  The same numbers as :func:`advance`, bit for bit.

    Parameters
    ----------
    xs : ndarray, shape (runs, 3)
        States of the runs (θ [rad], θ̇ [rad/s], τ [N·m]), live ones updated in place.
    us : ndarray, shape (runs, 1)
        Applied torque of each run [N·m].
    live : ndarray of bool, shape (runs,)
        Which runs to write back; the others are left untouched.
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps per sample.
    p : ndarray
        The design vector shared by the block, p[0] = CODE.
    """
    # (a vector zero-padded to the compiled engine's width has its entries but A = 0)
    cogged = (len(p) > 1 + COG_PHASE and p[1 + COG_AMP] != 0.0) or len(p) > 1 + STOP_HI
    if (len(p) > 1 + BACKLASH and p[1 + BACKLASH] > 0.0) or cogged:  # run by run
        for i in range(xs.shape[0]):
            if live[i]:
                advance(xs[i], us[i], t0, h, nsub, p)
    elif p[1 + FST] == 0.0:  # no Stribeck term: the rig without its entries skips e^(−x²)
        _advance_block(xs, us, live, t0, h, nsub, (p[1], p[2], p[3], p[4], p[5], p[6], p[7],
                                                   p[8]))
    else:
        _advance_block(xs, us, live, t0, h, nsub, (p[1], p[2], p[3], p[4], p[5], p[6], p[7],
                                                   p[8], p[9], p[10]))


@jitable
def _advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                   nsub: int, rig: Vector) -> None:
    half = 0.5 * h
    m = xs.shape[0]
    # one array per state component (runs contiguous): the loop over runs below has no
    # branch and no libm call, so it compiles to vector instructions.  A run that is not
    # live is advanced too (its numbers are never read) and not written back; the arrays
    # are padded with copies of run 0 to whole vectors (LANES), since a leftover run or
    # two would take the scalar path, several times slower per run.
    mp = -(-m // LANES) * LANES
    theta, omega, tau, u = np.empty(mp), np.empty(mp), np.empty(mp), np.empty(mp)
    for i in range(mp):
        r = i if i < m else 0
        theta[i], omega[i], tau[i], u[i] = xs[r, 0], xs[r, 1], xs[r, 2], us[r, 0]
    for j in range(nsub):
        t = t0 + j * h
        d0 = disturbance(t, rig)
        dhalf = disturbance(t + half, rig)
        d1 = disturbance(t + h, rig)
        for i in range(mp):
            theta[i], omega[i], tau[i] = rig_rk4_step_at(theta[i], omega[i], tau[i], u[i],
                                                         d0, dhalf, d1, h, rig)
    for i in range(m):
        if live[i]:
            xs[i, 0], xs[i, 1], xs[i, 2] = theta[i], omega[i], tau[i]


@jitable
def acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                 out: np.ndarray) -> None:
    """True θ̈ [rad/s²] at state x, time t, with input u[0] applied from t on, into out[0].

    Parameters
    ----------
    x : ndarray, shape (3,) or (5,)
        State (θ [rad], θ̇ [rad/s], τ [N·m]), with backlash then (θm [rad], θ̇m [rad/s]).
    u : ndarray, shape (1,)
        Applied torque [N·m] (acts directly when T = 0).
    t : float
        Time [s] (for d(t)).
    p : ndarray
        The design vector, p[0] = CODE.
    out : ndarray, shape (1,)
        Output: θ̈ [rad/s²].
    """
    rig = p[1:]
    if len(rig) > BACKLASH and rig[BACKLASH] > 0.0:  # the gear's torque, not the actuator's
        ts = gear_torque(x[3] - x[0], x[4] - x[1], rig[BACKLASH], rig[KGEAR], rig[CGEAR])
        out[0] = rig_acceleration(x[0], x[1], ts, t, rig)
        return
    acc = rig_acceleration(x[0], x[1], applied_torque(x[2], u[0], rig), t, rig)
    if len(rig) > STOP_HI:  # held at an end stop while pushed into it
        acc = stop_held(x[0], x[1], acc, _entry(rig, STOP_LO), _entry(rig, STOP_HI))
    out[0] = acc


@jitable
def observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """The observer's input: the command u itself (the observer's b0 = 1/I0 scales it).

    Parameters
    ----------
    zhat : ndarray, shape (3,)
        Observer estimate (θ̂, θ̂̇, f̂) (unused).
    u : ndarray, shape (1,)
        Command as logged [N·m].
    p : ndarray
        The design vector (unused).
    v : ndarray, shape (1,)
        Output: the observer input [N·m].
    """
    v[0] = u[0]
