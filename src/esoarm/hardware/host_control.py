"""The deployment controller: the scenario's observer and controller stepped one sample at a time.

It drives :class:`esoarm.engines.stepper.Stepper` (the controller half of the sample of
every engine, with the step functions of the scenario's kinds, :mod:`esoarm.kinds`) from
measured angles:

    ẑ_k = estimate(z_k, y_k)                    (observer kind)
    u_k = sat(control(ẑ_k, y_k, reference_k))   (controller kind, ±torque_limit)
    u_k, drive_k, duty_k = actuate(u_k, ẑ2_k)   (motor: torque -> PWM duty; a learned
                                                 table's −I0·m(ẑ1) in the drive and duty)
    v_k = observer_input(ẑ_k, u_k)              (plant kind: u_k itself for the lever arm;
                                                 the command before saturation with
                                                 actuator.observer_sees = "commanded")
    z_{k+1} = advance(z_k, ẑ_k, y_k, v_k)       (observer kind)

and a sample that never arrived is bridged with the observer kind's ``predict`` (the
measurement it expects), so a run fed the simulator's measurements reproduces
:func:`esoarm.engines.simulation.run_reference` bit for bit (tested).  The
reference is precomputed for all N samples with the same vectorized
:func:`esoarm.reference.evaluate_reference` call the simulators use.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from esoarm.engines.stepper import Stepper
from esoarm.plants.actuator import LIMIT, SEES, SEES_COMMANDED, actuate_with_table, saturate
from esoarm.scenario import Scenario

__all__ = ["DeploymentController", "SampleController"]


class SampleController(Protocol):
    """What the real-time loop drives per sample: :class:`DeploymentController` and the
    identification's excitation controller both provide it."""

    n_samples: int
    ts: float
    t: list[float]
    torque_limit: float
    zhat: tuple[float, float, float]

    def reference(self, k: int) -> float:
        """θd(t_k) [rad]."""

    def step(self, k: int, y: float) -> float:
        """Command u_k [N·m] from the measured angle y_k [rad]."""

    def commit(self, u: float) -> None:
        """The torque u_k [N·m] applied from t_k on."""

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a lost sample; return the estimate used for it."""


class DeploymentController:
    """Observer + controller for one run of a scenario, stepped per sample.

    Per sample k: ``u = step(k, y)`` (estimate, control law, saturation), then
    ``u_applied, duty = actuate(u)`` (the motor's duty, if any), then
    ``commit(u_applied)`` (observer update with the torque applied over
    [t_k, t_{k+1})).  A sample that never arrived is bridged with
    :meth:`predict` (observer update with zero innovation).

    Parameters
    ----------
    scn : Scenario
        The resolved scenario (plant, observer, controller, reference, rate, motor).

    Attributes
    ----------
    n_samples : int
        N = round(duration · rate_hz).
    ts : float
        Sample period [s].
    zhat : tuple of float
        Estimate ẑ_k of joint 0 used for the latest control [rad, rad/s, rad/s²].
    """

    __slots__ = ("_commanded", "_raw", "_ref", "_st", "drive", "kinds", "n_samples", "t",
                 "torque_limit", "ts", "zhat")

    def __init__(self, scn: Scenario) -> None:
        self._st = Stepper.of(scn)
        self.kinds = self._st.kinds
        self._ref = self._st.refs[0].tolist()
        self.t = (np.arange(scn.n_samples) * scn.sample_time).tolist()
        self.n_samples = len(self.t)
        self.ts = scn.sample_time
        self.torque_limit = float(self._st.designs.actuator[LIMIT])
        self.zhat: tuple[float, float, float] = (math.nan, math.nan, math.nan)
        #: the observer is fed the command before saturation (actuator.observer_sees)
        act = self._st.designs.actuator
        self._commanded = bool(len(act) > SEES and act[SEES] == SEES_COMMANDED)
        self._raw = math.nan
        #: the torque driving the rig for the latest command [N·m] (with a learned table)
        self.drive = math.nan

    @property
    def observer_state(self) -> np.ndarray:
        """A copy of the observer state z_{k+1} after the latest commit."""
        return self._st.z.copy()

    def reference(self, k: int) -> float:
        """θd(t_k) [rad]."""
        return self._ref[k]

    def step(self, k: int, y: float) -> float:
        """Control u_k [N·m] (saturated) from the measured angle y_k [rad]."""
        st = self._st
        zhat = st.estimate(y)
        st.control(k)
        st.saturate()
        self.zhat = (float(zhat[0]), float(zhat[1]), float(zhat[2]))
        self._raw = float(st.u[0])  # the command itself when the observer is fed it
        return saturate(self._raw, self.torque_limit)

    def actuate(self, u: float) -> tuple[float, float]:
        """(torque the host applies [N·m], PWM duty [counts] or NaN) for the command u.

        With a learned table the duty (and :attr:`drive`) hold its torque; the host's torque
        does not (the observer is fed the command without it).
        """
        st = self._st
        host, drive, duty = actuate_with_table(saturate(u, self.torque_limit),
                                               float(st.zhat[1]), float(st.zhat[0]),
                                               st.designs.actuator)
        self.drive = float(drive)
        return float(host), float(duty)

    def commit(self, u: float) -> None:
        """Advance the observer with the torque u_k [N·m] applied from t_k on.

        The observer's input is the plant kind's for u_k (u_k itself for the lever arm);
        with ``actuator.observer_sees = "commanded"`` the controller's command before
        saturation instead (the paper's ESO).
        """
        self._st.observe(self._raw if self._commanded else u)

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a missing sample: the observer kind's ``predict`` (zero innovation), then
        the update with u.

        Returns the estimate used for the missing sample.
        """
        zhat = self._st.bridge(u)
        return float(zhat[0]), float(zhat[1]), float(zhat[2])
