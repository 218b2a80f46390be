"""The digital twin of a URDF arm: the lever arm's rig, joint by joint.

Per joint i, with the true rigid-body model of :class:`~esoarm.plants.arms.model.ArmModel`
(payload included, kinetic energy scaled by s = ``inertia_scale``):

    s (M(q) q̈ + C(q, q̇) q̇) + g(q) = τ − F(q̇),    then  q̈ ← q̈ + d(t)
    F_i(q̇_i) = Fc_i tanh(q̇_i / vs_i) + b_i q̇_i          Coulomb + viscous friction
    d_i(t) = amplitude_i · sin(frequency_i · t)  [rad/s²]  the paper's eq. 6, per joint
    τ̇ = (u_applied − τ) / T      (actuator lag T > 0; τ = u_applied when T = 0)

integrated with classical RK4 at a fixed step h, d evaluated at each stage
time -- the lever arm's rig (:mod:`esoarm.plants.lever_arm`) with I0 θ̈ + G(θ) replaced by the
arm's rigid-body dynamics.  On the one-joint lever URDF it is the lever arm's
rig exactly: (τ − F)/s − G/s over I0 is (τ − G − F)/I with I = s·I0.

The disturbance enters as an acceleration, as in the paper (eq. 5); it is the
torque M(q)·d.  Each RK4 stage costs one Pinocchio ABA call (Featherstone's
articulated-body algorithm, O(n)) -- M and n are never formed for the twin --
and one call of a compiled helper (:func:`rk4_stage`) that does the rest of
the stage's arithmetic (friction, disturbance, lag, the RK4 combination):
Pinocchio cannot be called from numba, and NumPy's per-call overhead on
vectors of a few joints costs more than the ABA itself.

Parameters are packed in one float vector (:func:`pack_params`): friction
Fc, vs, b, disturbance amplitude and frequency per joint, then 1/s and T.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from esoarm._jit import jitable
from esoarm.plants.arms.model import ArmModel, import_pinocchio

__all__ = ["ArmTwin", "TwinParams", "pack_params", "twin_acceleration", "twin_advance"]


# packed-parameter layout: five blocks of n, then 1/s and the lag T
_FC, _VS, _B, _DA, _DW = range(5)


def pack_params(params: TwinParams, inertia_scale: float) -> np.ndarray:
    """One float vector of the twin's per-joint parameters, 1/s and the lag T.

    Parameters
    ----------
    params : TwinParams
        Friction, disturbance and lag per joint.
    inertia_scale : float
        s > 0, the factor on the true kinetic energy.

    Returns
    -------
    ndarray, shape (5n + 2,)
        (Fc [N·m] × n, vs [rad/s] × n, b [N·m·s/rad] × n, amplitude [rad/s²] × n,
        frequency [rad/s] × n, 1/s [1], T [s]).
    """
    blocks = [np.asarray(getattr(params, name), dtype=float) for name in (
        "coulomb_friction", "friction_velocity", "viscous_friction",
        "disturbance_amplitude", "disturbance_frequency")]
    return np.concatenate([*blocks, [1.0 / inertia_scale, float(params.lag)]])


@jitable
def joint_drive(v: np.ndarray, tau: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """ABA input (τ − F(q̇))/s into ``out``: torque less friction, over the scale s.

    Parameters
    ----------
    v : ndarray, shape (n,)
        Joint rates q̇ [rad/s]; friction opposes them.
    tau : ndarray, shape (n,)
        Torque acting on each joint [N·m], positive along increasing q.
    p : ndarray
        :func:`pack_params` of an arm of n joints (5n + 2 values).
    out : ndarray, shape (n,)
        Output: (τ − F(q̇))/s [N·m].
    """
    n = v.shape[0]
    inv_s = p[5 * n]
    for i in range(n):
        friction = p[_FC * n + i] * math.tanh(v[i] / p[_VS * n + i]) + p[_B * n + i] * v[i]
        out[i] = (tau[i] - friction) * inv_s


@jitable
def add_disturbance(acc: np.ndarray, t: float, p: np.ndarray) -> np.ndarray:
    """q̈ = ABA output + d(t), d_i = amplitude_i sin(frequency_i t) [rad/s²] (eq. 6).

    Parameters
    ----------
    acc : ndarray, shape (n,)
        Rigid-body acceleration from the ABA [rad/s²].
    t : float
        Time [s].
    p : ndarray
        :func:`pack_params` of an arm of n joints (5n + 2 values).

    Returns
    -------
    ndarray, shape (n,)
        q̈ [rad/s²] (a new array).
    """
    n = acc.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = acc[i] + p[_DA * n + i] * math.sin(p[_DW * n + i] * t)
    return out


@jitable
def rk4_begin(q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray, p: np.ndarray,
              w: np.ndarray) -> None:
    """Load the state (q, q̇, τ) as RK4 stage 0 into the workspace ``w`` (8, n).

    Parameters
    ----------
    q : ndarray, shape (n,)
        Joint angles at the start of the step [rad].
    v : ndarray, shape (n,)
        Joint rates at the start of the step [rad/s].
    tau : ndarray, shape (n,)
        Actuator lag state at the start of the step [N·m].
    u : ndarray, shape (n,)
        Applied input [N·m], held over the step.
    p : ndarray
        :func:`pack_params` of an arm of n joints (5n + 2 values).
    w : ndarray, shape (8, n)
        Workspace (:meth:`ArmModel.workspace`), written in place.
    """
    lag = p[p.shape[0] - 1]
    w[0, :] = q
    w[1, :] = v
    w[2, :] = tau
    w[4:7, :] = 0.0
    joint_drive(v, tau if lag > 0.0 else u, p, w[3])


@jitable
def rk4_stage(stage: int, q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray,
              t: float, h: float, acc: np.ndarray, p: np.ndarray, w: np.ndarray) -> None:
    """Finish RK4 stage ``stage`` (0-3) from the ABA output ``acc`` at stage time t.

    Workspace rows of ``w``: 0-2 the stage state (q, q̇, τ), 3 the ABA input
    for it, 4-6 the weighted sums of the stage derivatives.  After stage 3
    rows 0-2 hold the state at t + h (and row 3 its ABA input: the next
    step's stage 0).

    Parameters
    ----------
    stage : int
        The RK4 stage, 0 to 3.
    q : ndarray, shape (n,)
        Joint angles at the start of the step [rad].
    v : ndarray, shape (n,)
        Joint rates at the start of the step [rad/s].
    tau : ndarray, shape (n,)
        Actuator lag state at the start of the step [N·m].
    u : ndarray, shape (n,)
        Applied input [N·m], held over the step.
    t : float
        The stage's time [s] (t, t + h/2, t + h/2, t + h), for d(t).
    h : float
        Step length [s].
    acc : ndarray, shape (n,)
        ABA output at the stage state [rad/s²].
    p : ndarray
        :func:`pack_params` of an arm of n joints (5n + 2 values).
    w : ndarray, shape (8, n)
        Workspace (:meth:`ArmModel.workspace`), written in place.
    """
    n = q.shape[0]
    lag = p[p.shape[0] - 1]
    weight = 1.0 if stage == 0 or stage == 3 else 2.0
    coef = h if stage == 2 else 0.5 * h
    for i in range(n):
        dq = w[1, i]
        dv = acc[i] + p[_DA * n + i] * math.sin(p[_DW * n + i] * t)
        dtau = (u[i] - w[2, i]) / lag if lag > 0.0 else 0.0
        w[4, i] += weight * dq
        w[5, i] += weight * dv
        w[6, i] += weight * dtau
        if stage < 3:
            w[0, i] = q[i] + coef * dq
            w[1, i] = v[i] + coef * dv
            w[2, i] = tau[i] + coef * dtau
    if stage == 3:
        sixth = h / 6.0
        for i in range(n):
            w[0, i] = q[i] + sixth * w[4, i]
            w[1, i] = v[i] + sixth * w[5, i]
            w[2, i] = tau[i] + sixth * w[6, i]
            w[4, i] = 0.0
            w[5, i] = 0.0
            w[6, i] = 0.0
    joint_drive(w[1], w[2] if lag > 0.0 else u, p, w[3])


_STAGE_TIME = (0.0, 0.5, 0.5, 1.0)

_COMPILED: dict[str, Any] = {}


def compiled(name: str) -> Any:
    """The numba-compiled helper ``name`` (compiled on first use and cached on disk).

    numba is imported only here, so importing the arm's modules stays light;
    without numba the plain functions run (slowly, the same numbers).

    Parameters
    ----------
    name : str
        A helper of this module: "joint_drive", "add_disturbance", "rk4_begin" or
        "rk4_stage".

    Returns
    -------
    callable
        The compiled function (the plain one without numba).
    """
    func = _COMPILED.get(name)
    if func is None:
        plain = globals()[name]
        try:
            from numba import njit
        except ImportError:  # pragma: no cover - numba is a core dependency
            func = plain
        else:
            from esoarm._jit import register_all

            register_all()  # the helpers call each other: register them first
            func = njit(cache=True)(plain)
        _COMPILED[name] = func
    return func


@dataclass(frozen=True)
class TwinParams:
    """Per-joint parameters of the twin beyond the rigid body (arrays of length n).

    Attributes
    ----------
    coulomb_friction : ndarray
        Fc [N·m].
    friction_velocity : ndarray
        vs [rad/s], tanh smoothing of the Coulomb friction.
    viscous_friction : ndarray
        b [N·m·s/rad].
    disturbance_amplitude : ndarray
        [rad/s²].
    disturbance_frequency : ndarray
        [rad/s].
    lag : float
        Actuator time constant T [s]; 0 for none.
    """

    coulomb_friction: np.ndarray
    friction_velocity: np.ndarray
    viscous_friction: np.ndarray
    disturbance_amplitude: np.ndarray
    disturbance_frequency: np.ndarray
    lag: float = 0.0


def twin_acceleration(arm: ArmModel, x: np.ndarray, u: np.ndarray, t: float, tp: np.ndarray,
                      out: np.ndarray) -> None:
    """True q̈ [rad/s²] at the state x = (q, q̇, τ), time t, input u applied from t, into out.

    ``tp`` is :func:`pack_params`; with a lag the torque acting is the state τ.

    Parameters
    ----------
    arm : ArmModel
        The arm (its ``true`` model is stepped).
    x : ndarray, shape (3n,)
        State: q [rad] in x[:n], q̇ [rad/s] in x[n:2n], τ [N·m] in x[2n:3n].
    u : ndarray, shape (n,)
        Applied input [N·m] (acts directly when T = 0).
    t : float
        Time [s].
    tp : ndarray
        :func:`pack_params`.
    out : ndarray, shape (n,)
        Output: q̈ [rad/s²].
    """
    n = arm.n_joints
    v = x[n:2 * n]
    applied = x[2 * n:3 * n] if tp[-1] > 0.0 else u
    drive = np.empty(n)
    compiled("joint_drive")(v, applied, tp, drive)
    # M q̈ + C q̇ + g/s = (τ − F)/s  (ABA on the true model, gravity already g/s)
    acc = arm.aba(arm.true, arm.data("true"), arm.configuration(x[:n]), v, drive)
    out[:] = compiled("add_disturbance")(acc, t, tp)


def twin_advance(arm: ArmModel, x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
                 tp: np.ndarray) -> None:
    """Integrate x = (q, q̇, τ) in place over ``nsub`` classical RK4 steps of h [s], u held.

    One Pinocchio ABA call and one compiled :func:`rk4_stage` call per stage.

    Parameters
    ----------
    arm : ArmModel
        The arm (its ``true`` model is stepped).
    x : ndarray, shape (3n,)
        State (q [rad], q̇ [rad/s], τ [N·m]), updated in place.
    u : ndarray, shape (n,)
        Applied input [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = Ts).
    tp : ndarray
        :func:`pack_params`.
    """
    n = arm.n_joints
    q, v, tau = x[:n], x[n:2 * n], x[2 * n:3 * n]
    aba, model, data, config = arm.aba, arm.true, arm.data("true"), arm.configuration
    w = arm.workspace()
    begin, stage_done = compiled("rk4_begin"), compiled("rk4_stage")
    begin(q, v, tau, u, tp, w)
    for j in range(nsub):
        t = t0 + j * h
        for stage in range(4):
            acc = aba(model, data, config(w[0]), w[1], w[3])
            stage_done(stage, q, v, tau, u, t + _STAGE_TIME[stage] * h, h, acc, tp, w)
        x[:3 * n] = w[:3].ravel()


class ArmTwin:
    """The true arm stepped on separate (q, q̇, τ) arrays: a thin object over
    :func:`twin_acceleration` and :func:`twin_advance` (tests, notebooks).

    Parameters
    ----------
    arm : ArmModel
        From :func:`~esoarm.plants.arms.model.load_arm`; its ``true`` model is used.
    params : TwinParams
        Friction, disturbance and lag.
    """

    def __init__(self, arm: ArmModel, params: TwinParams) -> None:
        self.arm = arm
        self.params = params
        self._p = pack_params(params, arm.inertia_scale)
        self._lag = float(params.lag)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     t: float) -> np.ndarray:
        """True joint acceleration q̈ [rad/s²] at (q, q̇), torque τ [N·m] acting, time t [s].

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint angles [rad].
        v : ndarray, shape (n,)
            Joint rates [rad/s].
        tau : ndarray, shape (n,)
            Torque acting on each joint [N·m] (not lagged further).
        t : float
            Time [s], for d(t).

        Returns
        -------
        ndarray, shape (n,)
            q̈ [rad/s²].
        """
        out = np.empty(len(q))
        x = np.concatenate([q, v, tau])
        tp = self._p.copy()
        tp[-1] = 0.0  # τ given is the torque acting
        twin_acceleration(self.arm, x, np.asarray(tau, dtype=float), t, tp, out)
        return out

    def applied(self, tau: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Torque acting on the arm: the lag state τ when T > 0, else u itself.

        Parameters
        ----------
        tau : ndarray, shape (n,)
            Actuator lag state [N·m].
        u : ndarray, shape (n,)
            Applied input [N·m].

        Returns
        -------
        ndarray, shape (n,)
            ``tau`` or ``u`` (the same array, not a copy).
        """
        return tau if self._lag > 0.0 else u

    def advance(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray,
                t0: float, h: float, nsub: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Integrate over one sample: ``nsub`` classical RK4 steps of h [s] from t0, u held.

        Returns the state (q, q̇, τ) at t0 + nsub·h; τ is the lag state (zeros
        without lag).

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint angles [rad].
        v : ndarray, shape (n,)
            Joint rates [rad/s].
        tau : ndarray, shape (n,)
            Actuator lag state [N·m].
        u : ndarray, shape (n,)
            Applied input [N·m], held.
        t0 : float
            Start of the sample [s].
        h : float
            RK4 step [s].
        nsub : int
            Number of RK4 steps.

        Returns
        -------
        (q, v, tau) : (ndarray, ndarray, ndarray)
            New arrays [rad, rad/s, N·m]; the arguments are not changed.
        """
        n = len(q)
        x = np.concatenate([q, v, tau]).astype(float)
        twin_advance(self.arm, x, np.asarray(u, dtype=float), t0, h, nsub, self._p)
        return x[:n], x[n:2 * n], x[2 * n:]

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Mechanical energy s·T(q, q̇) + V(q) of the true arm [J] (no friction, no d).

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint angles [rad].
        v : ndarray, shape (n,)
            Joint rates [rad/s].

        Returns
        -------
        float
            Energy [J]; V with Pinocchio's reference (zero at the base frame's height).
        """
        pin = import_pinocchio()
        cfg = self.arm.configuration(q)
        model, data = self.arm.true, self.arm.data("true")
        kinetic = pin.computeKineticEnergy(model, data, cfg, v)
        potential = pin.computePotentialEnergy(model, data, cfg)  # with g/s
        return float(self.arm.inertia_scale * (kinetic + potential))
