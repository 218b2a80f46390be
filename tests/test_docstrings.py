"""numpydoc habits, held by a test: every public function of the covered modules documents
each of its parameters under ``Parameters`` and what it gives back under ``Returns``.

A function documents a parameter when its name starts a line of the ``Parameters`` section
(``name : type``; ``*args``/``**kwargs`` as such). A function returning None, a property and a
dunder need no ``Returns``. The covered modules grow as they are documented: the public API
(scenario, reference, result, analysis) and the kinds and engines.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest

COVERED = [
    "esoarm.scenario.checks",
    "esoarm.scenario.keys_doc",
    "esoarm.scenario.loading",
    "esoarm.scenario.schema",
    "esoarm.reference",
    "esoarm.result",
    "esoarm.observers.stability",
    "esoarm.observers.cascade",
    "esoarm.observers.linear",
    "esoarm.observers.nonlinear",
    "esoarm.controllers.computed_torque",
    "esoarm.engines.batch",
    "esoarm.engines.diagnosis",
    "esoarm.engines.fast",
    "esoarm.engines.loop",
    "esoarm.engines.metrics",
    "esoarm.engines.packing",
    "esoarm.engines.sample",
    "esoarm.engines.simulation",
    "esoarm.controllers.flc",
    "esoarm.controllers.pid",
    "esoarm.kinds",
    "esoarm.contract",
    "esoarm.plants.actuator",
    "esoarm.plants.axis",
    "esoarm.plants.elementary",
    "esoarm.plants.lever_arm",
    "esoarm.plants.model",
    "esoarm.plants.motor",
    "esoarm.plants.arms.rigid_body",
    "esoarm.plants.sensor",
    "esoarm.plants.arms.urdf",
    "esoarm.plants.arms.compiled",
    "esoarm.plants.arms.model",
    "esoarm.plants.arms.twin",
]


def _public_functions(module_name: str) -> list[tuple[str, object]]:
    module = importlib.import_module(module_name)
    out: list[tuple[str, object]] = []
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module_name:
            continue
        if inspect.isfunction(obj):
            out.append((name, obj))
        elif inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                func = member.__func__ if isinstance(member, classmethod | staticmethod) \
                    else member
                if inspect.isfunction(func) and func.__qualname__.startswith(obj.__name__ + "."):
                    out.append((f"{name}.{attr}", func))
    return out


def _section(doc: str, title: str) -> str | None:
    match = re.search(rf"^{title}\n-+\n(.*?)(?=^\S[^\n]*\n-+\n|\Z)", doc, flags=re.M | re.S)
    return match.group(1) if match else None


def problems(func: object) -> list[str]:
    """What the docstring of ``func`` lacks, one phrase each (empty: complete)."""
    doc = inspect.cleandoc(func.__doc__ or "")  # type: ignore[attr-defined]
    if not doc:
        return ["no docstring"]
    out = []
    sig = inspect.signature(func)  # type: ignore[arg-type]
    names = []
    for p in sig.parameters.values():
        if p.name in ("self", "cls"):
            continue
        prefix = {inspect.Parameter.VAR_POSITIONAL: "*",
                  inspect.Parameter.VAR_KEYWORD: "**"}.get(p.kind, "")
        names.append(prefix + p.name)
    if names:
        params = _section(doc, "Parameters")
        if params is None:
            out.append("no Parameters section")
        else:
            listed = {re.split(r"\s*:", line, maxsplit=1)[0].strip()
                      for line in params.splitlines() if line and not line[0].isspace()}
            listed = {n for item in listed for n in re.split(r",\s*", item)}
            out.extend(f"parameter '{n}' not documented" for n in names if n not in listed)
    annotation = sig.return_annotation
    returns_none = annotation in (None, "None", inspect.Signature.empty)
    if not returns_none and _section(doc, "Returns") is None and _section(doc, "Yields") is None:
        out.append("no Returns section")
    return out


@pytest.mark.parametrize("module_name", COVERED)
def test_public_functions_have_parameters_and_returns(module_name: str) -> None:
    bad = {name: p for name, func in _public_functions(module_name) if (p := problems(func))}
    assert not bad, f"{module_name}: " + "; ".join(f"{n}: {', '.join(p)}" for n, p in bad.items())


def test_the_check_sees_a_missing_parameter() -> None:
    def documented(a: int, b: int) -> int:
        """Sum.

        Parameters
        ----------
        a : int
            One.

        Returns
        -------
        int
            The sum.
        """
        return a + b

    assert problems(documented) == ["parameter 'b' not documented"]
