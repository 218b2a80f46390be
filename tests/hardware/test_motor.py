"""Torque <-> PWM duty mapping and the twin's motor law."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.plants import lever_arm
from esoarm.plants.lever_arm import RigParams, rig_acceleration
from esoarm.plants.motor import MotorParams
from esoarm.scenario import ScenarioError, load_scenario


@pytest.fixture
def motor() -> MotorParams:
    return MotorParams(supply_voltage=12.0, resistance=2.0, torque_constant=0.02,
                       gear_ratio=50.0, pwm_max=1023, deadband=0.08)


def test_duty_maps_back_to_torque_within_one_count(motor):
    one_count = motor.stall_gain / motor.pwm_max / (1 - motor.deadband)
    for u in np.linspace(-2, 2, 41):
        for omega in (-2.0, 0.0, 1.5):
            duty = motor.torque_to_duty(u, omega)
            assert abs(duty) <= motor.pwm_max
            assert motor.duty_to_torque(duty, omega) == pytest.approx(u, abs=one_count)


def test_saturates_at_full_supply(motor):
    assert motor.torque_to_duty(1e3, 0.0) == motor.pwm_max
    assert motor.torque_to_duty(-1e3, 0.0) == -motor.pwm_max
    assert motor.torque_to_duty(math.nan, 0.0) == 0


def test_deadband_is_compensated(motor):
    small = motor.torque_to_duty(1e-3, 0.0)
    assert abs(small) / motor.pwm_max >= motor.deadband  # pushed past the deadband
    assert motor.effective_fraction(int(0.5 * motor.deadband * motor.pwm_max)) == 0.0


def test_twin_law_is_the_motor_equation(motor):
    scn = load_scenario("test-1", {"motor.pwm_max": 1023, "motor.deadband": 0.08})
    assert MotorParams.from_scenario(scn) == motor
    rig = lever_arm.design(scn).vector[1:]  # the plant with the motor's back-EMF damping
    plain = RigParams.from_scenario(scn).vector
    duty, omega, theta, t = 300, 0.7, 0.2, 1.3
    # i = (Vs d − N Kt ω)/R, τ = N Kt i  (independent statement of the law)
    d = motor.effective_fraction(duty)
    tau = motor.gear_ratio * motor.torque_constant * (
        motor.supply_voltage * d - motor.gear_ratio * motor.torque_constant * omega
    ) / motor.resistance
    expected = rig_acceleration(theta, omega, tau, t, plain)
    got = rig_acceleration(theta, omega, motor.source_torque(duty), t, rig)
    assert got == pytest.approx(expected, rel=1e-12)


def test_motor_section_optional_and_round_trips(tmp_path):
    scn = load_scenario("test-1")
    assert scn.motor is None and "[motor]" not in scn.to_toml()
    with_motor = load_scenario("test-1", ["motor.pwm_max=1023"])
    text = with_motor.to_toml()
    assert "[motor]" in text
    path = tmp_path / "m.toml"
    path.write_text(text)
    assert load_scenario(str(path)) == with_motor.model_copy(update={"name": "test-1"})
    assert MotorParams.from_scenario(with_motor).pwm_max == 1023
    with pytest.raises(ScenarioError, match="motor.deadband"):
        load_scenario("test-1", ["motor.deadband=1.5"])
