"""A diverged run says what left the range and names the likely causes from the scenario."""

from __future__ import annotations

import math

import pytest

from esoarm.engines.diagnosis import divergence_causes, what_left
from esoarm.scenario import load_scenario

LIMIT = 1e6


@pytest.mark.parametrize(
    ("overrides", "cause"),
    [
        ({"rig.theta0": 1e9}, "rig.theta0 = 1e+09 rad"),
        ({"sensor.noise_deg": 1e9}, "sensor.noise_deg = 1e+09"),
        ({"rig.disturbance.amplitude": 1e12}, "rig.disturbance.amplitude = 1e+12"),
        ({"observer.eps": 0.005}, "observer.eps = 0.005 s, an unstable observer"),
        ({"rig.inertia_scale": 100.0}, "rig.inertia_scale = 100"),
        ({"controller.k1": 500.0}, "controller.k1 = 500"),
    ],
    ids=["theta0", "noise", "disturbance", "eps", "inertia", "gains"],
)
def test_the_likely_cause_is_named(overrides, cause):
    causes = divergence_causes(load_scenario("test-1", overrides), LIMIT)
    assert causes and causes[0].startswith(cause), causes


@pytest.mark.parametrize("name", ["test-1", "test-2"])
def test_nothing_stands_out_in_the_builtins(name):
    assert divergence_causes(load_scenario(name), LIMIT) == []


def test_what_left_names_the_first_quantity_out_of_range():
    assert what_left(2e6, 0.0, 0.0, 0.0, 0.0, LIMIT) == "the angle θ = 2e+06 rad"
    assert what_left(0.0, 3e6, 0.0, 0.0, 0.0, LIMIT).startswith("the angle estimate ẑ1")
    assert what_left(0.0, 0.0, math.inf, 0.0, 0.0, LIMIT).startswith("the rate estimate ẑ2")
    assert what_left(0.0, 0.0, 0.0, math.nan, 0.0, LIMIT).startswith("the perturbation")
    assert what_left(0.0, 0.0, 0.0, 0.0, math.nan, LIMIT).startswith("the control u")
