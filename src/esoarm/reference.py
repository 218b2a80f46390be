"""Reference trajectories θd(t) with their first two derivatives.

Both kinds are evaluated on whole time grids with NumPy (every engine
precomputes the reference at t_k = k·Ts, so all engines see identical values).

``quintic-steps``
    Rest-to-rest moves: move i starts at ``t0`` and lasts ``T``, from the
    previous target (or ``start``) to its ``target``, along the quintic
    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = (t − t0)/T; the angle is held between moves.
``multisine``
    θd(t) = offset + Σ aᵢ sin(ωᵢ t + φᵢ), ωᵢ in rad/s.
"""

from __future__ import annotations

import numpy as np

from esoarm.scenario import Multisine, QuinticSteps

__all__ = ["evaluate_reference"]


def _quintic_steps(
    ref: QuinticSteps, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.full_like(t, ref.start)
    vel = np.zeros_like(t)
    acc = np.zeros_like(t)
    previous = ref.start
    for t0, dur, target in ref.moves:
        delta = target - previous
        after = t >= t0 + dur
        pos[after] = target
        vel[after] = 0.0
        acc[after] = 0.0
        during = (t >= t0) & ~after
        s = (t[during] - t0) / dur
        s2 = s * s
        pos[during] = previous + delta * s2 * s * (10.0 - 15.0 * s + 6.0 * s2)
        vel[during] = delta * 30.0 * s2 * (1.0 - 2.0 * s + s2) / dur
        acc[during] = delta * 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2) / (dur * dur)
        previous = target
    return pos, vel, acc


def _multisine(ref: Multisine, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.full_like(t, ref.offset)
    vel = np.zeros_like(t)
    acc = np.zeros_like(t)
    phases = ref.phases or [0.0] * len(ref.amplitudes)
    for a, w, phi in zip(ref.amplitudes, ref.frequencies, phases, strict=True):
        arg = w * t + phi
        sin, cos = np.sin(arg), np.cos(arg)
        pos += a * sin
        vel += a * w * cos
        acc -= a * w * w * sin
    return pos, vel, acc


def evaluate_reference(
    ref: QuinticSteps | Multisine, t: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference angle θd [rad], rate θ̇d [rad/s] and acceleration θ̈d [rad/s²].

    Parameters
    ----------
    ref : QuinticSteps or Multisine
        The scenario's ``reference`` section.
    t : array_like
        Times [s].
    """
    t_arr = np.atleast_1d(np.asarray(t, dtype=float))
    if isinstance(ref, QuinticSteps):
        return _quintic_steps(ref, t_arr)
    return _multisine(ref, t_arr)
