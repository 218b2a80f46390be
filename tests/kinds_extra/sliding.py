"""Controller kind ``"sliding"`` (test only): sliding-mode control on the ESO's estimate.

Per joint, with e = ẑ1 − θd, ė = ẑ2 − θ̇d and the sliding variable s = ė + λ e:

    u = (θ̈d − λ ė − ẑ3 − k·sat(s/φ)) / b0

(the boundary layer φ replaces sign(s) by a saturation to avoid chattering).  On
s = 0 the error decays as e^(−λt).  No state of its own.  One module and one
``register("controller", sliding)`` line, written from docs/contract.md alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, PlantDesign, Vector, read_only

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

KIND = "sliding"
CODE = 8
JIT = True

#: Per joint in the vector (after the CODE): λ, k, φ, b0.
_LAM, _K, _PHI, _B0 = 0, 1, 2, 3
WIDTH = 4


class Params(Section):
    """``[controller]`` of kind "sliding": s = ė + λ e, u = (θ̈d − λė − ẑ3 − k sat(s/φ))/b0."""

    kind: Literal["sliding"] = Field("sliding", description="controller kind")
    lam: Annotated[float, Field(gt=0)] = Field(
        8.0, description="slope λ of the sliding surface", json_schema_extra=unit("1/s"))
    gain: Annotated[float, Field(ge=0)] = Field(
        20.0, description="switching gain k", json_schema_extra=unit("rad/s²"))
    boundary: Annotated[float, Field(gt=0)] = Field(
        0.5, description="boundary layer φ of the saturation", json_schema_extra=unit("rad/s"))


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, then λ, k, φ, b0 per joint); one unused state."""
    ctl = scn.controller
    assert isinstance(ctl, Params)
    rows = [[ctl.lam, ctl.gain, ctl.boundary, float(b0)] for b0 in plant.b0]
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], *rows])), 1)


@jitable
def initialize(c: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """No state of its own."""


@jitable
def control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
            p: Vector, u: np.ndarray) -> None:
    """u = (θ̈d − λ ė − ẑ3 − k·sat(s/φ)) / b0 per joint."""
    for j in range(len(y)):
        o = 1 + WIDTH * j
        lam = p[o + _LAM]
        e = zhat[3 * j] - refs[3 * j, k]
        de = zhat[3 * j + 1] - refs[3 * j + 1, k]
        s = de + lam * e
        r = s / p[o + _PHI]
        sat = max(-1.0, min(1.0, r))
        u[j] = (refs[3 * j + 2, k] - lam * de - zhat[3 * j + 2] - p[o + _K] * sat) / p[o + _B0]
