"""Controller kind ``"adrc-error"``: error-based linear ADRC, its own ESO driven by e = θd − y.

The tracking error e = r − y (r = θd, y the measured angle) of the plant θ̈ = f + b0 u obeys
ë = −b0 u + (r̈ − f): a double integrator in e with the input gain −b0 and a total
perturbation F = r̈ − f that holds the reference's second derivative.  An ESO of that model
(the linear ESO of eq. 8 with −b0; the same discretizations and tunings as
:mod:`esoarm.observers.linear`) estimates ẑ = (ê, ė̂, F̂), and the law

    u = (k2 ẑ1 + k1 ẑ2 + ẑ3) / b0

makes ë = −k1 ė − k2 e + (F − ẑ3).  No derivative of the reference is needed: the
controller sees only r_k and y_k, like a PID.  (Madoński, Herbst & Stanković, "ADRC in
output and error form: connection, equivalence, performance", Control Theory Technol. 2023,
arXiv:2211.07427; discrete forms: Herbst & Madoński, arXiv:2211.07309.)

Equivalence with the output-based form (the linear ESO + FLC with the same ε, k1, k2):
with w = (r, ṙ, r̈), the error-based state is w − ẑ_output exactly when w advances by the
observer's own model, w_{k+1} = Φ w_k ("zoh" and "current": r a polynomial of degree ≤ 2;
"euler": degree ≤ 1), and the initial states correspond (ṙ_0 = r̈_0 = 0 for the start
z_0 = (e_0, 0, 0)).  In particular at a constant set point the two command the same u
(tested, open and closed loop); along test-1's quintic moves (r⃛ ≠ 0) the error-based form
carries the reference's derivatives in its perturbation estimate and lags a little.

The ESO is fed the command it saturates itself to ±torque_limit (what the actuator applies,
the anti-windup of output-based ADRC), or with ``actuator.observer_sees = "commanded"`` the
command before saturation (the paper's ESO).  The observer kind of the scenario still runs beside it
and is logged (as with the PID).

State (3): the error ESO's z_k; the first sample sets z_0 = (e_0, 0, 0).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, Vector, read_only
from esoarm.controllers.common import (
    eso_input_limit,
    eso_words,
    flc_equivalent,
    one_joint,
    own_eso,
    zero_state,
)
from esoarm.plants.actuator import saturate

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "LinearADRCParams", "Params", "adrc_error_command",
           "control", "design", "error_eso_vector", "flc_equivalent", "initialize", "label"]

KIND = "adrc-error"
CODE = 3
JIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "adrc_error.c"

# Layout of the design vector after the CODE.
DISC, TS, B0, G1, G2, G3, PHI02, GAM0, GAM1, K1, K2, I0, LIMIT = range(13)
EULER, ZOH, CURRENT = 0, 1, 2


class LinearADRCParams(Section):
    """The keys every linear ADRC controller kind shares (gains and its own ESO)."""

    k1: float = Field(10.0, gt=0, description="error-rate gain k1 (closed loop "
                      "s² + k1 s + k2)", json_schema_extra=unit("1/s"))
    k2: float = Field(25.0, gt=0, description="error gain k2", json_schema_extra=unit("1/s²"))
    eps: Annotated[float, Field(gt=0)] = Field(
        0.09, description="the controller's own ESO: poles at −1/ε", json_schema_extra=unit("s"))
    discretization: Literal["euler", "zoh", "current"] = Field(
        "euler", description='its ESO: "euler" | "zoh" | "current" (as observer.discretization)')
    tuning: Literal["bandwidth", "half-gain"] = Field(
        "bandwidth", description='its ESO: "bandwidth" | "half-gain" (as observer.tuning)')


class Params(LinearADRCParams):
    """``[controller]`` of kind "adrc-error": error-based linear ADRC."""

    kind: Literal["adrc-error"] = Field(
        "adrc-error", description="controller kind (the registered kinds: esoarm.kinds)")


def error_eso_vector(params: LinearADRCParams, ts: float, b0: float, limit: float) -> np.ndarray:
    """The compact vector of the error ESO and the law (no CODE).

    Parameters
    ----------
    params : LinearADRCParams
        k1 [1/s], k2 [1/s²], ε [s], discretization, tuning.
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain b0 = 1/I0 [1/(kg·m²)] of the plant (the error model's is −b0).
    limit : float
        The clip of the ESO's input command [N·m]: torque_limit, or
        :data:`~esoarm.controllers.common.UNCLIPPED` (the ESO fed the command itself,
        ``actuator.observer_sees = "commanded"``).

    Returns
    -------
    ndarray, shape (13,)
        (discretization code, Ts, b0, gain G (Ts·β, Lp or Lc), Φ[0, 2], Γ[0]/b0·b0, Γ[1],
        k1, k2, I0, limit); "euler": Φ = I + Ts A, Γ = (0, Ts b0, 0); otherwise the exact
        ZOH model.
    """
    d = own_eso(params, ts, b0)
    disc = ("euler", "zoh", "current").index(params.discretization)
    return np.array([float(disc), ts, b0, *d.gain, d.phi[0, 2], d.gamma[0], d.gamma[1],
                     params.k1, params.k2, 1.0 / b0, limit])


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, :func:`error_eso_vector`); state: the error ESO's 3 states.

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
        The vector and 3 states.
    """
    one_joint(plant, "the adrc-error kind")
    vec = error_eso_vector(scn.controller, ts, float(plant.b0[0]), eso_input_limit(scn))
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], vec])), 3)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """Zero; the first sample sets z_0 = (e_0, 0, 0) (the reference is known there).

    Parameters
    ----------
    c : ndarray, shape (3,)
        The error ESO's state, set to zero.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """
    zero_state(c)


@jitable
def adrc_error_command(c: np.ndarray, e: float, k: int, v: Vector) -> float:
    """Raw command u_k [N·m] from the error e_k = r_k − y_k [rad]; advances the error ESO.

    Parameters
    ----------
    c : ndarray, shape (3,)
        The error ESO's state z_k (ê [rad], ė̂ [rad/s], F̂ [rad/s²]), updated in place to
        z_{k+1} with the saturated command (the command itself with ``observer_sees =
        "commanded"``).
    e : float
        Tracking error e_k = θd(t_k) − y_k [rad].
    k : int
        Sample index (k = 0 starts the ESO at (e_0, 0, 0)).
    v : ndarray or tuple of float
        :func:`error_eso_vector`.

    Returns
    -------
    float
        u_k = I0 (k2 ẑ1 + k1 ẑ2 + ẑ3) [N·m], before saturation.
    """
    if k == 0:
        c[0], c[1], c[2] = e, 0.0, 0.0
    z1, z2, z3 = c[0], c[1], c[2]
    inno = e - z1
    h1, h2, h3 = z1, z2, z3
    if v[DISC] == CURRENT:  # ẑ = z + Lc (e − z1)
        h1, h2, h3 = z1 + v[G1] * inno, z2 + v[G2] * inno, z3 + v[G3] * inno
    u: float = v[I0] * (v[K2] * h1 + v[K1] * h2 + h3)
    us = saturate(u, v[LIMIT])
    ts = v[TS]
    if v[DISC] == CURRENT:  # z⁺ = Φ ẑ + Γ (−u)
        c[0] = h1 + ts * h2 + v[PHI02] * h3 - v[GAM0] * us
        c[1] = h2 + ts * h3 - v[GAM1] * us
        c[2] = h3
    else:  # z⁺ = Φ z + Γ (−u) + G (e − z1); "euler": Φ = I + Ts A, Γ = (0, Ts b0, 0)
        c[0] = z1 + ts * z2 + v[PHI02] * z3 - v[GAM0] * us + v[G1] * inno
        c[1] = z2 + ts * z3 - v[GAM1] * us + v[G2] * inno
        c[2] = z3 + v[G3] * inno
    return u


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: Vector, u: np.ndarray) -> None:
    """Raw command u_k [N·m] from θd(t_k) and y_k (joint 0); the observer's ẑ is not used.

    Parameters
    ----------
    c : ndarray, shape (3,)
        The error ESO's state (:func:`adrc_error_command`).
    zhat : ndarray
        The observer kind's estimate (unused: this controller has its own ESO).
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d, θ̈d of joint j in rows 3j … 3j+2 (only θd is used).
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m] (before saturation).
    """
    u[0] = adrc_error_command(c, refs[0, k] - y[0], k, p[1:])


def label(params: Params) -> str:
    """The controller in titles: ``error-based ADRC (ε = 0.09 s, euler)``.

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"error-based ADRC ({eso_words(params)})"
