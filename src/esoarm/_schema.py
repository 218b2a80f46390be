"""Base pieces of the scenario schema, shared by the scenario and by every kind module.

A kind module (a plant, an observer, a controller) declares its validated
parameters as a :class:`Section` with a ``kind`` literal; the scenario puts the
registered kinds together as a tagged union (see :mod:`esoarm.kinds`).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict
from pydantic.json_schema import JsonDict

__all__ = ["PER_JOINT_KEYS", "Section", "joint_values", "show_joint_values", "unit"]

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
