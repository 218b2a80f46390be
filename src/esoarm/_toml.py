"""A small TOML writer for nested dicts of scalars and lists (scenarios, fitted twins).

Tables are written as ``[section]`` headers; a table inside a list (the per-joint
references ``reference.joints``) as an inline table ``{kind = "multisine", ...}``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["to_toml"]


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        # control characters are not allowed raw in a TOML string: \uXXXX
        escaped = "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c
                          for c in escaped)
        return f'"{escaped}"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):  # a table inside a list (reference.joints): an inline table
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()
                               if v is not None) + "}"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def to_toml(data: dict[str, Any], _prefix: str = "") -> str:
    """Write nested dicts of scalars and lists as TOML text (tables last)."""
    lines: list[str] = []
    tables = []
    for key, value in data.items():
        if value is None:  # an absent optional section (e.g. [motor])
            continue
        if isinstance(value, dict):
            tables.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, value in tables:
        name = f"{_prefix}{key}"
        body = to_toml(value, name + ".")
        lines.append("")
        lines.append(f"[{name}]")
        lines.append(body.rstrip("\n"))
    return "\n".join(line for line in lines).lstrip("\n") + "\n"
