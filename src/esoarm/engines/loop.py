"""The sampled-data closed loop, written once for every engine.

:func:`closed_loop` runs samples 0 … N−1 of one run; each sample is the
controller half and the plant half of :mod:`esoarm.engines.sample` (measure,
estimate, control, saturate, actuate; delay, log, observer update, plant
step), the functions the Gymnasium environment, the rig's host controller and
the emulated device call too.  The reference engine
(:mod:`esoarm.engines.simulation`) calls it as plain Python with the step
functions of the scenario's kinds; the batch engine (:mod:`esoarm.engines.batch`)
calls the very same function compiled, with the registry's dispatch functions
(:mod:`esoarm.kinds`).  :func:`closed_loop_block` takes the same samples for a
block of runs, runs innermost.

A run ends early, as diverged, when a joint's |θ| or |ẑ1| exceeds
:data:`DIVERGENCE_LIMIT` or θ, ẑ or u is not finite (:func:`within_limits`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from esoarm._jit import jitable
from esoarm.engines.sample import (
    DIVERGENCE_LIMIT,
    Designs,
    Sampling,
    Steps,
    advance_plant_into,
    command_into,
    log_sample,
    new_work,
    respond_into,
    sense_into,
    start_into,
    within_limits,
)

__all__ = ["DIVERGENCE_LIMIT", "borrowed", "borrowed_designs", "closed_loop", "closed_loop_block",
           "keep_alive", "log_sample", "within_limits"]


def borrowed(a: Any) -> Any:
    """``a`` itself; compiled, an array that holds no reference to its memory.

    Compiled (numba), every function an array reaches takes a reference on its memory
    on entry and drops it on exit -- an atomic increment and decrement -- and so does
    every view ``a[i]``; in the sample loops that came to 56-76 of each per run and sample,
    a quarter of the compiled engine's time.  The batch engine
    (:mod:`esoarm.engines.batch`) compiles this function to a copy of the array
    without its reference count (no atomic operations follow it).  Its memory must stay
    owned elsewhere for as long as the copy is used: by the caller for an argument, by
    a variable kept alive (:func:`keep_alive`) for an array the loop allocates.  Other
    values (tuples, numbers) pass unchanged.

    Parameters
    ----------
    a : ndarray or any
        The array (or value).

    Returns
    -------
    ndarray or any
        ``a`` (compiled: the same array, holding no reference).
    """
    return a


def keep_alive(owner: Any) -> None:
    """Nothing; a use of ``owner`` that keeps its arrays alive up to this point when compiled.

    Parameters
    ----------
    owner : any
        The arrays (or a tuple of them) whose :func:`borrowed` copies were used before.
    """


@jitable
def borrowed_designs(d: Designs) -> Designs:
    """``d`` with its arrays :func:`borrowed` (the caller owns them).

    Parameters
    ----------
    d : Designs
        The kinds' and the actuator's parameter vectors.

    Returns
    -------
    Designs
        The same vectors; compiled, the arrays among them hold no reference.
    """
    return Designs(borrowed(d.b0), borrowed(d.plant), borrowed(d.observer),
                   borrowed(d.controller), borrowed(d.actuator), d.n_observer, d.n_controller)


@jitable
def closed_loop(log: np.ndarray, x: np.ndarray, noise: np.ndarray, refs: np.ndarray,
                sg: Sampling, d: Designs, s: Steps) -> int:
    """Run samples 0 … N−1 of one run into ``log``; return the rows logged (< 0: diverged).

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ N)
        Filled column by column (:data:`esoarm.engines.metrics.LOG_ROWS` per joint).
    x : ndarray
        Plant state, initial state on entry (angles x[:joints], rates x[joints:2·joints]);
        advanced in place.
    noise : ndarray
        Standard-normal draws n_k, ``joints`` per sample.
    refs : ndarray, shape (3·joints, ≥ N)
        θd, θ̇d, θ̈d of each joint per sample [rad, rad/s, rad/s²].
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    d : Designs
        The kinds' and the actuator's parameter vectors, b0 and the state sizes.
    s : Steps
        The kinds' step functions (see :mod:`esoarm.contract`).

    Returns
    -------
    int
        N, or −(k+1) if the run diverged at sample k (row k is logged).
    """
    n = sg.n
    # the run's arrays, unpacked once (compiled, a record handed on costs reference counts)
    # and borrowed: ``work`` owns them until keep_alive below
    work = new_work(n, len(d.b0), d.n_observer, d.n_controller)
    y, u, drive, applied, duty, sat, acc, v, z, zhat, c, hist = (
        borrowed(work.y), borrowed(work.u), borrowed(work.drive), borrowed(work.applied),
        borrowed(work.duty), borrowed(work.sat), borrowed(work.acc), borrowed(work.v),
        borrowed(work.z), borrowed(work.zhat), borrowed(work.c), borrowed(work.hist))
    log, x, noise, refs, d = borrowed(log), borrowed(x), borrowed(noise), borrowed(refs), \
        borrowed_designs(d)
    sense_into(y, x, noise, 0, sg)
    start_into(z, c, y, d, s)
    for k in range(n):
        sense_into(y, x, noise, k, sg)
        command_into(y, u, drive, duty, sat, z, zhat, c, k, refs, d, s)
        if not respond_into(log, x, k, refs, y, u, sat, drive, applied, hist, z, zhat, acc, v,
                            sg, d, s):
            keep_alive(work)
            return -(k + 1)
        advance_plant_into(x, applied, k, sg, d.plant, s.plant_advance)
    keep_alive(work)
    return n


@jitable
def closed_loop_block(logs: np.ndarray, rows: np.ndarray, xs: np.ndarray, noises: np.ndarray,
                      refs: np.ndarray, sg: Sampling, d: Designs, s: Steps) -> None:
    """:func:`closed_loop` for a block of runs of one parameter set, runs innermost.

    Run i of the block has its own plant state ``xs[i]``, noise ``noises[i]`` and log
    ``logs[i]``; ``rows[i]`` receives what :func:`closed_loop` returns for it.  Each run
    takes the very steps of :func:`closed_loop` in the same order -- the same sample
    functions, the same arithmetic -- so its numbers are the same bits; only the loop
    order changes: each sample, and each RK4 step of the plant (the kind's
    ``advance_block``, ``s.plant_advance_block``), is taken for every run of the block
    before the next, and what depends on time only (the disturbance d(t)) is computed once
    for the block.  A run that diverges stops (its row is logged, as in
    :func:`closed_loop`) while the others go on.

    Parameters
    ----------
    logs : ndarray, shape (m, len(LOG_ROWS)·joints, ≥ N)
        One log per run (as ``log`` of :func:`closed_loop`).
    rows : ndarray of int, shape (m,)
        Output: N, or −(k+1) if run i diverged at sample k.
    xs : ndarray, shape (m, plant states)
        Plant states, initial on entry; advanced in place.
    noises : ndarray, shape (m, N·joints)
        Standard-normal draws per run.
    refs : ndarray, shape (3·joints, ≥ N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    sg : Sampling
        Samples N, timing [s] and sensor [rad].
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.
    """
    m = xs.shape[0]
    n = sg.n
    nj = len(d.b0)
    nz, nc = max(d.n_observer, 1), max(d.n_controller, 1)
    # per run: the arrays that carry state from one sample to the next; shared: scratch.
    # ``owned`` keeps them alive (keep_alive below); the loop uses them borrowed, so that
    # a view of a run's row costs no reference count
    owned = (np.empty((m, nj)), np.empty((m, nj)), np.empty((m, nj)), np.empty((m, nj)),
             np.zeros((m, nz)), np.zeros((m, 3 * nj)), np.zeros((m, nc)),
             np.zeros((m, max(n, 1) * nj)))
    y, u, sat, applied, z, zhat, c, hist = (
        borrowed(owned[0]), borrowed(owned[1]), borrowed(owned[2]), borrowed(owned[3]),
        borrowed(owned[4]), borrowed(owned[5]), borrowed(owned[6]), borrowed(owned[7]))
    scratch = new_work(0, nj, 0, 0)
    drive, duty, acc, v = (borrowed(scratch.drive), borrowed(scratch.duty),
                           borrowed(scratch.acc), borrowed(scratch.v))
    logs, xs, noises, refs, d = borrowed(logs), borrowed(xs), borrowed(noises), \
        borrowed(refs), borrowed_designs(d)
    alive = np.ones(m, dtype=np.bool_)
    for i in range(m):
        rows[i] = n
        sense_into(y[i], xs[i], noises[i], 0, sg)
        start_into(z[i], c[i], y[i], d, s)
    for k in range(n):
        for i in range(m):
            if not alive[i]:
                continue
            x, yi, ui, si, zi, zhi = xs[i], y[i], u[i], sat[i], z[i], zhat[i]
            sense_into(yi, x, noises[i], k, sg)
            command_into(yi, ui, drive, duty, si, zi, zhi, c[i], k, refs, d, s)
            if not respond_into(logs[i], x, k, refs, yi, ui, si, drive, applied[i], hist[i],
                                zi, zhi, acc, v, sg, d, s):
                alive[i] = False
                rows[i] = -(k + 1)
        # the plant step of every live run to t_{k+1} (the plant kind's block step)
        s.plant_advance_block(xs, applied, alive, k * sg.ts, sg.h, sg.nsub, d.plant)
    keep_alive((owned, scratch))
