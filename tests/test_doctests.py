"""The Examples sections of the numpydoc docstrings are run (doctest) over the whole package."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import esoarm

# __main__ runs the command line when imported
MODULES = sorted(m.name for m in pkgutil.walk_packages(esoarm.__path__, "esoarm.")
                 if not m.name.endswith("__main__"))


def _has_examples(name: str) -> bool:
    try:
        module = importlib.import_module(name)
    except ImportError:  # an optional dependency (its tests skip the same way)
        return False
    return any(t.examples for t in doctest.DocTestFinder().find(module))


@pytest.mark.parametrize("name", [m for m in MODULES if _has_examples(m)])
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"


def test_examples_exist() -> None:
    """The public entry points and the contract's kinds carry runnable examples."""
    names = [m for m in MODULES if _has_examples(m)]
    for expected in ("esoarm.scenario.loading", "esoarm.engines.simulation",
                     "esoarm.engines.metrics", "esoarm.observers.nonlinear",
                     "esoarm.controllers.pid", "esoarm.kinds"):
        assert expected in names
