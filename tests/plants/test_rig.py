"""The digital twin: rig dynamics (the sampled-data loop) and its RK4 integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from esoarm.plants.lever_arm import (
    RigParams,
    applied_torque,
    rig_acceleration,
    rig_advance,
    rig_derivative,
    rig_rk4_step,
)
from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import load_scenario


def _params(**kw) -> RigParams:
    base = dict(inertia=1.1 * 0.0225, gcoef=gravity_coefficient(0.5, 0.55, 0.15, 0.14, 9.81),
                coulomb_friction=0.05, friction_velocity=0.01, viscous_friction=0.01,
                disturbance_amplitude=0.2, disturbance_frequency=0.5, lag=0.0)
    base.update(kw)
    return RigParams(**base)


def test_from_scenario():
    rig = RigParams.from_scenario(load_scenario("test-1", {"actuator.lag": 0.04}))
    assert rig.inertia == pytest.approx(1.1 * 0.0225, rel=1e-15)
    assert rig.gcoef == pytest.approx((0.5 * 0.15 - 0.55 * 0.14) * 9.81, rel=1e-15)
    assert (rig.coulomb_friction, rig.friction_velocity, rig.viscous_friction) == (0.05, 0.01,
                                                                                   0.01)
    assert (rig.disturbance_amplitude, rig.disturbance_frequency, rig.lag) == (0.2, 0.5, 0.04)
    with pytest.raises(ValueError):
        rig.vector[0] = 1.0


@pytest.mark.parametrize("theta,omega,tau,t", [(0.3, -0.7, 0.4, 1.3), (-2.0, 0.005, -1.0, 7.0),
                                              (1.0, 0.0, 0.0, 0.0)])
def test_acceleration_formula(theta, omega, tau, t):
    p = _params()
    i = 1.1 * 0.0225
    g = (0.5 * 0.15 - 0.55 * 0.14) * 9.81 * math.cos(theta)
    fric = 0.05 * math.tanh(omega / 0.01) + 0.01 * omega
    expected = (tau - g - fric) / i + 0.2 * math.sin(0.5 * t)
    assert rig_acceleration(theta, omega, tau, t, p.vector) == pytest.approx(expected, rel=1e-14)


def test_derivative_with_and_without_lag():
    p0, p1 = _params(), _params(lag=0.05)
    d0 = rig_derivative(0.1, 0.2, 0.3, 0.9, 0.4, p0.vector)
    assert d0[0] == 0.2 and d0[2] == 0.0
    assert d0[1] == rig_acceleration(0.1, 0.2, 0.9, 0.4, p0.vector)  # τ = u without lag
    d1 = rig_derivative(0.1, 0.2, 0.3, 0.9, 0.4, p1.vector)
    assert d1[1] == rig_acceleration(0.1, 0.2, 0.3, 0.4, p1.vector)  # the lag state acts
    assert d1[2] == pytest.approx((0.9 - 0.3) / 0.05)
    assert applied_torque(0.3, 0.9, p0.vector) == 0.9
    assert applied_torque(0.3, 0.9, p1.vector) == 0.3


def _integrate(p: RigParams, u: float, h: float, t_end: float):
    n = int(round(t_end / h))
    return rig_advance(0.2, 0.0, 0.0, u, 0.0, h, n, p.vector)


def _exact(p: RigParams, u: float, t_end: float):
    def f(t, x):
        return rig_derivative(x[0], x[1], x[2], u, t, p.vector)

    sol = solve_ivp(f, (0, t_end), [0.2, 0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-14)
    return sol.y[:, -1]


@pytest.mark.parametrize("lag", [0.0, 0.05])
def test_rk4_is_fourth_order(lag):
    # smooth friction (vs large) so that the error constant is well defined
    p = _params(friction_velocity=1.0, lag=lag, disturbance_amplitude=3.0,
                disturbance_frequency=4.0)
    exact = _exact(p, 0.3, 1.0)
    errs = [np.max(np.abs(np.array(_integrate(p, 0.3, h, 1.0)) - exact)) for h in (0.02, 0.01)]
    assert 12.0 < errs[0] / errs[1] < 20.0, errs  # 2^4 = 16
    fine = np.array(_integrate(p, 0.3, 0.001, 1.0))
    np.testing.assert_allclose(fine, exact, rtol=0, atol=1e-10)


def test_disturbance_evaluated_at_stage_times():
    """Pure disturbance, one step: RK4 = Simpson's rule on d(t), exact to O(h^5)."""
    p = _params(gcoef=0.0, coulomb_friction=0.0, viscous_friction=0.0,
                disturbance_amplitude=2.0, disturbance_frequency=3.0)
    t0, h = 0.7, 0.001
    _, omega, _ = rig_rk4_step(0.0, 0.0, 0.0, 0.0, t0, h, p.vector)
    exact = 2.0 / 3.0 * (math.cos(3.0 * t0) - math.cos(3.0 * (t0 + h)))
    assert omega == pytest.approx(exact, rel=1e-10)
    # had d been frozen at t0, the error would be O(h²) ≫ 1e-10 relative
    assert abs(h * 2.0 * math.sin(3.0 * t0) - exact) > 1e-5 * abs(exact)


def test_advance_is_repeated_steps_with_time():
    p = _params()
    state = (0.1, 0.4, 0.0)
    for j in range(5):
        state = rig_rk4_step(*state, 0.5, 2.0 + j * 0.004, 0.004, p.vector)
    assert rig_advance(0.1, 0.4, 0.0, 0.5, 2.0, 0.004, 5, p.vector) == state


def test_lag_state_follows_first_order_response():
    p = _params(lag=0.05)
    _, _, tau = rig_advance(0.0, 0.0, 0.0, 1.0, 0.0, 0.001, 100, p.vector)
    # RK4 on τ̇ = (1 − τ)/T multiplies the error 1 − τ by R(z) per step, z = −h/T
    z = -0.001 / 0.05
    r = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert tau == pytest.approx(1.0 - r**100, rel=1e-13)
    assert tau == pytest.approx(1.0 - math.exp(-0.1 / 0.05), rel=1e-9)  # and ≈ the exact ODE
