"""The twin's position-periodic torque (rig.cogging) and the learned feedforward table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, run_reference
from esoarm.plants import lever_arm
from esoarm.plants.actuator import actuator_vector, feedforward
from esoarm.scenario import ScenarioError, load_scenario

COG = {"duration": 4.0, "rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6,
       "rig.cogging.phase": 0.3}


def test_cogging_torque_enters_the_acceleration() -> None:
    """θ̈ with cogging minus θ̈ without is A cos(nθ + φ)/I, at several angles."""
    scn = load_scenario("test-1", COG)
    p = lever_arm.design(scn).vector
    p0 = lever_arm.design(scn.with_overrides({"rig.cogging.amplitude": 0.0})).vector
    assert len(p0) == 1 + lever_arm.COG_AMP  # no cogging: the kernels' width is kept
    inertia = 1.1 * 0.0225
    for theta in (0.0, 0.4, 1.3, -2.0):
        a, b = np.zeros(1), np.zeros(1)
        x = np.array([theta, 0.2, 0.0])
        lever_arm.acceleration(x, np.array([0.1]), 1.0, p, a)
        lever_arm.acceleration(x, np.array([0.1]), 1.0, p0, b)
        want = 0.08 * math.cos(6 * theta + 0.3) / inertia
        assert a[0] - b[0] == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_zero_amplitude_is_the_plain_rig_bit_for_bit() -> None:
    base = load_scenario("test-1", {"duration": 2.0})
    zero = base.with_overrides({"rig.cogging.periods": 7, "rig.cogging.phase": 1.0})
    a, b = run_reference(base, prepare(base)), run_reference(zero, prepare(zero))
    assert np.array_equal(a.theta, b.theta) and np.array_equal(a.u, b.u)


def test_cogging_costs_tracking() -> None:
    base = load_scenario("test-1", {"duration": 4.0})
    cog = load_scenario("test-1", COG)
    e0 = run_reference(base, prepare(base)).metrics["rms_error"]
    e1 = run_reference(cog, prepare(cog)).metrics["rms_error"]
    assert e1 > 1.5 * e0


def test_feedforward_interpolates_periodically() -> None:
    scn = load_scenario("test-1", {"controller.feedforward_map": [1.0, 2.0, 3.0, 4.0]})
    a = actuator_vector(scn)
    i0 = scn.plant.inertia
    assert feedforward(0.0, a) == pytest.approx(-i0 * 1.0)
    assert feedforward(math.pi / 4, a) == pytest.approx(-i0 * 1.5)
    assert feedforward(7 * math.pi / 4, a) == pytest.approx(-i0 * 2.5)  # wraps to node 0
    assert feedforward(-math.pi / 4, a) == pytest.approx(-i0 * 2.5)
    assert feedforward(2 * math.pi, a) == pytest.approx(-i0 * 1.0)
    assert len(actuator_vector(load_scenario("test-1"))) == 11  # no table: unchanged


def test_the_drive_gets_the_table_and_the_observer_does_not() -> None:
    """With a constant table the logged u (the ESO's input) differs from the drive."""
    scn = load_scenario("test-1", {"duration": 1.0, "actuator.delay_samples": 0})
    ff = scn.with_overrides({"controller.feedforward_map": [2.0, 2.0]})
    a, b = run_reference(scn, prepare(scn)), run_reference(ff, prepare(ff))
    assert not np.array_equal(a.theta, b.theta)


@pytest.mark.parametrize(("over", "key"), [
    ({"rig.cogging.amplitude": -1.0}, "rig.cogging.amplitude"),
    ({"rig.cogging.periods": 0}, "rig.cogging.periods"),
])
def test_bad_keys_are_one_line_errors(over: dict, key: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ScenarioError) as err:
        load_scenario("test-1", over)
    assert f"'{key}" in str(err.value) and "\n" not in str(err.value)


def test_a_plant_without_the_model_refuses_cogging() -> None:
    with pytest.raises(ScenarioError, match="key 'rig.cogging.amplitude': plant.kind = 'axis'"):
        load_scenario("test-1", {"plant.kind": "axis", "rig.cogging.amplitude": 0.1})


def test_the_fast_kernel_runs_cogging_and_a_table() -> None:
    """(It refused both; its agreement with the reference engine with them:
    tests/engines/test_adrcc_fast_windup.py.)"""
    from esoarm.engines.fast import unsupported

    assert unsupported(load_scenario("test-1")) is None
    assert unsupported(load_scenario("test-1", COG)) is None
    table = load_scenario("test-1", {"controller.feedforward_map": [0.1, 0.2]})
    assert unsupported(table) is None


@pytest.mark.slow
def test_reference_and_compiled_agree_with_cogging_and_a_table() -> None:
    from esoarm.engines.batch import run_metrics
    from esoarm.engines.metrics import METRICS

    scn = load_scenario("test-1", {**COG, "controller.feedforward_map": [0.5, -0.3, 0.2, 1.0]})
    ref = run_reference(scn, prepare(scn)).metrics
    table = run_metrics([scn])
    for j, name in enumerate(METRICS):
        assert table.values[0, j] == pytest.approx(ref[name], rel=1e-9, abs=1e-12), name
