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
spatial inertia about the joint frame in compact form (15): mass [kg], two
zeros, h = m·c (3) [kg·m] and the rotational inertia about the frame origin
(9, row-major) [kg·m²].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from esoarm._jit import jitable

__all__ = ["HEAD", "ROW", "bias", "bias_offset", "cholesky_solve", "crba", "dynamics_terms",
           "forward_dynamics", "forward_dynamics_block", "mass_and_bias", "mass_offset",
           "model_size", "pack_model", "rnea", "scratch_offset", "solve_mass", "workspace_size"]

#: Values before the joints' rows, and per joint.
HEAD, ROW = 4, 32
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
    68
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
    return n * (12 + 15 + 24) + n * n + 3 * n + 21


def _compact_inertia(mass: float, com: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """The spatial inertia about the frame origin in compact form (15 values).

    (m, 0, 0, h = m c, I_c − m [c]×² row-major): the blocks of the 6×6
    [[m 1, −m [c]×], [m [c]×, I_c − m [c]×²]], (linear, angular) order, with I_c
    the rotational inertia about the centre of mass c.
    """
    cx = np.array([[0.0, -com[2], com[1]], [com[2], 0.0, -com[0]], [-com[1], com[0], 0.0]])
    out = np.zeros(15)
    out[0] = mass
    out[3:6] = mass * com
    out[6:] = (inertia - mass * cx @ cx).reshape(9)
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
        row[_INERTIA:_INERTIA + 15] = _compact_inertia(
            float(body.mass), np.asarray(body.lever, dtype=float),
            np.asarray(body.inertia, dtype=float))
    out.setflags(write=False)
    return out


# ---------------------------------------------------------------------------
# compiled helpers: all arrays are float64; ``m`` a packed model, ``ws`` the flat
# scratch (layout: :func:`_layout`), every quantity addressed by its offset in ``ws``.
# No views are cut from ``ws`` (in compiled code each view costs a reshape or a
# reference count, more than the arithmetic of a short chain).


@jitable
def _layout(n: int) -> tuple[int, int, int, int, int, int, int, int, int, int, int]:
    """Offsets in the scratch of n joints.

    Poses (12 per joint: R row-major, then p), compact inertias (15 per joint:
    m, h (3) at 3..5, I_o (9) at 6..14, i.e. row r, column c at 3r + c),
    velocities, accelerations, forces and subspaces (6 per joint), M (n·n,
    row-major), a zero vector and the bias (n each), a 6-column, a 15-value
    scratch, and n values left to the caller (:func:`scratch_offset`).
    """
    xs = 0
    ic = xs + 12 * n
    vel = ic + 15 * n
    acc = vel + 6 * n
    frc = acc + 6 * n
    ss = frc + 6 * n
    mm = ss + 6 * n
    zero = mm + n * n
    rhs = zero + n
    col = rhs + n
    tmp = col + 6
    return xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp


@jitable
def _pose(m: np.ndarray, i: int, qi: float, ws: np.ndarray, xo: int) -> None:
    """Joint i's frame in its parent's at angle qi: R into ws[xo:xo+9], p into ws[xo+9:xo+12].

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
        ws[xo + 3 * row] = a0 * j00 + a1 * j10 + a2 * j20
        ws[xo + 3 * row + 1] = a0 * j01 + a1 * j11 + a2 * j21
        ws[xo + 3 * row + 2] = a0 * j02 + a1 * j12 + a2 * j22
    ws[xo + 9] = px
    ws[xo + 10] = py
    ws[xo + 11] = pz


@jitable
def _subspace(m: np.ndarray, i: int, ws: np.ndarray, so: int) -> None:
    """Motion subspace S_i of joint i into ws[so:so+6]: (0, a) revolute, (a, 0) prismatic."""
    b = HEAD + ROW * i
    for k in range(6):
        ws[so + k] = 0.0
    off = 3 if m[b + _KIND] == REVOLUTE else 0
    for k in range(3):
        ws[so + off + k] = m[b + _AXIS + k]


@jitable
def _transforms(m: np.ndarray, q: np.ndarray, ws: np.ndarray) -> None:
    """The pose (:func:`_pose`) and subspace (6) of every joint at q, into ``ws``."""
    n = int(m[0])
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _layout(n)
    for i in range(n):
        _pose(m, i, q[i], ws, xs + 12 * i)
        _subspace(m, i, ws, ss + 6 * i)


@jitable
def _motion_in(ws: np.ndarray, xo: int, wo: int, oo: int) -> None:
    """ws[oo:oo+6] = X w (w at wo): a motion in the parent's frame seen in the child's (pose at xo).

    ω' = Rᵀ ω, v' = Rᵀ (v − p × ω).
    """
    px, py, pz = ws[xo + 9], ws[xo + 10], ws[xo + 11]
    w3, w4, w5 = ws[wo + 3], ws[wo + 4], ws[wo + 5]
    vx = ws[wo] - (py * w5 - pz * w4)
    vy = ws[wo + 1] - (pz * w3 - px * w5)
    vz = ws[wo + 2] - (px * w4 - py * w3)
    for c in range(3):
        ws[oo + c] = ws[xo + c] * vx + ws[xo + 3 + c] * vy + ws[xo + 6 + c] * vz
        ws[oo + 3 + c] = ws[xo + c] * w3 + ws[xo + 3 + c] * w4 + ws[xo + 6 + c] * w5


@jitable
def _force_out(ws: np.ndarray, xo: int, fo: int, oo: int) -> None:
    """ws[oo:oo+6] += Xᵀ f (f at fo): a force in the child's frame (pose at xo) in the parent's.

    f' = R f, n' = R n + p × (R f).
    """
    f0, f1, f2, f3, f4, f5 = ws[fo], ws[fo + 1], ws[fo + 2], ws[fo + 3], ws[fo + 4], ws[fo + 5]
    x00, x01, x02 = ws[xo], ws[xo + 1], ws[xo + 2]
    x10, x11, x12 = ws[xo + 3], ws[xo + 4], ws[xo + 5]
    x20, x21, x22 = ws[xo + 6], ws[xo + 7], ws[xo + 8]
    lx = x00 * f0 + x01 * f1 + x02 * f2
    ly = x10 * f0 + x11 * f1 + x12 * f2
    lz = x20 * f0 + x21 * f1 + x22 * f2
    px, py, pz = ws[xo + 9], ws[xo + 10], ws[xo + 11]
    ws[oo] += lx
    ws[oo + 1] += ly
    ws[oo + 2] += lz
    ws[oo + 3] += x00 * f3 + x01 * f4 + x02 * f5 + py * lz - pz * ly
    ws[oo + 4] += x10 * f3 + x11 * f4 + x12 * f5 + pz * lx - px * lz
    ws[oo + 5] += x20 * f3 + x21 * f4 + x22 * f5 + px * ly - py * lx


@jitable
def _load_inertia(m: np.ndarray, i: int, ws: np.ndarray, co: int) -> None:
    """Body i's compact inertia (15 values, :func:`_compact_inertia`) copied to ws[co:co+15]."""
    b = HEAD + ROW * i + _INERTIA
    for k in range(15):
        ws[co + k] = m[b + k]


@jitable
def _inertia_times(src: np.ndarray, co: int, ws: np.ndarray, wo: int, oo: int) -> None:
    """ws[oo:oo+6] = I w for the compact inertia at src[co:co+15], w at ws[wo:wo+6]:
    (m v − h × ω, I_o ω + h × v)."""
    mass = src[co]
    hx, hy, hz = src[co + 3], src[co + 4], src[co + 5]
    w0, w1, w2, w3, w4, w5 = ws[wo], ws[wo + 1], ws[wo + 2], ws[wo + 3], ws[wo + 4], ws[wo + 5]
    ws[oo] = mass * w0 - (hy * w5 - hz * w4)
    ws[oo + 1] = mass * w1 - (hz * w3 - hx * w5)
    ws[oo + 2] = mass * w2 - (hx * w4 - hy * w3)
    for r in range(3):
        i = co + 6 + 3 * r
        ws[oo + 3 + r] = src[i] * w3 + src[i + 1] * w4 + src[i + 2] * w5
    ws[oo + 3] += hy * w2 - hz * w1
    ws[oo + 4] += hz * w0 - hx * w2
    ws[oo + 5] += hx * w1 - hy * w0


@jitable
def _inertia_out(ws: np.ndarray, xo: int, co: int, po: int, to: int) -> None:
    """The compact inertia at co (child frame, pose at xo) added, in the parent's frame, at po.

    m' = m, h' = R h + m p, I' = R I Rᵀ − (p h_rᵀ + h_r pᵀ) + (2 h_r·p + m p·p) 1 − m p pᵀ
    with h_r = R h (the parallel-axis theorem moved to the parent's origin); ws[to:to+9]
    is scratch.
    """
    mass = ws[co]
    px, py, pz = ws[xo + 9], ws[xo + 10], ws[xo + 11]
    h0, h1, h2 = ws[co + 3], ws[co + 4], ws[co + 5]
    hr0 = ws[xo] * h0 + ws[xo + 1] * h1 + ws[xo + 2] * h2
    hr1 = ws[xo + 3] * h0 + ws[xo + 4] * h1 + ws[xo + 5] * h2
    hr2 = ws[xo + 6] * h0 + ws[xo + 7] * h1 + ws[xo + 8] * h2
    ws[po] += mass
    ws[po + 3] += hr0 + mass * px
    ws[po + 4] += hr1 + mass * py
    ws[po + 5] += hr2 + mass * pz
    io = co + 6
    for r in range(3):  # tmp = R I
        x0, x1, x2 = ws[xo + 3 * r], ws[xo + 3 * r + 1], ws[xo + 3 * r + 2]
        for c in range(3):
            ws[to + 3 * r + c] = x0 * ws[io + c] + x1 * ws[io + 3 + c] + x2 * ws[io + 6 + c]
    p = (px, py, pz)
    hr = (hr0, hr1, hr2)
    diag = 2.0 * (hr0 * px + hr1 * py + hr2 * pz) + mass * (px * px + py * py + pz * pz)
    for r in range(3):
        for c in range(3):
            val = (ws[to + 3 * r] * ws[xo + 3 * c] + ws[to + 3 * r + 1] * ws[xo + 3 * c + 1]
                   + ws[to + 3 * r + 2] * ws[xo + 3 * c + 2])
            val -= p[r] * hr[c] + hr[r] * p[c] + mass * p[r] * p[c]
            if r == c:
                val += diag
            ws[po + 6 + 3 * r + c] += val


@jitable
def _rnea_pass(m: np.ndarray, v: np.ndarray, a: np.ndarray, gravity: bool, ws: np.ndarray,
               tau: np.ndarray) -> None:
    """RNEA on the poses in ``ws``: τ = M(q) a + C(q, v) v (+ g(q) with ``gravity``)."""
    n = int(m[0])
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _layout(n)
    for i in range(n):
        parent = int(m[HEAD + ROW * i + _PARENT])
        x = xs + 12 * i
        s = ss + 6 * i
        vi, ai = vel + 6 * i, acc + 6 * i
        # v_i = X_i v_λ + S q̇_i ; a_i = X_i a_λ + S q̈_i + v_i ×ₘ (S q̇_i)
        if parent < 0:
            for r in range(6):
                ws[vi + r] = 0.0
                ws[ai + r] = 0.0
            if gravity:  # a_0 = −g (the base accelerates upwards): gravity on every body
                for c in range(3):
                    ws[ai + c] = -(ws[x + c] * m[1] + ws[x + 3 + c] * m[2]
                                   + ws[x + 6 + c] * m[3])
        else:
            _motion_in(ws, x, vel + 6 * parent, vi)
            _motion_in(ws, x, acc + 6 * parent, ai)
        qd, qdd = v[i], a[i]
        for r in range(6):
            ws[vi + r] += ws[s + r] * qd
            ws[ai + r] += ws[s + r] * qdd
        # v_i ×ₘ (S q̇): (ω × wl + vl × ww, ω × ww), w = S q̇
        wl0, wl1, wl2 = ws[s] * qd, ws[s + 1] * qd, ws[s + 2] * qd
        ww0, ww1, ww2 = ws[s + 3] * qd, ws[s + 4] * qd, ws[s + 5] * qd
        vl0, vl1, vl2 = ws[vi], ws[vi + 1], ws[vi + 2]
        om0, om1, om2 = ws[vi + 3], ws[vi + 4], ws[vi + 5]
        ws[ai] += om1 * wl2 - om2 * wl1 + vl1 * ww2 - vl2 * ww1
        ws[ai + 1] += om2 * wl0 - om0 * wl2 + vl2 * ww0 - vl0 * ww2
        ws[ai + 2] += om0 * wl1 - om1 * wl0 + vl0 * ww1 - vl1 * ww0
        ws[ai + 3] += om1 * ww2 - om2 * ww1
        ws[ai + 4] += om2 * ww0 - om0 * ww2
        ws[ai + 5] += om0 * ww1 - om1 * ww0
        # f_i = I a_i + v_i ×* (I v_i);  v ×* h = (ω × hl, ω × ha + vl × hl)
        inertia = HEAD + ROW * i + _INERTIA
        f = frc + 6 * i
        _inertia_times(m, inertia, ws, ai, f)
        _inertia_times(m, inertia, ws, vi, col)
        hl0, hl1, hl2 = ws[col], ws[col + 1], ws[col + 2]
        ha0, ha1, ha2 = ws[col + 3], ws[col + 4], ws[col + 5]
        ws[f] += om1 * hl2 - om2 * hl1
        ws[f + 1] += om2 * hl0 - om0 * hl2
        ws[f + 2] += om0 * hl1 - om1 * hl0
        ws[f + 3] += om1 * ha2 - om2 * ha1 + vl1 * hl2 - vl2 * hl1
        ws[f + 4] += om2 * ha0 - om0 * ha2 + vl2 * hl0 - vl0 * hl2
        ws[f + 5] += om0 * ha1 - om1 * ha0 + vl0 * hl1 - vl1 * hl0
    for i in range(n - 1, -1, -1):
        f = frc + 6 * i
        s = ss + 6 * i
        t = 0.0
        for r in range(6):
            t += ws[s + r] * ws[f + r]
        tau[i] = t
        parent = int(m[HEAD + ROW * i + _PARENT])
        if parent >= 0:  # f_λ += X_iᵀ f_i
            _force_out(ws, xs + 12 * i, f, frc + 6 * parent)


@jitable
def _crba_pass(m: np.ndarray, ws: np.ndarray) -> None:
    """CRBA on the poses in ``ws``: the full symmetric M(q) into ws's M (row-major)."""
    n = int(m[0])
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _layout(n)
    for i in range(n):
        _load_inertia(m, i, ws, ic + 15 * i)
        for j in range(n):  # joints off each other's path to the base stay 0 (a tree)
            ws[mm + n * i + j] = 0.0
    for i in range(n - 1, -1, -1):
        parent = int(m[HEAD + ROW * i + _PARENT])
        if parent >= 0:  # I^c_λ += X_iᵀ I^c_i X_i
            _inertia_out(ws, xs + 12 * i, ic + 15 * i, ic + 15 * parent, tmp)
    for i in range(n):
        s = ss + 6 * i
        _inertia_times(ws, ic + 15 * i, ws, s, col)  # F = I^c_i S_i
        d = 0.0
        for r in range(6):
            d += ws[s + r] * ws[col + r]
        ws[mm + n * i + i] = d
        j = i
        parent = int(m[HEAD + ROW * j + _PARENT])
        while parent >= 0:
            for r in range(6):
                ws[tmp + 9 + r] = 0.0
            _force_out(ws, xs + 12 * j, col, tmp + 9)  # F = X_jᵀ F
            for r in range(6):
                ws[col + r] = ws[tmp + 9 + r]
            j = parent
            sj = ss + 6 * j
            e = 0.0
            for r in range(6):
                e += ws[sj + r] * ws[col + r]
            ws[mm + n * i + j] = e
            ws[mm + n * j + i] = e
            parent = int(m[HEAD + ROW * j + _PARENT])


@jitable
def _copy_mass(ws: np.ndarray, n: int, out: np.ndarray) -> None:
    """ws's M into the (n, n) array ``out``."""
    mm = _layout(n)[6]
    for i in range(n):
        for j in range(n):
            out[i, j] = ws[mm + n * i + j]


@jitable
def _bias_pass(m: np.ndarray, v: np.ndarray, ws: np.ndarray, out: np.ndarray) -> None:
    """n(q, q̇) into ``out`` by RNEA with q̈ = 0, on the poses in ``ws``."""
    n = int(m[0])
    zero = _layout(n)[7]
    for i in range(n):
        ws[zero + i] = 0.0
    _rnea_pass(m, v, ws[zero:zero + n], True, ws, out)


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
    _transforms(m, q, ws)
    _rnea_pass(m, v, a, True, ws, tau)


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
    _transforms(m, q, ws)
    _bias_pass(m, v, ws, out)


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
    _transforms(m, q, ws)
    _crba_pass(m, ws)
    _copy_mass(ws, int(m[0]), out)


@jitable
def dynamics_terms(m: np.ndarray, q: np.ndarray, v: np.ndarray, ws: np.ndarray) -> None:
    """M(q) and n(q, q̇) left in the scratch ``ws`` (one transform pass, no copy).

    M is read back as ``ws[mass_offset(n) + n·i + j]`` [kg·m²] and n(q, q̇) as
    ``ws[bias_offset(n) + i]`` [N·m]; :func:`solve_mass` solves with that M.

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
    """
    n = int(m[0])
    rhs = _layout(n)[8]
    _transforms(m, q, ws)
    _bias_pass(m, v, ws, ws[rhs:rhs + n])
    _crba_pass(m, ws)


@jitable
def mass_offset(n: int) -> int:
    """Where :func:`dynamics_terms` leaves M (n·n values, row-major) in the scratch.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Offset in the scratch.
    """
    return _layout(n)[6]


@jitable
def bias_offset(n: int) -> int:
    """Where :func:`dynamics_terms` leaves n(q, q̇) (n values) in the scratch.

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Offset in the scratch.
    """
    return _layout(n)[8]


@jitable
def scratch_offset(n: int) -> int:
    """Start of the n values of the scratch no function of this module touches (the caller's).

    Parameters
    ----------
    n : int
        Number of joints.

    Returns
    -------
    int
        Offset in the scratch.
    """
    return _layout(n)[10] + 15


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
    _transforms(m, q, ws)
    _bias_pass(m, v, ws, out)
    _crba_pass(m, ws)
    _copy_mass(ws, int(m[0]), mass)


@jitable
def _cholesky_flat(a: np.ndarray, ao: int, n: int, b: np.ndarray) -> None:
    """:func:`cholesky_solve` on the n×n matrix stored row-major at a[ao:ao+n·n]."""
    for j in range(n):
        d = a[ao + n * j + j]
        for k in range(j):
            d -= a[ao + n * j + k] * a[ao + n * j + k]
        d = math.sqrt(d)
        a[ao + n * j + j] = d
        for i in range(j + 1, n):
            s = a[ao + n * i + j]
            for k in range(j):
                s -= a[ao + n * i + k] * a[ao + n * j + k]
            a[ao + n * i + j] = s / d
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s -= a[ao + n * i + k] * b[k]
        b[i] = s / a[ao + n * i + i]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        s = b[i]
        for k in range(i + 1, n):
            s -= a[ao + n * k + i] * b[k]
        b[i] = s / a[ao + n * i + i]


@jitable
def cholesky_solve(a: np.ndarray, b: np.ndarray) -> None:
    """Solve A x = b in place (x into ``b``) for a symmetric positive-definite A.

    ``a`` is overwritten by its Cholesky factor L (lower triangle).

    Parameters
    ----------
    a : ndarray, shape (n, n)
        A, symmetric positive definite (its lower triangle is read), C-contiguous;
        overwritten.
    b : ndarray, shape (n,)
        The right-hand side b; overwritten by the solution x.
    """
    _cholesky_flat(a.reshape(-1), 0, b.shape[0], b)


@jitable
def solve_mass(ws: np.ndarray, n: int, b: np.ndarray) -> None:
    """Solve M x = b in place (x into ``b``) with the M :func:`dynamics_terms` left in ``ws``.

    The M in ``ws`` is overwritten by its Cholesky factor.

    Parameters
    ----------
    ws : ndarray
        The scratch after :func:`dynamics_terms`.
    n : int
        Number of joints.
    b : ndarray, shape (n,)
        The right-hand side [N·m]; overwritten by the solution [rad/s²].
    """
    _cholesky_flat(ws, _layout(n)[6], n, b)


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
    dynamics_terms(m, q, v, ws)
    rhs = _layout(n)[8]
    for i in range(n):
        out[i] = tau[i] - ws[rhs + i]
    solve_mass(ws, n, out)


# ---------------------------------------------------------------------------
# a block of runs: the functions above for m runs at once, runs innermost.
#
# ``wb`` is the scratch of the block, shape (workspace_size(n), m): row k holds value k
# of the one-run scratch for every run, so every offset of :func:`_layout` is a row.
# Each run takes exactly the floating-point operations, in the same order, that the
# one-run functions take (the same bits: the tests hold them equal); with the runs
# innermost the compiler vectorises the arithmetic across runs.  Values that depend on
# the model only (the subspaces, the bodies' inertias, the fixed placements) are read
# once per call as scalars.


@jitable
def _subspace_values(m: np.ndarray, i: int) -> tuple[float, float, float, float, float, float]:
    """Joint i's motion subspace S_i as six scalars (the values :func:`_subspace` stores)."""
    b = HEAD + ROW * i
    a0, a1, a2 = m[b + _AXIS], m[b + _AXIS + 1], m[b + _AXIS + 2]
    if m[b + _KIND] == REVOLUTE:
        return 0.0, 0.0, 0.0, a0, a1, a2
    return a0, a1, a2, 0.0, 0.0, 0.0


@jitable
def _pose_block(m: np.ndarray, i: int, q: np.ndarray, wb: np.ndarray, xo: int) -> None:
    """:func:`_pose` of joint i for every run (q: (n, runs)) into rows xo … xo+11 of ``wb``."""
    runs = q.shape[1]
    b = HEAD + ROW * i
    ax, ay, az = m[b + _AXIS], m[b + _AXIS + 1], m[b + _AXIS + 2]
    r0 = b + _ROT
    a00, a01, a02 = m[r0], m[r0 + 1], m[r0 + 2]
    a10, a11, a12 = m[r0 + 3], m[r0 + 4], m[r0 + 5]
    a20, a21, a22 = m[r0 + 6], m[r0 + 7], m[r0 + 8]
    px0, py0, pz0 = m[b + _POS], m[b + _POS + 1], m[b + _POS + 2]
    if m[b + _KIND] == REVOLUTE:
        for r in range(runs):  # the sines and cosines first (library calls, one run at a time)
            qi = q[i, r]
            wb[xo + 9, r] = math.cos(qi)
            wb[xo + 10, r] = math.sin(qi)
        for r in range(runs):
            c, s = wb[xo + 9, r], wb[xo + 10, r]
            k = 1.0 - c
            j00, j01, j02 = c + k * ax * ax, k * ax * ay - s * az, k * ax * az + s * ay
            j10, j11, j12 = k * ax * ay + s * az, c + k * ay * ay, k * ay * az - s * ax
            j20, j21, j22 = k * ax * az - s * ay, k * ay * az + s * ax, c + k * az * az
            wb[xo, r] = a00 * j00 + a01 * j10 + a02 * j20
            wb[xo + 1, r] = a00 * j01 + a01 * j11 + a02 * j21
            wb[xo + 2, r] = a00 * j02 + a01 * j12 + a02 * j22
            wb[xo + 3, r] = a10 * j00 + a11 * j10 + a12 * j20
            wb[xo + 4, r] = a10 * j01 + a11 * j11 + a12 * j21
            wb[xo + 5, r] = a10 * j02 + a11 * j12 + a12 * j22
            wb[xo + 6, r] = a20 * j00 + a21 * j10 + a22 * j20
            wb[xo + 7, r] = a20 * j01 + a21 * j11 + a22 * j21
            wb[xo + 8, r] = a20 * j02 + a21 * j12 + a22 * j22
            wb[xo + 9, r] = px0
            wb[xo + 10, r] = py0
            wb[xo + 11, r] = pz0
    else:
        # R = R0 · 1 (the same products as the one-run pose, on constants)
        rot = (a00 * 1.0 + a01 * 0.0 + a02 * 0.0, a00 * 0.0 + a01 * 1.0 + a02 * 0.0,
               a00 * 0.0 + a01 * 0.0 + a02 * 1.0, a10 * 1.0 + a11 * 0.0 + a12 * 0.0,
               a10 * 0.0 + a11 * 1.0 + a12 * 0.0, a10 * 0.0 + a11 * 0.0 + a12 * 1.0,
               a20 * 1.0 + a21 * 0.0 + a22 * 0.0, a20 * 0.0 + a21 * 1.0 + a22 * 0.0,
               a20 * 0.0 + a21 * 0.0 + a22 * 1.0)
        dx = a00 * ax + a01 * ay + a02 * az
        dy = a10 * ax + a11 * ay + a12 * az
        dz = a20 * ax + a21 * ay + a22 * az
        for r in range(runs):
            qi = q[i, r]
            for k in range(9):
                wb[xo + k, r] = rot[k]
            wb[xo + 9, r] = px0 + qi * dx
            wb[xo + 10, r] = py0 + qi * dy
            wb[xo + 11, r] = pz0 + qi * dz


@jitable
def _inertia_out_block(wb: np.ndarray, xo: int, co: int, po: int) -> None:
    """:func:`_inertia_out` for every run (rows of ``wb``; its 9 scratch values kept local)."""
    io = co + 6
    for r in range(wb.shape[1]):
        mass = wb[co, r]
        px, py, pz = wb[xo + 9, r], wb[xo + 10, r], wb[xo + 11, r]
        h0, h1, h2 = wb[co + 3, r], wb[co + 4, r], wb[co + 5, r]
        x00, x01, x02 = wb[xo, r], wb[xo + 1, r], wb[xo + 2, r]
        x10, x11, x12 = wb[xo + 3, r], wb[xo + 4, r], wb[xo + 5, r]
        x20, x21, x22 = wb[xo + 6, r], wb[xo + 7, r], wb[xo + 8, r]
        hr0 = x00 * h0 + x01 * h1 + x02 * h2
        hr1 = x10 * h0 + x11 * h1 + x12 * h2
        hr2 = x20 * h0 + x21 * h1 + x22 * h2
        wb[po, r] += mass
        wb[po + 3, r] += hr0 + mass * px
        wb[po + 4, r] += hr1 + mass * py
        wb[po + 5, r] += hr2 + mass * pz
        i00, i01, i02 = wb[io, r], wb[io + 1, r], wb[io + 2, r]
        i10, i11, i12 = wb[io + 3, r], wb[io + 4, r], wb[io + 5, r]
        i20, i21, i22 = wb[io + 6, r], wb[io + 7, r], wb[io + 8, r]
        t00 = x00 * i00 + x01 * i10 + x02 * i20  # tmp = R I
        t01 = x00 * i01 + x01 * i11 + x02 * i21
        t02 = x00 * i02 + x01 * i12 + x02 * i22
        t10 = x10 * i00 + x11 * i10 + x12 * i20
        t11 = x10 * i01 + x11 * i11 + x12 * i21
        t12 = x10 * i02 + x11 * i12 + x12 * i22
        t20 = x20 * i00 + x21 * i10 + x22 * i20
        t21 = x20 * i01 + x21 * i11 + x22 * i21
        t22 = x20 * i02 + x21 * i12 + x22 * i22
        diag = 2.0 * (hr0 * px + hr1 * py + hr2 * pz) + mass * (px * px + py * py + pz * pz)
        tr = ((t00, t01, t02), (t10, t11, t12), (t20, t21, t22))
        xr = ((x00, x01, x02), (x10, x11, x12), (x20, x21, x22))
        p = (px, py, pz)
        hr = (hr0, hr1, hr2)
        for a in range(3):
            for c in range(3):
                val = tr[a][0] * xr[c][0] + tr[a][1] * xr[c][1] + tr[a][2] * xr[c][2]
                val -= p[a] * hr[c] + hr[a] * p[c] + mass * p[a] * p[c]
                if a == c:
                    val += diag
                wb[po + 6 + 3 * a + c, r] += val


@jitable
def _bias_block(m: np.ndarray, v: np.ndarray, wb: np.ndarray) -> None:
    """:func:`_bias_pass` (RNEA, q̈ = 0, gravity) for every run: n(q, q̇) into the rhs rows.

    One loop over the runs per joint and pass (each loop's set-up costs about as much as
    a few runs' arithmetic in a block of ten runs).
    """
    n = int(m[0])
    runs = wb.shape[1]
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _layout(n)
    g0, g1, g2 = m[1], m[2], m[3]
    for i in range(n):
        parent = int(m[HEAD + ROW * i + _PARENT])
        root = parent < 0
        x = xs + 12 * i
        vi, ai = vel + 6 * i, acc + 6 * i
        vp, ap = vel + 6 * max(parent, 0), acc + 6 * max(parent, 0)
        s0, s1, s2, s3, s4, s5 = _subspace_values(m, i)
        b = HEAD + ROW * i + _INERTIA
        mass, hx, hy, hz = m[b], m[b + 3], m[b + 4], m[b + 5]
        i00, i01, i02 = m[b + 6], m[b + 7], m[b + 8]
        i10, i11, i12 = m[b + 9], m[b + 10], m[b + 11]
        i20, i21, i22 = m[b + 12], m[b + 13], m[b + 14]
        f = frc + 6 * i
        qdd = 0.0
        for r in range(runs):
            x00, x01, x02 = wb[x, r], wb[x + 1, r], wb[x + 2, r]
            x10, x11, x12 = wb[x + 3, r], wb[x + 4, r], wb[x + 5, r]
            x20, x21, x22 = wb[x + 6, r], wb[x + 7, r], wb[x + 8, r]
            if root:  # v = 0, a = −g in the joint's frame (:func:`_rnea_pass`)
                v0, v1, v2, v3, v4, v5 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
                a0 = -(x00 * g0 + x10 * g1 + x20 * g2)
                a1 = -(x01 * g0 + x11 * g1 + x21 * g2)
                a2 = -(x02 * g0 + x12 * g1 + x22 * g2)
                a3, a4, a5 = 0.0, 0.0, 0.0
            else:  # X v_λ, X a_λ (:func:`_motion_in`)
                px, py, pz = wb[x + 9, r], wb[x + 10, r], wb[x + 11, r]
                w3, w4, w5 = wb[vp + 3, r], wb[vp + 4, r], wb[vp + 5, r]
                vx = wb[vp, r] - (py * w5 - pz * w4)
                vy = wb[vp + 1, r] - (pz * w3 - px * w5)
                vz = wb[vp + 2, r] - (px * w4 - py * w3)
                v0 = x00 * vx + x10 * vy + x20 * vz
                v1 = x01 * vx + x11 * vy + x21 * vz
                v2 = x02 * vx + x12 * vy + x22 * vz
                v3 = x00 * w3 + x10 * w4 + x20 * w5
                v4 = x01 * w3 + x11 * w4 + x21 * w5
                v5 = x02 * w3 + x12 * w4 + x22 * w5
                w3, w4, w5 = wb[ap + 3, r], wb[ap + 4, r], wb[ap + 5, r]
                vx = wb[ap, r] - (py * w5 - pz * w4)
                vy = wb[ap + 1, r] - (pz * w3 - px * w5)
                vz = wb[ap + 2, r] - (px * w4 - py * w3)
                a0 = x00 * vx + x10 * vy + x20 * vz
                a1 = x01 * vx + x11 * vy + x21 * vz
                a2 = x02 * vx + x12 * vy + x22 * vz
                a3 = x00 * w3 + x10 * w4 + x20 * w5
                a4 = x01 * w3 + x11 * w4 + x21 * w5
                a5 = x02 * w3 + x12 * w4 + x22 * w5
            qd = v[i, r]
            vl0, vl1, vl2 = v0 + s0 * qd, v1 + s1 * qd, v2 + s2 * qd
            om0, om1, om2 = v3 + s3 * qd, v4 + s4 * qd, v5 + s5 * qd
            a0, a1, a2 = a0 + s0 * qdd, a1 + s1 * qdd, a2 + s2 * qdd
            a3, a4, a5 = a3 + s3 * qdd, a4 + s4 * qdd, a5 + s5 * qdd
            wl0, wl1, wl2 = s0 * qd, s1 * qd, s2 * qd
            ww0, ww1, ww2 = s3 * qd, s4 * qd, s5 * qd
            a0 = a0 + (om1 * wl2 - om2 * wl1 + vl1 * ww2 - vl2 * ww1)
            a1 = a1 + (om2 * wl0 - om0 * wl2 + vl2 * ww0 - vl0 * ww2)
            a2 = a2 + (om0 * wl1 - om1 * wl0 + vl0 * ww1 - vl1 * ww0)
            a3 = a3 + (om1 * ww2 - om2 * ww1)
            a4 = a4 + (om2 * ww0 - om0 * ww2)
            a5 = a5 + (om0 * ww1 - om1 * ww0)
            wb[vi, r], wb[vi + 1, r], wb[vi + 2, r] = vl0, vl1, vl2
            wb[vi + 3, r], wb[vi + 4, r], wb[vi + 5, r] = om0, om1, om2
            wb[ai, r], wb[ai + 1, r], wb[ai + 2, r] = a0, a1, a2
            wb[ai + 3, r], wb[ai + 4, r], wb[ai + 5, r] = a3, a4, a5
            # f = I a (:func:`_inertia_times` on the body's inertia)
            fa0 = mass * a0 - (hy * a5 - hz * a4)
            fa1 = mass * a1 - (hz * a3 - hx * a5)
            fa2 = mass * a2 - (hx * a4 - hy * a3)
            fa3 = i00 * a3 + i01 * a4 + i02 * a5
            fa4 = i10 * a3 + i11 * a4 + i12 * a5
            fa5 = i20 * a3 + i21 * a4 + i22 * a5
            fa3 += hy * a2 - hz * a1
            fa4 += hz * a0 - hx * a2
            fa5 += hx * a1 - hy * a0
            # I v
            hl0 = mass * vl0 - (hy * om2 - hz * om1)
            hl1 = mass * vl1 - (hz * om0 - hx * om2)
            hl2 = mass * vl2 - (hx * om1 - hy * om0)
            ha0 = i00 * om0 + i01 * om1 + i02 * om2
            ha1 = i10 * om0 + i11 * om1 + i12 * om2
            ha2 = i20 * om0 + i21 * om1 + i22 * om2
            ha0 += hy * vl2 - hz * vl1
            ha1 += hz * vl0 - hx * vl2
            ha2 += hx * vl1 - hy * vl0
            wb[f, r] = fa0 + (om1 * hl2 - om2 * hl1)
            wb[f + 1, r] = fa1 + (om2 * hl0 - om0 * hl2)
            wb[f + 2, r] = fa2 + (om0 * hl1 - om1 * hl0)
            wb[f + 3, r] = fa3 + (om1 * ha2 - om2 * ha1 + vl1 * hl2 - vl2 * hl1)
            wb[f + 4, r] = fa4 + (om2 * ha0 - om0 * ha2 + vl2 * hl0 - vl0 * hl2)
            wb[f + 5, r] = fa5 + (om0 * ha1 - om1 * ha0 + vl0 * hl1 - vl1 * hl0)
    for i in range(n - 1, -1, -1):
        f = frc + 6 * i
        s0, s1, s2, s3, s4, s5 = _subspace_values(m, i)
        parent = int(m[HEAD + ROW * i + _PARENT])
        xo = xs + 12 * i
        oo = frc + 6 * max(parent, 0)
        for r in range(runs):
            f0, f1, f2 = wb[f, r], wb[f + 1, r], wb[f + 2, r]
            f3, f4, f5 = wb[f + 3, r], wb[f + 4, r], wb[f + 5, r]
            t = 0.0
            t += s0 * f0
            t += s1 * f1
            t += s2 * f2
            t += s3 * f3
            t += s4 * f4
            t += s5 * f5
            wb[rhs + i, r] = t
            if parent >= 0:  # f_λ += X_iᵀ f_i (:func:`_force_out`)
                x00, x01, x02 = wb[xo, r], wb[xo + 1, r], wb[xo + 2, r]
                x10, x11, x12 = wb[xo + 3, r], wb[xo + 4, r], wb[xo + 5, r]
                x20, x21, x22 = wb[xo + 6, r], wb[xo + 7, r], wb[xo + 8, r]
                lx = x00 * f0 + x01 * f1 + x02 * f2
                ly = x10 * f0 + x11 * f1 + x12 * f2
                lz = x20 * f0 + x21 * f1 + x22 * f2
                px, py, pz = wb[xo + 9, r], wb[xo + 10, r], wb[xo + 11, r]
                wb[oo, r] += lx
                wb[oo + 1, r] += ly
                wb[oo + 2, r] += lz
                wb[oo + 3, r] += x00 * f3 + x01 * f4 + x02 * f5 + py * lz - pz * ly
                wb[oo + 4, r] += x10 * f3 + x11 * f4 + x12 * f5 + pz * lx - px * lz
                wb[oo + 5, r] += x20 * f3 + x21 * f4 + x22 * f5 + px * ly - py * lx


@jitable
def _crba_block(m: np.ndarray, wb: np.ndarray) -> None:
    """:func:`_crba_pass` for every run: M(q) into the M rows of ``wb``."""
    n = int(m[0])
    runs = wb.shape[1]
    xs, ic, vel, acc, frc, ss, mm, zero, rhs, col, tmp = _layout(n)
    for i in range(n):  # one loop per joint (each loop over the runs costs its set-up)
        b = HEAD + ROW * i + _INERTIA
        co = ic + 15 * i
        for r in range(runs):
            for k in range(15):
                wb[co + k, r] = m[b + k]
            for j in range(n):
                wb[mm + n * i + j, r] = 0.0
    for i in range(n - 1, -1, -1):
        parent = int(m[HEAD + ROW * i + _PARENT])
        if parent >= 0:  # I^c_λ += X_iᵀ I^c_i X_i
            _inertia_out_block(wb, xs + 12 * i, ic + 15 * i, ic + 15 * parent)
    for i in range(n):
        s0, s1, s2, s3, s4, s5 = _subspace_values(m, i)
        co = ic + 15 * i
        for r in range(runs):  # F = I^c_i S_i (:func:`_inertia_times`), d = S_iᵀ F
            mass = wb[co, r]
            hx, hy, hz = wb[co + 3, r], wb[co + 4, r], wb[co + 5, r]
            c0 = mass * s0 - (hy * s5 - hz * s4)
            c1 = mass * s1 - (hz * s3 - hx * s5)
            c2 = mass * s2 - (hx * s4 - hy * s3)
            c3 = wb[co + 6, r] * s3 + wb[co + 7, r] * s4 + wb[co + 8, r] * s5
            c4 = wb[co + 9, r] * s3 + wb[co + 10, r] * s4 + wb[co + 11, r] * s5
            c5 = wb[co + 12, r] * s3 + wb[co + 13, r] * s4 + wb[co + 14, r] * s5
            c3 += hy * s2 - hz * s1
            c4 += hz * s0 - hx * s2
            c5 += hx * s1 - hy * s0
            wb[col, r], wb[col + 1, r], wb[col + 2, r] = c0, c1, c2
            wb[col + 3, r], wb[col + 4, r], wb[col + 5, r] = c3, c4, c5
            d = 0.0
            d += s0 * c0
            d += s1 * c1
            d += s2 * c2
            d += s3 * c3
            d += s4 * c4
            d += s5 * c5
            wb[mm + n * i + i, r] = d
        j = i
        parent = int(m[HEAD + ROW * j + _PARENT])
        while parent >= 0:
            xo = xs + 12 * j
            j = parent
            t0, t1, t2, t3, t4, t5 = _subspace_values(m, j)
            for r in range(runs):  # F = X_jᵀ F (:func:`_force_out` onto zeros), then S_jᵀ F
                f0, f1, f2 = wb[col, r], wb[col + 1, r], wb[col + 2, r]
                f3, f4, f5 = wb[col + 3, r], wb[col + 4, r], wb[col + 5, r]
                x00, x01, x02 = wb[xo, r], wb[xo + 1, r], wb[xo + 2, r]
                x10, x11, x12 = wb[xo + 3, r], wb[xo + 4, r], wb[xo + 5, r]
                x20, x21, x22 = wb[xo + 6, r], wb[xo + 7, r], wb[xo + 8, r]
                lx = x00 * f0 + x01 * f1 + x02 * f2
                ly = x10 * f0 + x11 * f1 + x12 * f2
                lz = x20 * f0 + x21 * f1 + x22 * f2
                px, py, pz = wb[xo + 9, r], wb[xo + 10, r], wb[xo + 11, r]
                c0 = 0.0 + lx
                c1 = 0.0 + ly
                c2 = 0.0 + lz
                c3 = 0.0 + (x00 * f3 + x01 * f4 + x02 * f5 + py * lz - pz * ly)
                c4 = 0.0 + (x10 * f3 + x11 * f4 + x12 * f5 + pz * lx - px * lz)
                c5 = 0.0 + (x20 * f3 + x21 * f4 + x22 * f5 + px * ly - py * lx)
                wb[col, r], wb[col + 1, r], wb[col + 2, r] = c0, c1, c2
                wb[col + 3, r], wb[col + 4, r], wb[col + 5, r] = c3, c4, c5
                e = 0.0
                e += t0 * c0
                e += t1 * c1
                e += t2 * c2
                e += t3 * c3
                e += t4 * c4
                e += t5 * c5
                wb[mm + n * i + j, r] = e
                wb[mm + n * j + i, r] = e
            parent = int(m[HEAD + ROW * j + _PARENT])


@jitable
def _solve_block(wb: np.ndarray, n: int, tau: np.ndarray, out: np.ndarray) -> None:
    """out = τ − n, then :func:`_cholesky_flat` on M, for every run (runs innermost)."""
    runs = wb.shape[1]
    ao, rhs = _layout(n)[6], _layout(n)[8]
    for i in range(n):
        for r in range(runs):
            out[i, r] = tau[i, r] - wb[rhs + i, r]
    for j in range(n):
        jj = ao + n * j + j
        for r in range(runs):
            d = wb[jj, r]
            for k in range(j):
                d -= wb[ao + n * j + k, r] * wb[ao + n * j + k, r]
            wb[jj, r] = math.sqrt(d)
        for i in range(j + 1, n):
            ij = ao + n * i + j
            for r in range(runs):
                s = wb[ij, r]
                for k in range(j):
                    s -= wb[ao + n * i + k, r] * wb[ao + n * j + k, r]
                wb[ij, r] = s / wb[jj, r]
    for i in range(n):  # L y = b
        for r in range(runs):
            s = out[i, r]
            for k in range(i):
                s -= wb[ao + n * i + k, r] * out[k, r]
            out[i, r] = s / wb[ao + n * i + i, r]
    for i in range(n - 1, -1, -1):  # Lᵀ x = y
        for r in range(runs):
            s = out[i, r]
            for k in range(i + 1, n):
                s -= wb[ao + n * k + i, r] * out[k, r]
            out[i, r] = s / wb[ao + n * i + i, r]


@jitable
def forward_dynamics_block(m: np.ndarray, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                           wb: np.ndarray, out: np.ndarray) -> None:
    """:func:`forward_dynamics` for a block of runs (column r is run r): the same bits.

    Parameters
    ----------
    m : ndarray
        Packed model (:func:`pack_model`).
    q, v : ndarray, shape (n, runs)
        Joint positions [rad or m] and velocities [rad/s or m/s] of each run.
    tau : ndarray, shape (n, runs)
        Joint torques [N·m] (forces [N] for prismatic joints).
    wb : ndarray, shape (workspace_size(n), runs)
        Scratch, overwritten.
    out : ndarray, shape (n, runs)
        Output: q̈ [rad/s² or m/s²] of each run (may not be ``tau``).
    """
    n = int(m[0])
    xs = _layout(n)[0]
    for i in range(n):
        _pose_block(m, i, q, wb, xs + 12 * i)
    _bias_block(m, v, wb)
    _crba_block(m, wb)
    _solve_block(wb, n, tau, out)
