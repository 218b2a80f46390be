"""Observer kind ``"cascade"``: the cascade extended state observer (CESO).

Source: K. Łakomy and R. Madonski, "Cascade extended state observer for active
disturbance rejection control applications under measurement noise", ISA
Transactions 109 (2021) 1-10, doi:10.1016/j.isatra.2020.09.007 (arXiv:2004.01483),
and the authors' reference implementation (MIT licence, MATLAB,
``observers/cesoObserverP2.m`` … ``P5.m``, ``extendedStateSelectorP*.m``).

For the plant of eq. 7 (θ̈ = f + b0 u, y = θ + noise) the cascade runs p ESOs of
eq. 8's structure, each with its own bandwidth ω_i (gains (3ω_i, 3ω_i², ω_i³),
Theorem 1 with ε_i = 1/ω_i).  Level 1 is the paper's ESO on the measurement;
level i ≥ 2 measures the *previous level's* angle estimate and takes the
perturbation estimated so far as a known input, so it only has to reconstruct
what the slower levels missed::

    level 1:     ż¹ = A z¹ + B b0 u + L1 (y − z¹1)
    level i ≥ 2: żⁱ = A zⁱ + B (b0 u + Σ_{j<i} zʲ3) + Li (zⁱ⁻¹1 − zⁱ1)

    A = [[0,1,0],[0,0,1],[0,0,0]],  B = (0, 1, 0)ᵀ,  Li = (3ω_i, 3ω_i², ω_i³)ᵀ

and the estimate handed to the controller is (zᵖ1, zᵖ2, Σ_i zⁱ3): the angle and
rate from the last level, the perturbation summed over the levels.  Because
level 1 is slow, the noise reaching the later levels has already been low-pass
filtered, so the fast last level recovers a high estimation bandwidth with less
noise in ẑ2 and ẑ3 (and so in the FLC's command) than one ESO of that bandwidth.

Parameters (``[observer]`` keys): ``eps`` is ε_p = 1/ω_p of the **last**
(fastest) level [s]; ``ratio`` α > 1 the bandwidth ratio between consecutive
levels, ω_i = ω_p / α^(p−i) (the authors' examples use α = 2); ``levels`` p
(1 … 5; p = 1 is the linear ESO: bit for bit for "zoh" and "current", to
rounding for "euler", whose update is grouped as Φ z + Ts β e here).

Discretizations: each level is the linear ESO's discretization
(:mod:`esoarm.observers.linear`) with its own gain and the known input
w_i = Σ_{j<i} ẑʲ3 entering as Γ w_i / b0 (Γ/b0 = (Ts²/2, Ts, 0) exact, (0, Ts, 0)
for Euler) and measurement m_i (y for level 1, ẑⁱ⁻¹1 after) at sample k:

``"euler"`` and ``"zoh"``
    zⁱ⁺ = Φ zⁱ + Γ (u + w_i/b0) + Li (m_i − zⁱ1), Li = Ts·βi or Ackermann's Lp.
``"current"``
    ẑⁱ = zⁱ + Lci (m_i − zⁱ1), zⁱ⁺ = Φ ẑⁱ + Γ (u + w_i/b0).

Every level's poles are those of a linear ESO with ε_i (Φ − Li C: a triple at
1 − Ts/ε_i for Euler, e^(−Ts/ε_i) otherwise), and the cascade is triangular, so
its poles are the union (stable when every level is).

:func:`linear_model` gives the observer as one discrete LTI system for
``esoarm analyze`` (exact: every level is linear).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm._schema import Section, unit
from esoarm.contract import ComponentDesign, ObserverLinearization, PlantDesign, Vector, read_only
from esoarm.observers.linear import CURRENT, design_observer, observer_warnings

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "C_SOURCE", "JIT", "KIND", "MAX_LEVELS", "Params", "advance", "design",
           "estimate", "initialize", "label", "level_eps", "linear_model", "linearization",
           "predict", "state_size", "summary", "warnings"]

KIND = "cascade"
CODE = 2
JIT = True
#: Linear for sensor noise (its linearization is exact): ``analyze --bandwidth`` ranks it.
NOISE_BUDGET = True
#: The same step in C99 for ``esoarm codegen`` (:mod:`esoarm.codegen.generate`).
C_SOURCE = "cascade.c"

#: most levels (the compiled engine's observer vector holds 32 values)
MAX_LEVELS = 5

# Layout of one joint's block (after the leading CODE): discretization, Ts, b0,
# Φ (9, row-major), Γ (3), p, then p gains of 3 (level 1 first).
DISC, TS, B0, PHI, GAMMA, LEVELS, GAINS = 0, 1, 2, 3, 12, 15, 16


@jitable
def block_size(levels: int) -> int:
    """Values per joint in the design vector for ``levels`` levels.

    Parameters
    ----------
    levels : int
        Number of cascaded ESOs p.

    Returns
    -------
    int
        16 + 3·p (discretization, Ts, b0, Φ, Γ, p, then 3 gains per level).
    """
    return GAINS + 3 * levels


class Params(Section):
    """``[observer]`` of kind "cascade": the cascade ESO of Łakomy and Madonski (2021)."""

    kind: Literal["cascade"] = Field(
        "cascade", description="observer kind (the registered kinds: esoarm.kinds)")
    eps: float = Field(
        0.09, gt=0, description="ε of the last (fastest) level: its poles at −1/ε",
        json_schema_extra=unit("s"),
    )
    levels: int = Field(
        2, ge=1, le=MAX_LEVELS, description="number of cascaded ESOs p (1: the linear ESO)",
        json_schema_extra=unit("1"),
    )
    ratio: float = Field(
        1.8, gt=1.0, le=20.0, description="bandwidth ratio α between consecutive levels, "
        "ω_i = ω_p/α^(p−i)", json_schema_extra=unit("1"),
    )
    discretization: Literal["euler", "zoh", "current"] = Field(
        "euler", description='"euler" | "zoh" | "current" (each level as the linear ESO\'s)'
    )


def level_eps(eps: float, levels: int, ratio: float) -> list[float]:
    """ε_i [s] of levels 1 … p (slowest first): ε_i = ε·α^(p−i).

    Parameters
    ----------
    eps : float
        ε of the last (fastest) level [s].
    levels : int
        Number of levels p.
    ratio : float
        Bandwidth ratio α > 1 between consecutive levels [1].

    Returns
    -------
    list of float
        ε_1 … ε_p [s], the last one ``eps``.

    Examples
    --------
    >>> level_eps(0.05, 2, 2.0)
    [0.1, 0.05]
    """
    return [eps * ratio ** (levels - 1 - i) for i in range(levels)]


def design(scn: Scenario, plant: PlantDesign, ts: float) -> ComponentDesign:
    """(CODE, one block per joint: discretization, Ts, b0, Φ, Γ, p, the p gains).

    Each level's gain is the linear ESO's for ε_i (:func:`level_eps`) and the
    scenario's discretization.  State: 3·p per joint.

    Parameters
    ----------
    scn : Scenario
        The validated scenario (its ``[observer]`` table).
    plant : PlantDesign
        The plant's design (n joints, nominal input gains b0 [1/(kg·m²)]).
    ts : float
        Sample period Ts [s].

    Returns
    -------
    ComponentDesign
        The vector above, 3·p·n states.
    """
    obs = scn.observer
    if not isinstance(obs, Params):  # pragma: no cover - the registry dispatches by kind
        raise TypeError("not a cascade observer table")
    blocks = []
    for b0 in plant.b0:
        lin = [design_observer(e, ts, float(b0), obs.discretization)
               for e in level_eps(obs.eps, obs.levels, obs.ratio)]
        head = np.concatenate([[float(lin[0].vector[0]), ts, float(b0)], lin[0].phi.ravel(),
                               lin[0].gamma, [float(obs.levels)]])
        blocks.append(np.concatenate([head, *[d.gain for d in lin]]))
    return ComponentDesign(read_only(np.concatenate([[float(CODE)], *blocks])),
                           3 * obs.levels * plant.n_joints)


# ---------------------------------------------------------------------------
# step functions (one joint per block; the levels in z[base + 3i : base + 3i + 3])


@jitable
def _level_estimate(z: np.ndarray, i: int, m: float, obs: Vector, g: int
                    ) -> tuple[float, float, float]:
    # ẑ of the level whose state starts at z[i] and gain at obs[g]: the state, or for
    # "current" its correction with the level's measurement m
    if obs[DISC] == CURRENT:
        e = m - z[i]
        return z[i] + obs[g] * e, z[i + 1] + obs[g + 1] * e, z[i + 2] + obs[g + 2] * e
    return z[i], z[i + 1], z[i + 2]


@jitable
def _estimate_joint(z: np.ndarray, base: int, y: float, obs: Vector
                    ) -> tuple[float, float, float]:
    levels = int(obs[LEVELS])
    m = y
    w = 0.0
    h1 = h2 = 0.0
    for lv in range(levels):
        h1, h2, h3 = _level_estimate(z, base + 3 * lv, m, obs, GAINS + 3 * lv)
        w += h3
        m = h1
    return h1, h2, w


@jitable
def _advance_joint(z: np.ndarray, base: int, y: float, u: float, obs: Vector) -> None:
    levels = int(obs[LEVELS])
    kind = obs[DISC]
    b0 = obs[B0]
    m = y  # the level's measurement
    w = 0.0  # the perturbation estimated by the slower levels
    for lv in range(levels):
        i = base + 3 * lv
        g = GAINS + 3 * lv
        h1, h2, h3 = _level_estimate(z, i, m, obs, g)
        v = u + w / b0  # the known input, as a torque
        if kind == CURRENT:
            s1, s2, s3 = h1, h2, h3
            c1 = c2 = c3 = 0.0
        else:  # EULER or ZOH: Φ z + Γ v + L (m − z1)
            s1, s2, s3 = z[i], z[i + 1], z[i + 2]
            e = m - z[i]
            c1, c2, c3 = obs[g] * e, obs[g + 1] * e, obs[g + 2] * e
        n1 = obs[PHI] * s1 + obs[PHI + 1] * s2 + obs[PHI + 2] * s3 + obs[GAMMA] * v
        n2 = obs[PHI + 3] * s1 + obs[PHI + 4] * s2 + obs[PHI + 5] * s3 + obs[GAMMA + 1] * v
        n3 = obs[PHI + 6] * s1 + obs[PHI + 7] * s2 + obs[PHI + 8] * s3 + obs[GAMMA + 2] * v
        # the next level uses this level's estimate at k, so take it before overwriting
        m = h1
        w += h3
        z[i] = n1 + c1
        z[i + 1] = n2 + c2
        z[i + 2] = n3 + c3


@jitable
def initialize(z: np.ndarray, y: np.ndarray, p: Vector) -> None:
    """z_0: every level at (y_0, 0, 0) per joint.

    Parameters
    ----------
    z : ndarray, shape (3·p·n,)
        Observer state (joint j's levels in ``z[3pj:3p(j+1)]``, level 1 first), set in place.
    y : ndarray, shape (n,)
        First measured angle(s) y_0 [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then one block per joint
        (:func:`design`).
    """
    obs = p[1:]
    levels = int(obs[LEVELS])
    for j in range(len(y)):
        for lv in range(levels):
            i = 3 * levels * j + 3 * lv
            z[i] = y[j]
            z[i + 1] = 0.0
            z[i + 2] = 0.0


@jitable
def predict(z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray) -> None:
    """A lost sample: the measurement the observer expects, level 1's angle per joint, into ``y``.

    Level 1 is the level the measurement enters (its innovation y − ẑ¹1).

    Parameters
    ----------
    z : ndarray, shape (3·p·n,)
        Observer state z_k of every level (not changed).
    zhat : ndarray, shape (3n,)
        The previous estimate ẑ_{k−1} (unused).
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then one block per joint.
    y : ndarray, shape (n,)
        Output: the predicted angle(s) [rad] (zero innovation).
    """
    levels = int(p[1 + LEVELS])
    for j in range(len(y)):
        y[j] = z[3 * levels * j]


def state_size(params: Params) -> int:
    """States per joint: 3 per level (angle, rate, perturbation of each cascaded ESO).

    Parameters
    ----------
    params : Params
        The kind's validated ``[observer]`` table.

    Returns
    -------
    int
    """
    return 3 * params.levels


@jitable
def estimate(z: np.ndarray, y: np.ndarray, p: Vector, zhat: np.ndarray) -> None:
    """ẑ_k = (ẑᵖ1, ẑᵖ2, Σ_i ẑⁱ3) per joint (module docstring).

    Parameters
    ----------
    z : ndarray, shape (3·p·n,)
        Observer state z_k of every level; not changed.
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then one block per joint
        (:func:`design`).
    zhat : ndarray, shape (3n,)
        Output: ẑ_k, angle [rad], rate [rad/s] and total perturbation [rad/s²] of joint j
        in ``zhat[3j:3j+3]``, written in place.
        The perturbation is f = θ̈ − b0·u (eq. 7): what accelerates θ besides the input.
    """
    if len(y) == 1:
        zhat[0], zhat[1], zhat[2] = _estimate_joint(z, 0, y[0], p[1:])
        return
    vec = np.asarray(p)
    levels = int(vec[1 + LEVELS])
    size = block_size(levels)
    for j in range(len(y)):
        obs = vec[1 + size * j:1 + size * (j + 1)]
        zhat[3 * j], zhat[3 * j + 1], zhat[3 * j + 2] = _estimate_joint(
            z, 3 * levels * j, y[j], obs)


@jitable
def advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray, p: Vector) -> None:
    """z_{k+1} in place: every level, slowest first, with u_k and the estimates at k.

    ``u`` is the plant's observer input (the command for the lever arm); ``zhat``
    is not needed (each level's estimate is recomputed from z_k and y_k).

    Parameters
    ----------
    z : ndarray, shape (3·p·n,)
        Observer state z_k of every level, updated in place to z_{k+1}.
    zhat : ndarray, shape (3n,)
        The estimate ẑ_k (unused).
    y : ndarray, shape (n,)
        Measured angle(s) y_k [rad].
    u : ndarray, shape (n,)
        The observer input u_k as applied (the saturated command [N·m] on the lever arm),
        entering as b0·u [rad/s²].
    p : ndarray or tuple of float
        The design vector; ``p[0]`` is the kind's CODE, then one block per joint
        (:func:`design`).
    """
    if len(y) == 1:
        _advance_joint(z, 0, y[0], u[0], p[1:])
        return
    vec = np.asarray(p)
    levels = int(vec[1 + LEVELS])
    size = block_size(levels)
    for j in range(len(y)):
        obs = vec[1 + size * j:1 + size * (j + 1)]
        _advance_joint(z, 3 * levels * j, y[j], u[j], obs)


# ---------------------------------------------------------------------------
# the observer as one discrete LTI system (esoarm analyze)


def linear_model(scn: Scenario, b0: float, ts: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cascade as z⁺ = P z + Q y + G u, ẑ = Hz z + Hy y (one joint; exact).

    Parameters
    ----------
    scn : Scenario
        With an ``[observer]`` of kind "cascade".
    b0 : float
        Nominal input gain 1/I0 [1/(kg·m²)].
    ts : float
        Sample period [s].

    Returns
    -------
    P (3p, 3p), Q (3p, 1), G (3p, 1), Hz (3, 3p), Hy (3, 1)
        z the 3p states (level 1 first); ẑ = (angle [rad], rate [rad/s],
        perturbation [rad/s²]).
    """
    return _model(scn.observer, b0, ts)


def _model(obs: Params, b0: float, ts: float
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    p = obs.levels
    lin = [design_observer(e, ts, b0, obs.discretization)
           for e in level_eps(obs.eps, p, obs.ratio)]
    n = 3 * p
    phi, gam = lin[0].phi, lin[0].gamma.reshape(3, 1)
    gam_w = gam / b0
    c = np.zeros((1, 3))
    c[0, 0] = 1.0
    pm, qm, gm = np.zeros((n, n)), np.zeros((n, 1)), np.zeros((n, 1))
    # the measurement m_i and known input w_i of each level as (row on z, on y)
    m_z, m_y = np.zeros((1, n)), np.ones((1, 1))
    w_z, w_y = np.zeros((1, n)), np.zeros((1, 1))
    ez, ey = np.zeros((3, n)), np.zeros((3, 1))
    current = lin[0].vector[0] == CURRENT
    for lv, d in enumerate(lin):
        sl = slice(3 * lv, 3 * lv + 3)
        sel = np.zeros((3, n))
        sel[:, sl] = np.eye(3)
        gain = d.gain.reshape(3, 1)
        innov_z = m_z - c @ sel  # m − z1 on z
        if current:
            ez, ey = sel + gain @ innov_z, gain @ m_y
            src_z, src_y = ez, ey
            corr_z, corr_y = np.zeros((3, n)), np.zeros((3, 1))
        else:
            ez, ey = sel, np.zeros((3, 1))
            src_z, src_y = sel, np.zeros((3, 1))
            corr_z, corr_y = gain @ innov_z, gain @ m_y
        pm[sl] = phi @ src_z + gam_w @ w_z + corr_z
        qm[sl] = phi @ src_y + gam_w @ w_y + corr_y
        gm[sl] = gam
        w_z, w_y = w_z + ez[2:3], w_y + ey[2:3]
        m_z, m_y = ez[0:1], ey[0:1]
    hz = np.vstack([ez[0:2], w_z])
    hy = np.vstack([ey[0:2], w_y])
    return pm, qm, gm, hz, hy


# ---------------------------------------------------------------------------
# what the rest of esoarm asks the kind


def label(params: Params) -> str:
    """The observer in titles: ``euler cascade ESO``.

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        The label.
    """
    return f"{params.discretization} cascade ESO"


def summary(params: Params) -> str:
    """One line on the settings: ``ε = 0.09 s (euler)`` (ε of the last level).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.

    Returns
    -------
    str
        ε [s] of the last level and the discretization.
    """
    return f"ε = {params.eps:g} s ({params.discretization})"


def warnings(params: Params, ts: float) -> list[str]:
    """The linear ESO's warnings for the last level's ε at Ts [s].

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.
    ts : float
        Sample period Ts [s].

    Returns
    -------
    list of str
        One-line warnings, empty when the design is fine.
    """
    return observer_warnings(params.eps, ts, params.discretization)


def linearization(params: Params, ts: float, b0: float) -> ObserverLinearization:
    """The cascade as one discrete LTI system for ``analyze`` (exact; :func:`linear_model`).

    Parameters
    ----------
    params : Params
        The ``[observer]`` table.
    ts : float
        Sample period Ts [s].
    b0 : float
        Input gain 1/I0 [1/(kg·m²)].

    Returns
    -------
    ObserverLinearization
        Its pole is the spectral radius of P.
    """
    pm, qm, gm, hz, hy = _model(params, b0, ts)
    pole = float(np.max(np.abs(np.linalg.eigvals(pm))))
    return ObserverLinearization(pm, qm, gm, hz, hy, pole, params.eps, params.discretization,
                                 "cascade ESO")
