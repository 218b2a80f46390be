"""Analysis helpers, and Theorems 1 and 2 checked numerically on simulated runs."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy import integrate, signal

from esoarm.engines.simulation import SimulationDiverged, simulate
from esoarm.observers.linear import DISCRETIZATIONS, design_observer
from esoarm.observers.stability import (
    analyze_observer,
    characteristic_polynomial,
    error_matrix,
    estimation_error,
    observer_gains,
    observer_poles,
    observer_warnings,
    pole_damping,
    theorem1_bound,
    theorem2_bound,
    tracking_l1_gain,
)
from esoarm.scenario import load_scenario, scenario_warnings

TS = 0.02  # the paper's 50 Hz


# ---------------------------------------------------------------------------
# gains and poles


@pytest.mark.parametrize("eps", [0.05, 0.09, 0.2])
def test_gains_and_poles_continuous(eps):
    np.testing.assert_allclose(observer_gains(eps), [3 / eps, 3 / eps**2, 1 / eps**3])
    np.testing.assert_array_equal(observer_poles(eps), [-1 / eps] * 3)
    a = analyze_observer(eps)
    assert a.stable and a.damping == 1.0 and a.spectral_radius == pytest.approx(-1 / eps)
    # eigenvalues of eq. 10's matrix, from python-control's view of the system
    sys = control.ss(error_matrix(eps), np.eye(3), np.eye(3), 0)
    np.testing.assert_allclose(np.sort(np.real(sys.poles())), [-1 / eps] * 3, rtol=1e-4)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("eps", [0.05, 0.09, 0.2])
def test_gains_and_poles_discrete(eps, disc):
    gains = observer_gains(eps, TS, disc)
    np.testing.assert_array_equal(gains, design_observer(eps, TS, 1 / 0.0225, disc).gain)
    pole = 1 - TS / eps if disc == "euler" else math.exp(-TS / eps)
    np.testing.assert_allclose(observer_poles(eps, TS, disc), [pole] * 3, rtol=1e-15)
    np.testing.assert_allclose(characteristic_polynomial(error_matrix(eps, TS, disc)),
                               [1, -3 * pole, 3 * pole**2, -(pole**3)], atol=1e-12)
    a = analyze_observer(eps, TS, disc)
    assert a.stable and a.ts_over_eps == pytest.approx(TS / eps)
    assert a.damping == pytest.approx(1.0)  # positive real poles at these ε


def test_characteristic_polynomial_matches_numpy_for_distinct_eigenvalues():
    m = np.array([[1.0, 2.0, 0.5], [0.0, -3.0, 1.0], [0.2, 0.0, 0.7]])
    np.testing.assert_allclose(characteristic_polynomial(m), np.poly(m), rtol=1e-12)


def test_helpers_reject_bad_arguments():
    with pytest.raises(ValueError, match="discretization"):
        observer_gains(0.09, TS, "rk4")
    with pytest.raises(ValueError, match="ts"):
        observer_gains(0.09, None, "zoh")
    with pytest.raises(ValueError, match="eps"):
        observer_poles(0.0)
    with pytest.raises(ValueError, match="k1"):
        tracking_l1_gain(0.0, 25.0)


# ---------------------------------------------------------------------------
# stability / damping check for ε against the sample rate


@pytest.mark.parametrize(
    ("ratio", "stable", "ringing"),
    [(0.5, True, False), (1.0, True, False), (1.5, True, True), (1.999, True, True),
     (2.0, False, False), (2.5, False, False)],
)
def test_euler_stability_boundary(ratio, stable, ringing):
    eps = TS / ratio
    a = analyze_observer(eps, TS, "euler")
    assert a.stable is stable
    assert a.spectral_radius == pytest.approx(abs(1 - ratio))
    msgs = observer_warnings(eps, TS, "euler")
    assert any("unstable" in m for m in msgs) is (not stable)
    assert any("negative real axis" in m for m in msgs) is ringing
    if ringing:
        # z-pole on the negative real axis: ζ = −ln|z| / √(ln²|z| + π²)
        lz = math.log(abs(1 - ratio))
        assert a.damping == pytest.approx(-lz / math.hypot(lz, math.pi))
        assert a.damping < 1


@pytest.mark.parametrize("disc", ("zoh", "current"))
def test_exact_discretizations_never_unstable_but_warn_when_too_fast(disc):
    for eps in (0.001, 0.005, 0.0399):
        msgs = observer_warnings(eps, TS, disc)
        assert len(msgs) == 1 and "faster than the sample rate" in msgs[0]
        assert analyze_observer(eps, TS, disc).stable
    assert observer_warnings(0.04, TS, disc) == []


def test_pole_damping():
    assert pole_damping(-2.0) == 1.0
    assert pole_damping(complex(-1, 1)) == pytest.approx(1 / math.sqrt(2))
    assert pole_damping(0.5, 0.01) == pytest.approx(1.0)
    assert pole_damping(0.0, 0.01) == 1.0
    assert pole_damping(1.0, 0.01) == 0.0
    assert pole_damping(-1.0, 0.01) == pytest.approx(0.0, abs=1e-15)
    assert pole_damping(1.1, 0.01) < 0


@pytest.mark.parametrize("eps", [0.09, 0.015, 0.0105, 0.005])
@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_scenario_warnings_use_the_analysis(eps, disc):
    scn = load_scenario("test-1", {"observer.eps": eps, "observer.discretization": disc})
    assert scenario_warnings(scn) == observer_warnings(eps, scn.sample_time, disc)


def test_warnings_predict_what_the_simulation_does():
    """Unstable by the analysis -> the run diverges; stable -> it does not."""
    with pytest.raises(SimulationDiverged):
        simulate("test-1", {"observer.eps": 0.0098}, warn=False)  # Ts/ε = 2.04
    ringing = simulate("test-1", {"observer.eps": 0.0105}, warn=False)  # Ts/ε = 1.90
    good = simulate("test-1", {"observer.eps": 0.09}, warn=False)
    assert np.all(np.isfinite(ringing.theta))
    assert ringing.rms_error > 10 * good.rms_error  # why it is worth a warning


# ---------------------------------------------------------------------------
# Theorem 1: steady-state estimation error against sup|γ| · (ε³, 3ε², 3ε)

# A 1 kHz, noise-free twin approximates the continuous observer of the theorem
# (Ts/ε ≈ 0.011); the sampled loop deviates from it by O(Ts/ε).
CONTINUOUS_LIKE = {"sensor.rate_hz": 1000.0, "sensor.noise_deg": 0.0,
                   "sensor.resolution_deg": 0.0}
# The total perturbation is exactly the disturbance, f = d(t) = 5 sin(0.5 t):
# no gravity, no friction, nominal inertia, arm held at 0.  Then γ = ḟ is a
# slow sinusoid and the error reaches the bound (quasi-static z̃ = h(0)·γ).
PURE_DISTURBANCE = {**CONTINUOUS_LIKE, "rig.inertia_scale": 1.0, "rig.coulomb_friction": 0.0,
                    "rig.viscous_friction": 0.0, "plant.g": 0.0, "reference.moves": [],
                    "rig.disturbance.amplitude": 5.0}


def _estimation_errors(res):
    return np.column_stack([res.theta - res.z[:, 0], res.omega - res.z[:, 1],
                            res.f_true - res.z[:, 2]])


def test_theorem1_bound_closed_form_is_the_l1_norm():
    """‖h_i‖₁ of the error system (eq. 10, input γ on z̃3) equals (ε³, 3ε², 3ε)."""
    eps = 0.09
    b = np.array([[0.0], [0.0], [1.0]])
    t = np.linspace(0, 40 * eps, 200001)
    for i, expected in enumerate(theorem1_bound(eps, 1.0)):
        c = np.zeros((1, 3))
        c[0, i] = 1.0
        _, h = signal.impulse((error_matrix(eps), b, c, 0), T=t)
        assert integrate.trapezoid(np.abs(h), t) == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_theorem1_bound_reached(disc):
    eps = 0.09
    res = simulate("test-1", {**PURE_DISTURBANCE, "observer.discretization": disc}, warn=False)
    ts = res.t[1]
    np.testing.assert_allclose(res.f_true, 5.0 * np.sin(0.5 * res.t), rtol=0, atol=1e-12)
    gamma = np.gradient(res.f_true, ts)
    bound = theorem1_bound(eps, np.max(np.abs(gamma)))
    settled = res.t >= 2.0  # e^{−t/ε} t² gone
    worst = np.max(np.abs(_estimation_errors(res)[settled]), axis=0)
    ratio = worst / bound
    assert np.all(ratio <= 1.0 + 2 * ts / eps), ratio
    assert np.all(ratio >= 0.95), ratio  # and the bound is tight


@pytest.mark.parametrize("name", ["test-1", "test-2"])
def test_theorem1_bound_holds_on_builtins(name):
    eps = 0.09
    res = simulate(name, CONTINUOUS_LIKE, warn=False)
    ts = res.t[1]
    gamma = np.gradient(res.f_true, ts)
    bound = theorem1_bound(eps, np.max(np.abs(gamma)))
    worst = np.max(np.abs(_estimation_errors(res)[res.t >= 1.0]), axis=0)
    assert np.all(worst <= bound), worst / bound


# ---------------------------------------------------------------------------
# Theorem 2: steady-state tracking error against μ/k2


def test_tracking_l1_gain():
    t = np.linspace(0, 30, 150001)
    for k1, k2 in [(10.0, 25.0), (12.0, 25.0), (4.0, 25.0), (1.0, 25.0), (3.0, 2.0)]:
        _, h = signal.impulse(([1.0], [1.0, k1, k2]), T=t)
        assert tracking_l1_gain(k1, k2) == pytest.approx(integrate.trapezoid(np.abs(h), t),
                                                         rel=1e-5)
    assert tracking_l1_gain(10.0, 25.0) == 1 / 25.0  # critically damped: exactly μ/k2


def test_theorem2_bound_values():
    kappa = np.array([0.5, -2.0, 1.0])
    assert theorem2_bound(kappa, 25.0) == 2.0 / 25.0
    assert theorem2_bound(kappa, 25.0, k1=10.0) == 2.0 / 25.0
    assert theorem2_bound(kappa, 25.0, k1=2.0) > 2.0 / 25.0  # underdamped: μ/k2 is not a bound


def test_estimation_error_is_eq17_residual():
    """κ from the estimates equals ë + k1 ė + k2 e measured on the true trajectory."""
    res = simulate("test-2", CONTINUOUS_LIKE, warn=False)
    ts = res.t[1]
    e = res.error
    de = res.omega - np.cos(0.5 * res.t) * 0.5 * 0.5  # θ̇ − θ̇d for θd = 0.5 sin(0.5 t)
    dde = res.f_true + res.u / 0.0225 + 0.5 * 0.25 * np.sin(0.5 * res.t)  # θ̈ − θ̈d
    residual = dde + 10.0 * de + 25.0 * e
    kappa = estimation_error(res)
    np.testing.assert_allclose(kappa, residual, rtol=0, atol=1e-9 * np.max(np.abs(kappa)))
    assert np.max(np.abs(res.u)) < res.scenario.actuator.torque_limit  # premise: unsaturated
    assert ts == pytest.approx(1e-3)


@pytest.mark.parametrize(("name", "overrides"), [
    ("test-1", CONTINUOUS_LIKE),
    ("test-2", CONTINUOUS_LIKE),
    ("test-2", {**CONTINUOUS_LIKE, "observer.discretization": "current"}),
    ("pure", PURE_DISTURBANCE),
])
def test_theorem2_steady_state_error_within_bound(name, overrides):
    scn = load_scenario("test-1" if name == "pure" else name, overrides)
    res = simulate(scn, warn=False)
    assert np.max(np.abs(res.u)) < scn.actuator.torque_limit  # Theorem 2's premise
    kappa = estimation_error(res)
    bound = theorem2_bound(kappa, scn.controller.k2, k1=scn.controller.k1)
    # k1² = 4 k2: the rigorous bound is the paper's μ/k2
    assert bound == pytest.approx(theorem2_bound(kappa, scn.controller.k2), rel=1e-15)
    reached = np.max(np.abs(res.error[res.t >= 2.0]))
    ratio = reached / bound
    assert ratio <= 1.0, ratio
    if name == "pure":
        assert ratio >= 0.95, ratio  # slowly varying κ: the bound is attained
    else:
        assert ratio >= 0.3, ratio  # not vacuous on the paper's scenarios
