"""Observer kind ``"luenberger"`` (test only): a Luenberger observer of the extended plant.

The extended plant of eq. 7 (θ, θ̇, f) with the gains that put the three error
poles at −1/ε, −2/ε and −3/ε: (s + 1/ε)(s + 2/ε)(s + 3/ε) = s³ + 6/ε s² + 11/ε² s + 6/ε³,
so β = (6/ε, 11/ε², 6/ε³); discretized with forward Euler at Ts.  It is the one module of
the contract experiment: registered with one line (``esoarm.kinds.register("observer",
luenberger)``), it must run through every command or be refused in one line.  It has
``eps`` but no ``discretization``, declares no fast-engine support, and gives ``analyze``
its linearization.
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

KIND = "luenberger"
CODE = 7
JIT = True
FAST = False

#: Per joint in the vector (after the CODE): Ts, b0, β1, β2, β3.
_TS, _B0, _B1, _B2, _B3 = 0, 1, 2, 3, 4
WIDTH = 5


class Params(Section):
    """``[observer]`` of kind "luenberger": error poles at −1/ε, −2/ε, −3/ε (Euler)."""

    kind: Literal["luenberger"] = Field("luenberger", description="observer kind")
    eps: Annotated[float, Field(gt=0)] = Field(
        0.09, description="the slowest error pole is −1/ε", json_schema_extra=unit("s"))


def gains(eps: float) -> tuple[float, float, float]:
    """(β1, β2, β3) = (6/ε, 11/ε², 6/ε³): error poles −1/ε, −2/ε, −3/ε."""
    return 6.0 / eps, 11.0 / eps**2, 6.0 / eps**3


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, then Ts, b0, β per joint); state 3 per joint."""
    obs = scn.observer
    assert isinstance(obs, Params)
    rows = [[ts, float(b0), *gains(obs.eps)] for b0 in plant.b0]
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], *rows])), 3 * plant.n_joints)


@jitable
def initialize(z: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """z_0 = (y_0, 0, 0) per joint."""
    for j in range(len(y)):
        z[3 * j] = y[j]
        z[3 * j + 1] = 0.0
        z[3 * j + 2] = 0.0


@jitable
def predict(z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray) -> None:
    """A lost sample: the measurement the observer expects at t_k, ẑ1 = z1 per joint, into ``y``.

    Parameters
    ----------
    z : ndarray, shape (3n,)
        Observer state z_k (not changed).
    zhat : ndarray, shape (3n,)
        The previous estimate ẑ_{k−1} (unused: z1 is the angle predicted for t_k).
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE.
    y : ndarray, shape (n,)
        Output: the predicted angle(s) [rad]; the estimate and update then see zero
        innovation.
    """
    for j in range(len(y)):
        y[j] = z[3 * j]


def state_size(params: Params) -> int:
    """States per joint: 3 (angle, rate, total perturbation)."""
    return 3


@jitable
def estimate(z: np.ndarray, y: np.ndarray, p: np.ndarray, zhat: np.ndarray) -> None:
    """ẑ_k = z_k (a predictive observer)."""
    for i in range(len(zhat)):
        zhat[i] = z[i]


@jitable
def advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray,
            p: np.ndarray) -> None:
    """Forward Euler of ż = A z + B u + β (y − z1), per joint."""
    for j in range(len(y)):
        i, o = 3 * j, 1 + WIDTH * j
        ts, b0 = p[o + _TS], p[o + _B0]
        e = y[j] - z[i]
        d1 = z[i + 1] + p[o + _B1] * e
        d2 = z[i + 2] + b0 * u[j] + p[o + _B2] * e
        d3 = p[o + _B3] * e
        z[i] += ts * d1
        z[i + 1] += ts * d2
        z[i + 2] += ts * d3


def warnings(params: Params, ts: float) -> list[str]:
    """Euler is unstable once the fastest pole leaves the unit circle: 3·Ts/ε ≥ 2."""
    if 3.0 * ts / params.eps >= 2.0:
        return [f"observer.eps = {params.eps:g} s: the luenberger observer is unstable at "
                f"Ts = {ts:g} s (Euler needs 3·Ts/ε < 2)"]
    return []


def linearization(params: Params, ts: float, b0: float) -> ObserverLinearization:
    """z⁺ = (I + Ts (A − βC)) z + Ts β y + Ts B u; ẑ = z."""
    beta = np.array(gains(params.eps)).reshape(3, 1)
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    c = np.array([[1.0, 0.0, 0.0]])
    pole = max(abs(1.0 - k * ts / params.eps) for k in (1.0, 2.0, 3.0))
    return ObserverLinearization(
        p=np.eye(3) + ts * (a - beta @ c), q=ts * beta,
        gamma=np.array([[0.0], [ts * b0], [0.0]]), hz=np.eye(3), hy=np.zeros((3, 1)),
        pole=pole,
        eps=params.eps, discretization="euler", label="Luenberger observer")
