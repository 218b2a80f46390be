"""Controller kind ``"flc"``: the paper's feedback-linearization controller, eq. 14-17.

    u = I0 (α − β̂),    α = θ̈d − k1 (ẑ2 − θ̇d) − k2 (ẑ1 − θd)

with β̂ = z3 (``compensation = "eso"``: the model updated by the ESO, the
proposed method) or β̂ = −G(ẑ1)/I0 (``"model"``: the initial model without a
perturbation estimate, the baseline of Fig. 7).  The result is saturated to
±torque_limit.  With perfect estimates the tracking error e = θ − θd obeys
ë + k1 ė + k2 e = κ (eq. 17), κ the estimation error; Theorem 2 bounds the
steady-state error by μ/k2 for |κ| ≤ μ (see :mod:`esoarm.observers.stability`).

As a kind (see :mod:`esoarm.contract`): :class:`Params` is the ``[controller]``
table, :func:`design` gives (CODE, :attr:`FLCParams.vector`) and :func:`control`
is the array-valued step function (the raw command; the actuator saturates).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, read_only
from esoarm.plants.actuator import saturate
from esoarm.plants.model import gravity_coefficient, gravity_torque

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "FAST", "FLC_LAW", "JIT", "KIND", "FLCParams", "Params", "control", "design",
           "flc_command", "flc_control", "initialize", "label", "saturate"]

KIND = "flc"
CODE = 0
JIT = True
#: The fast engine's C kernel models this controller.
FAST = True
#: The law of eq. 14-16: the frequency-domain analysis and κ (eq. 17) model it.
FLC_LAW = True
#: the kind's C for the generated controller (esoarm.codegen), beside this module
C_SOURCE = "flc.c"


class Params(Section):
    """``[controller]`` of kind "flc": feedback linearization (paper eq. 14-17)."""

    kind: Literal["flc"] = Field(
        "flc", description="controller kind (the registered kinds: esoarm.kinds)")
    k1: float = Field(10.0, gt=0, description="error-rate gain k1", json_schema_extra=unit("1/s"))
    k2: float = Field(25.0, gt=0, description="error gain k2", json_schema_extra=unit("1/s²"))
    compensation: Literal["eso", "model"] = Field(
        "eso", description='"eso": β̂ = z3 (proposed) | "model": β̂ = −G(ẑ1)/I0 (Fig. 7 baseline)'
    )
    feedforward_map: list[float] = Field(
        default_factory=list, max_length=4096,
        description="a learned position-periodic perturbation m(θ) (esoarm learn-map): N "
        "values at θ_i = 2π i/N, interpolated; the drive gets −I0·m(ẑ1) added, the ESO is "
        "fed the command without it and estimates what the table leaves ([] none)",
        json_schema_extra=unit("rad/s²"))

# Layout of the packed controller vector (FLCParams.vector).
K1, K2, I0, GCOEF, COMP, LIMIT = 0, 1, 2, 3, 4, 5
VECTOR_SIZE = 6
COMP_ESO, COMP_MODEL = 0, 1
COMPENSATIONS = ("eso", "model")


@jitable
def flc_command(z1: float, z2: float, z3: float, theta_ref: float, omega_ref: float,
                accel_ref: float, ctl: np.ndarray) -> float:
    """FLC law (eq. 14-16) from the estimate ẑ = (z1, z2, z3), before saturation.

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
        Torque command u [N·m].
    """
    # α = θ̈d − k1 (ẑ2 − θ̇d) − k2 (ẑ1 − θd)          (eq. 16)
    alpha = accel_ref - ctl[K1] * (z2 - omega_ref) - ctl[K2] * (z1 - theta_ref)
    if ctl[COMP] == COMP_ESO:
        beta_hat = z3  # the updated model: total perturbation from the ESO
    else:
        beta_hat = -gravity_torque(z1, ctl[GCOEF]) / ctl[I0]  # eq. 15 without d
    # u = I0 (α − β̂)                                    (eq. 14)
    u: float = ctl[I0] * (alpha - beta_hat)
    return u


@jitable
def flc_control(z1: float, z2: float, z3: float, theta_ref: float, omega_ref: float,
                accel_ref: float, ctl: np.ndarray) -> float:
    """FLC law (eq. 14-16), saturated to ±torque_limit [N·m] (:func:`flc_command`).

    Parameters
    ----------
    z1, z2, z3 : float
        Estimated angle [rad], rate [rad/s] and total perturbation [rad/s²].
    theta_ref, omega_ref, accel_ref : float
        Reference θd [rad], θ̇d [rad/s], θ̈d [rad/s²].
    ctl : ndarray, shape (6,)
        :attr:`FLCParams.vector` (``ctl[5]`` = torque_limit [N·m]).

    Returns
    -------
    float
        Torque command u [N·m] in [−torque_limit, torque_limit], positive along increasing θ.

    Examples
    --------
    >>> import numpy as np
    >>> ctl = np.array([10.0, 25.0, 0.5, 0.0, 0.0, 2.0])  # k1, k2, I0, gcoef, eso, limit
    >>> float(flc_control(0.0, 0.0, 0.0, 0.1, 0.0, 0.0, ctl))  # I0 · k2 · 0.1
    1.25
    >>> float(flc_control(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, ctl))  # saturated
    2.0
    """
    return saturate(flc_command(z1, z2, z3, theta_ref, omega_ref, accel_ref, ctl), ctl[LIMIT])


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
    def from_scenario(cls, scn: Scenario) -> FLCParams:
        """Controller parameters of a :class:`~esoarm.scenario.Scenario`.

        Parameters
        ----------
        scn : Scenario
            The validated scenario (``[controller]`` gains, ``[plant]`` nominal I0 and
            masses/lengths, ``[actuator]`` torque_limit).

        Returns
        -------
        FLCParams
            k1 [1/s], k2 [1/s²], I0 [kg·m²], (m1 l1 − m2 l2) g [N·m], compensation,
            torque_limit [N·m].
        """
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
        """Packed float vector for :func:`flc_control` (computed once).

        Returns
        -------
        ndarray, shape (6,)
            (k1 [1/s], k2 [1/s²], I0 [kg·m²], gcoef [N·m], compensation code
            (0 "eso", 1 "model"), torque_limit [N·m]), read-only.
        """
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


# ---------------------------------------------------------------------------
# the kind: design and array-valued step functions


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, :attr:`FLCParams.vector`) of the scenario; no controller state.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[controller]``, ``[plant]`` and ``[actuator]`` tables).
    plant : PlantDesign
        The plant's design (number of joints n, its vector).
    ts : float
        Sample period Ts [s] (unused: the law is static).

    Returns
    -------
    ComponentDesign
        Vector (CODE, k1, k2, I0, gcoef, compensation, torque_limit), one unused state.
    """
    if plant.n_joints != 1:
        raise ValueError("the FLC kind is designed for one joint")
    return ComponentDesign(
        read_only(np.concatenate([[float(CODE)], FLCParams.from_scenario(scn).vector])), 1)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """The FLC has no state of its own.

    Parameters
    ----------
    c : ndarray
        The controller's own state (length ``n_state`` of its design); left untouched.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    """


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: np.ndarray, u: np.ndarray) -> None:
    """Raw command u_k [N·m] (eq. 14-16) from ẑ_k and the reference at sample k into ``u``.

    ``refs`` holds (θd, θ̇d, θ̈d) of joint j in rows 3j … 3j+2, one column per sample.

    Parameters
    ----------
    c : ndarray
        The controller's own state (unused).
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k: angle [rad], rate [rad/s] and total perturbation [rad/s²] of
        joint j in ``zhat[3j:3j+3]``; the perturbation is f = θ̈ − b0·u (eq. 7).
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad] (unused: the law uses ẑ_k).
    refs : ndarray, shape (3n, N)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column per
        sample.
    k : int
        Sample index (column of ``refs``).
    p : ndarray
        The design vector; ``p[0]`` is the kind's CODE.
    u : ndarray, shape (n,)
        Output: the raw command u_k [N·m] per joint, written in place (positive along
        increasing θ; before saturation).
    """
    ctl = p[1:]
    u[0] = flc_command(zhat[0], zhat[1], zhat[2], refs[0, k], refs[1, k], refs[2, k], ctl)


def label(params: Params) -> str:
    """The controller in titles: ``eso compensation`` (or ``model compensation``).

    Parameters
    ----------
    params : Params
        The ``[controller]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"{params.compensation} compensation"
