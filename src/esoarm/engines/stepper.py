"""One sample at a time: the stepper every per-sample consumer drives.

The compiled loops (:mod:`esoarm.engines.loop`) run whole runs; everything that
takes one sample at a time -- the Gymnasium environment
(:mod:`esoarm.envs.lever_arm`), the rig's host controller
(:mod:`esoarm.hardware.host_control`), ``excite``'s guard loop
(:mod:`esoarm.studies.identification.experiment.excitation`), ``replay``
(:mod:`esoarm.hardware.replay`) and the PIL reference (through the host
controller) -- holds a :class:`Stepper`.  It is the only caller of a kind's step
functions outside the compiled loops, and it calls them through the sample
functions of :mod:`esoarm.engines.sample`, so a run stepped here is the run the
engines simulate (the tests hold them to the same bits).

Sample k, as in every engine:

1. sense: y_k (a simulated sensor, :meth:`Stepper.sense`) or a measured angle from a
   rig or a log (:meth:`Stepper.estimate` takes it); a NaN entry is a lost sample,
   bridged with the observer kind's ``predict`` (the measurement it expects: zero
   innovation);
2. command: ẑ_k (observer kind), the raw command (controller kind), saturation, the
   actuator (:meth:`Stepper.estimate`, :meth:`Stepper.control`, :meth:`Stepper.limit`);
3. hold: the drive of sample k − delay held over [t_k, t_{k+1}) (:meth:`Stepper.hold`);
4. record: log column k (:meth:`Stepper.record`);
5. update: the observer input of the plant kind, then z_{k+1} (:meth:`Stepper.observe`);
6. advance: the plant kind integrates to t_{k+1} (:meth:`Stepper.advance_plant`).

The arrays are sized from the kinds' declarations: the observer state z from the
observer's design (``state_size`` per joint, checked at registration by
:mod:`esoarm.kinds`), the estimate ẑ always 3 per joint (angle, rate, perturbation).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from esoarm.contract import ComponentDesign, PlantDesign
from esoarm.engines.sample import (
    Designs,
    Sampling,
    Steps,
    actuate_into,
    advance_plant_into,
    control_into,
    estimate_into,
    gate_into,
    record_into,
    saturate_into,
    sense_into,
    start_into,
    steps_of,
    update_observer_into,
)
from esoarm.plants.actuator import GATE, GATE_HI, LIMIT, actuator_vector, delayed_input

if TYPE_CHECKING:
    from esoarm.kinds import Kinds
    from esoarm.scenario import Scenario

__all__ = ["Stepper"]


class Stepper:
    """A scenario's observer, controller, actuator and plant steps, one sample at a time.

    Build it with :meth:`of` (the closed loop of a scenario) or :meth:`observer_of`
    (the observer alone, at any sample period: ``replay``, ``excite``).

    Parameters
    ----------
    kinds : Kinds
        The scenario's kind modules (:func:`esoarm.kinds.kinds_of`).
    plant : PlantDesign
        The plant's design (joints, b0, vector: its ``observer_input``).
    observer : ComponentDesign
        The observer's design (vector, state size).
    controller : ComponentDesign or None
        The controller's design (None: the observer alone; :meth:`control` refuses).
    actuator : ndarray
        :func:`esoarm.plants.actuator.actuator_vector` (its torque limit saturates).
    refs : ndarray, shape (3·joints, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2 (the controller's).
    sampling : Sampling
        Samples N, timing [s] and sensor [rad] (the plant half, the delay history).

    Attributes
    ----------
    y, u, drive, applied, duty, sat, acc, v : ndarray (joints,)
        Measurement y_k [rad], host's torque u_k [N·m], drive and held drive [N·m], PWM duty
        [counts] (NaN without a motor), saturation flags, true acceleration [rad/s²],
        observer input.
    z : ndarray
        Observer state (the observer's declared size).
    zhat : ndarray (3·joints,)
        Estimate ẑ_k: angle [rad], rate [rad/s], perturbation [rad/s²] of joint j in
        ``zhat[3j:3j+3]``.
    c : ndarray
        Controller state.
    started : bool
        The observer and controller have been initialized from a first measurement.
    lost : int
        Samples bridged with the observer's ``predict`` so far.
    """

    __slots__ = ("_hist", "acc", "applied", "c", "designs", "drive", "duty", "kinds",
                 "lost", "n_joints", "refs", "sampling", "sat", "started", "steps", "u", "v",
                 "y", "z", "zhat")

    def __init__(self, kinds: Kinds, plant: PlantDesign, observer: ComponentDesign,
                 controller: ComponentDesign | None, actuator: np.ndarray, refs: np.ndarray,
                 sampling: Sampling) -> None:
        nj = plant.n_joints
        self.kinds = kinds
        self.n_joints = nj
        ctl = controller if controller is not None else ComponentDesign(
            np.array([math.nan]), 1)
        self.designs = Designs(plant.b0, plant.vector, observer.vector, ctl.vector,
                               np.asarray(actuator, dtype=float), observer.n_state,
                               ctl.n_state)
        self.steps: Steps = steps_of(kinds)
        if controller is None:  # the observer alone: no control law to call
            self.steps = self.steps._replace(controller_initialize=_no_controller_state,
                                             controller_control=_no_controller)
        self.refs = refs
        self.sampling = sampling
        self.y, self.u, self.drive, self.applied = (np.zeros(nj) for _ in range(4))
        self.duty = np.full(nj, math.nan)
        self.sat, self.acc, self.v = np.zeros(nj), np.zeros(nj), np.zeros(nj)
        self.z = np.zeros(max(observer.n_state, 1))
        self.zhat = np.full(3 * nj, math.nan)
        self.c = np.zeros(max(ctl.n_state, 1))
        self._hist = np.zeros(max(sampling.n, 1) * nj)
        self.started = False
        self.lost = 0

    # -- construction ----------------------------------------------------------------
    @classmethod
    def of(cls, scn: Scenario) -> Stepper:
        """The closed loop of ``scn``: its kinds, designs, actuator, references, timing.

        Parameters
        ----------
        scn : Scenario
            A validated scenario.

        Returns
        -------
        Stepper
            Ready for the first measurement.
        """
        from esoarm.engines.simulation import prepare

        inp = prepare(scn, draw_noise=False)
        return cls(inp.kinds, inp.plant, inp.observer, inp.controller, inp.actuator, inp.refs,
                   inp.sampling)

    @classmethod
    def observer_of(cls, scn: Scenario, ts: float | None = None) -> Stepper:
        """The observer of ``scn`` alone, designed for the sample period ``ts`` [s].

        Parameters
        ----------
        scn : Scenario
            A validated scenario (its observer and plant kinds and settings).
        ts : float, optional
            Sample period [s] (default the scenario's).

        Returns
        -------
        Stepper
            Without a controller (:meth:`control` refuses); the actuator limit is
            unbounded; with ``rig.end_stops`` and ``actuator.stop_gate`` the observer's input
            is gated at the stops as in the closed loop.
        """
        from esoarm.kinds import kinds_of

        ts = scn.sample_time if ts is None else float(ts)
        kinds = kinds_of(scn)
        plant = kinds.plant.design(scn)
        obs = kinds.observer.design(scn, plant, ts)
        # the limit unbounded (the observer is fed the command as given) and, of the
        # scenario's actuator, the ESO's gate at the end stops alone (band 0: no gate)
        actuator = np.zeros(GATE_HI + 1)
        actuator[LIMIT] = math.inf
        actuator[GATE:GATE_HI + 1] = actuator_vector(scn)[GATE:GATE_HI + 1]
        sampling = Sampling(0, ts, ts, 1, 0, 0.0, 0.0)
        return cls(kinds, plant, obs, None, actuator, np.zeros((3 * plant.n_joints, 1)),
                   sampling)

    # -- the controller half -----------------------------------------------------------
    def sense(self, x: np.ndarray, noise: np.ndarray, k: int) -> np.ndarray:
        """Step 1 on a simulated sensor: y_k = Q(θ(t_k) + σ n) into :attr:`y`.

        Parameters
        ----------
        x : ndarray
            Plant state at t_k (angles first).
        noise : ndarray
            Standard-normal draws, ``joints`` per sample.
        k : int
            Sample index.

        Returns
        -------
        ndarray (joints,)
            :attr:`y`.
        """
        sense_into(self.y, x, noise, k, self.sampling)
        return self.y

    def start(self, y: np.ndarray | float | None = None) -> None:
        """Initialize the observer and the controller from the first measurement y_0 [rad].

        Parameters
        ----------
        y : array_like or float, optional
            y_0 per joint (default: :attr:`y` as it is).
        """
        if y is not None:
            self.y[:] = y
        start_into(self.z, self.c, self.y, self.designs, self.steps)
        self.started = True

    def estimate(self, y: np.ndarray | float | None = None) -> np.ndarray:
        """Step 2a: ẑ_k from z_k and y_k (the observer kind's ``estimate``).

        A NaN entry of ``y`` is a lost sample: every joint's measurement is replaced by
        the one the observer expects (its ``predict``: zero innovation).  The first
        call initializes the observer and the controller (:meth:`start`).

        Parameters
        ----------
        y : array_like or float, optional
            Measured angle(s) y_k [rad] (default: :attr:`y` as it is).

        Returns
        -------
        ndarray (3·joints,)
            :attr:`zhat`.

        Raises
        ------
        RuntimeError
            The first sample is lost (nothing to predict from).
        """
        if y is not None:
            self.y[:] = y
        if not self.started:
            if not np.all(np.isfinite(self.y)):
                raise RuntimeError("the first sample is lost: the observer has no state "
                                   "to predict from")
            self.start()
        elif not np.all(np.isfinite(self.y)):
            self.predict()
        estimate_into(self.z, self.y, self.zhat, self.designs, self.steps)
        return self.zhat

    def predict(self) -> np.ndarray:
        """A lost sample: the NaN entries of :attr:`y` = the measurement the observer expects.

        The observer kind's ``predict`` (from z_k and the previous estimate) for every
        joint whose measurement is missing (the others keep theirs); the estimate and
        update that follow then see zero innovation on them.

        Returns
        -------
        ndarray (joints,)
            :attr:`y`.
        """
        lost = ~np.isfinite(self.y)
        guess = np.empty(self.n_joints)
        self.kinds.observer.predict(self.z, self.zhat, self.designs.observer, guess)
        self.y[lost] = guess[lost]
        self.lost += 1
        return self.y

    def control(self, k: int) -> np.ndarray:
        """Step 2b: the controller kind's raw command of sample k into :attr:`u` [N·m].

        Parameters
        ----------
        k : int
            Sample index (column of the references).

        Returns
        -------
        ndarray (joints,)
            :attr:`u` (not saturated).
        """
        control_into(self.c, self.zhat, self.y, k, self.refs, self.u, self.designs,
                     self.steps)
        return self.u

    def limit(self, u: np.ndarray | float | None = None) -> np.ndarray:
        """Step 2c-d: :attr:`u` saturated to ±torque_limit, then through the actuator.

        :attr:`u` becomes the host's torque, :attr:`drive` the drive reaching the plant,
        :attr:`duty` the PWM duty (NaN without a motor).

        Parameters
        ----------
        u : array_like or float, optional
            A raw command [N·m] (default: :attr:`u` as it is).

        Returns
        -------
        ndarray (joints,)
            :attr:`u`.
        """
        self.saturate(u)
        return self.actuate()

    def saturate(self, u: np.ndarray | float | None = None) -> np.ndarray:
        """Step 2c alone: :attr:`u` clipped to ±torque_limit (flags in :attr:`sat`).

        Parameters
        ----------
        u : array_like or float, optional
            A raw command [N·m] (default: :attr:`u` as it is).

        Returns
        -------
        ndarray (joints,)
            :attr:`u`.
        """
        self._take(u)
        saturate_into(self.u, self.sat, self.designs.actuator)
        return self.u

    def actuate(self, u: np.ndarray | float | None = None) -> np.ndarray:
        """Step 2d alone: the saturated :attr:`u` through the actuator (motor: a duty).

        Parameters
        ----------
        u : array_like or float, optional
            A saturated command [N·m] (default: :attr:`u` as it is).

        Returns
        -------
        ndarray (joints,)
            :attr:`u`, the host's torque.
        """
        self._take(u)
        actuate_into(self.u, self.drive, self.duty, self.zhat, self.designs.actuator)
        return self.u

    def _take(self, u: np.ndarray | float | None) -> None:
        """A command given to :meth:`saturate` or :meth:`actuate` [N·m] into :attr:`u`."""
        if u is not None:
            self.u[:] = u

    # -- the plant half ----------------------------------------------------------------
    def hold(self, k: int) -> np.ndarray:
        """Step 3: record sample k's drive; :attr:`applied` = the drive of sample k − delay.

        Parameters
        ----------
        k : int
            Sample index.

        Returns
        -------
        ndarray (joints,)
            :attr:`applied` [N·m].
        """
        if k >= len(self._hist) // self.n_joints:  # a host running past N samples
            self._hist = np.concatenate([self._hist, np.zeros(len(self._hist))])
        delayed_input(self._hist, k, self.sampling.delay, self.drive, self.applied)
        return self.applied

    def record(self, log: np.ndarray, x: np.ndarray, k: int) -> bool:
        """Step 4: log column k; also the true acceleration and the observer input.

        Parameters
        ----------
        log : ndarray
            The run's log (:data:`esoarm.engines.metrics.LOG_ROWS` per joint).
        x : ndarray
            Plant state at t_k.
        k : int
            Sample index.

        Returns
        -------
        bool
            False if the run left the finite range (:func:`~esoarm.engines.sample.within_limits`).
        """
        return bool(record_into(log, x, k, self.refs, self.y, self.u, self.sat, self.applied,
                                self.zhat, self.acc, self.v, self.sampling, self.designs,
                                self.steps))

    def update(self) -> None:
        """Step 5 after :meth:`record`: z_{k+1} with the observer input :attr:`v` it left."""
        update_observer_into(self.z, self.zhat, self.y, self.v, self.designs, self.steps)

    def observe(self, u: np.ndarray | float | None = None) -> None:
        """Step 5 on a rig or a log: v_k of the host's torque (plant kind), then z_{k+1}.

        Parameters
        ----------
        u : array_like or float, optional
            The torque u_k applied from t_k on [N·m] (default: :attr:`u` as it is).
        """
        if u is not None:
            self.u[:] = u
        self.steps.plant_observer_input(self.zhat, self.u, self.designs.plant, self.v)
        gate_into(self.v, self.y, self.designs.actuator)
        self.update()

    def bridge(self, u: np.ndarray | float) -> np.ndarray:
        """A whole lost sample on a rig: predict y_k, estimate, observe with ``u``.

        Parameters
        ----------
        u : array_like or float
            The torque applied from t_k on [N·m].

        Returns
        -------
        ndarray (3·joints,)
            A copy of the estimate used for the lost sample.

        Raises
        ------
        RuntimeError
            No sample was received yet.
        """
        if not self.started:
            raise RuntimeError("no sample received yet")
        self.y[:] = math.nan
        zhat = self.estimate().copy()
        self.observe(u)
        return zhat

    def advance_plant(self, x: np.ndarray, k: int) -> None:
        """Step 6: the plant kind integrates x from t_k to t_{k+1} under :attr:`applied`.

        Parameters
        ----------
        x : ndarray
            Plant state, advanced in place.
        k : int
            Sample index.
        """
        advance_plant_into(x, self.applied, k, self.sampling, self.designs.plant,
                           self.steps.plant_advance)


def _no_controller_state(c: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """The observer-only stepper has no controller state."""


def _no_controller(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
                   p: np.ndarray, u: np.ndarray) -> None:
    raise RuntimeError("this stepper runs the observer alone (Stepper.observer_of): no "
                       "control law")
