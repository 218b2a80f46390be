"""Plant kind ``"dc-motor"``: an armature-controlled DC motor under speed control, inductance kept.

    J ω̇ = Km i − Kf ω − Td(t)          (the shaft: torque constant Km, viscous friction Kf)
    L di/dt = V − R i − Kb ω           (the armature: inductance L, resistance R, back-EMF Kb)

the textbook DC motor of MATLAB's examples, here with the parameters of MathWorks' "Apply
Extended State Observer for Reference Tracking of DC Motor" (Simulink Control Design,
R2024a: R = 2 Ω, L = 0.5 H, Km = Kb = 0.1, Kf = 0.2 N·m·s, J = 0.02 kg·m², a pulse
disturbance at 10 s; the ``dc-motor-eso`` scenario).  Unlike the lever arm's ``[motor]``
table (:mod:`esoarm.plants.motor`, inductance neglected), the electrical time constant
L/R = 0.25 s is longer than the mechanical one J/(Kf + Km·Kb/R) = 0.098 s, so the current
is a state.

**The measured output is the speed ω** (a tachometer, as in the example), and the input is
the armature voltage V.  From V to ω the plant is of second order,

    ω̈ = (Km/(J L))·V − (R/L + Kf/J)·ω̇ − ((Kf R + Km Kb)/(J L))·ω − (R Td + L Ṫd)/(J L),

so the observers and controllers of esoarm, written for ÿ = f + b0·u, take y = ω with
b0 = Km/(J L) [rad/s³ per V]: what a scenario calls the angle is the speed [rad/s], its
"rate" the angular acceleration, the "torque" limit a voltage limit [V] (:func:`units_of`).

As a kind (see :mod:`esoarm.contract`): state x = (ω, ω̇, i), one joint; (ω, i) are
integrated with classical RK4 at ``rig.step``, and ω̇ is the shaft's acceleration at the end
of the sample (from ω, i and the load, so it jumps with a step of the load, as the shaft's
does).  The load torque Td is a pulse of ``load_torque`` [N·m] from ``load_start`` for
``load_duration`` seconds (0 amplitude: none); a sample that straddles an edge of the pulse
takes the load of its RK4 steps' start.  The ``[rig]`` table of the lever arm does not apply.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import PlantDesign, Units, Vector, read_only

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "SPEED_UNITS", "Params", "acceleration", "advance",
           "advance_block", "check", "design", "load", "observer_input", "units_of"]

KIND = "dc-motor"
CODE = 3
JIT = True

# layout of the design vector after its CODE
RES, IND, KM, KB, KF, INERTIA, TD, T_ON, T_OFF = range(9)

#: The units of a speed loop: the "angle" is the speed, the drive a voltage.
SPEED_UNITS = Units(position="rad/s", velocity="rad/s²", acceleration="rad/s³", force="V",
                    inertia="V·s³/rad", damping="V·s²/rad", stiffness="V·s/rad",
                    compliance="rad/(V·s)", position_word="speed", force_word="voltage")


class Params(Section):
    """``[plant]`` of kind "dc-motor": an armature-controlled DC motor, speed measured."""

    kind: Literal["dc-motor"] = Field(
        "dc-motor", description='plant kind: "dc-motor" (armature-controlled DC motor, '
        "armature inductance kept, the speed measured)")
    resistance: float = Field(2.0, gt=0, description="armature resistance R",
                              json_schema_extra=unit("Ω"))
    inductance: float = Field(0.5, gt=0, description="armature inductance L",
                              json_schema_extra=unit("H"))
    torque_constant: float = Field(0.1, gt=0, description="torque constant Km",
                                   json_schema_extra=unit("N·m/A"))
    emf_constant: float = Field(0.1, ge=0, description="back-EMF constant Kb",
                                json_schema_extra=unit("V·s/rad"))
    friction: float = Field(0.2, ge=0, description="viscous friction Kf",
                            json_schema_extra=unit("N·m·s/rad"))
    inertia: float = Field(0.02, gt=0, description="rotor and load inertia J",
                           json_schema_extra=unit("kg·m²"))
    load_torque: float = Field(0.0, description="load torque Td of the pulse disturbance "
                               "(opposes positive speed)", json_schema_extra=unit("N·m"))
    load_start: float = Field(10.0, ge=0, description="start of the load pulse",
                              json_schema_extra=unit("s"))
    load_duration: float = Field(1.0, gt=0, description="length of the load pulse",
                                 json_schema_extra=unit("s"))
    omega0: float = Field(0.0, description="initial speed ω(0) (the armature current then "
                          "holds it against Kf)", json_schema_extra=unit("rad/s"))


def units_of(params: Params) -> Units:
    """The units commands print for this plant: speed [rad/s] measured, voltage applied.

    Parameters
    ----------
    params : Params
        The ``[plant]`` table (unused: always :data:`SPEED_UNITS`).

    Returns
    -------
    Units
    """
    return SPEED_UNITS


def check(scn: Scenario) -> str | None:
    """Nothing to cross-check beyond each key's own bounds.

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "dc-motor".

    Returns
    -------
    None
    """
    return None


def design(scn: Scenario) -> PlantDesign:
    """The motor for the step functions: vector (CODE, R, L, Km, Kb, Kf, J, Td, t_on,
    t_off), x0 = (ω0, 0, Kf·ω0/Km), b0 = Km/(J·L).

    Parameters
    ----------
    scn : Scenario
        A validated scenario whose ``[plant]`` is of kind "dc-motor".

    Returns
    -------
    PlantDesign
        vector [CODE, Ω, H, N·m/A, V·s/rad, N·m·s/rad, kg·m², N·m, s, s], x0 [rad/s,
        rad/s², A], n_joints = 1, b0 [rad/s³ per V].
    """
    p = scn.plant
    vec = [float(CODE), p.resistance, p.inductance, p.torque_constant, p.emf_constant,
           p.friction, p.inertia, p.load_torque, p.load_start,
           p.load_start + p.load_duration]
    i0 = p.friction * p.omega0 / p.torque_constant
    return PlantDesign(vector=read_only(np.array(vec)),
                       x0=read_only(np.array([p.omega0, 0.0, i0])), n_joints=1,
                       b0=read_only(np.array([p.torque_constant
                                              / (p.inertia * p.inductance)])))


@jitable
def load(t: float, m: Vector) -> float:
    """The load torque Td(t) [N·m]: the pulse of the design vector ``m`` (after its CODE).

    Parameters
    ----------
    t : float
        Time [s].
    m : tuple of float
        The design vector after its CODE (see :func:`design`).

    Returns
    -------
    float
        Td [N·m] (``load_torque`` inside [t_on, t_off), else 0).
    """
    return m[TD] if m[T_ON] <= t < m[T_OFF] else 0.0


@jitable
def _shaft(w: float, i: float, td: float, m: Vector) -> float:
    """ω̇ = (Km i − Kf ω − Td)/J [rad/s²]."""
    return (m[KM] * i - m[KF] * w - td) / m[INERTIA]


@jitable
def _rk4(w: float, i: float, v: float, td: float, h: float,
         m: Vector) -> tuple[float, float]:
    """One RK4 step of (ω, i) with the voltage v and the load td held."""
    def di(w_: float, i_: float) -> float:
        return (v - m[RES] * i_ - m[KB] * w_) / m[IND]

    a1, b1 = _shaft(w, i, td, m), di(w, i)
    a2, b2 = _shaft(w + 0.5 * h * a1, i + 0.5 * h * b1, td, m), di(w + 0.5 * h * a1,
                                                                  i + 0.5 * h * b1)
    a3, b3 = _shaft(w + 0.5 * h * a2, i + 0.5 * h * b2, td, m), di(w + 0.5 * h * a2,
                                                                  i + 0.5 * h * b2)
    a4, b4 = _shaft(w + h * a3, i + h * b3, td, m), di(w + h * a3, i + h * b3)
    return (w + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
            i + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4))


@jitable
def _tuple(p: np.ndarray) -> tuple[float, float, float, float, float, float, float, float,
                                    float]:
    return (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]), float(p[6]),
            float(p[7]), float(p[8]), float(p[9]))


@jitable
def _sample(w: float, i: float, v: float, t0: float, h: float, nsub: int,
            m: Vector) -> tuple[float, float, float]:
    """(ω, ω̇, i) after ``nsub`` RK4 steps of h from t0, the voltage v held."""
    t = t0
    for _ in range(nsub):
        w, i = _rk4(w, i, v, load(t, m), h, m)
        t = t + h
    return w, _shaft(w, i, load(t, m), m), i


@jitable
def advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
            p: np.ndarray) -> None:
    """Integrate x = (ω, ω̇, i) in place over one sample: ``nsub`` RK4 steps of h [s], the
    voltage u[0] held.

    Parameters
    ----------
    x : ndarray, shape (3,)
        State (ω [rad/s], ω̇ [rad/s²], i [A]), updated in place.
    u : ndarray, shape (1,)
        Armature voltage [V], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s] (the load pulse depends on it).
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = the sample time Ts).
    p : ndarray
        The design vector, p[0] = CODE (see :func:`design`).
    """
    m = _tuple(p)
    x[0], x[1], x[2] = _sample(float(x[0]), float(x[2]), float(u[0]), t0, h, nsub, m)


@jitable
def advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                  nsub: int, p: np.ndarray) -> None:
    """:func:`advance` for each live run i of a block (``xs[i]``, ``us[i]``), the same bits.

    Parameters
    ----------
    xs : ndarray, shape (runs, 3)
        States of the block's runs (as ``x`` of :func:`advance`), updated in place.
    us : ndarray, shape (runs, 1)
        Armature voltage of each run [V].
    live : ndarray of bool, shape (runs,)
        Which runs to advance; the others are left untouched.
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps per sample.
    p : ndarray
        The design vector, p[0] = CODE, shared by the block.
    """
    m = _tuple(p)
    for k in range(xs.shape[0]):
        if live[k]:
            xs[k, 0], xs[k, 1], xs[k, 2] = _sample(float(xs[k, 0]), float(xs[k, 2]),
                                                   float(us[k, 0]), t0, h, nsub, m)


@jitable
def acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                 out: np.ndarray) -> None:
    """The true second derivative of the output, ω̈ [rad/s³], at x with the voltage u[0].

    ω̈ = (Km (V − R i − Kb ω)/L − Kf ω̇)/J, with ω̇ from the state (ω, i) and the load at t;
    the load's own derivative (an impulse at the pulse's edges) is left out.

    Parameters
    ----------
    x : ndarray, shape (3,)
        State (ω, ω̇, i) [rad/s, rad/s², A].
    u : ndarray, shape (1,)
        Armature voltage [V].
    t : float
        Time [s] (the load pulse).
    p : ndarray
        The design vector, p[0] = CODE.
    out : ndarray, shape (1,)
        Output: ω̈ [rad/s³].
    """
    m = _tuple(p)
    w, i = float(x[0]), float(x[2])
    dw = _shaft(w, i, load(t, m), m)
    di = (u[0] - m[RES] * i - m[KB] * w) / m[IND]
    out[0] = (m[KM] * di - m[KF] * dw) / m[INERTIA]


@jitable
def observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """The observer's input: the voltage itself (b0 = Km/(J L) scales it).

    Parameters
    ----------
    zhat : ndarray, shape (3,)
        Observer estimate (unused).
    u : ndarray, shape (1,)
        Voltage as applied [V].
    p : ndarray
        The design vector (unused).
    v : ndarray, shape (1,)
        Output: the observer input [V].
    """
    v[0] = u[0]
