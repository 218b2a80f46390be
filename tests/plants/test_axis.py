"""Plant kind "axis": one rotary or prismatic axis in SI units (esoarm.plants.axis)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines import batch
from esoarm.engines.simulation import prepare, run_reference
from esoarm.kinds import kinds_of, plant_advance
from esoarm.plants import axis
from esoarm.scenario import ScenarioError, load_scenario


def _scn(**over):
    base = {"plant.kind": "axis", "plant.motion": "prismatic", "controller.kind": "pid"}
    return load_scenario("test-1", {**base, **{f"plant.{k}": v for k, v in over.items()}})


def test_linear_axis_matches_the_closed_form():
    # no Coulomb friction: M v' = u − Fv v − offset; from rest under constant u:
    # v(t) = (u − offset)/Fv · (1 − e^(−Fv t/M)),  q(t) = (u − offset)/Fv · (t − M/Fv (1 − e^…))
    m, fv, off, u = 95.0, 200.0, -3.0, 50.0
    scn = _scn(mass=m, viscous_friction=fv, coulomb_friction=0.0, offset=off)
    d = axis.design(scn)
    x, uu = np.array(d.x0), np.array([u])
    h, steps = 1e-3, 2000
    for _ in range(steps):
        axis.advance(x, uu, 0.0, h, 1, d.vector)
    t = h * steps
    a = (u - off) / fv
    tau = m / fv
    assert x[1] == pytest.approx(a * (1 - math.exp(-t / tau)), rel=1e-11)
    assert x[0] == pytest.approx(a * (t - tau * (1 - math.exp(-t / tau))), rel=1e-11)


def test_inverse_dynamics_inverts_the_acceleration_with_asymmetric_friction():
    scn = _scn(mass=2.0, viscous_friction=3.0, viscous_asymmetry=1.0, coulomb_friction=4.0,
               coulomb_asymmetry=-2.0, offset=0.5)
    ax = tuple(axis.design(scn).vector[1:])
    for v, fc, fv in ((0.5, 3.0, 3.5), (-0.5, 5.0, 2.5)):
        tau = axis.inverse_dynamics(0.1, v, 1.5, ax)
        expected = 2.0 * 1.5 + fc * math.tanh(v / 0.001) + fv * v + 0.5
        assert tau == pytest.approx(expected, rel=1e-14)
        assert axis.axis_acceleration(0.1, v, tau, ax) == pytest.approx(1.5, rel=1e-12)


def test_rotary_gravity_and_the_prismatic_refusal():
    scn = load_scenario("test-1", {"plant.kind": "axis", "plant.gravity": 2.0,
                                   "plant.coulomb_friction": 0.0, "plant.viscous_friction": 0.0})
    ax = tuple(axis.design(scn).vector[1:])
    assert axis.inverse_dynamics(math.pi / 3, 0.0, 0.0, ax) == pytest.approx(1.0, rel=1e-14)
    with pytest.raises(ScenarioError, match="plant.gravity: only a rotary axis"):
        _scn(gravity=1.0)
    with pytest.raises(ScenarioError, match="plant.coulomb_asymmetry"):
        _scn(coulomb_friction=1.0, coulomb_asymmetry=3.0)


def test_block_step_and_dispatch_give_the_same_bits():
    scn = _scn(coulomb_asymmetry=0.02)
    p = axis.design(scn).vector
    rng = np.random.default_rng(1)
    xs = rng.normal(size=(5, 3)) * 0.01
    us = rng.normal(size=(5, 1))
    live = np.array([True, True, False, True, True])
    expected = xs.copy()
    for i in range(5):
        if live[i]:
            axis.advance(expected[i], us[i], 0.0, 1e-3, 3, p)
            x2 = xs[i].copy()
            plant_advance(x2, us[i], 0.0, 1e-3, 3, p)
            np.testing.assert_array_equal(x2, expected[i])
    axis.advance_block(xs, us, live, 0.0, 1e-3, 3, p)
    np.testing.assert_array_equal(xs, expected)


def test_emps_runs_in_both_engines_with_the_same_numbers():
    scn = load_scenario("emps", {"duration": 3.0})
    assert kinds_of(scn).plant is axis and kinds_of(scn).jit
    ref = run_reference(scn, prepare(scn))
    row = batch.run_metrics([scn], blocked=False).row(0)
    assert row["rms_u"] == pytest.approx(ref.metrics["rms_u"], rel=1e-12)
    assert row["rms_error"] == pytest.approx(ref.metrics["rms_error"], rel=1e-12)
    # the PD loop tracks the 0.24 m moves to a fraction of a millimetre with forces of tens of N
    assert ref.metrics["max_abs_error"] < 2e-4 and 5.0 < ref.metrics["rms_u"] < 200.0


def test_angle_sensor_keys_on_a_prismatic_axis_are_flagged():
    """The sensor's degree keys on an axis measured in m: said in words, with what they do."""
    from esoarm.scenario import scenario_warnings

    base = {"plant.kind": "axis", "plant.motion": "prismatic", "controller.kind": "pid"}
    flagged = scenario_warnings(load_scenario("test-1", base))  # the default sensor
    assert any(m.startswith("sensor.noise_deg = 0.2 is an angle") and "0.00349 m" in m
               for m in flagged), flagged
    assert any(m.startswith("sensor.resolution_deg = 0.05") for m in flagged), flagged
    quiet = load_scenario("test-1", {**base, "sensor.noise_deg": 0.0,
                                     "sensor.resolution_deg": 0.0})
    assert not [m for m in scenario_warnings(quiet) if "is an angle" in m]
    assert not [m for m in scenario_warnings(load_scenario("emps")) if "is an angle" in m]
    rotary = load_scenario("test-1", {"plant.kind": "axis", "controller.kind": "pid"})
    assert not [m for m in scenario_warnings(rotary) if "is an angle" in m]
