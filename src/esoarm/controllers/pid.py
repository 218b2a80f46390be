"""Controller kind ``"pid"``: a discrete PID on the measured angle, the classical baseline.

On the tracking error of the measurement, e_k = θd(t_k) − y_k [rad], with the
sample period Ts:

    P_k = kp · e_k
    D_k = a · D_{k−1} + kd · (1 − a) · (e_k − e_{k−1}) / Ts,   a = Tf / (Tf + Ts)
    u_k = P_k + I_k + D_k                       (saturated by the actuator to ±torque_limit)
    I_{k+1} = I_k + ki · Ts · e_k               unless u_k is saturated and e_k drives it further

D is kd·s/(Tf·s + 1) discretized with backward Euler (Tf = ``derivative_filter``;
0 gives the unfiltered difference), starting with no derivative kick (e_{−1} = e_0).
The integrator uses forward Euler, so u_k does not depend on e_k through I,
and stops integrating while the command is saturated in the direction the
error pushes it (conditional integration, the anti-windup).  I_0 = 0, D_0 = 0.

With ``compensation = "none"`` (the default) the PID ignores the observer's estimate: the
ESO still runs beside it (its estimates are logged), so a PID run shows what the
perturbation estimate adds.  ``compensation = "eso"`` adds it: u_k = PID_k − ẑ3_k/b0
(MATLAB's Disturbance Compensator block, u = u0 + Kd·d̂ with Kd = −1/b0), so a user keeps
their PID and the ESO cancels the total perturbation it sees; the anti-windup judges the
compensated command.
The default gains are tuned on test-1, rounded: ``esoarm tune test-1 --set
controller.kind=pid --vary controller.kp=0.1:3 --vary controller.kd=0.005:0.5
--vary controller.ki=0:5 --seeds 2 --maxiter 12 --popsize 6`` (objective
rms_error + rms_u) found kp = 2.96, kd = 0.072, ki = 1.98 (RMS error 0.0075 rad,
RMS u 0.037 N·m; kp at the top of its range).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, Vector, read_only
from esoarm.controllers.common import integration_held, one_joint, pid_vector, zero_state

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "Params", "control", "design", "initialize", "label",
           "pid_command"]

KIND = "pid"
CODE = 1
JIT = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "pid.c"

KP, KI, KD, TF, LIMIT, TS, COMP, INV_B0 = range(8)
COMPENSATIONS = ("none", "eso")
# controller state: integrator, filtered derivative, previous error
INT, DER, EPREV = range(3)


class Params(Section):
    """``[controller]`` of kind "pid": discrete PID with derivative filter and anti-windup."""

    kind: Literal["pid"] = Field(
        "pid", description="controller kind (the registered kinds: esoarm.kinds)")
    kp: float = Field(3.0, ge=0, description="proportional gain kp",
                      json_schema_extra=unit("N·m/rad"))
    ki: float = Field(2.0, ge=0, description="integral gain ki",
                      json_schema_extra=unit("N·m/(rad·s)"))
    kd: float = Field(0.07, ge=0, description="derivative gain kd",
                      json_schema_extra=unit("N·m·s/rad"))
    derivative_filter: float = Field(
        0.02, ge=0, description="time constant Tf of the derivative's first-order filter",
        json_schema_extra=unit("s"))
    compensation: Literal["none", "eso"] = Field(
        "none", description='"none": the PID alone | "eso": the ESO\'s perturbation estimate '
        "compensated, u = PID − ẑ3/b0 (a disturbance compensator)",
        json_schema_extra={"own_meaning": True})


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, kp, ki, kd, Tf, torque_limit, Ts); state: integrator, derivative, last error.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[controller]``, ``[plant]`` and ``[actuator]`` tables).
    plant : PlantDesign
        The plant's design (number of joints n, its vector).
    ts : float
        Sample period Ts [s] (the PID's discretization step).

    Returns
    -------
    ComponentDesign
        kp [N·m/rad], ki [N·m/(rad·s)], kd [N·m·s/rad], Tf [s], torque_limit [N·m],
        Ts [s], compensation (0 "none", 1 "eso"), 1/b0 [kg·m²] after the CODE; three states
        (I [N·m], D [N·m], e_{k−1} [rad]).
    """
    ctl = scn.controller
    if not isinstance(ctl, Params):  # pragma: no cover - the registry dispatches by kind
        raise TypeError("not a PID controller table")
    one_joint(plant, "the PID kind")
    vec = [float(CODE), *pid_vector(ctl, scn.actuator.torque_limit, ts),
           float(COMPENSATIONS.index(ctl.compensation)), 1.0 / float(plant.b0[0])]
    return ComponentDesign(read_only(np.array(vec)), 3)


@jitable
def pid_command(e: float, k: int, c: np.ndarray, pid: Vector, comp: float = 0.0) -> float:
    """PID command u_k [N·m] for the error e_k [rad] at sample k; updates the state ``c``.

    ``pid`` is the design vector without its CODE; ``c`` = (I, D, e_{k−1}).

    Parameters
    ----------
    e : float
        Tracking error e_k = θd(t_k) − y_k [rad] (positive when the arm is below the
        reference).
    k : int
        Sample index (k = 0: no derivative kick, e_{−1} = e_0).
    c : ndarray, shape (3,)
        Controller state (I_k [N·m], D_{k−1} [N·m], e_{k−1} [rad]), updated in place to
        (I_{k+1}, D_k, e_k).
    pid : ndarray or tuple of float
        (kp [N·m/rad], ki [N·m/(rad·s)], kd [N·m·s/rad], Tf [s], torque_limit [N·m], Ts [s],
        ...).
    comp : float
        A compensation added to the command [N·m] (−ẑ3/b0 with ``compensation = "eso"``),
        part of the command the anti-windup judges.

    Returns
    -------
    float
        The command u_k = P_k + I_k + D_k + comp [N·m], before saturation.

    Examples
    --------
    >>> import numpy as np
    >>> c = np.zeros(3)
    >>> pid = (2.0, 1.0, 0.0, 0.0, 10.0, 0.1)  # kp, ki, kd, Tf, limit, Ts
    >>> float(pid_command(0.5, 0, c, pid)), float(c[0])  # P = 1.0; then I = 0.1 * 0.5
    (1.0, 0.05)
    """
    ts = pid[TS]
    e_prev = e if k == 0 else c[EPREV]
    a = pid[TF] / (pid[TF] + ts)
    der = a * c[DER] + pid[KD] * (1.0 - a) * (e - e_prev) / ts
    u: float = pid[KP] * e + c[INT] + der + comp
    if not integration_held(u, e, pid[LIMIT]):  # the anti-windup
        c[INT] = c[INT] + pid[KI] * ts * e
    c[DER] = der
    c[EPREV] = e
    return u


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """I_0 = 0, D_0 = 0 (the first sample has no derivative kick).

    Parameters
    ----------
    c : ndarray
        The controller's own state (length ``n_state`` of its design): (I, D, e_{k−1}), set to zero.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """
    zero_state(c)


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: Vector, u: np.ndarray) -> None:
    """Raw PID command u_k [N·m] from the measured y_k and θd(t_k) into ``u`` (joint 0).

    Parameters
    ----------
    c : ndarray
        The controller's own state: (I, D, e_{k−1}), updated in place (:func:`pid_command`).
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k: angle [rad], rate [rad/s] and total perturbation [rad/s²] of
        joint j in ``zhat[3j:3j+3]``; the perturbation is f = θ̈ − b0·u (eq. 7); with
        ``compensation = "eso"`` −ẑ3/b0 is added to the command.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad]; e_k = θd(t_k) − y_k.
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m] per joint, written in place (positive along
        increasing θ; before saturation).
    """
    pid = p[1:]
    comp = -pid[INV_B0] * zhat[2] if pid[COMP] == 1.0 else 0.0
    u[0] = pid_command(refs[0, k] - y[0], k, c, pid, comp)


def label(params: Params) -> str:
    """The controller in titles: ``pid controller``, ``+ ESO compensation`` when compensated.

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    return "pid controller + ESO compensation" if params.compensation == "eso" \
        else "pid controller"
