"""Controller kind ``"computed-torque"``: the paper's FLC on n joints of a URDF arm.

With the observers' estimates q̂ = ẑ1, q̂̇ = ẑ2 of every joint, the tracking
law of eq. 16 per joint,

    α_i = q̈d_i − k1_i (ẑ2_i − q̇d_i) − k2_i (ẑ1_i − qd_i)

and the torque (saturated per joint by the actuator):

``compensation = "eso"`` (the paper's eq. 14 on n joints)
    τ = M̂(q̂) (α − ẑ3), or with ``feedforward`` τ = M̂(q̂) (α − ẑ3) + n̂(q̂, q̂̇)
``compensation = "model"`` (computed torque on the nominal model, Fig. 7's baseline)
    τ = M̂(q̂) α + n̂(q̂, q̂̇)       (the observers still run and supply q̂, q̂̇)

M̂ and n̂ are the nominal model's (the URDF as written, :mod:`esoarm.plants.arms.model`).
Each joint's ẑ3 estimates q̈ − v with v = M̂⁻¹(τ − c n̂) the observers' input
(:func:`esoarm.plants.arms.urdf.observer_input`), so with perfect estimates
M̂(q̈ − ẑ3) = τ − c n̂ gives q̈ = α: the paper's error dynamics (eq. 17) on
every joint.  On one joint τ = I0 (α − z3): the FLC exactly.

As a kind (see :mod:`esoarm.contract`): the reference engine calls Pinocchio
for M̂ and n̂; the compiled engine runs :func:`control_compiled` in its place
(``JIT = True``), the same law on :mod:`esoarm.plants.arms.rigid_body` and the
nominal model packed at the end of the vector.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable, jitable_as
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, read_only
from esoarm.controllers import flc as _flc
from esoarm.plants.arms.rigid_body import (
    bias_offset,
    dynamics_terms,
    mass_offset,
    model_size,
    scratch_offset,
    workspace_size,
)

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "Params", "check", "control", "control_compiled", "design",
           "initialize", "label", "per_joint", "tracking_acceleration"]

KIND = "computed-torque"
CODE = 2
JIT = True
#: The compiled step functions agree with the reference (Pinocchio) to rounding, not
#: bit for bit (:data:`esoarm.plants.arms.compiled.ENGINE_TOLERANCE`).
COMPILED_EXACT = False

_PositiveGain = Annotated[float, Field(gt=0)]
_HANDLE, _COMP, _FF, _UNIT = 1, 2, 3, 4


class Params(Section):
    """``[controller]`` of kind "computed-torque": the FLC on n joints (a URDF arm)."""

    kind: Literal["computed-torque"] = Field(
        "computed-torque",
        description='controller kind: "computed-torque" (the FLC on a URDF arm)')
    k1: _PositiveGain | list[_PositiveGain] = Field(
        10.0, description="error-rate gain k1: one number for every joint, or one per joint",
        json_schema_extra=unit("1/s"))
    k2: _PositiveGain | list[_PositiveGain] = Field(
        25.0, description="error gain k2: one number for every joint, or one per joint",
        json_schema_extra=unit("1/s²"))
    compensation: Literal["eso", "model"] = Field(
        "eso", description='"eso": τ = M̂(α − ẑ3) (proposed) | "model": τ = M̂α + n̂ '
        "(computed torque on the nominal model, the Fig. 7 baseline)")
    feedforward: bool = Field(
        False, description='with "eso": add the nominal n̂(q̂, q̂̇) to τ (the observers then '
        "estimate only what the nominal model misses)")


def per_joint(value: float | list[float], n: int) -> np.ndarray:
    """A per-joint key as n values (one number applies to every joint).

    Parameters
    ----------
    value : float or list of float
        The key's value: one number, or one per joint (the loader checks the length).
    n : int
        Number of joints.

    Returns
    -------
    ndarray, shape (n,)
        The values as floats, in the key's unit.
    """
    if isinstance(value, list):
        return np.array(value, dtype=float)
    return np.full(n, float(value))


def _unit_vector(k1: float, k2: float) -> np.ndarray:
    # The FLC law of a unit-inertia joint without perturbation estimate is α
    # itself: I0 (α − β̂) with I0 = 1, β̂ = z3 = 0.
    vec = np.zeros(_flc.VECTOR_SIZE)
    vec[_flc.K1], vec[_flc.K2], vec[_flc.I0] = k1, k2, 1.0
    vec[_flc.COMP], vec[_flc.LIMIT] = _flc.COMP_ESO, math.inf
    return vec


@jitable
def tracking_acceleration(z1: float, z2: float, q_ref: float, v_ref: float, a_ref: float,
                          unit_ctl: np.ndarray) -> float:
    """α = q̈d − k1 (ẑ2 − q̇d) − k2 (ẑ1 − qd) [rad/s²] (eq. 16), by the lever arm's law.

    ``unit_ctl`` is the FLC vector of a unit-inertia joint without perturbation
    estimate; :func:`esoarm.controllers.flc.flc_command` then returns α exactly.

    Parameters
    ----------
    z1, z2 : float
        Estimated joint angle ẑ1 [rad] and rate ẑ2 [rad/s].
    q_ref, v_ref, a_ref : float
        Reference qd [rad], q̇d [rad/s], q̈d [rad/s²].
    unit_ctl : ndarray, shape (6,)
        The joint's unit FLC vector (k1 [1/s], k2 [1/s²], I0 = 1, 0, "eso", limit ∞).

    Returns
    -------
    float
        The tracking acceleration α [rad/s²], positive along increasing q.
    """
    return float(_flc.flc_command(z1, z2, 0.0, q_ref, v_ref, a_ref, unit_ctl))


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, handle, model flag, feed-forward flag, one unit FLC vector per joint, the
    nominal model packed for the compiled engine).

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[controller]``, ``[plant]`` and ``[actuator]`` tables).
    plant : PlantDesign
        The plant's design (number of joints n, its vector).
    ts : float
        Sample period Ts [s] (unused: the law is static).

    Returns
    -------
    ComponentDesign
        The packed vector above, one unused state.

    Raises
    ------
    ValueError
        If the plant is not a URDF arm.
    """
    from esoarm.plants.arms import urdf
    from esoarm.plants.arms.compiled import nominal_offset, true_offset

    if int(plant.vector[0]) != urdf.CODE:
        raise ValueError("the computed-torque controller needs plant.kind = 'urdf'")
    n = plant.n_joints
    ctl = scn.controller
    k1, k2 = per_joint(ctl.k1, n), per_joint(ctl.k2, n)
    head = [float(CODE), float(plant.vector[urdf.HANDLE]), float(ctl.compensation == "model"),
            float(urdf.feeds_forward(scn))]
    units = [_unit_vector(float(a), float(b)) for a, b in zip(k1, k2, strict=True)]
    nominal = plant.vector[nominal_offset(n):true_offset(n)]
    return ComponentDesign(read_only(np.concatenate([head, *units, nominal])), 1)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """Computed torque has no state of its own.

    Parameters
    ----------
    c : ndarray
        The controller's own state (length ``n_state`` of its design); left untouched.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """


@jitable
def control_compiled(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
                     p: np.ndarray, u: np.ndarray) -> None:
    """:func:`control` as the compiled engine runs it: M̂, n̂ by :mod:`esoarm.plants.arms.rigid_body`.

    Parameters
    ----------
    c : ndarray
        The controller's own state (unused).
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k: angle [rad], rate [rad/s] and total perturbation [rad/s²] of
        joint j in ``zhat[3j:3j+3]``.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad] (unused: the law uses ẑ_k).
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE, the nominal model packed after the
        per-joint gains.
    u : ndarray, shape (n,)
        Output: the raw torque u_k [N·m] per joint, written in place (positive along
        increasing q; before saturation).
    """
    n = u.shape[0]
    size = _flc.VECTOR_SIZE
    nominal = p[_UNIT + size * n:_UNIT + size * n + model_size(n)]
    ws = np.empty(workspace_size(n))  # the one allocation: α in the caller's part
    alpha = scratch_offset(n)
    for j in range(n):
        i = 3 * j
        ws[alpha + j] = tracking_acceleration(zhat[i], zhat[i + 1], refs[i, k], refs[i + 1, k],
                                              refs[i + 2, k],
                                              p[_UNIT + size * j:_UNIT + size * (j + 1)])
    dynamics_terms(nominal, zhat[0:3 * n:3], zhat[1:3 * n:3], ws)  # M̂ and n̂ at (q̂, q̂̇)
    mm, nb = mass_offset(n), bias_offset(n)
    model = p[_COMP] != 0.0
    for r in range(n):
        acc = 0.0
        for j in range(n):
            a = ws[alpha + j]
            acc += ws[mm + n * r + j] * (a if model else a - zhat[3 * j + 2])
        u[r] = acc + ws[nb + r] if model or p[_FF] != 0.0 else acc


@jitable_as(control_compiled, array_arg=5)
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: np.ndarray, u: np.ndarray) -> None:
    """Raw torque u_k [N·m] per joint from ẑ_k and the reference at sample k (module docstring).

    Parameters
    ----------
    c : ndarray
        The controller's own state (unused).
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k: angle [rad], rate [rad/s] and total perturbation [rad/s²] of
        joint j in ``zhat[3j:3j+3]``; the perturbation is q̈ − b0·v, v the observers' input.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad] (unused: the law uses ẑ_k).
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m] per joint, written in place (positive along
        increasing θ; before the actuator's saturation).
    """
    from esoarm.plants.arms.urdf import arm_of

    arm = arm_of(p)
    n = len(u)
    size = _flc.VECTOR_SIZE
    alpha = np.empty(n)
    for j in range(n):
        i = 3 * j
        unit_ctl = p[_UNIT + size * j:_UNIT + size * (j + 1)]
        alpha[j] = tracking_acceleration(zhat[i], zhat[i + 1], refs[i, k], refs[i + 1, k],
                                         refs[i + 2, k], unit_ctl)
    q_hat = zhat[0:3 * n:3]
    m_hat = arm.mass_matrix(q_hat)
    if p[_COMP] != 0.0:  # "model": computed torque on the nominal model alone
        u[:] = m_hat @ alpha + arm.bias(q_hat, zhat[1:3 * n:3])
        return
    tau = m_hat @ (alpha - zhat[2:3 * n:3])
    if p[_FF] != 0.0:
        tau = tau + arm.bias(q_hat, zhat[1:3 * n:3])
    u[:] = tau


def check(scn: Scenario) -> str | None:
    """One line if the plant is not a URDF arm (computed torque needs M̂ and n̂), else None.

    Parameters
    ----------
    scn : Scenario
        The validated scenario.

    Returns
    -------
    str or None
        The error line naming ``controller.kind``, or None when the scenario fits.
    """
    if scn.plant.kind != "urdf":
        return ("key 'controller.kind': 'computed-torque' needs plant.kind = 'urdf' "
                "(the lever arm uses 'flc')")
    return None


def label(params: Params) -> str:
    """The controller in titles: ``eso compensation`` (or ``model compensation``).

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"{params.compensation} compensation"
