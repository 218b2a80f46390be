"""The digital twin of a URDF arm: the lever arm's rig, joint by joint.

Per joint i, with the true rigid-body model of :class:`~esoarm.arms.urdf.ArmModel`
(payload included, kinetic energy scaled by s = ``inertia_scale``):

    s (M(q) q̈ + C(q, q̇) q̇) + g(q) = τ − F(q̇),    then  q̈ ← q̈ + d(t)
    F_i(q̇_i) = Fc_i tanh(q̇_i / vs_i) + b_i q̇_i          Coulomb + viscous friction
    d_i(t) = amplitude_i · sin(frequency_i · t)  [rad/s²]  the paper's eq. 6, per joint
    τ̇ = (u_applied − τ) / T      (actuator lag T > 0; τ = u_applied when T = 0)

integrated with classical RK4 at a fixed step h, d evaluated at each stage
time -- the lever arm's rig (``esoarm.rig``) with I0 θ̈ + G(θ) replaced by the
arm's rigid-body dynamics.  On the one-joint lever URDF it is the lever arm's
rig exactly: (τ − F)/s − G/s over I0 is (τ − G − F)/I with I = s·I0.

The disturbance enters as an acceleration, as in the paper (eq. 5); it is the
torque M(q)·d.  Each RK4 stage costs one Pinocchio ABA call (Featherstone's
articulated-body algorithm, O(n)) -- M and n are never formed for the twin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from esoarm.arms.urdf import ArmModel, import_pinocchio

__all__ = ["ArmTwin", "TwinParams"]


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


class ArmTwin:
    """The true arm: its acceleration and its RK4 integration (one ABA per stage).

    Parameters
    ----------
    arm : ArmModel
        From :func:`~esoarm.arms.urdf.load_arm`; its ``true`` model is used.
    params : TwinParams
        Friction, disturbance and lag.
    """

    def __init__(self, arm: ArmModel, params: TwinParams) -> None:
        pin = import_pinocchio()
        self.arm = arm
        self.params = params
        self._aba = pin.aba
        self._model = arm.true
        self._data = arm.true.createData()
        self._config = arm.configuration
        self._s = arm.inertia_scale
        self._fc = np.asarray(params.coulomb_friction, dtype=float)
        self._vs = np.asarray(params.friction_velocity, dtype=float)
        self._b = np.asarray(params.viscous_friction, dtype=float)
        self._da = np.asarray(params.disturbance_amplitude, dtype=float)
        self._dw = np.asarray(params.disturbance_frequency, dtype=float)
        self._lag = float(params.lag)
        self._frictionless = not (self._fc.any() or self._b.any())
        self._undisturbed = not self._da.any()

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     t: float) -> np.ndarray:
        """True joint acceleration q̈ [rad/s²] at (q, q̇), torque τ [N·m], time t [s]."""
        drive = tau if self._frictionless else (
            tau - (self._fc * np.tanh(v / self._vs) + self._b * v))
        # M q̈ + C q̇ + g/s = (τ − F)/s  (ABA on the true model, gravity already g/s)
        acc = np.array(self._aba(self._model, self._data, self._config(q), v, drive / self._s))
        if self._undisturbed:
            return acc
        return acc + self._da * np.sin(self._dw * t)

    def applied(self, tau: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Torque acting on the arm: the lag state τ when T > 0, else u itself."""
        return tau if self._lag > 0.0 else u

    def derivative(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray,
                   t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Time derivative of the state (q, q̇, τ) under the applied input u [N·m]."""
        if self._lag > 0.0:
            return v, self.acceleration(q, v, tau, t), (u - tau) / self._lag
        return v, self.acceleration(q, v, u, t), None

    def rk4_step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray,
                 t: float, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One classical RK4 step of length h [s] from time t with u held."""
        half = 0.5 * h
        a1, b1, c1 = self.derivative(q, v, tau, u, t)
        if c1 is None:  # no lag: τ is not a state
            a2, b2, _ = self.derivative(q + half * a1, v + half * b1, tau, u, t + half)
            a3, b3, _ = self.derivative(q + half * a2, v + half * b2, tau, u, t + half)
            a4, b4, _ = self.derivative(q + h * a3, v + h * b3, tau, u, t + h)
            sixth = h / 6.0
            return (q + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
                    v + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4), tau)
        a2, b2, c2 = self.derivative(q + half * a1, v + half * b1, tau + half * c1, u, t + half)
        a3, b3, c3 = self.derivative(q + half * a2, v + half * b2, tau + half * c2, u, t + half)
        a4, b4, c4 = self.derivative(q + h * a3, v + h * b3, tau + h * c3, u, t + h)
        sixth = h / 6.0
        return (q + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
                v + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4),
                tau + sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4))  # type: ignore[operator]

    def advance(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, u: np.ndarray,
                t0: float, h: float, nsub: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Integrate over one sample: ``nsub`` RK4 steps of h [s] from t0, u held."""
        for j in range(nsub):
            q, v, tau = self.rk4_step(q, v, tau, u, t0 + j * h, h)
        return q, v, tau

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Mechanical energy s·T(q, q̇) + V(q) of the true arm [J] (no friction, no d)."""
        pin = import_pinocchio()
        cfg = self._config(q)
        kinetic = pin.computeKineticEnergy(self._model, self._data, cfg, v)
        potential = pin.computePotentialEnergy(self._model, self._data, cfg)  # with g/s
        return float(self._s * (kinetic + potential))
