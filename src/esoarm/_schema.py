"""Base pieces of the scenario schema, shared by the scenario and by every kind module.

A kind module (a plant, an observer, a controller) declares its validated
parameters as a :class:`Section` with a ``kind`` literal; the scenario puts the
registered kinds together as a tagged union (see :mod:`esoarm.kinds`).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import JsonDict

__all__ = ["PER_JOINT_KEYS", "Actuator", "Section", "joint_values", "show_joint_values", "unit"]

#: Observer and controller keys that may be one number or a list of one per joint.
PER_JOINT_KEYS = ("eps", "k1", "k2")


class Section(BaseModel):
    """A scenario table: immutable, strict types, no unknown keys, no NaN or inf."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def unit(symbol: str) -> JsonDict:
    """``json_schema_extra`` carrying a field's SI unit (shown in the docs)."""
    return {"unit": symbol}


def joint_values(value: float | list[float]) -> list[float]:
    """A key that is one number or one per joint, as a list (``0.02`` → ``[0.02]``)."""
    return [float(v) for v in value] if isinstance(value, list) else [float(value)]


def show_joint_values(value: float | list[float]) -> str:
    """``0.02`` or, per joint, ``[0.015, 0.02]`` (numbers as ``:g``) for messages."""
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"


class Actuator(Section):
    """Torque saturation, PWM resolution, first-order lag and transport delay (the
    scenario's ``[actuator]``; here, below the kinds, because a kind's ``design`` reads it
    and the registration check designs with its defaults)."""

    torque_limit: float = Field(
        2.0, gt=0, description="saturation |u| ≤ torque_limit", json_schema_extra=unit("N·m")
    )
    lag: float = Field(
        0.0, ge=0, description="first-order lag time constant T (0: none)",
        json_schema_extra=unit("s"),
    )
    delay_samples: int = Field(
        0, ge=0, description="transport delay in samples", json_schema_extra=unit("samples")
    )
    pwm_bits: int = Field(
        0, ge=0, le=16, description="resolution of the PWM drive (0: an ideal torque source): "
        "the torque is rounded to torque_limit·m/(2^bits − 1), sign and magnitude, e.g. 8 for "
        "Arduino analogWrite; with a [motor] table use motor.pwm_max instead",
        json_schema_extra=unit("bits"),
    )
    stop_gate: float = Field(
        0.0, ge=0, description="gate the ESO's b0·u term (the observer fed 0) while the "
        "measured angle is within this distance of a rig.end_stops stop and the command "
        "pushes into it, so that z3 does not wind up against the stop (0: no gate)",
        json_schema_extra=unit("rad"),
    )
    observer_sees: Literal["applied", "commanded"] = Field(
        "applied", description='what the ESO is fed: "applied" the saturated command the '
        'actuator applies (anti-windup) | "commanded" the controller\'s command before '
        "saturation (the paper's ESO, which winds up while the command saturates)",
    )
