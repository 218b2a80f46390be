"""Consumers that compare kinds ask the registry which kinds declare a flag (issue 31).

``identify`` takes the axis fit where the plant declares ``AXIS_FIT``; ``analyze
--bandwidth`` compares the observer kinds that declare ``NOISE_BUDGET`` against the one
that declares ``BASELINE``.  A kind registered with a flag is picked up without editing
the consumer; a second ``BASELINE`` is refused at registration.
"""

from __future__ import annotations

import types

import pytest

from esoarm import kinds
from esoarm.observers import linear
from esoarm.scenario import load_scenario
from kinds_extra import reduced


def _with(module: types.ModuleType, **flags: object) -> types.ModuleType:
    out = types.ModuleType(module.__name__)
    for attr in dir(module):
        if not attr.startswith("__"):
            setattr(out, attr, getattr(module, attr))
    out.__file__ = module.__file__
    for name, value in flags.items():
        setattr(out, name, value)
    return out


def test_the_package_kinds_flags() -> None:
    assert kinds.having("observer", "NOISE_BUDGET") == ("linear", "cascade")
    assert kinds.baseline_observer() == "linear"
    assert kinds.having("plant", "AXIS_FIT") == ("axis",)
    assert kinds.can(load_scenario("emps"), "AXIS_FIT")
    assert not kinds.can(load_scenario("test-1"), "AXIS_FIT")
    assert kinds.can(load_scenario("test-1"), "NOISE_BUDGET")
    assert not kinds.can(load_scenario("test-1", {"observer.kind": "nonlinear"}),
                         "NOISE_BUDGET")
    with pytest.raises(KeyError):
        kinds.having("plant", "NOISE_BUDGET")  # an observer's flag


def test_a_registered_kind_with_the_flag_is_compared_without_editing_the_consumer() -> None:
    from esoarm.studies.frequency.noise import recommend_eps

    flagged = _with(reduced, NOISE_BUDGET=True)
    kinds.register("observer", flagged)
    try:
        assert kinds.having("observer", "NOISE_BUDGET") == ("linear", "cascade", "reduced")
        why: list[str] = []
        recs = recommend_eps(load_scenario("test-1"), 10.0, why=why)
        named = {r.kind for r in recs} | {w.partition(":")[0] for w in why}
        assert named == {"linear", "cascade", "reduced"}, (recs, why)
    finally:
        kinds.unregister("observer", flagged)
    assert kinds.having("observer", "NOISE_BUDGET") == ("linear", "cascade")


def test_a_second_baseline_is_refused_in_one_line() -> None:
    with pytest.raises(ImportError, match=r"BASELINE = True is esoarm\.observers\.linear's"):
        kinds.register("observer", _with(reduced, BASELINE=True))
    assert kinds.baseline_observer() == "linear"
    assert linear.BASELINE is True


def test_a_flag_that_is_not_a_bool_is_refused() -> None:
    with pytest.raises(ImportError, match="NOISE_BUDGET must be True or False"):
        kinds.register("observer", _with(reduced, NOISE_BUDGET="yes"))
