"""The deployment controller: the paper's ESO + FLC stepped one sample at a time.

It is :class:`esoarm.observers.linear.ExtendedStateObserver` and
:func:`esoarm.controllers.flc.flc_control` -- the very functions the simulators call
-- driven from measured angles (SPEC §2 steps 2-5):

    ẑ_k = estimate(y_k)                 (eq. 8, discretized; SPEC §2 step 5)
    u_k = sat(I0 (α_k − β̂_k))           (eq. 14-16)
    update(u_k)                         (z_{k+1})

so a run fed the simulator's measurements reproduces
:func:`esoarm.engines.simulation.run_reference` bit for bit (tested).  For the
interpreter hot path the packed parameter vectors are held as tuples of Python
floats (the same IEEE doubles as the NumPy vectors, without NumPy scalar
boxing), and the reference is precomputed for all N samples with the same
vectorized :func:`esoarm.reference.evaluate_reference` call the simulators use.
"""

from __future__ import annotations

import dataclasses
import math

from esoarm.controllers.flc import flc_control
from esoarm.engines.simulation import prepare
from esoarm.observers.linear import ExtendedStateObserver
from esoarm.scenario import Scenario

__all__ = ["DeploymentController"]


class DeploymentController:
    """ESO + FLC for one run of a scenario, stepped per sample.

    Per sample k: ``u = step(k, y)`` (estimate, control law), then
    ``commit(u_applied)`` (observer update with the torque actually applied
    over [t_k, t_{k+1}); the same u in the ideal-torque case).  A sample that
    never arrived is bridged with :meth:`predict` (observer update with zero
    innovation).

    Parameters
    ----------
    scn : Scenario
        The resolved scenario (plant, observer, controller, reference, rate).

    Attributes
    ----------
    n_samples : int
        N = round(duration · rate_hz).
    ts : float
        Sample period [s].
    eso : ExtendedStateObserver or None
        Created at the first sample, z_0 = (y_0, 0, 0) (SPEC §2).
    zhat : tuple of float
        Estimate ẑ_k used for the latest control [rad, rad/s, rad/s²].
    """

    __slots__ = ("_accel", "_ctl", "_design", "_omega", "_ref", "eso", "n_samples", "t",
                 "torque_limit", "ts", "zhat")

    def __init__(self, scn: Scenario) -> None:
        from esoarm.observers.linear import design_observer

        inp = prepare(scn)
        design = design_observer(scn.observer.eps, scn.sample_time, inp.b0,
                                 scn.observer.discretization)
        # same numbers, held as Python floats for the interpreter
        self._design = dataclasses.replace(design, vector=tuple(design.vector.tolist()))
        self._ctl = tuple(inp.ctl.tolist())
        self._ref = inp.theta_ref.tolist()
        self._omega = inp.omega_ref.tolist()
        self._accel = inp.accel_ref.tolist()
        self.t = inp.t.tolist()
        self.n_samples = len(self.t)
        self.ts = scn.sample_time
        self.torque_limit = scn.actuator.torque_limit
        self.eso: ExtendedStateObserver | None = None
        self.zhat: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def reference(self, k: int) -> float:
        """θd(t_k) [rad]."""
        return self._ref[k]

    def step(self, k: int, y: float) -> float:
        """Control u_k [N·m] (saturated) from the measured angle y_k [rad]."""
        eso = self.eso
        if eso is None:
            eso = self.eso = ExtendedStateObserver(self._design, y)  # type: ignore[arg-type]
        z1, z2, z3 = self.zhat = eso.estimate(y)
        return flc_control(z1, z2, z3, self._ref[k], self._omega[k], self._accel[k], self._ctl)

    def commit(self, u: float) -> None:
        """Advance the observer with the torque u_k [N·m] applied from t_k on."""
        self.eso.update(u)  # type: ignore[union-attr]

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a missing sample: estimate with zero innovation, update with u.

        Returns the estimate used for the missing sample.
        """
        eso = self.eso
        if eso is None:
            raise RuntimeError("no sample received yet")
        zhat = eso.estimate(eso.z[0])
        eso.update(u)
        return zhat
