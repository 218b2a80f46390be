"""The sampled-data closed loop, written once for every engine.

:func:`closed_loop` is the statement of the loop's semantics.  The reference
engine (:mod:`esoarm.engines.simulation`) calls it as plain Python with the
step functions of the scenario's kinds; the batch engine
(:mod:`esoarm.engines.batch`) calls the very same function compiled, with the
registry's dispatch functions (:mod:`esoarm.kinds`).  One sample k, t_k = k·Ts:

1. measure: y_k = Q(θ(t_k) + σ n_k) per joint (:func:`esoarm.plants.sensor.measure`)
2. reference (θd, θ̇d, θ̈d) at t_k (precomputed, ``refs[:, k]``)
3. estimate ẑ_k (observer kind), control (controller kind), saturate to
   ±torque_limit, through the actuator (motor: duty; :func:`esoarm.plants.actuator.actuate`)
4. log row k (:data:`esoarm.engines.metrics.LOG_ROWS`): true θ(t_k), θd, e_k = θ(t_k) − θd,
   u_k, ẑ_k, the true perturbation f_k = θ̈(t_k) − b0·v_k, y_k, the saturation flag, θ̇(t_k)
5. observer update with (y_k, v_k): v_k is the plant kind's observer input for u_k
   (u_k itself for the lever arm, M̂(q̂)⁻¹(u_k − c·n̂) for a URDF arm)
6. the drive of sample k − delay (0 before the first command) held over
   [t_k, t_{k+1}); the plant kind integrates to t_{k+1}

A run ends early, as diverged, when a joint's |θ| or |ẑ1| exceeds
:data:`DIVERGENCE_LIMIT` or θ, ẑ or u is not finite (:func:`within_limits`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from esoarm._jit import jitable
from esoarm.engines.metrics import ERR, NROW, OM, REF, SAT, TH, Z1, Z2, Z3, F, U, Y
from esoarm.plants.actuator import LIMIT, actuate, delayed_input, saturate
from esoarm.plants.sensor import measure

__all__ = ["DIVERGENCE_LIMIT", "closed_loop", "closed_loop_block", "log_sample", "within_limits"]

#: |θ| or |z1| beyond this [rad] (or any non-finite value) ends a run as diverged.
DIVERGENCE_LIMIT = 1e6


@jitable
def within_limits(theta: float, z1: float, z2: float, z3: float, u: float) -> bool:
    """The divergence rule shared by every engine: all finite, |θ| and |z1| below the limit.

    A NaN anywhere fails (NaN compares false), so does ±inf.
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


@jitable
def closed_loop(
    log: np.ndarray, n: int, x: np.ndarray, noise: np.ndarray, sigma: float, q: float,
    refs: np.ndarray, ts: float, h: float, nsub: int, delay: int, b0: np.ndarray,
    pp: np.ndarray, op: np.ndarray, cp: np.ndarray, ap: np.ndarray, nz: int, nc: int,
    plant_advance: Callable[..., None], plant_acceleration: Callable[..., None],
    plant_observer_input: Callable[..., None], observer_initialize: Callable[..., None],
    observer_estimate: Callable[..., None],
    observer_advance: Callable[..., None], controller_initialize: Callable[..., None],
    controller_control: Callable[..., None],
) -> int:
    """Run samples 0 … n−1 of one run into ``log``; return the rows logged (< 0: diverged).

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ n)
        Filled column by column (:data:`esoarm.engines.metrics.LOG_ROWS` per joint).
    n : int
        Samples N.
    x : ndarray
        Plant state, initial state on entry (angles x[:joints], rates x[joints:2·joints]);
        advanced in place.
    noise : ndarray
        Standard-normal draws n_k, ``joints`` per sample.
    sigma, q : float
        Noise std dev and quantization step [rad].
    refs : ndarray, shape (3·joints, ≥ n)
        θd, θ̇d, θ̈d of each joint per sample [rad, rad/s, rad/s²].
    ts, h : float
        Sample period and RK4 step [s].
    nsub, delay : int
        RK4 steps per sample; transport delay [samples].
    b0 : ndarray (joints,)
        Nominal input gain of the logged perturbation f = θ̈ − b0 v (v the observer input).
    pp, op, cp, ap : ndarray
        Plant, observer, controller and actuator parameter vectors.
    nz, nc : int
        Observer and controller state sizes.
    plant_advance, ... controller_control : callable
        The kinds' step functions (see :mod:`esoarm.contract`).

    Returns
    -------
    int
        n, or −(k+1) if the run diverged at sample k (row k is logged).
    """
    nj = len(b0)
    limit = ap[LIMIT]
    y = np.empty(nj)
    u = np.empty(nj)
    drive = np.empty(nj)
    applied = np.empty(nj)
    acc = np.empty(nj)
    v = np.empty(nj)
    sat = np.empty(nj)
    z = np.zeros(max(nz, 1))
    zhat = np.zeros(max(nz, 1))
    c = np.zeros(max(nc, 1))
    hist = np.zeros(max(n, 1) * nj)
    for j in range(nj):
        y[j] = measure(x[j], noise[j], sigma, q)
    observer_initialize(z, y, op)
    controller_initialize(c, y, cp)
    for k in range(n):
        tk = k * ts
        # 1. measure
        for j in range(nj):
            y[j] = measure(x[j], noise[k * nj + j], sigma, q)
        # 3. estimate, control, saturate, actuate
        observer_estimate(z, y, op, zhat)
        controller_control(c, zhat, y, refs, k, cp, u)
        for j in range(nj):
            raw = u[j]
            u[j] = saturate(raw, limit)
            sat[j] = 1.0 if u[j] != raw and raw == raw else 0.0
            u[j], drive[j], _ = actuate(u[j], zhat[3 * j + 1], ap)
        # 6. (first half) the input held over [t_k, t_{k+1})
        delayed_input(hist, k, delay, drive, applied)
        # 4. log
        plant_acceleration(x, applied, tk, pp, acc)
        plant_observer_input(zhat, u, pp, v)
        ok = True
        for j in range(nj):
            ok = log_sample(log, k, j, nj, x, refs[3 * j, k], u[j], zhat,
                            acc[j] - b0[j] * v[j], y[j], sat[j]) and ok
        if not ok:
            return -(k + 1)
        # 5. observer update
        observer_advance(z, zhat, y, v, op)
        # 6. integrate the plant to t_{k+1}
        plant_advance(x, applied, tk, h, nsub, pp)
    return n


@jitable
def closed_loop_block(
    logs: np.ndarray, rows: np.ndarray, n: int, xs: np.ndarray, noises: np.ndarray,
    sigma: float, q: float, refs: np.ndarray, ts: float, h: float, nsub: int, delay: int,
    b0: np.ndarray, pp: np.ndarray, op: np.ndarray, cp: np.ndarray, ap: np.ndarray, nz: int,
    nc: int,
    plant_advance_block: Callable[..., None], plant_acceleration: Callable[..., None],
    plant_observer_input: Callable[..., None], observer_initialize: Callable[..., None],
    observer_estimate: Callable[..., None],
    observer_advance: Callable[..., None], controller_initialize: Callable[..., None],
    controller_control: Callable[..., None],
) -> None:
    """:func:`closed_loop` for a block of runs of one parameter set, runs innermost.

    Run i of the block has its own plant state ``xs[i]``, noise ``noises[i]`` and log
    ``logs[i]``; ``rows[i]`` receives what :func:`closed_loop` returns for it.  Each run
    takes the very steps of :func:`closed_loop` in the same order -- the same step
    functions, the same arithmetic -- so its numbers are the same bits; only the loop
    order changes: each sample, and each RK4 step of the plant (the kind's
    ``advance_block``), is taken for every run of the block before the next, and what
    depends on time only (the disturbance d(t)) is computed once for the block.  A run
    that diverges stops (its row is logged, as in :func:`closed_loop`) while the others
    go on.
    """
    m = xs.shape[0]
    nj = len(b0)
    limit = ap[LIMIT]
    y = np.empty((m, nj))
    u = np.empty((m, nj))
    drive = np.empty(nj)
    applied = np.empty((m, nj))
    acc = np.empty(nj)
    v = np.empty(nj)
    sat = np.empty(nj)
    z = np.zeros((m, max(nz, 1)))
    zhat = np.zeros((m, max(nz, 1)))
    c = np.zeros((m, max(nc, 1)))
    hist = np.zeros((m, max(n, 1) * nj))
    alive = np.ones(m, dtype=np.bool_)
    for i in range(m):
        rows[i] = n
        for j in range(nj):
            y[i, j] = measure(xs[i, j], noises[i, j], sigma, q)
        observer_initialize(z[i], y[i], op)
        controller_initialize(c[i], y[i], cp)
    for k in range(n):
        tk = k * ts
        for i in range(m):
            if not alive[i]:
                continue
            x = xs[i]
            log = logs[i]
            yi, ui, zi, zh = y[i], u[i], z[i], zhat[i]
            # 1. measure
            for j in range(nj):
                yi[j] = measure(x[j], noises[i, k * nj + j], sigma, q)
            # 3. estimate, control, saturate, actuate
            observer_estimate(zi, yi, op, zh)
            controller_control(c[i], zh, yi, refs, k, cp, ui)
            for j in range(nj):
                raw = ui[j]
                ui[j] = saturate(raw, limit)
                sat[j] = 1.0 if ui[j] != raw and raw == raw else 0.0
                ui[j], drive[j], _ = actuate(ui[j], zh[3 * j + 1], ap)
            # 6. (first half) the input held over [t_k, t_{k+1})
            delayed_input(hist[i], k, delay, drive, applied[i])
            # 4. log
            plant_acceleration(x, applied[i], tk, pp, acc)
            plant_observer_input(zh, ui, pp, v)
            ok = True
            for j in range(nj):
                ok = log_sample(log, k, j, nj, x, refs[3 * j, k], ui[j], zh,
                                acc[j] - b0[j] * v[j], yi[j], sat[j]) and ok
            if not ok:
                alive[i] = False
                rows[i] = -(k + 1)
                continue
            # 5. observer update
            observer_advance(zi, zh, yi, v, op)
        # 6. integrate every live run to t_{k+1} (the plant kind's block step)
        plant_advance_block(xs, applied, alive, tk, h, nsub, pp)
