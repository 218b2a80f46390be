"""One ESO per joint and computed torque on the nominal model (the paper's FLC, n joints).

Each joint i has its own extended state observer -- the paper's eq. 8 with the
lever arm's step functions and design (:mod:`esoarm.observers.linear`:
``eso_estimate``, ``eso_advance``, ``design_observer`` with the gains of
Theorem 1 from that joint's ε_i) -- on the extended plant

    q̈_i = f_i + v_i,    v = M̂(q̂)⁻¹ (τ − c · n̂(q̂, q̂̇))        (b0 = 1)

where q̂ = ẑ1, q̂̇ = ẑ2 are the observers' estimates, c = 1 when the nominal
n̂ is fed forward and 0 otherwise.  ẑ3_i estimates the joint's lumped
perturbation f_i: coupling from the other joints, gravity and Coriolis terms
(unless fed forward), friction, payload and inertia error, disturbance -- as
the paper's z3 absorbs −G/I0 + d.  On one joint, v = τ/I0 = b0·u: the lever arm.

Tracking law per joint, eq. 16 with the observers' rates:

    α_i = q̈d_i − k1_i (ẑ2_i − q̇d_i) − k2_i (ẑ1_i − qd_i)

and the torque, saturated per joint to ±torque_limit_i:

``compensation = "eso"`` (the paper's eq. 14 on n joints)
    τ = M̂(q̂) (α − ẑ3)          or, with ``feedforward``, τ = M̂(q̂) (α − ẑ3) + n̂(q̂, q̂̇)
``compensation = "model"`` (computed torque on the nominal model, Fig. 7's baseline)
    τ = M̂(q̂) α + n̂(q̂, q̂̇)       (the observers still run and supply q̂, q̂̇)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from esoarm.controllers import flc as _flc
from esoarm.controllers.flc import flc_control, saturate
from esoarm.observers.linear import design_observer, eso_advance, eso_estimate
from esoarm.plants.urdf import ArmModel

__all__ = ["ArmController", "JointObservers", "tracking_acceleration"]


def _alpha_vector(k1: float, k2: float) -> np.ndarray:
    # The FLC law of a unit-inertia joint without perturbation estimate and
    # without saturation is α itself: I0 (α − β̂) with I0 = 1, β̂ = z3 = 0.
    vec = np.zeros(_flc.VECTOR_SIZE)
    vec[_flc.K1], vec[_flc.K2], vec[_flc.I0] = k1, k2, 1.0
    vec[_flc.COMP], vec[_flc.LIMIT] = _flc.COMP_ESO, math.inf
    return vec


def tracking_acceleration(z1: float, z2: float, q_ref: float, v_ref: float, a_ref: float,
                          unit_ctl: np.ndarray) -> float:
    """α = q̈d − k1 (ẑ2 − q̇d) − k2 (ẑ1 − qd) [rad/s²] (eq. 16), by the lever arm's law.

    ``unit_ctl`` is the controller vector of a unit-inertia joint (see
    :class:`ArmController`); :func:`esoarm.controllers.flc.flc_control` then
    returns α exactly.
    """
    return float(flc_control(z1, z2, 0.0, q_ref, v_ref, a_ref, unit_ctl))


class JointObservers:
    """n independent ESOs (eq. 8), one per joint, stepped one sample at a time.

    Parameters
    ----------
    eps : ndarray (n,)
        ε_i [s] per joint.
    ts : float
        Sample period [s].
    discretization : {"euler", "zoh", "current"}
    y0 : ndarray (n,)
        First measurement [rad]; initial state z_i = (y0_i, 0, 0).
    """

    def __init__(self, eps: np.ndarray, ts: float, discretization: str,
                 y0: np.ndarray) -> None:
        self.designs = [design_observer(float(e), ts, 1.0, discretization) for e in eps]
        self._obs = [d.vector for d in self.designs]
        n = len(self._obs)
        self.z = np.zeros((n, 3))
        self.z[:, 0] = y0
        self.zhat = self.z.copy()
        self._y = np.array(y0, dtype=float)

    def estimate(self, y: np.ndarray) -> np.ndarray:
        """Take the measurements y_k [rad]; return ẑ_k, shape (n, 3)."""
        self._y = y
        z = self.z
        for i, obs in enumerate(self._obs):
            self.zhat[i] = eso_estimate(z[i, 0], z[i, 1], z[i, 2], y[i], obs)
        return self.zhat

    def update(self, v: np.ndarray) -> None:
        """Advance to z_{k+1} with the observer inputs v_k = M̂⁻¹(τ − c n̂) [rad/s²]."""
        z, zh, y = self.z, self.zhat, self._y
        for i, obs in enumerate(self._obs):
            z[i] = eso_advance(z[i, 0], z[i, 1], z[i, 2], zh[i, 0], zh[i, 1], zh[i, 2],
                               y[i], v[i], obs)


@dataclass(frozen=True)
class ArmController:
    """Computed torque on the nominal model with the observers' estimates.

    Attributes
    ----------
    arm : ArmModel
        Supplies the nominal M̂(q) and n̂(q, q̇).
    k1, k2 : ndarray (n,)
        Per-joint gains [1/s], [1/s²].
    compensation : {"eso", "model"}
    feedforward : bool
        With "eso": add the nominal n̂(q̂, q̂̇) to the torque (and remove it from
        what the observers must estimate).
    torque_limit : ndarray (n,)
        Per-joint saturation [N·m].
    """

    arm: ArmModel
    k1: np.ndarray
    k2: np.ndarray
    compensation: str
    feedforward: bool
    torque_limit: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "_unit", [_alpha_vector(float(a), float(b))
                                           for a, b in zip(self.k1, self.k2, strict=True)])

    def __call__(self, zhat: np.ndarray, q_ref: np.ndarray, v_ref: np.ndarray,
                 a_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Torque command u_k [N·m] and the observer input v_k [rad/s²].

        Parameters
        ----------
        zhat : ndarray (n, 3)
            Estimates (q̂ [rad], q̂̇ [rad/s], f̂ [rad/s²]) per joint.
        q_ref, v_ref, a_ref : ndarray (n,)
            Reference position, rate and acceleration at t_k.
        """
        unit = self._unit  # type: ignore[attr-defined]
        alpha = np.array([tracking_acceleration(zhat[i, 0], zhat[i, 1], q_ref[i], v_ref[i],
                                                a_ref[i], unit[i]) for i in range(len(unit))])
        q_hat = zhat[:, 0]
        m_hat = self.arm.mass_matrix(q_hat)
        model = self.compensation != "eso"
        ff = model or self.feedforward
        n_hat = self.arm.bias(q_hat, zhat[:, 1]) if ff else None
        if model:
            tau = m_hat @ alpha + n_hat
        else:
            tau = m_hat @ (alpha - zhat[:, 2])
            if n_hat is not None:
                tau = tau + n_hat
        u = np.array([saturate(tau[i], self.torque_limit[i]) for i in range(len(tau))])
        # the observers' input: what the torque does through the nominal model,
        # less the fed-forward n̂ (which the observers then need not estimate)
        drive = u - n_hat if (self.feedforward and not model) else u
        v = np.linalg.solve(m_hat, drive)
        return u, v
