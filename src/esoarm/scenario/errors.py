"""The scenario's error and warning classes (one line naming the key or file)."""

from __future__ import annotations

__all__ = ["ScenarioError", "ScenarioWarning"]


class ScenarioError(ValueError):
    """Bad scenario input: the message is one line naming the key or file."""


class ScenarioWarning(UserWarning):
    """A legal but risky scenario setting (e.g. an observer too fast for Ts)."""


# Shown as esoarm.scenario.ScenarioError, where users import them from.
ScenarioError.__module__ = ScenarioWarning.__module__ = "esoarm.scenario"
