"""Deployment controller and device-side twin against the reference simulator.

The host's DeploymentController fed by the emulator's Twin (encoder counts,
device-side noise) must reproduce esoarm.engines.simulation.run_reference bit for bit:
u_k, ẑ_k and the measured angle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, run_reference
from esoarm.hardware.emulator import NoiseStream, Twin
from esoarm.hardware.host_control import DeploymentController
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.plants.sensor import measure, noise_sequence
from esoarm.scenario import builtin_names, load_scenario

VARIANTS = {
    "plain": [],
    "lag-delay": ["actuator.lag=0.03", "actuator.delay_samples=2"],
    "1kHz": ["sensor.rate_hz=1000", "observer.eps=0.02"],
    "motor": ["motor.pwm_max=1023", "motor.deadband=0.05", "actuator.delay_samples=1"],
    "coloured": ["sensor.noise_ar=[0.7, 0.1]", "sensor.noise_deg=0.3",
                 "sensor.vibration_deg=0.05", "sensor.vibration_hz=6"],
    "backlash-pwm": ["rig.backlash_deg=1.5", "actuator.pwm_bits=8"],
}


def _host_over_twin(scn):
    ctl = DeploymentController(scn)
    twin = Twin(scn)
    q = math.radians(scn.sensor.resolution_deg)
    u_log, z_log, y_log = [], [], []
    for k in range(ctl.n_samples):
        y = q * twin.count()
        u, duty = ctl.actuate(ctl.step(k, y))  # the host's torque and the motor's duty
        ctl.commit(u)
        twin.advance(twin.torque_of_duty(int(duty)) if scn.motor else u)
        u_log.append(u)
        z_log.append(ctl.zhat)
        y_log.append(y)
    return np.array(u_log), np.array(z_log), np.array(y_log)


@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("compensation", ["eso", "model"])
@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))  # the rig: a lever
def test_same_numbers_as_reference(name, disc, compensation, variant):
    sets = VARIANTS[variant]
    if load_scenario(name).motor is not None:  # a motor's pwm_max is its PWM resolution
        sets = [s for s in sets if not s.startswith("actuator.pwm_bits")]
    scn = load_scenario(name, [f"observer.discretization={disc}",
                               f"controller.compensation={compensation}", "duration=2", *sets])
    inp = prepare(scn)  # with a [motor] table both sides apply it (one actuator step)
    ref = run_reference(scn, inp)
    u, z, y = _host_over_twin(scn)
    assert np.array_equal(u, ref.u)
    assert np.array_equal(z, ref.z)
    expected_y = [measure(th, n, inp.sigma, inp.q) for th, n in zip(ref.theta, inp.noise,
                                                                      strict=True)]
    assert np.array_equal(y, expected_y)


def test_noise_stream_continues_the_simulators_sequence():
    for n in (1, 100, 4096, 5000):
        stream = NoiseStream(seed=3, noise_deg=0.2, block=1000)
        assert np.array_equal([stream.next() for _ in range(n)], noise_sequence(3, n, 0.2))
    zero = NoiseStream(seed=3, noise_deg=0.0)
    assert [zero.next() for _ in range(3)] == [0.0, 0.0, 0.0]


def test_predict_is_a_zero_innovation_step():
    scn = load_scenario("test-1", ["duration=1"])
    a, b = DeploymentController(scn), DeploymentController(scn)
    for ctl in (a, b):
        ctl.commit(ctl.step(0, 0.01))
    za = a.predict(0.3)
    b.step(1, b.observer_state[0])  # a measurement equal to the estimate: no innovation
    b.commit(0.3)
    assert za == b.zhat and np.array_equal(a.observer_state, b.observer_state)


def test_controller_respects_torque_limit():
    scn = load_scenario("test-1", ["actuator.torque_limit=0.1", "duration=1"])
    ctl = DeploymentController(scn)
    for k in range(ctl.n_samples):
        u = ctl.step(k, 0.5 * math.sin(k))  # wild measurements
        assert abs(u) <= 0.1
        ctl.commit(u)


@pytest.mark.parametrize("variant", ["plain", "lag-delay"])
def test_an_arm_whose_observer_input_is_not_u(variant):
    """test-1 as a one-joint URDF arm: the host feeds its observer the plant kind's input.

    The URDF kind's observer input is M̂(q̂)⁻¹(u − c·n̂), not u; a host controller that
    advanced the ESO with u (as it once did) commands another torque from sample 1 on.
    """
    pytest.importorskip("pinocchio")
    scn = load_scenario("test-1-urdf", ["duration=2", *VARIANTS[variant]])
    ref = run_reference(scn, prepare(scn))
    u, z, _ = _host_over_twin(scn)
    assert np.array_equal(u, ref.u)
    assert np.array_equal(z, ref.z)
