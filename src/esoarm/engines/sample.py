"""One sample of the sampled-data loop, written once: a controller half and a plant half.

Every place that takes a sample calls these functions: the one-run loop and
the block loop (:mod:`esoarm.engines.loop`, as plain Python in the reference
engine and compiled in the batch engine), and the one-sample stepper
(:class:`esoarm.engines.stepper.Stepper`) that the Gymnasium environment, the
rig's host controller, ``excite``'s guard loop and ``replay`` drive.  The C kernel
of the fast engine (``_fast_kernel.c``) is the only other statement of the sample,
held to these numbers by the tests.  Sample k, t_k = k·Ts:

controller half (:func:`command_into`)
    1. measure y_k = Q(θ(t_k) + σ n_k) per joint (:func:`sense_into`; on a rig the
       encoder does it);
    2. estimate ẑ_k (observer kind, :func:`estimate_into`), control (controller kind,
       :func:`control_into`), saturate to ±torque_limit (:func:`saturate_into`),
       through the actuator (:func:`actuate_into`: with a motor, the torque
       becomes a PWM duty; the host's torque u_k is what is logged and observed,
       the drive is what reaches the plant);
plant half (:func:`respond_into`, then :func:`advance_plant_into`)
    3. the drive of sample k − delay (0 before the first command) is held over
       [t_k, t_{k+1}) (:func:`esoarm.plants.actuator.delayed_input`);
    4. log row k (:func:`record_into`): true θ(t_k), θd, e_k, u_k, ẑ_k, the true
       perturbation f_k = θ̈(t_k) − b0·v_k, y_k, the saturation flag, θ̇(t_k),
       where v_k is the plant kind's observer input for u_k (u_k itself for the
       lever arm, M̂(q̂)⁻¹(u_k − c·n̂) for a URDF arm);
    5. observer update with (y_k, v_k) (:func:`update_observer_into`; v_k = 0 while the
       ESO's gate at an end stop holds, :func:`gate_into`);
    6. the plant kind integrates to t_{k+1} (:func:`advance_plant_into`).

What travels between them are four records, plain tuples that numba compiles:
:class:`Sampling` (timing and sensor), :class:`Designs` (the parameter
vectors), :class:`Steps` (the kinds' step functions: the kind modules' own in
Python, the registry's dispatch functions compiled) and :class:`Work` (the
state and scratch arrays of one run).  Each step is written once, on the
arrays themselves; the loops unpack their Work once per run and call them:
compiled, every function a record reaches takes a reference on each of its
arrays and drops it again, every sample (twelve atomic increments and
decrements per function for a Work), which had doubled the compiled
engine's cost per sample.  Only the plant half's :func:`hold` and
:func:`advance_plant` take a Work (the emulated device's twin).

A run ends early, as diverged, when a joint's |θ| or |ẑ1| exceeds
:data:`DIVERGENCE_LIMIT` or θ, ẑ or u is not finite (:func:`within_limits`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from esoarm._jit import jitable
from esoarm.contract import Vector
from esoarm.engines.metrics import ERR, NROW, OM, REF, SAT, TH, Z1, Z2, Z3, F, U, Y
from esoarm.plants.actuator import (
    LIMIT,
    SEES,
    SEES_COMMANDED,
    actuate_with_table,
    delayed_input,
    gated,
    saturate,
)
from esoarm.plants.sensor import measure

__all__ = ["DIVERGENCE_LIMIT", "Designs", "Sampling", "Steps", "Work", "actuate_into",
           "advance_plant", "advance_plant_into", "command_into", "control_into",
           "estimate_into", "gate_into", "hold", "log_sample", "new_work", "record_into",
           "respond_into", "saturate_into", "sense_into", "start_into", "steps_of",
           "update_observer_into", "within_limits"]

#: |θ| or |z1| beyond this [rad] (or any non-finite value) ends a run as diverged.
DIVERGENCE_LIMIT = 1e6


class Sampling(NamedTuple):
    """Timing and sensor of a run.

    Attributes
    ----------
    n : int
        Samples N.
    ts : float
        Sample period Ts [s].
    h : float
        RK4 step of the plant [s].
    nsub : int
        RK4 steps per sample.
    delay : int
        Transport delay [samples].
    sigma : float
        Encoder noise standard deviation σ [rad].
    q : float
        Encoder quantization step [rad] (0: none).
    """

    n: int
    ts: float
    h: float
    nsub: int
    delay: int
    sigma: float
    q: float


class Designs(NamedTuple):
    """The parameter vectors of a run's kinds and actuator, and the state sizes.

    Attributes
    ----------
    b0 : ndarray, shape (joints,)
        Nominal input gain per joint [1/(kg·m²)] (of the logged perturbation f = θ̈ − b0·v).
    plant, observer, controller : ndarray or tuple of float
        The kinds' parameter vectors (element 0 is the kind's CODE).
    actuator : ndarray or tuple of float
        :func:`esoarm.plants.actuator.actuator_vector`.
    n_observer, n_controller : int
        Sizes of the observer's and the controller's state arrays.
    """

    b0: np.ndarray
    plant: Vector
    observer: Vector
    controller: Vector
    actuator: Vector
    n_observer: int
    n_controller: int


class Steps(NamedTuple):
    """The kinds' step functions (see :mod:`esoarm.contract`), one field per step.

    In Python the kind modules' own functions (:func:`steps_of`); compiled, the
    registry's dispatch functions (:mod:`esoarm.kinds`).  ``plant_advance_block``
    is None for a plant without a block step (only the block loop calls it).
    """

    plant_advance: Callable[..., None]
    plant_advance_block: Any
    plant_acceleration: Callable[..., None]
    plant_observer_input: Callable[..., None]
    observer_initialize: Callable[..., None]
    observer_estimate: Callable[..., None]
    observer_advance: Callable[..., None]
    controller_initialize: Callable[..., None]
    controller_control: Callable[..., None]


class Work(NamedTuple):
    """The state and scratch arrays of one run (all float64, updated in place).

    Attributes
    ----------
    y : ndarray (joints,)
        Measured angles y_k [rad].
    u : ndarray (joints,)
        Command: raw from the controller, then saturated, then the host's torque u_k [N·m].
    drive : ndarray (joints,)
        Torque driving the plant for sample k [N·m] (before the delay).
    applied : ndarray (joints,)
        Drive held over [t_k, t_{k+1}) (sample k − delay) [N·m].
    duty : ndarray (joints,)
        PWM duty [counts] (NaN without a motor).
    sat : ndarray (joints,)
        1.0 where the command hit ±torque_limit.
    acc : ndarray (joints,)
        True acceleration θ̈(t_k) [rad/s²].
    v : ndarray (joints,)
        Observer input v_k (the plant kind's ``observer_input`` of u_k).
    z : ndarray
        Observer state z_k (the size its design declares).
    zhat : ndarray (3·joints,)
        Estimate ẑ_k: angle, rate, perturbation per joint (whatever the observer's state).
    c : ndarray
        Controller state.
    hist : ndarray (N·joints,)
        Drives of samples 0 … k (for the transport delay).
    """

    y: np.ndarray
    u: np.ndarray
    drive: np.ndarray
    applied: np.ndarray
    duty: np.ndarray
    sat: np.ndarray
    acc: np.ndarray
    v: np.ndarray
    z: np.ndarray
    zhat: np.ndarray
    c: np.ndarray
    hist: np.ndarray


def steps_of(kinds: Any) -> Steps:
    """The step functions of a scenario's kind modules (:class:`esoarm.kinds.Kinds`).

    Parameters
    ----------
    kinds : Kinds
        The (plant, observer, controller) kind modules of a scenario.

    Returns
    -------
    Steps
        Their step functions; ``plant_advance_block`` None when the plant has none.
    """
    plant, observer, controller = kinds
    return Steps(plant.advance, getattr(plant, "advance_block", None), plant.acceleration,
                 plant.observer_input, observer.initialize, observer.estimate,
                 observer.advance, controller.initialize, controller.control)


@jitable
def new_work(n: int, nj: int, nz: int, nc: int) -> Work:
    """Fresh arrays for a run of n samples, nj joints, observer and controller sizes nz, nc.

    Parameters
    ----------
    n : int
        Samples N (the transport-delay history holds N·nj drives).
    nj : int
        Number of joints.
    nz, nc : int
        Lengths of the observer's and the controller's state arrays (at least 1 is
        allocated).

    Returns
    -------
    Work
        Per-joint arrays uninitialized; z (nz: the observer's declared state), ẑ (always
        3 per joint: angle, rate, perturbation), c and the drive history zero.
    """
    return Work(np.empty(nj), np.empty(nj), np.empty(nj), np.empty(nj), np.empty(nj),
                np.empty(nj), np.empty(nj), np.empty(nj), np.zeros(max(nz, 1)),
                np.zeros(3 * nj), np.zeros(max(nc, 1)), np.zeros(max(n, 1) * nj))


@jitable
def within_limits(theta: float, z1: float, z2: float, z3: float, u: float) -> bool:
    """The divergence rule shared by every engine: all finite, |θ| and |z1| below the limit.

    A NaN anywhere fails (NaN compares false), so does ±inf.

    Parameters
    ----------
    theta : float
        True angle θ(t_k) [rad].
    z1, z2, z3 : float
        Estimate ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²].
    u : float
        Logged command u_k [N·m].

    Returns
    -------
    bool
        True while every value is finite and |θ|, |ẑ1| < :data:`DIVERGENCE_LIMIT` [rad].
    """
    lim = DIVERGENCE_LIMIT
    return (
        math.isfinite(theta + z2 + z3 + u) and abs(theta) < lim and abs(z1) < lim
    )


@jitable
def log_sample(log: np.ndarray, k: int, j: int, nj: int, x: np.ndarray, ref: float, u: float,
               zhat: np.ndarray, f: float, y: float, sat: float) -> bool:
    """Step 4 for joint j of nj: log row k, then the divergence rule on what was logged.

    Rows as :data:`esoarm.engines.metrics.LOG_ROWS`; ``x`` is the plant state (angles,
    rates, ... of the nj joints), ``zhat`` the estimate (3 per joint), ``f`` the true
    perturbation θ̈(t_k) − b0·v_k.  True while :func:`within_limits` holds.

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·nj, ≥ N)
        The run's log; rows j·NROW … of column k are written.
    k : int
        Sample index (t_k = k·Ts).
    j : int
        Joint index.
    nj : int
        Number of joints.
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states).
    ref : float
        Reference θd(t_k) of joint j [rad]; the logged error is e = θ − θd [rad].
    u : float
        The host's torque u_k of joint j [N·m].
    zhat : ndarray, shape (3·nj,)
        Estimate ẑ_k (angle [rad], rate [rad/s], perturbation [rad/s²] per joint).
    f : float
        True total perturbation θ̈(t_k) − b0·v_k [rad/s²].
    y : float
        Measured angle y_k [rad].
    sat : float
        1.0 if the command was clipped at ±torque_limit, else 0.0.

    Returns
    -------
    bool
        :func:`within_limits` of the logged row (False: the run diverged).
    """
    r = j * NROW
    i = 3 * j
    log[r + TH, k] = x[j]
    log[r + REF, k] = ref
    log[r + ERR, k] = x[j] - ref
    log[r + U, k] = u
    log[r + Z1, k] = zhat[i]
    log[r + Z2, k] = zhat[i + 1]
    log[r + Z3, k] = zhat[i + 2]
    log[r + F, k] = f
    log[r + Y, k] = y
    log[r + SAT, k] = sat
    log[r + OM, k] = x[nj + j]
    return within_limits(x[j], zhat[i], zhat[i + 1], zhat[i + 2], u)


# ---------------------------------------------------------------------------
# the steps on plain arrays (the loops call these; the record versions below unpack a Work)
#
# Compiled, a record handed to a function costs one reference-count increment and
# decrement per array it holds (12 for a Work), in every function it reaches, every
# sample; the loops therefore unpack their Work once per run and call these.


@jitable
def sense_into(y: np.ndarray, x: np.ndarray, noise: np.ndarray, k: int, sg: Sampling) -> None:
    """Step 1: y_k = Q(θ_j(t_k) + σ n) per joint j, n = ``noise[k·joints + j]``, into ``y``.

    Parameters
    ----------
    y : ndarray (joints,)
        Output: the measured angles y_k [rad].
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states) at t_k.
    noise : ndarray
        Standard-normal draws, ``joints`` per sample.
    k : int
        Sample index (t_k = k·Ts).
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    """
    nj = len(y)
    for j in range(nj):
        y[j] = measure(x[j], noise[k * nj + j], sg.sigma, sg.q)


@jitable
def start_into(z: np.ndarray, c: np.ndarray, y: np.ndarray, d: Designs, s: Steps) -> None:
    """The observer's state ``z`` and the controller's ``c`` initialized from y_0 = ``y`` [rad].

    Parameters
    ----------
    z : ndarray
        Observer state, initialized in place.
    c : ndarray
        Controller state, initialized in place.
    y : ndarray (joints,)
        The first measurement y_0 [rad].
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    s.observer_initialize(z, y, d.observer)
    s.controller_initialize(c, y, d.controller)


@jitable
def estimate_into(z: np.ndarray, y: np.ndarray, zhat: np.ndarray, d: Designs, s: Steps) -> None:
    """Step 2a: the estimate ẑ_k from z_k and y_k into ``zhat`` (observer kind).

    Parameters
    ----------
    z : ndarray
        Observer state z_k (not changed).
    y : ndarray (joints,)
        Measured angles y_k [rad].
    zhat : ndarray
        Output: the estimate ẑ_k (3 per joint first).
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    s.observer_estimate(z, y, d.observer, zhat)


@jitable
def control_into(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, k: int, refs: np.ndarray,
                 u: np.ndarray, d: Designs, s: Steps) -> None:
    """Step 2b: the raw command into ``u`` (controller kind).

    Parameters
    ----------
    c : ndarray
        Controller state, updated in place.
    zhat : ndarray
        The estimate ẑ_k (3 per joint first).
    y : ndarray (joints,)
        Measured angles y_k [rad].
    k : int
        Sample index (t_k = k·Ts).
    refs : ndarray, shape (3·joints, ≥ N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    u : ndarray (joints,)
        Output: the raw command [N·m].
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    s.controller_control(c, zhat, y, refs, k, d.controller, u)


@jitable
def saturate_into(u: np.ndarray, sat: np.ndarray, a: Vector) -> None:
    """Step 2c: ``u`` clipped to ±torque_limit; ``sat`` flags the clipped joints.

    A NaN command passes (and is not flagged), so a fault stays visible.  With
    ``actuator.observer_sees = "commanded"`` (the paper's ESO) ``u`` keeps the command, which
    the observer is then fed and the log shows; :func:`actuate_into` saturates what drives
    the plant.

    Parameters
    ----------
    u : ndarray (joints,)
        Command [N·m], clipped in place.
    sat : ndarray (joints,)
        Output: 1.0 where the command was clipped, else 0.0.
    a : ndarray or tuple of float
        The actuator vector (:func:`esoarm.plants.actuator.actuator_vector`; ``a[LIMIT]`` =
        torque_limit [N·m]).
    """
    limit = a[LIMIT]
    keep = len(a) > SEES and a[SEES] == SEES_COMMANDED
    for j in range(len(u)):
        raw = u[j]
        limited = saturate(raw, limit)
        sat[j] = 1.0 if limited != raw and raw == raw else 0.0
        u[j] = raw if keep else limited


@jitable
def actuate_into(u: np.ndarray, drive: np.ndarray, duty: np.ndarray, zhat: np.ndarray,
                 a: Vector) -> None:
    """Step 2d: the saturated ``u`` through the actuator (:func:`esoarm.plants.actuator.actuate`).

    ``u`` becomes the host's torque, ``drive`` the torque driving the plant, ``duty`` the
    PWM duty (NaN without a motor); a learned table adds to the drive and the duty, not to
    ``u`` (:func:`esoarm.plants.actuator.actuate_with_table`).  With
    ``actuator.observer_sees = "commanded"`` ``u`` stays the controller's command (its
    saturation drives the plant).

    Parameters
    ----------
    u : ndarray (joints,)
        The saturated command [N·m], replaced by the host's torque u_k [N·m].
    drive : ndarray (joints,)
        Output: the torque driving the plant [N·m].
    duty : ndarray (joints,)
        Output: the PWM duty [counts] (NaN without a motor).
    zhat : ndarray
        The estimate ẑ_k; ``zhat[3j + 1]`` is joint j's rate estimate [rad/s] (the motor's
        back-EMF).
    a : ndarray or tuple of float
        The actuator vector (:func:`esoarm.plants.actuator.actuator_vector`).
    """
    keep = len(a) > SEES and a[SEES] == SEES_COMMANDED
    for j in range(len(u)):
        raw = u[j]
        host, drive[j], duty[j] = actuate_with_table(saturate(raw, a[LIMIT]), zhat[3 * j + 1],
                                                     zhat[3 * j], a)
        u[j] = raw if keep else host


@jitable
def command_into(y: np.ndarray, u: np.ndarray, drive: np.ndarray, duty: np.ndarray,
                 sat: np.ndarray, z: np.ndarray, zhat: np.ndarray, c: np.ndarray, k: int,
                 refs: np.ndarray, d: Designs, s: Steps) -> None:
    """The controller half after the measurement ``y``: estimate, control, saturate, actuate.

    Parameters
    ----------
    y : ndarray (joints,)
        Measured angles y_k [rad].
    u : ndarray (joints,)
        Output: the host's torque u_k [N·m].
    drive : ndarray (joints,)
        Output: the torque driving the plant for sample k [N·m].
    duty : ndarray (joints,)
        Output: the PWM duty [counts] (NaN without a motor).
    sat : ndarray (joints,)
        Output: 1.0 where the command hit ±torque_limit.
    z : ndarray
        Observer state z_k.
    zhat : ndarray
        Output: the estimate ẑ_k.
    c : ndarray
        Controller state, updated in place.
    k : int
        Sample index (t_k = k·Ts).
    refs : ndarray, shape (3·joints, ≥ N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    estimate_into(z, y, zhat, d, s)
    control_into(c, zhat, y, k, refs, u, d, s)
    saturate_into(u, sat, d.actuator)
    actuate_into(u, drive, duty, zhat, d.actuator)


@jitable
def record_into(log: np.ndarray, x: np.ndarray, k: int, refs: np.ndarray, y: np.ndarray,
                u: np.ndarray, sat: np.ndarray, applied: np.ndarray, zhat: np.ndarray,
                acc: np.ndarray, v: np.ndarray, sg: Sampling, d: Designs, s: Steps) -> bool:
    """Step 4: log column k (every joint); False if the run left the finite range.

    Also leaves the true acceleration θ̈(t_k) in ``acc`` and the observer input v_k
    (the plant kind's ``observer_input`` of the host's torque) in ``v``.

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ N)
        The run's log (:data:`esoarm.engines.metrics.LOG_ROWS` per joint); column k is
        written.
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states) at t_k.
    k : int
        Sample index (t_k = k·Ts).
    refs : ndarray, shape (3·joints, ≥ N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    y : ndarray (joints,)
        Measured angles y_k [rad].
    u : ndarray (joints,)
        The host's torque u_k [N·m].
    sat : ndarray (joints,)
        1.0 where the command hit ±torque_limit.
    applied : ndarray (joints,)
        The drive held over [t_k, t_{k+1}) [N·m].
    zhat : ndarray
        The estimate ẑ_k.
    acc : ndarray (joints,)
        Output: the true acceleration θ̈(t_k) [rad/s²].
    v : ndarray (joints,)
        Output: the observer input v_k.
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.

    Returns
    -------
    bool
        False if a joint's logged row breaks :func:`within_limits`.
    """
    nj = len(y)
    s.plant_acceleration(x, applied, k * sg.ts, d.plant, acc)
    s.plant_observer_input(zhat, u, d.plant, v)
    b0 = d.b0
    ok = True
    for j in range(nj):
        ok = log_sample(log, k, j, nj, x, refs[3 * j, k], u[j], zhat,
                        acc[j] - b0[j] * v[j], y[j], sat[j]) and ok
    gate_into(v, y, d.actuator)
    return ok


@jitable
def gate_into(v: np.ndarray, y: np.ndarray, a: Vector) -> None:
    """Step 5's input gated at an end stop: v_j = 0 where :func:`esoarm.plants.actuator.gated`.

    Parameters
    ----------
    v : ndarray (joints,)
        The observer input v_k, set to 0 in place where gated.
    y : ndarray (joints,)
        Measured angles y_k [rad].
    a : ndarray or tuple of float
        The actuator vector (the gate's band and the stops).
    """
    for j in range(len(v)):
        if gated(y[j], v[j], a):
            v[j] = 0.0


@jitable
def update_observer_into(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, v: np.ndarray,
                         d: Designs, s: Steps) -> None:
    """Step 5: z_{k+1} from (z_k, ẑ_k, y_k) and the observer input ``v``.

    Parameters
    ----------
    z : ndarray
        Observer state z_k, advanced in place to z_{k+1}.
    zhat : ndarray
        The estimate ẑ_k.
    y : ndarray (joints,)
        Measured angles y_k [rad].
    v : ndarray (joints,)
        The observer input v_k.
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    s.observer_advance(z, zhat, y, v, d.observer)


@jitable
def respond_into(log: np.ndarray, x: np.ndarray, k: int, refs: np.ndarray, y: np.ndarray,
                 u: np.ndarray, sat: np.ndarray, drive: np.ndarray, applied: np.ndarray,
                 hist: np.ndarray, z: np.ndarray, zhat: np.ndarray, acc: np.ndarray,
                 v: np.ndarray, sg: Sampling, d: Designs, s: Steps) -> bool:
    """Steps 3-5: hold the delayed drive, log column k, update the observer.

    Returns False (and skips the update) if the run left the finite range.

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ N)
        The run's log (:data:`esoarm.engines.metrics.LOG_ROWS` per joint); column k is
        written.
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states) at t_k.
    k : int
        Sample index (t_k = k·Ts).
    refs : ndarray, shape (3·joints, ≥ N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    y : ndarray (joints,)
        Measured angles y_k [rad].
    u : ndarray (joints,)
        The host's torque u_k [N·m].
    sat : ndarray (joints,)
        1.0 where the command hit ±torque_limit.
    drive : ndarray (joints,)
        The torque driving the plant for sample k [N·m] (before the delay).
    applied : ndarray (joints,)
        Output: the drive held over [t_k, t_{k+1}) (sample k − delay) [N·m].
    hist : ndarray (N·joints,)
        Drives of samples 0 … k (sample k's is written).
    z : ndarray
        Observer state z_k, advanced in place to z_{k+1}.
    zhat : ndarray
        The estimate ẑ_k.
    acc : ndarray (joints,)
        Output: the true acceleration θ̈(t_k) [rad/s²].
    v : ndarray (joints,)
        Output: the observer input v_k.
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.

    Returns
    -------
    bool
        True if the run goes on; False if it diverged at sample k (row k is logged).
    """
    delayed_input(hist, k, sg.delay, drive, applied)
    if not record_into(log, x, k, refs, y, u, sat, applied, zhat, acc, v, sg, d, s):
        return False
    update_observer_into(z, zhat, y, v, d, s)
    return True


@jitable
def advance_plant_into(x: np.ndarray, applied: np.ndarray, k: int, sg: Sampling, plant: Vector,
                       plant_advance: Callable[..., None]) -> None:
    """Step 6: the plant kind integrates x from t_k to t_{k+1} under ``applied``.

    Parameters
    ----------
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states), advanced in place to t_{k+1}.
    applied : ndarray (joints,)
        The drive held over [t_k, t_{k+1}) [N·m].
    k : int
        Sample index (t_k = k·Ts).
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    plant : ndarray or tuple of float
        The plant kind's parameter vector (element 0 its CODE).
    plant_advance : callable
        The plant kind's ``advance(x, u, t0, h, nsub, p)``.
    """
    plant_advance(x, applied, k * sg.ts, sg.h, sg.nsub, plant)


# ---------------------------------------------------------------------------
# the plant half on a Work record (the emulated device's twin)


@jitable
def hold(w: Work, k: int, delay: int) -> None:
    """Step 3: record sample k's drive; ``w.applied`` = the drive of sample k − delay (or 0).

    Parameters
    ----------
    w : Work
        The run's state and scratch arrays; ``w.hist`` and ``w.applied`` [N·m] are written.
    k : int
        Sample index (t_k = k·Ts).
    delay : int
        Transport delay [samples].
    """
    delayed_input(w.hist, k, delay, w.drive, w.applied)


@jitable
def advance_plant(x: np.ndarray, w: Work, k: int, sg: Sampling, plant: Vector,
                  plant_advance: Callable[..., None]) -> None:
    """Step 6 (:func:`advance_plant_into`): the plant integrates x to t_{k+1} under ``w.applied``.

    Parameters
    ----------
    x : ndarray
        Plant state (angles x[:joints] [rad], rates x[joints:2·joints] [rad/s], then any
        further states), advanced in place to t_{k+1}.
    w : Work
        The run's state and scratch arrays (``w.applied`` [N·m]).
    k : int
        Sample index (t_k = k·Ts).
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    plant : ndarray or tuple of float
        The plant kind's parameter vector (element 0 its CODE).
    plant_advance : callable
        The plant kind's ``advance(x, u, t0, h, nsub, p)``.
    """
    advance_plant_into(x, w.applied, k, sg, plant, plant_advance)
