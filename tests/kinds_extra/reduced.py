"""Observer kind ``"reduced"`` (test only): a reduced-order ESO with 2 states per joint.

The measured angle is taken as it is (ẑ1 = y) and only the rate and the total
perturbation (ξ2, ξ3) are observed.  With the extended plant of eq. 7,
θ̇ = ω, ω̇ = f + b0 u, ḟ = 0, the reduced-order observer (Luenberger's construction)
keeps w = (ξ̂2, ξ̂3) − L y per joint:

    ẇ = F (w + L y) + (b0 u, 0),   F = [[−l1, 1], [−l2, 0]],   (ξ̂2, ξ̂3) = w + L y,

with both error poles at −1/ε: l1 = 2/ε, l2 = 1/ε².  Forward Euler at Ts (stable for
Ts/ε < 2).  Its state is not the angle (w holds no position at all), so a lost sample is
bridged by ``predict`` from the previous estimate: y ≈ ẑ1 + Ts·ẑ2.  One module and one
``register("observer", reduced)`` line, written from docs/contract.md alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, ObserverLinearization, PlantDesign, Vector, read_only

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

KIND = "reduced"
CODE = 8
JIT = True

#: Per joint in the vector (after the CODE): Ts, b0, l1, l2.
_TS, _B0, _L1, _L2 = 0, 1, 2, 3
WIDTH = 4


class Params(Section):
    """``[observer]`` of kind "reduced": both error poles of (ξ2, ξ3) at −1/ε (Euler)."""

    kind: Literal["reduced"] = Field("reduced", description="observer kind")
    eps: Annotated[float, Field(gt=0)] = Field(
        0.09, description="time constant of both error poles", json_schema_extra=unit("s"))


def gains(eps: float) -> tuple[float, float]:
    """(l1, l2) = (2/ε, 1/ε²): s² + l1 s + l2 = (s + 1/ε)²."""
    return 2.0 / eps, 1.0 / eps**2


def state_size(params: Params) -> int:
    """Two states per joint (w2, w3)."""
    return 2


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, then Ts, b0, l1, l2 per joint); state 2 per joint."""
    obs = scn.observer
    assert isinstance(obs, Params)
    rows = [[ts, float(b0), *gains(obs.eps)] for b0 in plant.b0]
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], *rows])), 2 * plant.n_joints)


@jitable
def initialize(z: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """(ξ̂2, ξ̂3) = 0 at the first sample: w_0 = −L y_0 per joint."""
    for j in range(len(y)):
        o = 1 + WIDTH * j
        z[2 * j] = -p[o + _L1] * y[j]
        z[2 * j + 1] = -p[o + _L2] * y[j]


@jitable
def estimate(z: np.ndarray, y: np.ndarray, p: Vector, zhat: np.ndarray) -> None:
    """ẑ = (y, w2 + l1 y, w3 + l2 y) per joint."""
    for j in range(len(y)):
        o = 1 + WIDTH * j
        zhat[3 * j] = y[j]
        zhat[3 * j + 1] = z[2 * j] + p[o + _L1] * y[j]
        zhat[3 * j + 2] = z[2 * j + 1] + p[o + _L2] * y[j]


@jitable
def advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray, p: Vector) -> None:
    """Forward Euler of ẇ = F ξ̂ + (b0 u, 0) with ξ̂ = (ẑ2, ẑ3)."""
    for j in range(len(y)):
        o = 1 + WIDTH * j
        ts, l1, l2 = p[o + _TS], p[o + _L1], p[o + _L2]
        x2, x3 = zhat[3 * j + 1], zhat[3 * j + 2]
        z[2 * j] += ts * (-l1 * x2 + x3 + p[o + _B0] * u[j])
        z[2 * j + 1] += ts * (-l2 * x2)


@jitable
def predict(z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray) -> None:
    """A lost sample: y ≈ ẑ1 + Ts·ẑ2 of the previous estimate (w holds no angle)."""
    for j in range(len(y)):
        y[j] = zhat[3 * j] + p[1 + WIDTH * j + _TS] * zhat[3 * j + 1]


def warnings(params: Params, ts: float) -> list[str]:
    """Euler is unstable once the double pole 1 − Ts/ε leaves the unit circle."""
    if ts / params.eps >= 2.0:
        return [f"observer.eps = {params.eps:g} s: the reduced-order ESO is unstable at "
                f"Ts = {ts:g} s (Euler needs Ts/ε < 2)"]
    return []


def linearization(params: Params, ts: float, b0: float) -> ObserverLinearization:
    """w⁺ = (I + Ts F) w + Ts F L y + Ts (b0, 0) u;  ẑ = Hz w + Hy y."""
    l1, l2 = gains(params.eps)
    f = np.array([[-l1, 1.0], [-l2, 0.0]])
    gain = np.array([[l1], [l2]])
    return ObserverLinearization(
        p=np.eye(2) + ts * f, q=ts * f @ gain, gamma=np.array([[ts * b0], [0.0]]),
        hz=np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        hy=np.array([[1.0], [l1], [l2]]), pole=1.0 - ts / params.eps,
        eps=params.eps, discretization="euler", label="reduced-order ESO")
