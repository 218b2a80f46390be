"""Gear backlash (two-mass dead-zone model) and the PWM drive's resolution, closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, run_reference
from esoarm.plants import lever_arm
from esoarm.plants.actuator import actuate, actuator_vector
from esoarm.plants.backlash import gear_torque
from esoarm.scenario import ScenarioError, load_scenario

# a free arm: no gravity, friction, disturbance or lag, so the only torques are τa and τs
FREE = {"plant.g": 0.0, "rig.coulomb_friction": 0.0, "rig.viscous_friction": 0.0,
        "rig.disturbance.amplitude": 0.0, "actuator.lag": 0.0}


def _design(**over: float) -> tuple:  # type: ignore[type-arg]
    scn = load_scenario("test-1", {**FREE, "rig.backlash_deg": 2.0, **over})
    return scn, lever_arm.design(scn)


def test_gear_torque_is_a_dead_zone() -> None:
    alpha, k, c = 0.01, 40.0, 0.0
    for delta in np.linspace(-0.05, 0.05, 101):
        expected = k * (delta - math.copysign(alpha, delta)) if abs(delta) > alpha else 0.0
        assert gear_torque(delta, 0.0, alpha, k, c) == pytest.approx(expected, abs=1e-15)
    # the damper pushes while closing, never pulls while parting
    assert gear_torque(0.011, 1.0, alpha, k, 0.1) == pytest.approx(40 * 0.001 + 0.1)
    assert gear_torque(0.011, -1.0, alpha, k, 0.1) == 0.0
    assert gear_torque(-0.011, 1.0, alpha, k, 0.1) == 0.0


def test_motor_side_flies_freely_across_the_gap() -> None:
    """In the gap θm = τa t²/(2 Jm) (RK4 is exact on a quadratic) and the arm does not move;
    contact at t* = √(2 α Jm / τa)."""
    scn, d = _design()
    alpha, jm, tau_a = math.radians(1.0), scn.rig.motor_inertia, 0.01
    t_star = math.sqrt(2 * alpha * jm / tau_a)
    x = np.array(d.x0)
    h = scn.rig.step
    u = np.array([tau_a])
    k = 0
    while (k + 1) * h < t_star:
        lever_arm.advance(x, u, k * h, h, 1, d.vector)
        k += 1
        t = k * h
        assert x[0] == 0.0 and x[1] == 0.0  # the arm is untouched
        assert x[3] == pytest.approx(tau_a * t * t / (2 * jm), rel=1e-12)
    lever_arm.advance(x, u, k * h, h, 1, d.vector)
    lever_arm.advance(x, u, (k + 1) * h, h, 1, d.vector)
    assert x[1] > 0.0  # in contact one step later: the arm is pushed


def test_momentum_is_the_impulse_of_the_drive() -> None:
    """τs is internal: Jm θ̇m + I θ̇ = τa t exactly (RK4 keeps linear invariants)."""
    scn, d = _design()
    inertia = scn.rig.inertia_scale * scn.plant.inertia
    x = np.array(d.x0)
    u = np.array([0.05])
    ts, h, nsub = scn.sample_time, scn.rig.step, scn.substeps
    for k in range(200):
        lever_arm.advance(x, u, k * ts, h, nsub, d.vector)
    t = 200 * ts
    assert scn.rig.motor_inertia * x[4] + inertia * x[1] == pytest.approx(0.05 * t, rel=1e-12)
    # and after the contact has settled (damped) the arm is driven through the gear:
    # Δ = θm − θ ≈ α + (I/(Jm + I)) τa / k (the spring's deflection at the common acceleration)
    delta = x[3] - x[0]
    expected = math.radians(1.0) + inertia / (inertia + scn.rig.motor_inertia) * 0.05 / 50.0
    assert delta == pytest.approx(expected, rel=1e-3)


def test_zero_backlash_is_the_rigid_plant() -> None:
    scn = load_scenario("test-1", {"duration": 2.0})
    stiff = scn.with_overrides({"rig.gear_stiffness": 7.0, "rig.motor_inertia": 0.01})
    a, b = run_reference(scn, prepare(scn)), run_reference(stiff, prepare(stiff))
    assert np.array_equal(a.theta, b.theta) and np.array_equal(a.u, b.u)
    assert len(lever_arm.design(scn).x0) == 3


def test_backlash_costs_tracking() -> None:
    """The arm rattles in the play: the same loop tracks worse with 2° of it."""
    base = load_scenario("test-1", {"duration": 10.0})
    play = base.with_overrides({"rig.backlash_deg": 2.0})
    e0 = run_reference(base, prepare(base)).metrics["rms_error"]
    e1 = run_reference(play, prepare(play)).metrics["rms_error"]
    assert e1 > e0


@pytest.mark.parametrize("bits", [1, 4, 8, 12])
def test_pwm_levels(bits: int) -> None:
    scn = load_scenario("test-1", {"actuator.pwm_bits": bits, "actuator.torque_limit": 1.5})
    a = actuator_vector(scn)
    levels = 2**bits - 1
    for u in np.linspace(-1.5, 1.5, 301):
        host, drive, duty = actuate(float(u), 0.0, a)
        assert host == drive == 1.5 * duty / levels
        assert duty == round(u / 1.5 * levels) or abs(u / 1.5 * levels % 1 - 0.5) < 1e-9
        assert abs(drive - u) <= 0.5 * 1.5 / levels * (1 + 1e-12)
    assert math.isnan(actuate(math.nan, 0.0, a)[0])  # a fault stays visible


def test_pwm_run_logs_only_levels() -> None:
    scn = load_scenario("test-1", {"duration": 5.0, "actuator.pwm_bits": 8})
    res = run_reference(scn, prepare(scn))
    m = res.u / scn.actuator.torque_limit * 255
    assert np.array_equal(m, np.round(m))
    assert len(np.unique(res.u)) > 5


@pytest.mark.parametrize("over, key", [
    ({"rig.backlash_deg": 1.0, "rig.gear_stiffness": 1e4}, "rig.step"),
    ({"rig.backlash_deg": -1.0}, "rig.backlash_deg"),
    ({"actuator.pwm_bits": 8, "motor.pwm_max": 255}, "actuator.pwm_bits"),
    ({"actuator.pwm_bits": 17}, "actuator.pwm_bits"),
])
def test_bad_keys_are_one_line_errors(over: dict, key: str) -> None:
    with pytest.raises(ScenarioError) as err:
        load_scenario("test-1", over)
    assert f"'{key}" in str(err.value) and "\n" not in str(err.value)


def test_a_plant_without_the_model_refuses_backlash() -> None:
    with pytest.raises(ScenarioError, match="key 'rig.backlash_deg': plant.kind = 'axis'"):
        load_scenario("test-1", {"plant.kind": "axis", "rig.backlash_deg": 1.0})
