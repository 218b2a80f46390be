"""Controller kind ``"adrc-tf"``: linear ADRC in its minimum-footprint transfer-function form.

The output-based linear ADRC (the linear ESO of eq. 8 + the FLC of eq. 14-16 with
β̂ = ẑ3) commands

    u_k = I0 (θ̈d + k1 θ̇d + k2 θd) − c_k,     c_k = I0 (k2 ẑ1 + k1 ẑ2 + ẑ3)

and c is the output of a linear system driven by the measurement y and the applied
(saturated) command u_lim: the ESO (z⁺ = P z + Q y + Γ u_lim, ẑ = Hz z + Hy y, in any
discretization and tuning of :mod:`esoarm.observers.linear`) read through K = I0 (k2, k1, 1).
Its transfer function has a third-order denominator (the ESO's error poles) and is realised
here with three storage variables, as G. Herbst does for discrete ADRC ("A minimum-footprint
implementation of discrete-time ADRC", arXiv:2104.01943; Madoński et al., Control Theory
Technol. 2023), in observer-canonical form, but in the δ operator δ = (z − 1)/Ts (Middleton &
Goodwin) rather than the shift z:

    c_k  = d·y_k + x1_k
    u_k  = I0 (θ̈d + k1 θ̇d + k2 θd) − c_k            (then saturated: u_lim)
    x1⁺  = x1 + (−α1 x1 + Ts x2 + β1 y_k + γ1 u_lim)
    x2⁺  = x2 + (−α2 x1 + Ts x3 + β2 y_k + γ2 u_lim)
    x3⁺  = x3 + (−α3 x1        + β3 y_k + γ3 u_lim)

15 products per sample whatever the discretization (the state-space ESO + FLC: 10 with
"euler", 18 with "zoh" or "current"), three storage variables.  Why δ: the
shift form's coefficients (z³ + a1 z² + a2 z + a3 with the triple pole near 1) cancel each other
(β·y terms of ±5 N·m for a command of 0.1 N·m), and in float32 on the AVR it missed the
float64 reference by 2e-4 of the torque limit over test-1; the δ form's increments are small
and it agrees to 5e-7 (measured on the same inputs, numpy float32).  The realisation is the
same input-output map as the state-space form, for every input sequence, saturation included
(u_lim fed back is what the ESO would see), so it commands the same u to round-off on any
reference: the equivalence Herbst derives, tested here against the state-space kinds in the
closed loop.  The coefficients come from the ESO's matrices (:func:`tf_coefficients`), so
every discretization and the half-gain tuning get their TF form.

The start: the state that a loop at rest at y_0 (z = (y_0, 0, 0), u = 0) has, the fixed point
of the recursion (:func:`initialize` computes it from the coefficients).  With Herbst's
setpoint law (no reference derivatives) set ``feedforward = false``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm.contract import ComponentDesign, PlantDesign, Vector, read_only
from esoarm.controllers.adrc_error import LinearADRCParams
from esoarm.controllers.common import (
    eso_input_limit,
    eso_words,
    flc_equivalent,
    one_joint,
    own_eso,
)
from esoarm.observers.linear import discrete_linearization
from esoarm.plants.actuator import saturate

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "Params", "adrc_tf_command", "control", "design",
           "flc_equivalent", "initialize", "label", "tf_coefficients"]

KIND = "adrc-tf"
CODE = 4
JIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "adrc_tf.c"

# Layout of the design vector after the CODE.
A1, A2, A3, TS, BY1, BY2, BY3, BU1, BU2, BU3, D, F0, F1, F2, LIMIT = range(15)


class Params(LinearADRCParams):
    """``[controller]`` of kind "adrc-tf": linear ADRC as one transfer function (Herbst)."""

    kind: Literal["adrc-tf"] = Field(
        "adrc-tf", description="controller kind (the registered kinds: esoarm.kinds)")
    feedforward: bool = Field(
        True, description="true: I0 (θ̈d + k1 θ̇d + k2 θd) as the FLC | false: I0 k2 θd only "
        "(Herbst's setpoint law)")


def tf_coefficients(params: LinearADRCParams, ts: float, b0: float) -> np.ndarray:
    """(α1, α2, α3, Ts, β1, β2, β3, γ1, γ2, γ3, d): the ESO + law read as c(y, u_lim), δ form.

    The ESO's linear model z⁺ = P z + Q y + Γ u, c = K (Hz z + Hy y) with K = I0 (k2, k1, 1)
    is written in δ: δz = (P − I)/Ts z + (Q y + Γ u)/Ts, and brought to observer-canonical
    form by T = O_c⁻¹ O (O the observability matrix of ((P − I)/Ts, K Hz), O_c that of the
    companion form).  Stored times Ts, so that one step is x⁺ = x + (…).

    Parameters
    ----------
    params : LinearADRCParams
        k1 [1/s], k2 [1/s²], ε [s], discretization, tuning.
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].

    Returns
    -------
    ndarray, shape (11,)
        α·Ts (the δ-denominator's coefficients times Ts), Ts [s], β·Ts [N·m/rad] and γ·Ts
        (dimensionless) the inputs' columns, d [N·m/rad] the direct term of y.
    """
    d = own_eso(params, ts, b0)
    lin = discrete_linearization(d, d.gain, 0.0, "ESO")
    gain = np.array([params.k2, params.k1, 1.0]) / b0
    cw = gain @ lin.hz  # c = cw z + dy y
    dy = float(gain @ lin.hy[:, 0])
    a_delta = (lin.p - np.eye(3)) / ts
    alpha = np.poly(a_delta)[1:]
    companion = np.array([[-alpha[0], 1.0, 0.0], [-alpha[1], 0.0, 1.0], [-alpha[2], 0.0, 0.0]])
    e1 = np.array([1.0, 0.0, 0.0])
    obs = np.vstack([cw, cw @ a_delta, cw @ a_delta @ a_delta])
    obs_c = np.vstack([e1, e1 @ companion, e1 @ companion @ companion])
    tmat = np.linalg.solve(obs_c, obs)
    ny = tmat @ lin.q[:, 0]  # (δ form: /Ts, stored ×Ts)
    nu = tmat @ lin.gamma[:, 0]
    return np.array([*(alpha * ts), ts, *ny, *nu, dy])


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, :func:`tf_coefficients`, feedforward I0·(k2, k1, 1), limit); 3 states.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[controller]`` and ``[actuator]`` tables).
    plant : PlantDesign
        The plant's design (one joint; its b0 [1/(kg·m²)]).
    ts : float
        Sample period Ts [s].

    Returns
    -------
    ComponentDesign
        The vector (16 values; the limit the fed-back command is clipped to is
        :data:`~esoarm.controllers.common.UNCLIPPED` with ``actuator.observer_sees =
        "commanded"``: the command before saturation fed back) and 3 states.
    """
    one_joint(plant, "the adrc-tf kind")
    ctl = scn.controller
    b0 = float(plant.b0[0])
    i0 = 1.0 / b0
    ff = [i0 * ctl.k2, i0 * ctl.k1, i0] if ctl.feedforward else [i0 * ctl.k2, 0.0, 0.0]
    vec = np.concatenate([[float(CODE)], tf_coefficients(ctl, ts, b0), ff,
                          [eso_input_limit(scn)]])
    return ComponentDesign(read_only(vec), 3)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """The state of a loop at rest at y_0: the fixed point under y ≡ y_0, u ≡ 0.

    Every increment zero: x1 = β3 y_0 / α3, x2 = (α1 x1 − β1 y_0)/Ts,
    x3 = (α2 x1 − β2 y_0)/Ts (then c_0 = I0 k2 y_0, the state-space form's K ẑ_0).

    Parameters
    ----------
    c : ndarray, shape (3,)
        The storage variables (x1, x2, x3), set in place.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """
    v = p[1:]
    y0 = y[0]
    x1 = v[BY3] * y0 / v[A3]
    c[0] = x1
    c[1] = (v[A1] * x1 - v[BY1] * y0) / v[TS]
    c[2] = (v[A2] * x1 - v[BY2] * y0) / v[TS]


@jitable
def adrc_tf_command(c: np.ndarray, y: float, theta_ref: float, omega_ref: float,
                    accel_ref: float, v: Vector) -> float:
    """Raw command u_k [N·m]; the storage variables advanced with the saturated command.

    Parameters
    ----------
    c : ndarray, shape (3,)
        (x1, x2, x3), updated in place.
    y : float
        Measured angle y_k [rad].
    theta_ref, omega_ref, accel_ref : float
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] at t_k.
    v : ndarray or tuple of float
        The design vector without its CODE.

    Returns
    -------
    float
        u_k [N·m] before saturation.
    """
    x1, x2, x3 = c[0], c[1], c[2]
    ck = v[D] * y + x1
    u: float = v[F0] * theta_ref + v[F1] * omega_ref + v[F2] * accel_ref - ck
    ul = saturate(u, v[LIMIT])
    ts = v[TS]
    c[0] = x1 + (ts * x2 - v[A1] * x1 + v[BY1] * y + v[BU1] * ul)
    c[1] = x2 + (ts * x3 - v[A2] * x1 + v[BY2] * y + v[BU2] * ul)
    c[2] = x3 + (-v[A3] * x1 + v[BY3] * y + v[BU3] * ul)
    return u


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: Vector, u: np.ndarray) -> None:
    """Raw command u_k [N·m] from y_k and the reference (joint 0); ẑ is not used.

    Parameters
    ----------
    c : ndarray, shape (3,)
        The storage variables (:func:`adrc_tf_command`).
    zhat : ndarray
        The observer kind's estimate (unused: the ESO is inside the transfer function).
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2.
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m] (before saturation).
    """
    u[0] = adrc_tf_command(c, y[0], refs[0, k], refs[1, k], refs[2, k], p[1:])


def label(params: Params) -> str:
    """The controller in titles: ``ADRC, transfer-function form (ε = 0.09 s, euler)``.

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"ADRC, transfer-function form ({eso_words(params)})"
