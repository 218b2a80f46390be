"""Feedback-linearization controller (FLC) of the paper, eq. 14-17.

    u = I0 (α − β̂),    α = θ̈d − k1 (ẑ2 − θ̇d) − k2 (ẑ1 − θd)

with β̂ = z3 (``compensation = "eso"``: the model updated by the ESO, the
proposed method) or β̂ = −G(ẑ1)/I0 (``"model"``: the initial model without a
perturbation estimate, the baseline of Fig. 7).  The result is saturated to
±torque_limit.  With perfect estimates the tracking error e = θ − θd obeys
ë + k1 ė + k2 e = κ (eq. 17), κ the estimation error; Theorem 2 bounds the
steady-state error by μ/k2 for |κ| ≤ μ (see :mod:`esoarm.studies.analysis`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from esoarm._jit import jitable
from esoarm.plants.model import gravity_coefficient, gravity_torque

__all__ = ["FLCParams", "flc_control", "saturate"]

# Layout of the packed controller vector (FLCParams.vector).
K1, K2, I0, GCOEF, COMP, LIMIT = 0, 1, 2, 3, 4, 5
VECTOR_SIZE = 6
COMP_ESO, COMP_MODEL = 0, 1
COMPENSATIONS = ("eso", "model")


@jitable
def saturate(u, limit):  # type: ignore[no-untyped-def]
    """Clip u to ±limit [N·m]; NaN passes through so faults stay visible."""
    if u > limit:
        return limit
    if u < -limit:
        return -limit
    return u


@jitable
def flc_control(z1, z2, z3, theta_ref, omega_ref, accel_ref, ctl):  # type: ignore[no-untyped-def]
    """FLC law (eq. 14-16) from the estimate ẑ = (z1, z2, z3), saturated.

    Parameters
    ----------
    z1, z2, z3 : float
        Estimated angle [rad], rate [rad/s] and total perturbation [rad/s²].
    theta_ref, omega_ref, accel_ref : float
        Reference θd [rad], θ̇d [rad/s], θ̈d [rad/s²].
    ctl : ndarray, shape (6,)
        :attr:`FLCParams.vector`.

    Returns
    -------
    float
        Torque command u [N·m], |u| ≤ torque_limit.
    """
    # α = θ̈d − k1 (ẑ2 − θ̇d) − k2 (ẑ1 − θd)          (eq. 16)
    alpha = accel_ref - ctl[K1] * (z2 - omega_ref) - ctl[K2] * (z1 - theta_ref)
    if ctl[COMP] == COMP_ESO:
        beta_hat = z3  # the updated model: total perturbation from the ESO
    else:
        beta_hat = -gravity_torque(z1, ctl[GCOEF]) / ctl[I0]  # eq. 15 without d
    # u = I0 (α − β̂)                                    (eq. 14)
    return saturate(ctl[I0] * (alpha - beta_hat), ctl[LIMIT])


@dataclass(frozen=True)
class FLCParams:
    """Controller parameters.

    Attributes
    ----------
    k1 : float
        Error-rate gain [1/s].
    k2 : float
        Error gain [1/s²].
    inertia : float
        Nominal I0 [kg·m²].
    gcoef : float
        Nominal (m1 l1 − m2 l2) g [N·m].
    compensation : {"eso", "model"}
    torque_limit : float
        Saturation [N·m].
    """

    k1: float
    k2: float
    inertia: float
    gcoef: float
    compensation: str
    torque_limit: float

    @classmethod
    def from_scenario(cls, scn) -> FLCParams:  # type: ignore[no-untyped-def]
        """Controller parameters of a :class:`~esoarm.scenario.Scenario`."""
        p = scn.plant
        return cls(
            k1=scn.controller.k1,
            k2=scn.controller.k2,
            inertia=p.inertia,
            gcoef=gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g),
            compensation=scn.controller.compensation,
            torque_limit=scn.actuator.torque_limit,
        )

    @cached_property
    def vector(self) -> np.ndarray:
        """Packed float vector for :func:`flc_control` (computed once)."""
        vec = np.empty(VECTOR_SIZE)
        vec[K1], vec[K2], vec[I0], vec[GCOEF] = self.k1, self.k2, self.inertia, self.gcoef
        vec[COMP] = COMPENSATIONS.index(self.compensation)
        vec[LIMIT] = self.torque_limit
        vec.setflags(write=False)
        return vec

    def __call__(
        self, zhat: tuple[float, float, float], theta_ref: float, omega_ref: float, accel_ref: float
    ) -> float:
        """Torque command [N·m] for estimate ``zhat`` and the reference at t_k."""
        return float(flc_control(zhat[0], zhat[1], zhat[2], theta_ref, omega_ref, accel_ref,
                                 self.vector))
