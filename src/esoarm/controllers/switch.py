"""Controller kind ``"switch"``: the PID, then ESO + FLC from ``switch_at``, bumpless both ways.

A rig commissioned with a PID switches to the ESO + FLC (eq. 14-16, β̂ = ẑ3) at
t = ``switch_at`` and, if ``switch_back`` > 0, back to the PID at that time.  The ESO runs
beside the PID from the first sample (every scenario's observer does), so at the switch it
holds the running loop's estimate: nothing to initialise.  What would jump is u:

PID → FLC (``transfer = "bumpless"``)
    Δ = u_{k−1} − u_FLC,k at the first FLC sample; then u_k = u_FLC,k + Δ·a^(k − k_s),
    a = e^(−Ts/transfer_time): the FLC's command, entered from the PID's last one.
FLC → PID
    the PID's integrator is set so that its first command is the last one applied,
    I = u_{k−1} − kp·e_k, its derivative started without a kick (D = 0, e_{k−1} = e_k):
    the classic bumpless PID start.
``transfer = "hard"``
    no offset, the PID started from I = 0 (what switching the kind would do).

The PID and FLC laws are :func:`esoarm.controllers.pid.pid_command` and
:func:`esoarm.controllers.flc.flc_command` on slices of this kind's vector.
State: the PID's (I, D, e_{k−1}), the mode (0 PID, 1 FLC), the last applied (saturated)
command u_{k−1} [N·m], the offset Δ [N·m].
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, Vector, read_only
from esoarm.controllers.common import PID_SIZE, one_joint, pid_vector, zero_state
from esoarm.controllers.flc import FLCParams, flc_command
from esoarm.controllers.pid import pid_command
from esoarm.plants.actuator import saturate

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "Params", "control", "design", "initialize", "label",
           "switch_command"]

KIND = "switch"
CODE = 5
JIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "switch.c"

# Layout after the CODE: the PID's vector (6), the FLC's vector (6), then the switch.
PID0, FLC0, K_SWITCH, K_BACK, DECAY = 0, PID_SIZE, 12, 13, 14
# state
INT, DER, EPREV, MODE, ULAST, OFFSET = range(6)


class Params(Section):
    """``[controller]`` of kind "switch": PID, then ESO + FLC, and back, without a bump."""

    kind: Literal["switch"] = Field(
        "switch", description="controller kind (the registered kinds: esoarm.kinds)")
    kp: float = Field(3.0, ge=0, description="PID: proportional gain kp",
                      json_schema_extra=unit("N·m/rad"))
    ki: float = Field(2.0, ge=0, description="PID: integral gain ki",
                      json_schema_extra=unit("N·m/(rad·s)"))
    kd: float = Field(0.07, ge=0, description="PID: derivative gain kd",
                      json_schema_extra=unit("N·m·s/rad"))
    derivative_filter: float = Field(0.02, ge=0, description="PID: derivative filter Tf",
                                     json_schema_extra=unit("s"))
    k1: float = Field(10.0, gt=0, description="FLC: error-rate gain k1",
                      json_schema_extra=unit("1/s"))
    k2: float = Field(25.0, gt=0, description="FLC: error gain k2",
                      json_schema_extra=unit("1/s²"))
    switch_at: float = Field(10.0, ge=0, description="time of the switch from the PID to the "
                             "ESO + FLC", json_schema_extra=unit("s"))
    switch_back: float = Field(0.0, ge=0, description="time of the switch back to the PID "
                               "(0: never)", json_schema_extra=unit("s"))
    transfer: Literal["bumpless", "hard"] = Field(
        "bumpless", description='"bumpless": the FLC entered from the PID\'s last command, the '
        'PID restarted from the last command | "hard": neither')
    transfer_time: float = Field(0.3, gt=0, description="bumpless: time constant of the "
                                 "offset's decay after PID → FLC", json_schema_extra=unit("s"))


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, PID vector, FLC vector, k_switch, k_back, decay); six states.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (``[controller]``, ``[plant]``, ``[actuator]``).
    plant : PlantDesign
        The plant's design (one joint).
    ts : float
        Sample period Ts [s].

    Returns
    -------
    ComponentDesign
        The vector (16 values; ``decay`` 0 for a hard transfer) and 6 states.
    """
    one_joint(plant, "the switch kind")
    c = scn.controller
    limit = scn.actuator.torque_limit
    pid = pid_vector(c, limit, ts)
    p = scn.plant
    flc = FLCParams(c.k1, c.k2, p.inertia, 0.0, "eso", limit).vector
    k_switch = float(math.ceil(c.switch_at / ts - 1e-9))
    k_back = float(math.ceil(c.switch_back / ts - 1e-9)) if c.switch_back > 0 else -1.0
    decay = math.exp(-ts / c.transfer_time) if c.transfer == "bumpless" else 0.0
    bumpless = 1.0 if c.transfer == "bumpless" else 0.0
    vec = np.array([float(CODE), *pid, *flc[:4], bumpless, flc[5], k_switch, k_back, decay])
    return ComponentDesign(read_only(vec), 6)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """The PID's state zero, mode PID, no command yet.

    Parameters
    ----------
    c : ndarray, shape (6,)
        The state, set in place.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """
    zero_state(c)


@jitable
def switch_command(c: np.ndarray, zhat: np.ndarray, y: float, theta_ref: float,
                   omega_ref: float, accel_ref: float, k: int, v: Vector) -> float:
    """Raw command u_k [N·m] of the PID or the FLC (with the transfer's offset).

    Parameters
    ----------
    c : ndarray, shape (6,)
        State (I, D, e_{k−1}, mode, u_{k−1}, Δ), updated in place.
    zhat : ndarray
        The observer's estimate ẑ_k (angle, rate, perturbation).
    y : float
        Measured angle y_k [rad].
    theta_ref, omega_ref, accel_ref : float
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] at t_k.
    k : int
        Sample index.
    v : ndarray or tuple of float
        The design vector without its CODE.

    Returns
    -------
    float
        u_k [N·m] before saturation.
    """
    flc_mode = k >= v[K_SWITCH] and not (v[K_BACK] >= 0.0 and k >= v[K_BACK])
    bumpless = v[FLC0 + 4] == 1.0  # the FLC vector's compensation slot holds the transfer
    e = theta_ref - y
    u: float
    if flc_mode:
        flc = (v[FLC0], v[FLC0 + 1], v[FLC0 + 2], v[FLC0 + 3], 0.0, v[FLC0 + 5])
        u_flc = flc_command(zhat[0], zhat[1], zhat[2], theta_ref, omega_ref, accel_ref,
                            flc)  # type: ignore[arg-type]  # a tuple, as compiled
        if c[MODE] == 0.0:  # PID → FLC
            c[OFFSET] = c[ULAST] - u_flc if (bumpless and k > 0) else 0.0
            c[MODE] = 1.0
        u = u_flc + c[OFFSET]
        c[OFFSET] = c[OFFSET] * v[DECAY]
    else:
        if c[MODE] == 1.0:  # FLC → PID: restart from the last command
            c[INT] = c[ULAST] - v[PID0] * e if bumpless else 0.0
            c[DER] = 0.0
            c[EPREV] = e
            c[MODE] = 0.0
        pid = (v[PID0], v[PID0 + 1], v[PID0 + 2], v[PID0 + 3], v[PID0 + 4], v[PID0 + 5])
        u = pid_command(e, k, c, pid)
    c[ULAST] = saturate(u, v[FLC0 + 5])
    return u


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: Vector, u: np.ndarray) -> None:
    """Raw command u_k [N·m] of the active law into ``u`` (joint 0).

    Parameters
    ----------
    c : ndarray, shape (6,)
        State (:func:`switch_command`).
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] per joint, one column per sample.
    k : int
        Sample index.
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m].
    """
    u[0] = switch_command(c, zhat, y[0], refs[0, k], refs[1, k], refs[2, k], k, p[1:])


def label(params: Params) -> str:
    """The controller in titles: ``PID → ESO + FLC at 10 s (bumpless)``.

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    back = f", back at {params.switch_back:g} s" if params.switch_back > 0 else ""
    return f"PID → ESO + FLC at {params.switch_at:g} s{back} ({params.transfer})"
