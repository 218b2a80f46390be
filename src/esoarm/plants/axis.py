"""Plant kind ``"axis"``: any single rotary or prismatic axis driven by a torque or force.

    M q̈ = τ − F(q̇) − offset − G cos q
    F(q̇) = Fc(q̇) tanh(q̇/vs) + Fv(q̇) q̇,   Fc(q̇), Fv(q̇) = the positive-direction values
                                           for q̇ ≥ 0, the negative-direction ones below
    τ̇ = (u_applied − τ) / T      (``actuator.lag`` T > 0; τ = u_applied when T = 0)

This is the inverse dynamic model of a one-degree-of-freedom drive as robotics
writes it (Khalil and Dombre; the EMPS benchmark's eq. 1): τ = M q̈ + Fv q̇ +
Fc sign(q̇) + offset, with the sign smoothed by tanh(q̇/vs) so that RK4 integrates
it (vs = ``friction_velocity``, far below the speeds of a move).  Asymmetric
friction (a worn screw) is the difference between the directions:
Fv± = Fv ± ``viscous_asymmetry``/2, Fc± = Fc ± ``coulomb_asymmetry``/2.

Units follow ``motion``: a ``"prismatic"`` axis has q [m], M a mass [kg], τ a
force [N], Fv [N·s/m], Fc and offset [N]; a ``"rotary"`` one q [rad], M an
inertia [kg·m²], τ a torque [N·m], Fv [N·m·s/rad], Fc, offset and G [N·m]
(:func:`units`).  Gravity G cos q only for a rotary axis (a prismatic axis's
weight along its slide is a constant: the offset).

As a kind (see :mod:`esoarm.contract`): state x = (q, q̇, τ), one joint, b0 = 1/M
(the model known to the controller is the plant itself, as identified);
integrated with classical RK4 at ``rig.step`` from ``q0``.  The ``[rig]`` table
of the lever arm (its inertia scale, friction and disturbance) does not apply.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import PRISMATIC_UNITS, ROTARY_UNITS, PlantDesign, Units, Vector, read_only
from esoarm.plants.actuator import back_emf_damping
from esoarm.plants.elementary import cos, tanh

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "MOTOR", "Params",
           "acceleration", "advance", "advance_block",
           "axis_acceleration", "axis_rk4_step", "check", "design", "inverse_dynamics",
           "observer_input", "units", "units_of"]

KIND = "axis"
CODE = 2
JIT = True
#: Driven by the actuator's motor when the scenario has a ``[motor]`` table (its back-EMF
#: damping, :func:`esoarm.plants.actuator.back_emf_damping`, joins Fv in both directions).
MOTOR = True
#: ``identify`` fits it as one axis in SI units (IDIM-LS, output error beside it).
AXIS_FIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "axis.c"

# layout of the design vector after its CODE
MASS, FVP, FVN, FCP, FCN, OFFSET, GRAV, VS, LAG = range(9)


class Params(Section):
    """``[plant]`` of kind "axis": one rotary or prismatic axis, its physical parameters."""

    kind: Literal["axis"] = Field(
        "axis", description='plant kind: "axis" (one rotary or prismatic axis, SI units)')
    motion: Literal["rotary", "prismatic"] = Field(
        "rotary", description='"rotary" (q in rad, torque in N·m) or "prismatic" (q in m, '
        "force in N)")
    mass: float = Field(0.025, gt=0, description="mass M [kg] (prismatic) or moment of "
                        "inertia J [kg·m²] (rotary)", json_schema_extra=unit("kg or kg·m²"))
    viscous_friction: float = Field(
        0.01, ge=0, description="viscous friction Fv, mean of the two directions",
        json_schema_extra=unit("N·s/m or N·m·s/rad"))
    coulomb_friction: float = Field(
        0.05, ge=0, description="Coulomb friction Fc, mean of the two directions",
        json_schema_extra=unit("N or N·m"))
    viscous_asymmetry: float = Field(
        0.0, description="Fv(q̇ > 0) − Fv(q̇ < 0)", json_schema_extra=unit("N·s/m or N·m·s/rad"))
    coulomb_asymmetry: float = Field(
        0.0, description="Fc(q̇ > 0) − Fc(q̇ < 0)", json_schema_extra=unit("N or N·m"))
    offset: float = Field(0.0, description="constant force or torque the drive supplies on "
                          "top (τ = M q̈ + F(q̇) + offset): a slide's weight, a drive offset",
                          json_schema_extra=unit("N or N·m"))
    gravity: float = Field(0.0, description="gravity torque G of G·cos q (rotary only)",
                           json_schema_extra=unit("N·m"))
    friction_velocity: float = Field(
        0.001, gt=0, description="tanh smoothing velocity vs of the Coulomb friction",
        json_schema_extra=unit("m/s or rad/s"))
    q0: float = Field(0.0, description="initial position q(0)", json_schema_extra=unit("m or rad"))


def units(motion: str) -> dict[str, str]:
    """SI units of an axis's quantities by name, for ``motion`` "rotary" or "prismatic".

    Parameters
    ----------
    motion : str
        "rotary" or "prismatic" (anything else is taken as rotary).

    Returns
    -------
    dict of str to str
        Quantity name ("position", "velocity", "force", ...) to its SI unit.

    Examples
    --------
    >>> units("prismatic")["viscous_friction"]
    'N·s/m'
    """
    if motion == "prismatic":
        return {"position": "m", "velocity": "m/s", "force": "N", "mass": "kg",
                "viscous_friction": "N·s/m", "coulomb_friction": "N", "offset": "N"}
    return {"position": "rad", "velocity": "rad/s", "force": "N·m", "inertia": "kg·m²",
            "viscous_friction": "N·m·s/rad", "coulomb_friction": "N·m", "offset": "N·m",
            "gravity": "N·m"}


def units_of(params: Params) -> Units:
    """The units commands print for this axis: m, m/s, N when prismatic, else rad, N·m.

    Parameters
    ----------
    params : Params
        The ``[plant]`` table.

    Returns
    -------
    Units
        :data:`esoarm.contract.PRISMATIC_UNITS` or :data:`esoarm.contract.ROTARY_UNITS`.

    Examples
    --------
    >>> units_of(Params(motion="prismatic")).force
    'N'
    """
    return PRISMATIC_UNITS if params.motion == "prismatic" else ROTARY_UNITS


def check(scn: Scenario) -> str | None:
    """A prismatic axis has no G cos q term; friction in each direction must be ≥ 0.

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "axis".

    Returns
    -------
    str or None
        A one-line message naming the offending key, or None when the plant is consistent.
    """
    p = scn.plant
    if p.motion == "prismatic" and p.gravity != 0.0:
        return ("plant.gravity: only a rotary axis has a G·cos q term; a prismatic axis's "
                "weight along its slide is a constant force: put it in plant.offset")
    for key, mean, delta in (("viscous", p.viscous_friction, p.viscous_asymmetry),
                             ("coulomb", p.coulomb_friction, p.coulomb_asymmetry)):
        if abs(delta) > 2.0 * mean:
            return (f"plant.{key}_asymmetry = {delta:g}: the friction of one direction would be "
                    f"negative (|asymmetry| ≤ 2·plant.{key}_friction = {2.0 * mean:g})")
    return None


def design(scn: Scenario) -> PlantDesign:
    """The axis of ``scn`` for the step functions: vector (CODE, M, Fv+, Fv−, Fc+, Fc−,
    offset, G, vs, T), x0 = (q0, 0, 0), b0 = 1/M.

    With a ``[motor]`` table the motor's back-EMF damping (N·Kt)²/R (the actuator's,
    :func:`esoarm.plants.actuator.back_emf_damping`) is added to Fv+ and Fv−.

    Parameters
    ----------
    scn : Scenario
        A validated scenario whose ``[plant]`` is of kind "axis".

    Returns
    -------
    PlantDesign
        vector [CODE, kg or kg·m², N·s/m or N·m·s/rad (×2), N or N·m (×3), N·m, m/s or
        rad/s, s], x0 [m or rad, m/s or rad/s, N or N·m], n_joints = 1, b0 = 1/M.
    """
    p = scn.plant
    fv = p.viscous_friction
    damping = back_emf_damping(scn)
    if damping is not None:
        fv = fv + damping
    vec = [float(CODE), p.mass,
           fv + 0.5 * p.viscous_asymmetry,
           fv - 0.5 * p.viscous_asymmetry,
           p.coulomb_friction + 0.5 * p.coulomb_asymmetry,
           p.coulomb_friction - 0.5 * p.coulomb_asymmetry,
           p.offset, p.gravity, p.friction_velocity, scn.actuator.lag]
    return PlantDesign(vector=read_only(np.array(vec)),
                       x0=read_only(np.array([p.q0, 0.0, 0.0])), n_joints=1,
                       b0=read_only(np.array([1.0 / p.mass])))


@jitable
def inverse_dynamics(q: float, v: float, a: float, ax: Vector) -> float:
    """The force/torque τ [N or N·m] that gives acceleration ``a`` at (q, v): M a + F(v) +
    offset + G cos q, ``ax`` the vector after the CODE (see :func:`design`).

    Parameters
    ----------
    q : float
        Position [m or rad].
    v : float
        Velocity q̇ [m/s or rad/s]; friction opposes it.
    a : float
        Acceleration q̈ [m/s² or rad/s²].
    ax : tuple of float
        The design vector after its CODE: (M, Fv+, Fv−, Fc+, Fc−, offset, G, vs, T) (see
        :func:`design`).

    Returns
    -------
    float
        τ [N or N·m], positive in the direction of positive q.
    """
    pos = v >= 0.0
    fc = ax[FCP] if pos else ax[FCN]
    fv = ax[FVP] if pos else ax[FVN]
    friction = fc * tanh(v / ax[VS]) + fv * v
    return ax[MASS] * a + friction + ax[OFFSET] + ax[GRAV] * cos(q)


@jitable
def axis_acceleration(q: float, v: float, tau: float, ax: Vector) -> float:
    """q̈ [m/s² or rad/s²] under the force/torque ``tau`` acting on the axis.

    Parameters
    ----------
    q : float
        Position [m or rad].
    v : float
        Velocity q̇ [m/s or rad/s].
    tau : float
        Force or torque acting on the axis [N or N·m], positive towards positive q.
    ax : tuple of float
        The design vector after its CODE: (M, Fv+, Fv−, Fc+, Fc−, offset, G, vs, T) (see
        :func:`design`).

    Returns
    -------
    float
        q̈ = (τ − F(q̇) − offset − G cos q)/M [m/s² or rad/s²].
    """
    return (tau - inverse_dynamics(q, v, 0.0, ax)) / ax[MASS]


@jitable
def _derivative(q: float, v: float, tau: float, u: float,
                ax: Vector) -> tuple[float, float, float]:
    lag = ax[LAG]
    lagged = lag > 0.0
    torque = tau if lagged else u
    dtau = (u - tau) / lag if lagged else 0.0
    return v, axis_acceleration(q, v, torque, ax), dtau


@jitable
def axis_rk4_step(q: float, v: float, tau: float, u: float, h: float,
                  ax: Vector) -> tuple[float, float, float]:
    """One classical RK4 step of length h [s] of (q, q̇, τ) with u held.

    Parameters
    ----------
    q : float
        Position [m or rad].
    v : float
        Velocity [m/s or rad/s].
    tau : float
        Lagged actuator force/torque τ [N or N·m] (unused and unchanged when T = 0).
    u : float
        Applied force/torque command [N or N·m], held over the step.
    h : float
        Step length [s], > 0.
    ax : tuple of float
        The design vector after its CODE: (M, Fv+, Fv−, Fc+, Fc−, offset, G, vs, T) (see
        :func:`design`).

    Returns
    -------
    (q, v, tau) : (float, float, float)
        The state after the step, same units.
    """
    half = 0.5 * h
    a1, b1, c1 = _derivative(q, v, tau, u, ax)
    a2, b2, c2 = _derivative(q + half * a1, v + half * b1, tau + half * c1, u, ax)
    a3, b3, c3 = _derivative(q + half * a2, v + half * b2, tau + half * c2, u, ax)
    a4, b4, c4 = _derivative(q + h * a3, v + h * b3, tau + h * c3, u, ax)
    sixth = h / 6.0
    return (q + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
            v + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
            tau + sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4))


@jitable
def _tuple(p: np.ndarray) -> tuple[float, float, float, float, float, float, float, float,
                                    float]:
    return (float(p[1]), float(p[2]), float(p[3]), float(p[4]), float(p[5]), float(p[6]),
            float(p[7]), float(p[8]), float(p[9]))


@jitable
def advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
            p: np.ndarray) -> None:
    """Integrate x = (q, q̇, τ) in place over one sample: ``nsub`` RK4 steps of h [s], u[0]
    held (the axis is time-invariant: t0 is not used).

    Parameters
    ----------
    x : ndarray, shape (3,)
        State (q [m or rad], q̇ [m/s or rad/s], τ [N or N·m]), updated in place.
    u : ndarray, shape (1,)
        Applied force/torque [N or N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s] (unused: time-invariant).
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = the sample time Ts).
    p : ndarray
        The design vector, p[0] = CODE (see :func:`design`).
    """
    ax = _tuple(p)
    q, v, tau, u0 = float(x[0]), float(x[1]), float(x[2]), float(u[0])
    for _ in range(nsub):
        q, v, tau = axis_rk4_step(q, v, tau, u0, h, ax)
    x[0], x[1], x[2] = q, v, tau


@jitable
def advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                  nsub: int, p: np.ndarray) -> None:
    """:func:`advance` for each live run i of a block (``xs[i]``, ``us[i]``), the same bits.

    Parameters
    ----------
    xs : ndarray, shape (runs, 3)
        States of the block's runs (as ``x`` of :func:`advance`), updated in place.
    us : ndarray, shape (runs, 1)
        Applied force/torque of each run [N or N·m].
    live : ndarray of bool, shape (runs,)
        Which runs to advance; the others are left untouched.
    t0 : float
        Start of the sample [s] (unused).
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps per sample.
    p : ndarray
        The design vector, p[0] = CODE, shared by the block.
    """
    ax = _tuple(p)
    for i in range(xs.shape[0]):
        if live[i]:
            q, v, tau, u0 = xs[i, 0], xs[i, 1], xs[i, 2], us[i, 0]
            for _ in range(nsub):
                q, v, tau = axis_rk4_step(q, v, tau, u0, h, ax)
            xs[i, 0], xs[i, 1], xs[i, 2] = q, v, tau


@jitable
def acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                 out: np.ndarray) -> None:
    """True q̈ at state x with input u[0] applied from t on, into out[0].

    Parameters
    ----------
    x : ndarray, shape (3,)
        State (q, q̇, τ) [m or rad, m/s or rad/s, N or N·m].
    u : ndarray, shape (1,)
        Applied force/torque [N or N·m] (used when there is no lag, T = 0).
    t : float
        Time [s] (unused: time-invariant).
    p : ndarray
        The design vector, p[0] = CODE.
    out : ndarray, shape (1,)
        Output: q̈ [m/s² or rad/s²].
    """
    ax = _tuple(p)
    torque = x[2] if ax[LAG] > 0.0 else u[0]
    out[0] = axis_acceleration(x[0], x[1], torque, ax)


@jitable
def observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """The observer's input: the command u itself (b0 = 1/M scales it).

    Parameters
    ----------
    zhat : ndarray, shape (3,)
        Observer estimate (q̂, q̂̇, f̂) (unused).
    u : ndarray, shape (1,)
        Command as logged [N or N·m].
    p : ndarray
        The design vector (unused).
    v : ndarray, shape (1,)
        Output: the observer input [N or N·m].
    """
    v[0] = u[0]
