"""Reference trajectories θd(t) with their first two derivatives.

Both kinds are evaluated on whole time grids with NumPy (every engine
precomputes the reference at t_k = k·Ts, so all engines see identical values).

``quintic-steps``
    Rest-to-rest moves: move i starts at ``t0`` and lasts ``T``, from the
    previous target (or ``start``) to its ``target``, along the quintic
    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = (t − t0)/T; the angle is held between moves.
``multisine``
    θd(t) = offset + Σ aᵢ sin(ωᵢ t + φᵢ), ωᵢ in rad/s.

For an arm of n joints (:func:`reference_rows`) one of the above drives every
joint, and two more kinds exist:

``per-joint``
    one quintic-steps or multisine reference per joint, in URDF order;
``range``
    quintic-steps of every joint at once through its limits: position p is
    mid + p · fraction · half of the joint's range [lower, upper].
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from esoarm._schema import Section as _Section
from esoarm._schema import unit as _unit

__all__ = ["REFERENCE_KINDS", "Multisine", "PerJoint", "QuinticSteps", "RangeMoves", "Reference",
           "evaluate_reference", "joint_count", "needs_limits", "reference_rows"]


# ---------------------------------------------------------------------------
# the scenario's [reference] table: one model per kind

class QuinticSteps(_Section):
    """Rest-to-rest quintic moves, the angle held between moves."""

    kind: Literal["quintic-steps"] = "quintic-steps"
    start: float = Field(
        0.0, description="angle before the first move", json_schema_extra=_unit("rad")
    )
    moves: list[list[float]] = Field(
        default_factory=lambda: [[1.0, 2.0, 1.0], [10.0, 2.0, 0.0]],
        description="[start s, duration s, target rad] per move, in time order",
    )


class Multisine(_Section):
    """θd(t) = offset + Σ amplitudes[i] · sin(frequencies[i] · t + phases[i])."""

    kind: Literal["multisine"] = "multisine"
    amplitudes: list[float] = Field(
        default_factory=lambda: [0.5], description="amplitudes", json_schema_extra=_unit("rad")
    )
    frequencies: list[float] = Field(
        default_factory=lambda: [0.5], description="angular frequencies",
        json_schema_extra=_unit("rad/s"),
    )
    phases: list[float] = Field(
        default_factory=list, description="phases (empty: all zero)", json_schema_extra=_unit("rad")
    )
    offset: float = Field(0.0, description="constant offset", json_schema_extra=_unit("rad"))


class RangeMoves(_Section):
    """An arm's joints through their limits: rest-to-rest quintic moves, all joints at once.

    Positions are fractions of each joint's half range around its middle:
    position p of joint j is mid_j + p · fraction · half_j (needs joint limits).
    """

    kind: Literal["range"] = "range"
    fraction: float = Field(0.75, gt=0, le=1, description="share of each joint's half range used",
                            json_schema_extra=_unit("1"))
    start: float = Field(0.0, ge=-1, le=1, description="position before the first move (−1…1)",
                         json_schema_extra=_unit("1"))
    moves: list[list[float]] = Field(
        default_factory=lambda: [[1.0, 3.0, 1.0], [8.0, 3.0, -1.0], [15.0, 3.0, 0.0]],
        description="[start s, duration s, position −1…1] per move, in time order",
    )


SingleReference = Annotated[QuinticSteps | Multisine, Field(discriminator="kind")]


class PerJoint(_Section):
    """One reference per joint of an arm, in URDF order."""

    kind: Literal["per-joint"] = "per-joint"
    joints: list[SingleReference] = Field(
        default_factory=lambda: [QuinticSteps()],  # type: ignore[arg-type]
        min_length=1,
        description="one [[reference.joints]] table (quintic-steps or multisine) per joint",
    )


Reference = Annotated[QuinticSteps | Multisine | RangeMoves | PerJoint,
                      Field(discriminator="kind")]

#: The ``[reference]`` table's kinds (the scenario's tagged union :data:`Reference`).
REFERENCE_KINDS = (QuinticSteps, Multisine, RangeMoves, PerJoint)


# ---------------------------------------------------------------------------
# evaluation


def _quintic_steps(
    ref: QuinticSteps, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.full_like(t, ref.start)
    vel = np.zeros_like(t)
    acc = np.zeros_like(t)
    previous = ref.start
    for t0, dur, target in ref.moves:
        delta = target - previous
        after = t >= t0 + dur
        pos[after] = target
        vel[after] = 0.0
        acc[after] = 0.0
        during = (t >= t0) & ~after
        s = (t[during] - t0) / dur
        s2 = s * s
        pos[during] = previous + delta * s2 * s * (10.0 - 15.0 * s + 6.0 * s2)
        vel[during] = delta * 30.0 * s2 * (1.0 - 2.0 * s + s2) / dur
        acc[during] = delta * 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2) / (dur * dur)
        previous = target
    return pos, vel, acc


def _multisine(ref: Multisine, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos = np.full_like(t, ref.offset)
    vel = np.zeros_like(t)
    acc = np.zeros_like(t)
    phases = ref.phases or [0.0] * len(ref.amplitudes)
    for a, w, phi in zip(ref.amplitudes, ref.frequencies, phases, strict=True):
        arg = w * t + phi
        sin, cos = np.sin(arg), np.cos(arg)
        pos += a * sin
        vel += a * w * cos
        acc -= a * w * w * sin
    return pos, vel, acc


def evaluate_reference(
    ref: QuinticSteps | Multisine, t: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference angle θd [rad], rate θ̇d [rad/s] and acceleration θ̈d [rad/s²].

    Parameters
    ----------
    ref : QuinticSteps or Multisine
        The scenario's ``reference`` section.
    t : array_like
        Times [s].

    Returns
    -------
    (ndarray, ndarray, ndarray)
        θd [rad], θ̇d [rad/s], θ̈d [rad/s²], each of the shape of ``t`` (at least 1-D).

    Examples
    --------
    >>> from esoarm.reference import Multisine
    >>> pos, vel, acc = evaluate_reference(Multisine(amplitudes=[1.0], frequencies=[2.0]), 0.0)
    >>> float(pos[0]), float(vel[0]), float(acc[0])
    (0.0, 2.0, 0.0)
    """
    t_arr = np.atleast_1d(np.asarray(t, dtype=float))
    if isinstance(ref, QuinticSteps):
        return _quintic_steps(ref, t_arr)
    return _multisine(ref, t_arr)


def joint_count(ref: object) -> int | None:
    """Joints a reference is written for (``per-joint``), None if it fits any number.

    Parameters
    ----------
    ref : reference section
        Any ``[reference]`` kind.

    Returns
    -------
    int or None
        The number of ``[[reference.joints]]`` tables of a ``per-joint`` reference, else None.
    """
    return len(ref.joints) if isinstance(ref, PerJoint) else None


def needs_limits(ref: object, n_joints: int) -> list[int]:
    """Joints whose reference is defined by their limits (all of them for ``range``).

    Parameters
    ----------
    ref : reference section
        Any ``[reference]`` kind.
    n_joints : int
        Joints of the plant.

    Returns
    -------
    list of int
        Joint indices (0-based) whose position limits the reference needs.
    """
    return list(range(n_joints)) if isinstance(ref, RangeMoves) else []


def reference_rows(ref: object, t: np.ndarray, n_joints: int,
                   limits: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """θd, θ̇d, θ̈d of every joint as rows 3j, 3j+1, 3j+2 of a (3·n, N) array.

    Parameters
    ----------
    ref : reference section
        Any reference kind; a single quintic-steps or multisine drives every joint.
    t : ndarray (N,)
        Sample times [s].
    n_joints : int
        Joints n.
    limits : (lower, upper), optional
        Joint position limits [rad or m], needed by the ``range`` kind.

    Returns
    -------
    ndarray, shape (3·n, N)
        θd [rad or m], θ̇d, θ̈d of joint j in rows 3j, 3j+1, 3j+2.

    Raises
    ------
    ValueError
        A ``range`` reference without ``limits``.
    """
    if isinstance(ref, PerJoint):
        parts = [np.stack(evaluate_reference(r, t)) for r in ref.joints]
    elif isinstance(ref, RangeMoves):
        if limits is None:
            raise ValueError("reference kind 'range' needs joint limits")
        lower, upper = limits
        parts = []
        for j in range(n_joints):
            mid = 0.5 * (float(lower[j]) + float(upper[j]))
            half = 0.5 * (float(upper[j]) - float(lower[j])) * ref.fraction
            steps = QuinticSteps(start=mid + ref.start * half,
                                 moves=[[t0, dur, mid + pos * half] for t0, dur, pos in ref.moves])
            parts.append(np.stack(evaluate_reference(steps, t)))
    else:
        one = np.stack(evaluate_reference(ref, t))  # type: ignore[arg-type]
        parts = [one] * n_joints
    return np.concatenate(parts, axis=0)
