"""One block of a streamed run: the samples of :func:`esoarm.engines.loop.closed_loop`,
indexed within the block (:mod:`esoarm.engines.stream`; compiled by its ``kernels``)."""

from __future__ import annotations

import numpy as np

from esoarm._jit import jitable
from esoarm.engines.loop import borrowed, borrowed_designs, keep_alive
from esoarm.engines.sample import (
    Designs,
    Sampling,
    Steps,
    advance_plant_into,
    command_into,
    gate_into,
    log_sample,
    sense_into,
    start_into,
    update_observer_into,
)
from esoarm.plants.actuator import delayed_input

__all__ = ["stream_block"]


@jitable
def stream_block(log: np.ndarray, x: np.ndarray, noise: np.ndarray, refs: np.ndarray,
                 k0: int, off: int, m: int, y: np.ndarray, u: np.ndarray, drive: np.ndarray,
                 applied: np.ndarray, duty: np.ndarray, sat: np.ndarray, acc: np.ndarray,
                 v: np.ndarray, z: np.ndarray, zhat: np.ndarray, c: np.ndarray,
                 hist: np.ndarray, sg: Sampling, d: Designs, s: Steps) -> int:
    """Samples k0 … k0+m−1 of one run, each exactly as in :func:`~esoarm.engines.loop.closed_loop`.

    The block's arrays hold sample k in column (or draw) ``k − k0 + off``: ``off`` is 0
    for the first block and 1 after it, so that a kind that treats sample 0 apart (the
    PID's first difference) sees index 0 only at k = 0.  Time is the run's, t_k = k·Ts.
    The transport delay's drives are ``hist``: from index 0 in the first block, after
    the previous block's last ``delay`` drives (copied to its front) in the next ones.

    Parameters
    ----------
    log : ndarray, shape (len(LOG_ROWS)·joints, ≥ off + m)
        The block's log.
    x : ndarray
        Plant state at t_k0, advanced in place to t_{k0+m}.
    noise : ndarray ((off + m)·joints,)
        The block's noise draws (joint index fastest).
    refs : ndarray, shape (3·joints, ≥ off + m)
        θd, θ̇d, θ̈d of the block's samples [rad, rad/s, rad/s²].
    k0, off, m : int
        First sample of the block, its column offset (0 or 1) and its length.
    y, u, drive, applied, duty, sat, acc, v, z, zhat, c : ndarray
        The run's state and scratch arrays (:class:`esoarm.engines.sample.Work`), carried
        from the previous block.
    hist : ndarray ((delay + m)·joints,)
        The drives of the transport delay (see above).
    sg : Sampling
        Timing and sensor of the run.
    d : Designs
        The kinds' and the actuator's parameter vectors.
    s : Steps
        The kinds' step functions.

    Returns
    -------
    int
        m, or −(i+1) if the run diverged at sample k0 + i (its row, column i + off, logged).
    """
    nj = len(y)
    owner = (log, x, noise, refs, y, u, drive, applied, duty, sat, acc, v, z, zhat, c, hist)
    log, x, noise, refs = borrowed(log), borrowed(x), borrowed(noise), borrowed(refs)
    y, u, drive, applied, duty, sat = (borrowed(y), borrowed(u), borrowed(drive),
                                       borrowed(applied), borrowed(duty), borrowed(sat))
    acc, v, z, zhat, c, hist = (borrowed(acc), borrowed(v), borrowed(z), borrowed(zhat),
                                borrowed(c), borrowed(hist))
    d = borrowed_designs(d)
    if k0 == 0:
        sense_into(y, x, noise, 0, sg)
        start_into(z, c, y, d, s)
    b0 = d.b0
    for i in range(m):
        k = k0 + i
        col = i + off
        sense_into(y, x, noise, col, sg)
        command_into(y, u, drive, duty, sat, z, zhat, c, col, refs, d, s)
        # steps 3-5 (esoarm.engines.sample.respond_into), the log and the delay indexed
        # within the block, time t_k = k·Ts the run's
        delayed_input(hist, k if k0 == 0 else i + sg.delay, sg.delay, drive, applied)
        s.plant_acceleration(x, applied, k * sg.ts, d.plant, acc)
        s.plant_observer_input(zhat, u, d.plant, v)
        ok = True
        for j in range(nj):
            ok = log_sample(log, col, j, nj, x, refs[3 * j, col], u[j], zhat,
                            acc[j] - b0[j] * v[j], y[j], sat[j]) and ok
        if not ok:
            keep_alive(owner)
            return -(i + 1)
        gate_into(v, y, d.actuator)
        update_observer_into(z, zhat, y, v, d, s)
        advance_plant_into(x, applied, k, sg, d.plant, s.plant_advance)
    keep_alive(owner)
    return m
