"""The deployment controller: the scenario's observer and controller stepped one sample at a time.

It calls the step functions of the scenario's kinds (:mod:`esoarm.kinds`) --
the very functions every simulation engine calls -- driven from measured
angles, and the actuator functions of :mod:`esoarm.plants.actuator`:

    ẑ_k = estimate(z_k, y_k)                    (observer kind)
    u_k = sat(control(ẑ_k, y_k, reference_k))   (controller kind, ±torque_limit)
    u_k, duty_k = actuate(u_k, ẑ2_k)            (motor: torque -> PWM duty)
    z_{k+1} = advance(z_k, ẑ_k, y_k, u_k)       (observer kind)

so a run fed the simulator's measurements reproduces
:func:`esoarm.engines.simulation.run_reference` bit for bit (tested).  The
reference is precomputed for all N samples with the same vectorized
:func:`esoarm.reference.evaluate_reference` call the simulators use.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from esoarm.engines.simulation import prepare
from esoarm.plants.actuator import LIMIT, actuate, saturate
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

    __slots__ = ("_act", "_c", "_cp", "_op", "_ref", "_refs", "_started", "_u", "_y", "_z",
                 "_zhat", "kinds", "n_samples", "t", "torque_limit", "ts", "zhat")

    def __init__(self, scn: Scenario) -> None:
        inp = prepare(scn, draw_noise=False)
        self.kinds = inp.kinds
        nj = inp.plant.n_joints
        self._op, self._cp, self._act = inp.observer.vector, inp.controller.vector, inp.actuator
        self._refs = inp.refs
        self._ref = inp.refs[0].tolist()
        self._z = np.zeros(max(inp.observer.n_state, 1))
        self._zhat = np.zeros(max(inp.observer.n_state, 1))
        self._c = np.zeros(max(inp.controller.n_state, 1))
        self._y = np.zeros(nj)
        self._u = np.zeros(nj)
        self._started = False
        self.t = inp.t.tolist()
        self.n_samples = len(self.t)
        self.ts = scn.sample_time
        self.torque_limit = float(inp.actuator[LIMIT])
        self.zhat: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    @property
    def observer_state(self) -> np.ndarray:
        """A copy of the observer state z_{k+1} after the latest commit."""
        return self._z.copy()

    def reference(self, k: int) -> float:
        """θd(t_k) [rad]."""
        return self._ref[k]

    def step(self, k: int, y: float) -> float:
        """Control u_k [N·m] (saturated) from the measured angle y_k [rad]."""
        obs, ctl = self.kinds.observer, self.kinds.controller
        self._y[0] = y
        if not self._started:
            obs.initialize(self._z, self._y, self._op)
            ctl.initialize(self._c, self._y, self._cp)
            self._started = True
        obs.estimate(self._z, self._y, self._op, self._zhat)
        ctl.control(self._c, self._zhat, self._y, self._refs, k, self._cp, self._u)
        self.zhat = (float(self._zhat[0]), float(self._zhat[1]), float(self._zhat[2]))
        return float(saturate(self._u[0], self.torque_limit))

    def actuate(self, u: float) -> tuple[float, float]:
        """(torque the host applies [N·m], PWM duty [counts] or NaN) for the command u."""
        u_applied, _, duty = actuate(u, self._zhat[1], self._act)
        return float(u_applied), float(duty)

    def commit(self, u: float) -> None:
        """Advance the observer with the torque u_k [N·m] applied from t_k on."""
        self._u[0] = u
        self.kinds.observer.advance(self._z, self._zhat, self._y, self._u, self._op)

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a missing sample: estimate with zero innovation, update with u.

        Returns the estimate used for the missing sample.
        """
        if not self._started:
            raise RuntimeError("no sample received yet")
        obs = self.kinds.observer
        self._y[0] = self._z[0]  # y = ẑ1: no innovation
        obs.estimate(self._z, self._y, self._op, self._zhat)
        zhat = (float(self._zhat[0]), float(self._zhat[1]), float(self._zhat[2]))
        self.commit(u)
        return zhat
