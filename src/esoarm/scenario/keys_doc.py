"""Reference tables generated from the scenario schema (README, docs).

Generating them keeps the documentation from drifting: the tests compare the
README's table with :func:`scenario_keys_markdown`.  Regenerate with
``python -m esoarm.scenario.keys_doc``.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from esoarm.scenario import Scenario

__all__ = ["scenario_keys", "scenario_keys_markdown"]


def _fmt(value: Any) -> str:
    if isinstance(value, str):
        return f'`"{value}"`'
    return f"`{value!r}`"


def _unit_of(field: Any) -> str:
    extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
    return str(extra.get("unit", ""))


def _kind_rows(section: str, models: tuple[type[BaseModel], ...]) -> list[tuple[str, ...]]:
    """Rows of a section whose keys depend on its ``kind`` (the default kind first)."""
    rows: list[tuple[str, ...]] = []
    names = [m.model_fields["kind"].default for m in models]
    several = len(models) > 1
    kinds_text = " or ".join(f"`{n}`" + (" (default)" if i == 0 and several else "")
                             for i, n in enumerate(names))
    rows.append((f"{section}.kind", _fmt(names[0]), "",
                 f"{kinds_text}" + ("; the keys below belong to one kind each" if several
                                    else "")))
    for model in models:
        inst = model()
        tag = model.model_fields["kind"].default
        for name, field in model.model_fields.items():
            if name == "kind":
                continue
            desc = field.description or ""
            rows.append((f"{section}.{name}", _fmt(getattr(inst, name)), _unit_of(field),
                         f"({tag}) {desc}" if several else desc))
    return rows


def scenario_keys() -> list[tuple[str, str, str, str]]:
    """(dotted key, default, unit, description) for every scenario key.

    Returns
    -------
    list of (str, str, str, str)
        One row per key, in the order of the schema; kind tables list every kind's keys.
    """
    from esoarm.scenario.schema import KIND_SECTIONS

    rows: list[tuple[str, str, str, str]] = []

    def walk(model: type[BaseModel], instance: BaseModel, prefix: str) -> None:
        for name, field in model.model_fields.items():
            value = getattr(instance, name)
            if not prefix and name in KIND_SECTIONS:
                rows.extend(_kind_rows(name, KIND_SECTIONS[name]))  # type: ignore[arg-type]
                continue
            if isinstance(value, BaseModel):
                walk(type(value), value, prefix + name + ".")
                continue
            if value is None and name == "motor":  # optional table, absent by default
                from esoarm.scenario.schema import Motor

                rows.append(("motor", "absent", "", (field.description or "")
                             + "; give a `[motor]` table to enable it, with these defaults:"))
                walk(Motor, Motor(), "motor.")
                continue
            rows.append((prefix + name, _fmt(value), _unit_of(field), field.description or ""))

    walk(Scenario, Scenario(), "")
    return rows


def scenario_keys_markdown() -> str:
    """The scenario keys as a Markdown table.

    Returns
    -------
    str
        A Markdown table (key, default, unit, meaning), one row per key, ending in a newline.
    """
    lines = ["| key | default | unit | meaning |", "|---|---|---|---|"]
    for key, default, unit, desc in scenario_keys():
        lines.append(f"| `{key}` | {default} | {unit} | {desc.replace('|', chr(92) + '|')} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(scenario_keys_markdown(), end="")
