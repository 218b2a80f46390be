"""Rigid-body dynamics of a URDF arm as plain functions on arrays (numba-compilable).

The compiled engine cannot call Pinocchio, so the dynamics the URDF plant kind
and the computed-torque controller need -- the bias n(q, q̇) = C(q, q̇) q̇ + g(q),
the joint-space inertia M(q) and the forward dynamics q̈ = M(q)⁻¹(τ − n) -- are
written here again, on a flat float array extracted once from the Pinocchio
model (:func:`pack_model`).  Pinocchio stays the parser and the reference:
the tests hold these functions to Pinocchio's ``rnea``, ``crba``,
``nonLinearEffects`` and ``aba`` within 1e-10 (relative) on random states of
every built-in arm and of the example robots.

Algorithms (Featherstone, *Rigid Body Dynamics Algorithms*, 2008):

* :func:`rnea` -- the recursive Newton-Euler algorithm (ch. 5.3): velocities
  and accelerations outward, forces inward, τ_i = S_iᵀ f_i;
* :func:`crba` -- the composite-rigid-body algorithm (ch. 6.2):
  I^c_λ(i) += X_iᵀ I^c_i X_i, then M_ij = S_jᵀ X…ᵀ I^c_i S_i up the chain;
* :func:`forward_dynamics` -- M q̈ = τ − n by a Cholesky factorization of M.

Conventions are Pinocchio's: spatial motion (linear, angular), force (linear,
moment), each joint's frame placed in its parent's by the URDF's fixed
placement and then the joint's motion (a rotation about, or a translation
along, its axis).  Revolute, continuous (its angle q; Pinocchio stores cos q,
sin q) and prismatic joints; the model is a tree in Pinocchio's joint order
(every parent before its children), a serial chain being the usual case.

Layout of a packed model (:func:`pack_model`): ``[n, g_x, g_y, g_z]`` (the
gravity vector of the model [m/s²]), then per joint :data:`ROW` values:
parent (−1: the base), kind (0 revolute, 1 prismatic), axis (3), the fixed
placement's rotation (9, row-major) and translation (3) [m], and the body's
6×6 spatial inertia about the joint frame (36) [kg, kg·m, kg·m²].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from esoarm._jit import jitable

__all__ = ["HEAD", "ROW", "bias", "cholesky_solve", "crba", "forward_dynamics",
           "mass_and_bias", "model_size", "pack_model", "rnea", "workspace_size"]

#: Values before the joints' rows, and per joint.
HEAD, ROW = 4, 53
_PARENT, _KIND, _AXIS, _ROT, _POS, _INERTIA = 0, 1, 2, 5, 14, 17
REVOLUTE, PRISMATIC = 0, 1


@jitable
def model_size(n: int) -> int:
    """Length of a packed model of n joints.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        HEAD + ROW·n values.

    Examples
    --------
    >>> model_size(2)
    110
    """
    return HEAD + ROW * n


@jitable
def workspace_size(n: int) -> int:
    """Length of the scratch array :func:`rnea`, :func:`crba` and
    :func:`forward_dynamics` take for n joints.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Number of float64 values.
    """
    return n * (36 + 36 + 24) + n * n + 2 * n + 42


def _spatial_inertia(mass: float, com: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """6×6 spatial inertia about the frame origin, (linear, angular) order.

    [[m 1, −m [c]×], [m [c]×, I_c − m [c]×²]] with I_c the rotational inertia
    about the centre of mass c.
    """
    cx = np.array([[0.0, -com[2], com[1]], [com[2], 0.0, -com[0]], [-com[1], com[0], 0.0]])
    out = np.zeros((6, 6))
    out[:3, :3] = mass * np.eye(3)
    out[:3, 3:] = -mass * cx
    out[3:, :3] = mass * cx
    out[3:, 3:] = inertia - mass * cx @ cx
    return out


def pack_model(model: Any) -> np.ndarray:
    """A Pinocchio model of 1-dof joints as one float array (layout in the module docstring).

    Parameters
    ----------
    model : pinocchio.Model
        Revolute (any axis, bounded or continuous) and prismatic joints only.

    Returns
    -------
    ndarray, shape (model_size(n),)
        The packed model, read-only.

    Raises
    ------
    ValueError
        A joint of another type (a one-line message naming it).
    """
    import pinocchio as pin

    n = model.njoints - 1
    out = np.zeros(model_size(n))
    out[0] = n
    out[1:4] = np.asarray(model.gravity.linear, dtype=float)
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    for i in range(n):
        jid = i + 1
        joint = model.joints[jid]
        if joint.nv != 1:
            raise ValueError(f"joint '{model.names[jid]}' ({joint.shortname()}) has "
                             f"{joint.nv} degrees of freedom; only 1-dof joints are packed")
        subspace = np.asarray(data.joints[jid].S, dtype=float).reshape(6)
        linear, angular = subspace[:3], subspace[3:]
        row = out[HEAD + ROW * i: HEAD + ROW * (i + 1)]
        row[_PARENT] = model.parents[jid] - 1
        if np.any(angular != 0.0):
            if np.any(linear != 0.0):
                raise ValueError(f"joint '{model.names[jid]}' ({joint.shortname()}) is "
                                 "neither a pure rotation nor a pure translation")
            row[_KIND], axis = REVOLUTE, angular
        else:
            row[_KIND], axis = PRISMATIC, linear
        row[_AXIS:_AXIS + 3] = axis
        placement = model.jointPlacements[jid]
        row[_ROT:_ROT + 9] = np.asarray(placement.rotation, dtype=float).reshape(9)
        row[_POS:_POS + 3] = np.asarray(placement.translation, dtype=float)
        body = model.inertias[jid]
        row[_INERTIA:_INERTIA + 36] = _spatial_inertia(
            float(body.mass), np.asarray(body.lever, dtype=float),
            np.asarray(body.inertia, dtype=float)).reshape(36)
    out.setflags(write=False)
    return out


# ---------------------------------------------------------------------------
# compiled helpers: all arrays are float64; ``m`` a packed model, ``ws`` scratch


@jitable
def _pose(m: np.ndarray, i: int, qi: float, x: np.ndarray) -> None:
    """Joint i's frame in its parent's at angle qi: R into x[0:3, 0:3], p into x[3, 0:3].

    The fixed placement (R0, p0) then the joint motion: R = R0 · exp([a]× qi),
    p = p0 (revolute) or R = R0, p = p0 + R0 a qi (prismatic).
    """
    b = HEAD + ROW * i
    ax, ay, az = m[b + _AXIS], m[b + _AXIS + 1], m[b + _AXIS + 2]
    r0 = b + _ROT
    px, py, pz = m[b + _POS], m[b + _POS + 1], m[b + _POS + 2]
    if m[b + _KIND] == REVOLUTE:  # Rodrigues
        c, s = math.cos(qi), math.sin(qi)
        k = 1.0 - c
        j00, j01, j02 = c + k * ax * ax, k * ax * ay - s * az, k * ax * az + s * ay
        j10, j11, j12 = k * ax * ay + s * az, c + k * ay * ay, k * ay * az - s * ax
        j20, j21, j22 = k * ax * az - s * ay, k * ay * az + s * ax, c + k * az * az
    else:
        j00, j01, j02, j10, j11, j12, j20, j21, j22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
        px += qi * (m[r0] * ax + m[r0 + 1] * ay + m[r0 + 2] * az)
        py += qi * (m[r0 + 3] * ax + m[r0 + 4] * ay + m[r0 + 5] * az)
        pz += qi * (m[r0 + 6] * ax + m[r0 + 7] * ay + m[r0 + 8] * az)
    for row in range(3):
        a0, a1, a2 = m[r0 + 3 * row], m[r0 + 3 * row + 1], m[r0 + 3 * row + 2]
        x[row, 0] = a0 * j00 + a1 * j10 + a2 * j20
        x[row, 1] = a0 * j01 + a1 * j11 + a2 * j21
        x[row, 2] = a0 * j02 + a1 * j12 + a2 * j22
    x[3, 0] = px
    x[3, 1] = py
    x[3, 2] = pz


@jitable
def _subspace(m: np.ndarray, i: int, s: np.ndarray) -> None:
    """Motion subspace S_i of joint i (6): (0, a) revolute, (a, 0) prismatic."""
    b = HEAD + ROW * i
    for k in range(6):
        s[k] = 0.0
    off = 3 if m[b + _KIND] == REVOLUTE else 0
    for k in range(3):
        s[off + k] = m[b + _AXIS + k]


@jitable
def _transforms(m: np.ndarray, q: np.ndarray, xs: np.ndarray, ss: np.ndarray) -> None:
    """The pose ``xs[i]`` (:func:`_pose`) and subspace ``ss[i]`` (6) of every joint at q."""
    n = int(m[0])
    for i in range(n):
        _pose(m, i, q[i], xs[i])
        _subspace(m, i, ss[i])


@jitable
def _motion_in(x: np.ndarray, w: np.ndarray, out: np.ndarray) -> None:
    """out = X w: a motion in the parent's frame seen in the child's (pose x).

    ω' = Rᵀ ω, v' = Rᵀ (v − p × ω).
    """
    px, py, pz = x[3, 0], x[3, 1], x[3, 2]
    vx = w[0] - (py * w[5] - pz * w[4])
    vy = w[1] - (pz * w[3] - px * w[5])
    vz = w[2] - (px * w[4] - py * w[3])
    for c in range(3):
        out[c] = x[0, c] * vx + x[1, c] * vy + x[2, c] * vz
        out[3 + c] = x[0, c] * w[3] + x[1, c] * w[4] + x[2, c] * w[5]


@jitable
def _force_out(x: np.ndarray, f: np.ndarray, out: np.ndarray) -> None:
    """out += Xᵀ f: a force in the child's frame (pose x) added in the parent's.

    f' = R f, n' = R n + p × (R f).
    """
    lx = x[0, 0] * f[0] + x[0, 1] * f[1] + x[0, 2] * f[2]
    ly = x[1, 0] * f[0] + x[1, 1] * f[1] + x[1, 2] * f[2]
    lz = x[2, 0] * f[0] + x[2, 1] * f[1] + x[2, 2] * f[2]
    px, py, pz = x[3, 0], x[3, 1], x[3, 2]
    out[0] += lx
    out[1] += ly
    out[2] += lz
    out[3] += x[0, 0] * f[3] + x[0, 1] * f[4] + x[0, 2] * f[5] + py * lz - pz * ly
    out[4] += x[1, 0] * f[3] + x[1, 1] * f[4] + x[1, 2] * f[5] + pz * lx - px * lz
    out[5] += x[2, 0] * f[3] + x[2, 1] * f[4] + x[2, 2] * f[5] + px * ly - py * lx


@jitable
def _load_inertia(m: np.ndarray, i: int, ci: np.ndarray) -> None:
    """Body i's inertia in compact form: mass ci[0, 0], h = m·c in ci[1, 0:3], and the
    rotational inertia about the frame origin in ci[2:5, 0:3]."""
    b = HEAD + ROW * i + _INERTIA
    ci[0, 0] = m[b]
    ci[1, 0] = m[b + 6 * 5 + 1]  # [h]× is the lower-left block of the 6×6 inertia
    ci[1, 1] = m[b + 6 * 3 + 2]
    ci[1, 2] = m[b + 6 * 4 + 0]
    for r in range(3):
        for c in range(3):
            ci[2 + r, c] = m[b + 6 * (3 + r) + 3 + c]


@jitable
def _inertia_times(ci: np.ndarray, w: np.ndarray, out: np.ndarray) -> None:
    """out = I w for a compact inertia ci: (m v − h × ω, I_o ω + h × v)."""
    mass = ci[0, 0]
    hx, hy, hz = ci[1, 0], ci[1, 1], ci[1, 2]
    out[0] = mass * w[0] - (hy * w[5] - hz * w[4])
    out[1] = mass * w[1] - (hz * w[3] - hx * w[5])
    out[2] = mass * w[2] - (hx * w[4] - hy * w[3])
    for r in range(3):
        out[3 + r] = ci[2 + r, 0] * w[3] + ci[2 + r, 1] * w[4] + ci[2 + r, 2] * w[5]
    out[3] += hy * w[2] - hz * w[1]
    out[4] += hz * w[0] - hx * w[2]
    out[5] += hx * w[1] - hy * w[0]


@jitable
def _inertia_out(x: np.ndarray, ci: np.ndarray, cp: np.ndarray, tmp: np.ndarray) -> None:
    """cp += the compact inertia ci (child frame, pose x) expressed in the parent's frame.

    m' = m, h' = R h + m p, I' = R I Rᵀ − (p h_rᵀ + h_r pᵀ) + (2 h_r·p + m p·p) 1 − m p pᵀ
    with h_r = R h (the parallel-axis theorem moved to the parent's origin).
    """
    mass = ci[0, 0]
    px, py, pz = x[3, 0], x[3, 1], x[3, 2]
    hr0 = x[0, 0] * ci[1, 0] + x[0, 1] * ci[1, 1] + x[0, 2] * ci[1, 2]
    hr1 = x[1, 0] * ci[1, 0] + x[1, 1] * ci[1, 1] + x[1, 2] * ci[1, 2]
    hr2 = x[2, 0] * ci[1, 0] + x[2, 1] * ci[1, 1] + x[2, 2] * ci[1, 2]
    cp[0, 0] += mass
    cp[1, 0] += hr0 + mass * px
    cp[1, 1] += hr1 + mass * py
    cp[1, 2] += hr2 + mass * pz
    for r in range(3):  # tmp = R I
        for c in range(3):
            tmp[r, c] = x[r, 0] * ci[2, c] + x[r, 1] * ci[3, c] + x[r, 2] * ci[4, c]
    p = (px, py, pz)
    hr = (hr0, hr1, hr2)
    diag = 2.0 * (hr0 * px + hr1 * py + hr2 * pz) + mass * (px * px + py * py + pz * pz)
    for r in range(3):
        for c in range(3):
            val = tmp[r, 0] * x[c, 0] + tmp[r, 1] * x[c, 1] + tmp[r, 2] * x[c, 2]
            val -= p[r] * hr[c] + hr[r] * p[c] + mass * p[r] * p[c]
            if r == c:
                val += diag
            cp[2 + r, c] += val


@jitable
def _rnea_pass(m: np.ndarray, v: np.ndarray, a: np.ndarray, gravity: bool, xs: np.ndarray,
               ss: np.ndarray, vel: np.ndarray, acc: np.ndarray, frc: np.ndarray,
               tau: np.ndarray, ci: np.ndarray, col: np.ndarray) -> None:
    """RNEA on precomputed poses: τ = M(q) a + C(q, v) v (+ g(q) with ``gravity``).

    ``ci`` (≥ 5×3) and ``col`` (6) are scratch.
    """
    n = int(m[0])
    for i in range(n):
        parent = int(m[HEAD + ROW * i + _PARENT])
        x = xs[i]
        s = ss[i]
        vi, ai = vel[i], acc[i]
        # v_i = X_i v_λ + S q̇_i ; a_i = X_i a_λ + S q̈_i + v_i ×ₘ (S q̇_i)
        if parent < 0:
            for r in range(6):
                vi[r] = 0.0
                ai[r] = 0.0
            if gravity:  # a_0 = −g (the base accelerates upwards): gravity on every body
                for c in range(3):
                    ai[c] = -(x[0, c] * m[1] + x[1, c] * m[2] + x[2, c] * m[3])
        else:
            _motion_in(x, vel[parent], vi)
            _motion_in(x, acc[parent], ai)
        qd, qdd = v[i], a[i]
        for r in range(6):
            vi[r] += s[r] * qd
            ai[r] += s[r] * qdd
        # v_i ×ₘ (S q̇): (ω × wl + vl × ww, ω × ww), w = S q̇
        wl0, wl1, wl2 = s[0] * qd, s[1] * qd, s[2] * qd
        ww0, ww1, ww2 = s[3] * qd, s[4] * qd, s[5] * qd
        vl0, vl1, vl2, om0, om1, om2 = vi[0], vi[1], vi[2], vi[3], vi[4], vi[5]
        ai[0] += om1 * wl2 - om2 * wl1 + vl1 * ww2 - vl2 * ww1
        ai[1] += om2 * wl0 - om0 * wl2 + vl2 * ww0 - vl0 * ww2
        ai[2] += om0 * wl1 - om1 * wl0 + vl0 * ww1 - vl1 * ww0
        ai[3] += om1 * ww2 - om2 * ww1
        ai[4] += om2 * ww0 - om0 * ww2
        ai[5] += om0 * ww1 - om1 * ww0
        # f_i = I a_i + v_i ×* (I v_i);  v ×* h = (ω × hl, ω × ha + vl × hl)
        _load_inertia(m, i, ci)
        f = frc[i]
        _inertia_times(ci, ai, f)
        _inertia_times(ci, vi, col)
        hl0, hl1, hl2, ha0, ha1, ha2 = col[0], col[1], col[2], col[3], col[4], col[5]
        f[0] += om1 * hl2 - om2 * hl1
        f[1] += om2 * hl0 - om0 * hl2
        f[2] += om0 * hl1 - om1 * hl0
        f[3] += om1 * ha2 - om2 * ha1 + vl1 * hl2 - vl2 * hl1
        f[4] += om2 * ha0 - om0 * ha2 + vl2 * hl0 - vl0 * hl2
        f[5] += om0 * ha1 - om1 * ha0 + vl0 * hl1 - vl1 * hl0
    for i in range(n - 1, -1, -1):
        f = frc[i]
        s = ss[i]
        t = 0.0
        for r in range(6):
            t += s[r] * f[r]
        tau[i] = t
        parent = int(m[HEAD + ROW * i + _PARENT])
        if parent >= 0:  # f_λ += X_iᵀ f_i
            _force_out(xs[i], f, frc[parent])


@jitable
def _crba_pass(m: np.ndarray, xs: np.ndarray, ss: np.ndarray, ic: np.ndarray,
               col: np.ndarray, tmp: np.ndarray, out: np.ndarray) -> None:
    """CRBA on precomputed poses: the full symmetric M(q) into ``out`` (n, n)."""
    n = int(m[0])
    for i in range(n):
        for r in range(5):
            for c in range(3):
                ic[i, r, c] = 0.0
        _load_inertia(m, i, ic[i])
        for j in range(n):  # joints off each other's path to the base stay 0 (a tree)
            out[i, j] = 0.0
    for i in range(n - 1, -1, -1):
        parent = int(m[HEAD + ROW * i + _PARENT])
        if parent >= 0:  # I^c_λ += X_iᵀ I^c_i X_i
            _inertia_out(xs[i], ic[i], ic[parent], tmp)
    for i in range(n):
        s = ss[i]
        _inertia_times(ic[i], s, col)  # F = I^c_i S_i
        d = 0.0
        for r in range(6):
            d += s[r] * col[r]
        out[i, i] = d
        j = i
        parent = int(m[HEAD + ROW * j + _PARENT])
        while parent >= 0:
            for r in range(6):
                tmp[5, r] = 0.0
            _force_out(xs[j], col, tmp[5])  # F = X_jᵀ F
            for r in range(6):
                col[r] = tmp[5, r]
            j = parent
            sj = ss[j]
            e = 0.0
            for r in range(6):
                e += sj[r] * col[r]
            out[i, j] = e
            out[j, i] = e
            parent = int(m[HEAD + ROW * j + _PARENT])


@jitable
def _views(m: np.ndarray, ws: np.ndarray) -> tuple[np.ndarray, ...]:
    """The scratch arrays of n joints as views of ``ws`` (no allocation).

    Transforms (n, 6, 6), composite inertias (n, 6, 6), velocities, accelerations,
    forces and subspaces (n, 6) each, M (n, n), a zero vector and the bias (n),
    a 6-column and a 6×6 scratch.
    """
    n = int(m[0])
    o = 0
    xs = ws[o:o + 36 * n].reshape((n, 6, 6))
    o += 36 * n
    ic = ws[o:o + 36 * n].reshape((n, 6, 6))
    o += 36 * n
    vel = ws[o:o + 6 * n].reshape((n, 6))
    o += 6 * n
    acc = ws[o:o + 6 * n].reshape((n, 6))
    o += 6 * n
    frc = ws[o:o + 6 * n].reshape((n, 6))
    o += 6 * n
    ss = ws[o:o + 6 * n].reshape((n, 6))
    o += 6 * n
    mm = ws[o:o + n * n].reshape((n, n))
    o += n * n
    zero = ws[o:o + n]
    o += n
    rhs = ws[o:o + n]
    o += n
    col = ws[o:o + 6]
    o += 6
    tmp = ws[o:o + 36].reshape((6, 6))
    return xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp


@jitable
def rnea(m: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray, ws: np.ndarray,
         tau: np.ndarray) -> None:
    """Inverse dynamics τ = M(q) q̈ + C(q, q̇) q̇ + g(q) [N·m or N] into ``tau``.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q, v, a : ndarray, shape (n,)
        Joint positions [rad or m], velocities and accelerations.
    ws : ndarray
        Scratch of length :func:`workspace_size` (n).
    tau : ndarray, shape (n,)
        Output: the joint torques (forces for prismatic joints).
    """
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _views(m, ws)
    _transforms(m, q, xs, ss)
    _rnea_pass(m, v, a, True, xs, ss, vel, acc, frc, tau, tmp, col)


@jitable
def bias(m: np.ndarray, q: np.ndarray, v: np.ndarray, ws: np.ndarray, out: np.ndarray) -> None:
    """n(q, q̇) = C(q, q̇) q̇ + g(q) [N·m] into ``out`` (RNEA with q̈ = 0); ``ws`` as :func:`rnea`.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q : ndarray, shape (n,)
        Joint positions [rad or m].
    v : ndarray, shape (n,)
        Joint velocities [rad/s or m/s].
    ws : ndarray
        Scratch of length :func:`workspace_size` (n), overwritten.
    out : ndarray, shape (n,)
        Output: n(q, q̇) [N·m, N for prismatic joints], the torque that holds q̈ = 0.
    """
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _views(m, ws)
    _transforms(m, q, xs, ss)
    zero[:] = 0.0
    _rnea_pass(m, v, zero, True, xs, ss, vel, acc, frc, out, tmp, col)


@jitable
def crba(m: np.ndarray, q: np.ndarray, ws: np.ndarray, out: np.ndarray) -> None:
    """The joint-space inertia M(q) [kg·m²] into ``out`` (n, n), both triangles.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q : ndarray, shape (n,)
        Joint positions [rad or m].
    ws : ndarray
        Scratch of length :func:`workspace_size` (n), overwritten.
    out : ndarray, shape (n, n)
        Output: M(q) [kg·m², kg for prismatic joints], symmetric.
    """
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _views(m, ws)
    _transforms(m, q, xs, ss)
    _crba_pass(m, xs, ss, ic, col, tmp, out)


@jitable
def mass_and_bias(m: np.ndarray, q: np.ndarray, v: np.ndarray, ws: np.ndarray,
                  mass: np.ndarray, out: np.ndarray) -> None:
    """M(q) into ``mass`` and n(q, q̇) into ``out`` with one transform pass.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q : ndarray, shape (n,)
        Joint positions [rad or m].
    v : ndarray, shape (n,)
        Joint velocities [rad/s or m/s].
    ws : ndarray
        Scratch of length :func:`workspace_size` (n), overwritten.
    mass : ndarray, shape (n, n)
        Output: M(q) (as :func:`crba`).
    out : ndarray, shape (n,)
        Output: n(q, q̇) (as :func:`bias`).
    """
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _views(m, ws)
    _transforms(m, q, xs, ss)
    zero[:] = 0.0
    _rnea_pass(m, v, zero, True, xs, ss, vel, acc, frc, out, tmp, col)
    _crba_pass(m, xs, ss, ic, col, tmp, mass)


@jitable
def cholesky_solve(a: np.ndarray, b: np.ndarray) -> None:
    """Solve A x = b in place (x into ``b``) for a symmetric positive-definite A.

    ``a`` is overwritten by its Cholesky factor L (lower triangle).

    Parameters
    ----------
    a : ndarray, shape (n, n)
        A, symmetric positive definite (its lower triangle is read); overwritten.
    b : ndarray, shape (n,)
        The right-hand side b; overwritten by the solution x.
    """
    n = b.shape[0]
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        d = math.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s -= a[i, k] * b[k]
        b[i] = s / a[i, i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        s = b[i]
        for k in range(i + 1, n):
            s -= a[k, i] * b[k]
        b[i] = s / a[i, i]


@jitable
def forward_dynamics(m: np.ndarray, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     ws: np.ndarray, out: np.ndarray) -> None:
    """q̈ = M(q)⁻¹ (τ − C(q, q̇) q̇ − g(q)) [rad/s² or m/s²] into ``out``.

    One transform pass, RNEA with q̈ = 0 for the bias, CRBA for M, a Cholesky
    solve (Pinocchio's ``aba`` gives the same to rounding).  ``out`` may be ``tau``.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q : ndarray, shape (n,)
        Joint positions [rad or m].
    v : ndarray, shape (n,)
        Joint velocities [rad/s or m/s].
    tau : ndarray, shape (n,)
        Joint torques [N·m] (forces [N] for prismatic joints), positive along increasing q.
    ws : ndarray
        Scratch of length :func:`workspace_size` (n), overwritten.
    out : ndarray, shape (n,)
        Output: q̈ [rad/s² or m/s²].
    """
    n = int(m[0])
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _views(m, ws)
    _transforms(m, q, xs, ss)
    for i in range(n):
        zero[i] = 0.0
    _rnea_pass(m, v, zero, True, xs, ss, vel, acc, frc, rhs, tmp, col)
    _crba_pass(m, xs, ss, ic, col, tmp, mm)
    for i in range(n):
        out[i] = tau[i] - rhs[i]
    cholesky_solve(mm, out)
