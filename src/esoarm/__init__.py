"""esoarm: ESO-based feedback-linearization control of a robotic lever arm.

Quick start::

    import esoarm
    result = esoarm.simulate("test-1", {"observer.eps": 0.05})
    print(result.metrics)
    result.plot("run.png")
"""

from esoarm.engines.simulation import SimulationDiverged, simulate
from esoarm.result import SimResult
from esoarm.scenario import Scenario, ScenarioError, builtin_names, load_scenario

__version__ = "0.1.0"

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
