"""esoarm: ESO-based feedback-linearization control of a robotic lever arm.

Quick start::

    import esoarm
    result = esoarm.simulate("test-1", {"observer.eps": 0.05})
    print(result.metrics)
    result.plot("run.png")
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from esoarm._cache import configure_numba

# numba caches esoarm's kernels on disk: give it a writable place (before it is imported)
# when neither the installed sources nor the home directory can be written
configure_numba()

if TYPE_CHECKING:
    from esoarm.engines.simulation import SimulationDiverged, simulate
    from esoarm.result import SimResult
    from esoarm.scenario import Scenario, ScenarioError, builtin_names, load_scenario

__version__ = "0.1.0"

# Imported on first use (PEP 562), so that ``import esoarm`` -- and every
# ``esoarm`` command -- starts without loading NumPy, pydantic or numba.
_LAZY = {
    "SimulationDiverged": "esoarm.engines.simulation",
    "simulate": "esoarm.engines.simulation",
    "SimResult": "esoarm.result",
    "Scenario": "esoarm.scenario",
    "ScenarioError": "esoarm.scenario",
    "builtin_names": "esoarm.scenario",
    "load_scenario": "esoarm.scenario",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'esoarm' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])

__all__ = [
    "Scenario",
    "ScenarioError",
    "SimResult",
    "SimulationDiverged",
    "__version__",
    "builtin_names",
    "load_scenario",
    "simulate",
]
