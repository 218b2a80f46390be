"""What the controller kinds share: plain functions, written once, that the kinds import.

Not a kind (no ``KIND``): the pieces that the PID, the switch and the linear ADRC forms
(:mod:`~esoarm.controllers.pid`, :mod:`~esoarm.controllers.switch`,
:mod:`~esoarm.controllers.adrc_error`, :mod:`~esoarm.controllers.adrc_tf`) each had
written again:

- the one-joint check of a design (:func:`one_joint`);
- the PID's part of a design vector (:func:`pid_vector`) and its anti-windup, conditional
  integration (:func:`integration_held`);
- the clip of the command a controller's own ESO is fed (:func:`eso_input_limit`): the
  saturated command the actuator applies (anti-windup), or the command itself (the
  paper's ESO);
- the own ESO of a linear ADRC form (:func:`own_eso`) and its words in a title
  (:func:`eso_words`);
- a zero start of a controller's state (:func:`zero_state`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm._jit import jitable
from esoarm.observers.linear import ESODesign, design_observer

if TYPE_CHECKING:
    from esoarm.contract import PlantDesign

__all__ = ["UNCLIPPED", "eso_input_limit", "eso_words", "flc_equivalent", "integration_held",
           "one_joint", "own_eso",
           "pid_vector", "zero_state"]

#: Length of :func:`pid_vector` (kp, ki, kd, Tf, torque_limit, Ts).
PID_SIZE = 6


def one_joint(plant: PlantDesign, kind: str) -> None:
    """Refuse a plant of more than one joint for a one-joint controller kind.

    Parameters
    ----------
    plant : PlantDesign
        The plant's design.
    kind : str
        The controller's words in the message (e.g. ``"the PID kind"``).

    Raises
    ------
    ValueError
        ``plant.n_joints != 1``.
    """
    if plant.n_joints != 1:
        raise ValueError(f"{kind} is designed for one joint")


def pid_vector(ctl: Any, limit: float, ts: float) -> list[float]:
    """The PID's part of a design vector: (kp, ki, kd, Tf, torque_limit, Ts).

    Parameters
    ----------
    ctl : Params
        A ``[controller]`` table with ``kp`` [N·m/rad], ``ki`` [N·m/(rad·s)], ``kd``
        [N·m·s/rad] and ``derivative_filter`` Tf [s].
    limit : float
        torque_limit [N·m] (the anti-windup's saturation).
    ts : float
        Sample period Ts [s].

    Returns
    -------
    list of float
        :data:`PID_SIZE` values, in the order :func:`esoarm.controllers.pid.pid_command`
        reads them.
    """
    return [float(ctl.kp), float(ctl.ki), float(ctl.kd), float(ctl.derivative_filter),
            float(limit), float(ts)]


@jitable
def integration_held(u: float, e: float, limit: float) -> bool:
    """The PID's anti-windup: True while u is saturated in the direction e drives it.

    Conditional integration: the integrator stops while |u| > limit and the error pushes
    the command further out.

    Parameters
    ----------
    u : float
        The command before saturation [N·m].
    e : float
        Tracking error e = θd − y [rad].
    limit : float
        torque_limit [N·m].

    Returns
    -------
    bool
        True: hold the integrator this sample.

    Examples
    --------
    >>> integration_held(3.0, 0.1, 2.0), integration_held(3.0, -0.1, 2.0)
    (True, False)
    """
    return (u > limit and e > 0.0) or (u < -limit and e < 0.0)


#: The clip of an own ESO's input when it is fed the command itself [N·m]: none in effect
#: (finite, so that the generated C carries it; float32 holds it).
UNCLIPPED = 1e30


def eso_input_limit(scn: Any) -> float:
    """What a controller's own ESO clips its input command to [N·m].

    Parameters
    ----------
    scn : Scenario
        ``actuator.torque_limit`` and ``actuator.observer_sees``.

    Returns
    -------
    float
        torque_limit with ``observer_sees = "applied"`` (the ESO fed the saturated command,
        what the actuator applies: the anti-windup); :data:`UNCLIPPED` with
        ``"commanded"`` (the command itself, the paper's ESO, which winds up while the
        command saturates).
    """
    if scn.actuator.observer_sees == "commanded":
        return UNCLIPPED
    return float(scn.actuator.torque_limit)


@jitable
def zero_state(c: np.ndarray) -> None:
    """Every entry of a controller's state set to zero (a kind's ``initialize``).

    Parameters
    ----------
    c : ndarray
        The state, set in place.
    """
    for i in range(len(c)):
        c[i] = 0.0


def own_eso(params: Any, ts: float, b0: float) -> ESODesign:
    """The linear ESO of a linear ADRC form's own keys (ε, discretization, tuning).

    Parameters
    ----------
    params : LinearADRCParams
        ``eps`` [s], ``discretization``, ``tuning``.
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain b0 = 1/I0 [1/(kg·m²)].

    Returns
    -------
    ESODesign
        :func:`esoarm.observers.linear.design_observer` of those keys.
    """
    return design_observer(params.eps, ts, b0, params.discretization, params.tuning)


def flc_equivalent(params: Any) -> dict[str, object]:
    """The FLC of eq. 14-16 with ``compensation = "eso"`` and the linear ESO of a linear ADRC
    form's own keys: the same feedback loop y → u (the kind contract's ``flc_equivalent``).

    The output-based form in either realisation (adrc-tf) commands the same u as that FLC to
    round-off; the error-based form (adrc-error) differs from it only in the reference path
    (at rest, the same u to round-off: tests/controllers/test_flc_equivalent.py), so the
    margins, sensitivities and noise gains of the frequency-domain analysis are the same.

    Parameters
    ----------
    params : LinearADRCParams
        k1 [1/s], k2 [1/s²], ``eps`` [s], ``discretization``, ``tuning``.

    Returns
    -------
    dict
        Scenario overrides (``controller.*``, ``observer.*``).
    """
    return {"controller.kind": "flc", "controller.compensation": "eso",
            "controller.k1": params.k1, "controller.k2": params.k2,
            "observer.kind": "linear", "observer.eps": params.eps,
            "observer.discretization": params.discretization,
            "observer.tuning": params.tuning}


def eso_words(params: Any) -> str:
    """The own ESO in a title: ``ε = 0.09 s, euler`` (``, half-gain`` when halved).

    Parameters
    ----------
    params : LinearADRCParams
        ``eps`` [s], ``discretization``, ``tuning``.

    Returns
    -------
    str
        The words.
    """
    tune = ", half-gain" if params.tuning == "half-gain" else ""
    return f"ε = {params.eps:g} s, {params.discretization}{tune}"
