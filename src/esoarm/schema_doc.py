"""Reference tables generated from the scenario schema (README, docs).

Generating them keeps the documentation from drifting: the tests compare the
README's table with :func:`scenario_keys_markdown`.  Regenerate with
``python -m esoarm.schema_doc``.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from esoarm.scenario import Multisine, QuinticSteps, Scenario

__all__ = ["scenario_keys", "scenario_keys_markdown"]


def _fmt(value: Any) -> str:
    if isinstance(value, str):
        return f'`"{value}"`'
    return f"`{value!r}`"


def scenario_keys() -> list[tuple[str, str, str, str]]:
    """(dotted key, default, unit, description) for every scenario key."""
    rows: list[tuple[str, str, str, str]] = []

    def walk(model: type[BaseModel], instance: BaseModel, prefix: str) -> None:
        for name, field in model.model_fields.items():
            value = getattr(instance, name)
            if isinstance(value, BaseModel) and not isinstance(value, QuinticSteps | Multisine):
                walk(type(value), value, prefix + name + ".")
                continue
            if isinstance(value, QuinticSteps | Multisine):
                continue
            if value is None and name == "motor":  # optional table, absent by default
                from esoarm.scenario import Motor

                rows.append(("motor", "absent", "", (field.description or "")
                             + "; give a `[motor]` table to enable it, with these defaults:"))
                walk(Motor, Motor(), "motor.")
                continue
            extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
            rows.append((prefix + name, _fmt(value), str(extra.get("unit", "")),
                         field.description or ""))

    walk(Scenario, Scenario(), "")
    for ref in (QuinticSteps(), Multisine()):
        for name, field in type(ref).model_fields.items():
            extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
            desc = field.description or ""
            if name == "kind":
                if isinstance(ref, Multisine):
                    continue
                rows.append(("reference.kind", _fmt(ref.kind), "",
                             "`quintic-steps` (default) or `multisine`; the keys below"
                             " belong to one kind each"))
                continue
            rows.append((f"reference.{name}", _fmt(getattr(ref, name)),
                         str(extra.get("unit", "")), f"({ref.kind}) {desc}"))
    return rows


def scenario_keys_markdown() -> str:
    """The scenario keys as a Markdown table."""
    lines = ["| key | default | unit | meaning |", "|---|---|---|---|"]
    for key, default, unit, desc in scenario_keys():
        lines.append(f"| `{key}` | {default} | {unit} | {desc.replace('|', chr(92) + '|')} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(scenario_keys_markdown(), end="")
