"""The feedback-linearization controller, eq. 14-17."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from esoarm.controllers.flc import FLCParams, flc_control, saturate
from esoarm.plants.lever_arm import RigParams, rig_acceleration
from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import load_scenario

I0 = 0.0225
GC = gravity_coefficient(0.5, 0.55, 0.15, 0.14, 9.81)


def _ctl(compensation="eso", limit=1e9, k1=10.0, k2=25.0) -> FLCParams:
    return FLCParams(k1=k1, k2=k2, inertia=I0, gcoef=GC, compensation=compensation,
                     torque_limit=limit)


def test_eso_compensation_formula():
    z, ref = (0.3, -0.2, 1.7), (0.5, 0.1, -0.4)
    alpha = -0.4 - 10.0 * (-0.2 - 0.1) - 25.0 * (0.3 - 0.5)
    expected = I0 * (alpha - 1.7)
    assert flc_control(*z, *ref, _ctl().vector) == pytest.approx(expected, rel=1e-15)


def test_model_compensation_formula():
    z, ref = (0.3, -0.2, 1.7), (0.5, 0.1, -0.4)
    alpha = -0.4 - 10.0 * (-0.2 - 0.1) - 25.0 * (0.3 - 0.5)
    beta = -GC * math.cos(0.3) / I0  # z3 ignored
    expected = I0 * (alpha - beta)
    assert flc_control(*z, *ref, _ctl("model").vector) == pytest.approx(expected, rel=1e-14)


@given(st.floats(-1e6, 1e6), st.floats(1e-3, 1e3))
def test_saturate(u, limit):
    s = saturate(u, limit)
    assert -limit <= s <= limit
    assert s == u or abs(s) == limit
    assert saturate(s, limit) == s


def test_saturate_nan_passes_through():
    assert math.isnan(saturate(float("nan"), 2.0))


def test_command_is_saturated():
    assert flc_control(-10.0, 0.0, 0.0, 0.0, 0.0, 0.0, _ctl(limit=2.0).vector) == 2.0
    assert flc_control(10.0, 0.0, 0.0, 0.0, 0.0, 0.0, _ctl(limit=2.0).vector) == -2.0


def test_callable_params_agree_with_function():
    ctl = FLCParams.from_scenario(load_scenario("test-2", {"controller.compensation": "model"}))
    assert ctl.compensation == "model" and ctl.torque_limit == 2.0 and ctl.inertia == I0
    assert ctl((0.1, 0.2, 0.3), 0.4, 0.5, 0.6) == flc_control(0.1, 0.2, 0.3, 0.4, 0.5, 0.6,
                                                              ctl.vector)


@pytest.mark.parametrize("compensation", ["eso", "model"])
@pytest.mark.parametrize("theta,omega", [(0.2, 0.0), (-1.0, 0.7), (2.5, -3.0)])
def test_linearizes_the_nominal_plant(compensation, theta, omega):
    """Perfect estimates on the nominal plant: θ̈ = α, so ë + k1 ė + k2 e = 0 (eq. 17, κ = 0)."""
    nominal = RigParams(inertia=I0, gcoef=GC, coulomb_friction=0.0, friction_velocity=1.0,
                        viscous_friction=0.0, disturbance_amplitude=0.0,
                        disturbance_frequency=0.0, lag=0.0)
    f = rig_acceleration(theta, omega, 0.0, 0.0, nominal.vector)  # total perturbation −G/I0
    ref = (0.4, -0.3, 0.8)
    u = flc_control(theta, omega, f, *ref, _ctl(compensation).vector)
    acc = rig_acceleration(theta, omega, u, 0.0, nominal.vector)
    e, de = theta - ref[0], omega - ref[1]
    assert acc - ref[2] + 10.0 * de + 25.0 * e == pytest.approx(0.0, abs=1e-12)


def test_flc_vector_is_read_only():
    vec = _ctl().vector
    with pytest.raises(ValueError):
        vec[0] = 1.0
    assert np.all(np.isfinite(vec))
