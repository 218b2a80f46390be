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


def test_a_pid_controller_has_no_k1_k2_and_the_other_causes_still_count():
    scn = load_scenario("test-1", {"controller.kind": "pid", "observer.eps": 0.005})
    assert divergence_causes(scn, LIMIT)[0].startswith("observer.eps = 0.005 s")


@pytest.mark.parametrize("name", ["test-1", "test-2"])
def test_nothing_stands_out_in_the_builtins(name):
    assert divergence_causes(load_scenario(name), LIMIT) == []


def test_what_left_names_the_first_quantity_out_of_range():
    assert what_left(2e6, 0.0, 0.0, 0.0, 0.0, LIMIT) == "the angle θ = 2e+06 rad"
    assert what_left(0.0, 3e6, 0.0, 0.0, 0.0, LIMIT).startswith("the angle estimate ẑ1")
    assert what_left(0.0, 0.0, math.inf, 0.0, 0.0, LIMIT).startswith("the rate estimate ẑ2")
    assert what_left(0.0, 0.0, 0.0, math.nan, 0.0, LIMIT).startswith("the perturbation")
    assert what_left(0.0, 0.0, 0.0, 0.0, math.nan, LIMIT).startswith("the control u")


@pytest.mark.parametrize(
    ("overrides", "left", "cause"),
    [
        ({"rig.theta0": 1e9}, "the angle θ = 1e+09 rad", "rig.theta0"),
        ({"sensor.noise_deg": 1e9}, "the angle estimate ẑ1", "sensor.noise_deg"),
        ({"rig.disturbance.amplitude": 1e12}, "the angle θ", "rig.disturbance.amplitude"),
        ({"observer.eps": 0.005}, "ẑ1", "observer.eps = 0.005 s"),
        ({"plant.inertia": 1e-300}, "", "plant.inertia"),  # cos(inf) inside a step
    ],
    ids=["theta0", "noise", "disturbance", "eps", "overflow-inside-a-step"],
)
def test_a_diverged_run_says_what_and_why(overrides, left, cause):
    from esoarm.engines.simulation import SimulationDiverged, simulate

    with pytest.raises(SimulationDiverged) as info:
        simulate(load_scenario("test-1", {**overrides, "duration": 2.0}), warn=False)
    msg = str(info.value)
    assert "\n" not in msg and left in msg and f"likely cause: {cause}" in msg, msg
    assert "check observer.eps" not in msg or cause.startswith("observer.eps")
    assert len(info.value.result.t) >= 1


def test_cli_warns_when_the_command_is_saturated_most_of_the_run(run_cli):
    res = run_cli("simulate", "test-1", "--set", "actuator.torque_limit=0.05", "--json")
    assert res.exit_code == 0
    assert "sat at the torque limit ±0.05 N·m in 57.5 % of the samples" in res.stderr
    import json

    assert json.loads(res.stdout)["saturated_fraction"] == pytest.approx(0.575)
    calm = run_cli("simulate", "test-1", "--json")
    assert "torque limit" not in calm.stderr


def test_a_diverged_pid_run_is_a_one_line_failure_not_an_internal_error():
    from click.testing import CliRunner

    from esoarm.cli import cli

    res = CliRunner().invoke(cli, ["simulate", "test-1", "--set", "controller.kind=pid",
                                   "--set", "observer.eps=0.004", "--set", "duration=2",
                                   "--quiet"])
    assert res.exit_code == 1, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "diverged" in lines[0] and "observer.eps = 0.004 s" in lines[0]


def test_saturation_warning_does_not_round_up_to_all_samples():
    """0.995 was shown as '100 %' beside saturated_fraction = 0.995."""
    from esoarm.engines.diagnosis import saturation_warning

    assert "in 99.5 % of the samples" in saturation_warning(0.995, 0.001)
    assert "in 100 % of the samples" in saturation_warning(1.0, 0.001)
    assert saturation_warning(0.2, 1.0) is None


def test_saturation_warning_names_no_particular_controller():
    """The warning serves every controller kind (PID too), so it does not say "FLC"."""
    from esoarm.engines.diagnosis import saturation_warning

    text = saturation_warning(0.9, 0.5)
    assert text is not None and "FLC" not in text
    assert "the controller was designed for" in text
