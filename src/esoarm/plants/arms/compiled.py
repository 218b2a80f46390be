"""The URDF plant kind's step functions as the compiled engine runs them.

The reference engine steps a URDF arm with Pinocchio (:mod:`esoarm.plants.arms.twin`);
numba cannot call Pinocchio, so the batch engine compiles these functions in
their place (:func:`esoarm._jit.jitable_as`).  They take the same arguments
and do the same arithmetic around the rigid body -- :func:`~esoarm.plants.arms.twin.rk4_begin`,
:func:`~esoarm.plants.arms.twin.rk4_stage` and
:func:`~esoarm.plants.arms.twin.joint_drive` are shared -- with the rigid-body
terms from :mod:`esoarm.plants.arms.rigid_body` on the models packed into the design
vector.  Both agree to rounding (forward dynamics within 1e-10 of Pinocchio's
ABA); a closed-loop run by both agrees to the tolerance
:data:`ENGINE_TOLERANCE` states.

Layout of the plant's design vector (n joints)::

    [CODE, handle, c, n, twin (5n + 2: pack_params), nominal model, true model]

each model :func:`esoarm.plants.arms.rigid_body.pack_model` (the true one with the
payload and its gravity divided by the inertia scale).
"""

from __future__ import annotations

import math

import numpy as np

from esoarm._jit import jitable
from esoarm.plants.arms.rigid_body import (
    bias_offset,
    dynamics_terms,
    forward_dynamics,
    forward_dynamics_block,
    model_size,
    scratch_offset,
    solve_mass,
    workspace_size,
)
from esoarm.plants.arms.twin import _B, _DA, _DW, _FC, _VS, joint_drive, rk4_begin, rk4_stage

__all__ = ["ENGINE_TOLERANCE", "NJ", "TWIN", "acceleration", "advance", "advance_block",
           "nominal_offset", "observer_input", "true_offset"]

#: Position of n and of the twin's parameters in the design vector.
NJ, TWIN = 3, 4

#: Metrics of a closed-loop run of an arm: the compiled engine against the reference
#: engine (Pinocchio), relative to the metric's size (rounding differences of the rigid
#: body, ~1e-15 per evaluation, grown by the closed loop over 4,000 samples).
ENGINE_TOLERANCE = 1e-6


@jitable
def nominal_offset(n: int) -> int:
    """Start of the nominal model in the design vector of n joints.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Index of the nominal model's first value (TWIN + 5n + 2).
    """
    return TWIN + 5 * n + 2


@jitable
def true_offset(n: int) -> int:
    """Start of the true model in the design vector of n joints.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Index of the true model's first value (after the nominal model).
    """
    return TWIN + 5 * n + 2 + model_size(n)


@jitable
def _parts(p: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    n = int(p[NJ])
    tp = p[TWIN:TWIN + 5 * n + 2]
    a = nominal_offset(n)
    b = true_offset(n)
    return n, tp, p[a:b], p[b:b + model_size(n)]


@jitable
def _advance_one(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int, n: int,
                 tp: np.ndarray, true: np.ndarray, w: np.ndarray, ws: np.ndarray,
                 acc: np.ndarray) -> None:
    q, v, tau = x[:n], x[n:2 * n], x[2 * n:3 * n]
    rk4_begin(q, v, tau, u, tp, w)
    for j in range(nsub):
        t = t0 + j * h
        for stage in range(4):
            frac = 0.0 if stage == 0 else (1.0 if stage == 3 else 0.5)
            forward_dynamics(true, w[0], w[1], w[3], ws, acc)
            rk4_stage(stage, q, v, tau, u, t + frac * h, h, acc, tp, w)
        for i in range(n):
            x[i] = w[0, i]
            x[n + i] = w[1, i]
            x[2 * n + i] = w[2, i]


@jitable
def advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
            p: np.ndarray) -> None:
    """Integrate x = (q, q̇, τ) in place over ``nsub`` RK4 steps of h [s], u held (compiled).

    Parameters
    ----------
    x : ndarray, shape (3n,)
        State: q [rad] in x[:n], q̇ [rad/s] in x[n:2n], lag τ [N·m] in x[2n:3n]; updated in
        place.
    u : ndarray, shape (n,)
        Applied torque per joint [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = Ts).
    p : ndarray
        The design vector (see the module docstring), p[0] = CODE.
    """
    n, tp, _, true = _parts(p)
    _advance_one(x, u, t0, h, nsub, n, tp, true, np.zeros((8, n)),
                 np.empty(workspace_size(n)), np.empty(n))


@jitable
def _drive_block(v: np.ndarray, tau: np.ndarray, tp: np.ndarray, out: np.ndarray) -> None:
    """:func:`~esoarm.plants.arms.twin.joint_drive` for every run (arrays (n, runs))."""
    n, runs = v.shape
    inv_s = tp[5 * n]
    for i in range(n):
        fc, vs, b = tp[_FC * n + i], tp[_VS * n + i], tp[_B * n + i]
        for r in range(runs):
            friction = fc * math.tanh(v[i, r] / vs) + b * v[i, r]
            out[i, r] = (tau[i, r] - friction) * inv_s


@jitable
def _stage_block(stage: int, base: np.ndarray, u: np.ndarray, t: float, h: float,
                 acc: np.ndarray, tp: np.ndarray, w: np.ndarray) -> None:
    """:func:`~esoarm.plants.arms.twin.rk4_stage` for every run: ``base`` (3, n, runs) the
    step's start (q, q̇, τ), ``w`` (8, n, runs) its workspace rows, ``acc`` (n, runs)."""
    n, runs = acc.shape
    lag = tp[tp.shape[0] - 1]
    weight = 1.0 if stage == 0 or stage == 3 else 2.0
    coef = h if stage == 2 else 0.5 * h
    for i in range(n):
        dist = tp[_DA * n + i] * math.sin(tp[_DW * n + i] * t)  # d(t): the same for every run
        for r in range(runs):
            dq = w[1, i, r]
            dv = acc[i, r] + dist
            dtau = (u[i, r] - w[2, i, r]) / lag if lag > 0.0 else 0.0
            w[4, i, r] += weight * dq
            w[5, i, r] += weight * dv
            w[6, i, r] += weight * dtau
            if stage < 3:
                w[0, i, r] = base[0, i, r] + coef * dq
                w[1, i, r] = base[1, i, r] + coef * dv
                w[2, i, r] = base[2, i, r] + coef * dtau
    if stage == 3:
        sixth = h / 6.0
        for i in range(n):
            for r in range(runs):
                w[0, i, r] = base[0, i, r] + sixth * w[4, i, r]
                w[1, i, r] = base[1, i, r] + sixth * w[5, i, r]
                w[2, i, r] = base[2, i, r] + sixth * w[6, i, r]
                w[4, i, r] = 0.0
                w[5, i, r] = 0.0
                w[6, i, r] = 0.0
    _drive_block(w[1], w[2] if lag > 0.0 else u, tp, w[3])


@jitable
def advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                  nsub: int, p: np.ndarray) -> None:
    """:func:`advance` for each live run i of a block (``xs[i]``, ``us[i]``), the same bits.

    The runs are advanced together, runs innermost
    (:func:`~esoarm.plants.arms.rigid_body.forward_dynamics_block`, then the RK4 stage of
    :func:`~esoarm.plants.arms.twin.rk4_stage` for every run): each run takes the
    operations :func:`advance` takes, in the same order.  A run that is not live
    is carried as the zero state and not written back.

    Parameters
    ----------
    xs : ndarray, shape (runs, 3n)
        States of the runs, live ones updated in place.
    us : ndarray, shape (runs, n)
        Applied torque of each run [N·m].
    live : ndarray of bool, shape (runs,)
        Which runs to advance.
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps per sample.
    p : ndarray
        The design vector (see the module docstring), p[0] = CODE.
    """
    n, tp, _, true = _parts(p)
    runs = xs.shape[0]
    base = np.zeros((3, n, runs))  # the state at the start of the RK4 step
    u = np.zeros((n, runs))
    for r in range(runs):
        if live[r]:
            for i in range(n):
                base[0, i, r] = xs[r, i]
                base[1, i, r] = xs[r, n + i]
                base[2, i, r] = xs[r, 2 * n + i]
                u[i, r] = us[r, i]
    w = np.zeros((8, n, runs))
    wb = np.empty((workspace_size(n), runs))
    acc = np.empty((n, runs))
    lag = tp[tp.shape[0] - 1]
    w[0:3] = base  # rk4_begin
    _drive_block(base[1], base[2] if lag > 0.0 else u, tp, w[3])
    for j in range(nsub):
        t = t0 + j * h
        for stage in range(4):
            frac = 0.0 if stage == 0 else (1.0 if stage == 3 else 0.5)
            forward_dynamics_block(true, w[0], w[1], w[3], wb, acc)
            _stage_block(stage, base, u, t + frac * h, h, acc, tp, w)
        base[:] = w[0:3]
    for r in range(runs):
        if live[r]:
            for i in range(n):
                xs[r, i] = base[0, i, r]
                xs[r, n + i] = base[1, i, r]
                xs[r, 2 * n + i] = base[2, i, r]


@jitable
def acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                 out: np.ndarray) -> None:
    """True q̈ [rad/s²] at state x, time t, input u applied from t on, into ``out`` (compiled).

    Parameters
    ----------
    x : ndarray, shape (3n,)
        State (q [rad], q̇ [rad/s], τ [N·m]).
    u : ndarray, shape (n,)
        Applied torque [N·m] (acts directly when T = 0).
    t : float
        Time [s].
    p : ndarray
        The design vector (see the module docstring), p[0] = CODE.
    out : ndarray, shape (n,)
        Output: q̈ [rad/s²].
    """
    n, tp, _, true = _parts(p)
    v = x[n:2 * n]
    lag = tp[tp.shape[0] - 1]
    ws = np.empty(workspace_size(n))  # the one allocation: the drive in the caller's part
    free = scratch_offset(n)
    drive = ws[free:free + n]
    joint_drive(v, x[2 * n:3 * n] if lag > 0.0 else u, tp, drive)
    forward_dynamics(true, x[:n], v, drive, ws, out)
    for i in range(n):  # q̈ = ABA output + d(t) (add_disturbance)
        out[i] = out[i] + tp[3 * n + i] * math.sin(tp[4 * n + i] * t)


@jitable
def observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """v = M̂(q̂)⁻¹ (u − c·n̂(q̂, q̂̇)) [rad/s²] into ``v`` (compiled).

    Parameters
    ----------
    zhat : ndarray, shape (3n,)
        Estimate (q̂ [rad], q̂̇ [rad/s], f̂ [rad/s²]) of joint j in zhat[3j:3j+3].
    u : ndarray, shape (n,)
        Command as applied [N·m].
    p : ndarray
        The design vector (see the module docstring), p[0] = CODE.
    v : ndarray, shape (n,)
        Output: v [rad/s²].
    """
    n, _, nominal, _ = _parts(p)
    ws = np.empty(workspace_size(n))
    dynamics_terms(nominal, zhat[0:3 * n:3], zhat[1:3 * n:3], ws)  # M̂ and n̂ at (q̂, q̂̇)
    nb = bias_offset(n)
    c = p[2]
    for i in range(n):
        v[i] = u[i] - ws[nb + i] if c != 0.0 else u[i]
    solve_mass(ws, n, v)
