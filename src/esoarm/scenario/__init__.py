"""Scenario files: the validated, immutable description of one closed-loop run.

A scenario is a TOML file (the scenario format).  Every key has a default; a file gives only
what differs.  Built-in scenarios ship in ``esoarm/scenarios/*.toml`` and are
addressed by name.  Validation happens here, once, at the edge: the numerics
trust a :class:`Scenario`.

Errors are raised as :class:`ScenarioError`, whose message is one line naming
the offending key or file and what is allowed.  Risky but legal settings give
:class:`ScenarioWarning` (see :func:`scenario_warnings`).
"""

from __future__ import annotations

from esoarm._limits import MAX_RUNS, MAX_SAMPLES
from esoarm._toml import to_toml
from esoarm.scenario.checks import scenario_warnings, timing_warnings
from esoarm.scenario.errors import ScenarioError, ScenarioWarning
from esoarm.scenario.loading import builtin_names, load_scenario
from esoarm.scenario.schema import Scenario, parse_override

__all__ = [
    "MAX_RUNS",
    "MAX_SAMPLES",
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "builtin_names",
    "load_scenario",
    "parse_override",
    "scenario_warnings",
    "timing_warnings",
    "to_toml",
]
