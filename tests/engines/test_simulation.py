"""The reference simulator against docs/semantics.md: a second engine, determinism, bounds.

The second engine is ``tests/reference_impl.py``, written from the text of docs/semantics.md
with NumPy matrices, scipy's ``expm`` and its own RK4; the semantics require
agreement to relative 1e-9 on RMS values.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import reference_impl
from esoarm.engines.simulation import SimulationDiverged, prepare, simulate
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.scenario import builtin_names, load_scenario

RTOL = 1e-9

# Every feature of the sampled-data loop at least once, every discretization with each
# feature that interacts with it.  Short runs where the feature shows early.
ENGINE_CASES = {
    "test-1": ("test-1", {}),
    "test-2": ("test-2", {}),
    "test-1-zoh": ("test-1", {"observer.discretization": "zoh"}),
    "test-1-current": ("test-1", {"observer.discretization": "current"}),
    "test-2-zoh": ("test-2", {"observer.discretization": "zoh"}),
    "test-2-current": ("test-2", {"observer.discretization": "current"}),
    "lag-euler": ("test-1", {"actuator.lag": 0.03, "duration": 6.0}),
    "lag-current": ("test-2", {"actuator.lag": 0.03, "observer.discretization": "current",
                               "duration": 6.0}),
    "delay-zoh": ("test-2", {"actuator.delay_samples": 3, "observer.discretization": "zoh",
                             "duration": 6.0}),
    "delay-lag-current": ("test-1", {"actuator.delay_samples": 2, "actuator.lag": 0.02,
                                     "observer.discretization": "current", "duration": 6.0}),
    "saturation-euler": ("test-1", {"actuator.torque_limit": 0.03, "duration": 6.0}),
    "saturation-zoh": ("test-2", {"actuator.torque_limit": 0.04,
                                  "observer.discretization": "zoh", "duration": 6.0}),
    "noise-free-no-quantizer": ("test-1", {"sensor.noise_deg": 0.0, "sensor.resolution_deg": 0.0,
                                           "duration": 6.0}),
    "noise-only-current": ("test-2", {"sensor.resolution_deg": 0.0, "sensor.noise_deg": 0.5,
                                      "sensor.seed": 11, "observer.discretization": "current",
                                      "duration": 6.0}),
    "model-compensation-euler": ("test-2", {"controller.compensation": "model"}),
    "model-compensation-current": ("test-1", {"controller.compensation": "model",
                                              "observer.discretization": "current",
                                              "duration": 6.0}),
    "fast-rate-eps-small-zoh": ("test-1", {"sensor.rate_hz": 200.0, "observer.eps": 0.02,
                                           "observer.discretization": "zoh", "duration": 3.0}),
    "theta0-multisine-phases": ("test-2", {"rig.theta0": 0.3, "reference.phases": [0.4],
                                           "reference.offset": 0.2, "duration": 6.0}),
    "other-gains-friction": ("test-1", {"controller.k1": 6.0, "controller.k2": 40.0,
                                        "rig.coulomb_friction": 0.1, "rig.viscous_friction": 0.05,
                                        "rig.inertia_scale": 0.8, "rig.step": 0.0005,
                                        "duration": 6.0}),
    "stiction-zoh": ("test-1", {"rig.stiction": 0.15, "rig.stribeck_velocity": 0.05,
                                "rig.coulomb_friction": 0.1, "observer.discretization": "zoh",
                                "duration": 6.0}),
}


@pytest.mark.parametrize("case", list(ENGINE_CASES))
def test_matches_independent_implementation(case):
    name, overrides = ENGINE_CASES[case]
    scn = load_scenario(name, overrides)
    ours = simulate(scn, warn=False)
    theirs = reference_impl.run(scn.to_dict())
    for key in ("rms_error", "rms_u", "max_abs_error"):
        assert ours.metrics[key] == pytest.approx(theirs[key], rel=RTOL, abs=0.0), key
    # the whole series, not only the summaries
    np.testing.assert_array_equal(ours.t, theirs["t"])
    scale_theta = np.max(np.abs(theirs["theta"])) + 1e-3
    np.testing.assert_allclose(ours.theta_ref, theirs["theta_ref"], rtol=0,
                               atol=1e-13 * scale_theta)
    np.testing.assert_allclose(ours.theta, theirs["theta"], rtol=0, atol=RTOL * scale_theta)
    np.testing.assert_allclose(ours.error, theirs["error"], rtol=0, atol=RTOL * scale_theta)
    np.testing.assert_allclose(ours.u, theirs["u"], rtol=0,
                               atol=RTOL * np.max(np.abs(theirs["u"])))
    for i in range(3):
        col = theirs["z"][:, i]
        np.testing.assert_allclose(ours.z[:, i], col, rtol=0, atol=RTOL * np.max(np.abs(col)))
    np.testing.assert_allclose(ours.f_true, theirs["f_true"], rtol=0,
                               atol=RTOL * np.max(np.abs(theirs["f_true"])))
    if "torque_limit" in str(overrides):
        assert np.mean(np.abs(ours.u) == scn.actuator.torque_limit) > 0.2  # really saturating


def test_second_engine_is_sensitive():
    """The comparison can fail: a 1e-6 change of one parameter is detected."""
    scn = load_scenario("test-1", {"duration": 6.0})
    ours = simulate(scn, warn=False)
    nudged = scn.to_dict()
    nudged["rig"]["inertia_scale"] *= 1 + 1e-6
    theirs = reference_impl.run(nudged)
    assert ours.metrics["rms_error"] != pytest.approx(theirs["rms_error"], rel=RTOL, abs=0.0)


# ---------------------------------------------------------------------------
# determinism


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_deterministic_bit_for_bit(disc):
    scn = load_scenario("test-2", {"observer.discretization": disc, "duration": 5.0})
    a = simulate(scn, warn=False)
    b = simulate(load_scenario("test-2", {"observer.discretization": disc, "duration": 5.0}),
                 warn=False)
    for field in ("t", "theta", "theta_ref", "error", "u", "z", "f_true", "omega"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert a.metrics == b.metrics


def test_seed_changes_the_noise_and_only_the_noise():
    a = simulate("test-1", {"duration": 3.0, "sensor.seed": 1}, warn=False)
    b = simulate("test-1", {"duration": 3.0, "sensor.seed": 2}, warn=False)
    assert not np.array_equal(a.z, b.z)
    assert np.array_equal(a.theta_ref, b.theta_ref)
    c = simulate("test-1", {"duration": 3.0, "sensor.seed": 1, "sensor.noise_deg": 0.0},
                 warn=False)
    d = simulate("test-1", {"duration": 3.0, "sensor.seed": 2, "sensor.noise_deg": 0.0},
                 warn=False)
    assert np.array_equal(c.z, d.z)


# ---------------------------------------------------------------------------
# every built-in x every discretization runs and stays bounded


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))  # arms: test_arm_scenarios
def test_builtin_runs_bounded(name, disc):
    scn = load_scenario(name, {"observer.discretization": disc})
    res = simulate(scn, warn=False)
    n = scn.n_samples
    assert n == 1000
    for field in ("t", "theta", "theta_ref", "error", "u", "f_true", "omega"):
        arr = getattr(res, field)
        assert arr.shape == (n,) and np.all(np.isfinite(arr)), field
    assert res.z.shape == (n, 3) and np.all(np.isfinite(res.z))
    assert np.max(np.abs(res.u)) <= scn.actuator.torque_limit
    # bounded in the engineering sense: the arm follows the reference
    assert res.max_abs_error < 0.2  # rad
    assert res.rms_error < 0.05  # rad
    assert np.max(np.abs(res.z[:, 1] - res.omega)) < 1.0  # rad/s, velocity estimate
    assert set(res.metrics) >= {"rms_error", "rms_u", "max_abs_error"}


# ---------------------------------------------------------------------------
# Details of the sampled-data loop checked directly on the log


def test_log_semantics():
    scn = load_scenario("test-1", {"duration": 4.0, "actuator.delay_samples": 2})
    res = simulate(scn, warn=False)
    ts = scn.sample_time
    assert np.array_equal(res.t, np.arange(scn.n_samples) * ts)
    assert np.array_equal(res.error, res.theta - res.theta_ref)  # true, not measured
    assert res.theta[0] == scn.rig.theta0 and res.omega[0] == 0.0
    # f_true = θ̈(t_k) − b0 u_k, with the torque applied from t_k on (here u_{k-2}, 0 at first)
    b0 = 1.0 / scn.plant.inertia
    from esoarm.plants.lever_arm import RigParams, rig_acceleration

    rig = RigParams.from_scenario(scn).vector
    applied = np.concatenate([[0.0, 0.0], res.u[:-2]])
    acc = np.array([rig_acceleration(th, om, ua, t, rig)
                    for th, om, ua, t in zip(res.theta, res.omega, applied, res.t, strict=True)])
    np.testing.assert_array_equal(res.f_true, acc - b0 * res.u)


def test_delay_holds_zero_before_first_command():
    """With d samples of delay the arm feels no torque before t_d."""
    scn = load_scenario("test-1", {"duration": 1.0, "actuator.delay_samples": 5,
                                   "rig.disturbance.amplitude": 0.0, "rig.theta0": 0.0})
    res = simulate(scn, warn=False)
    # only gravity (and friction) act: θ̈ = −G(θ)/I, the reference is still at rest
    gc = (0.5 * 0.15 - 0.55 * 0.14) * 9.81
    expected_acc0 = -gc / (1.1 * 0.0225)
    assert res.f_true[0] + res.u[0] / 0.0225 == pytest.approx(expected_acc0, rel=1e-12)
    nodelay = simulate(load_scenario("test-1", {"duration": 1.0,
                                                "rig.disturbance.amplitude": 0.0}), warn=False)
    assert not np.array_equal(res.theta[1:6], nodelay.theta[1:6])


def test_noise_is_drawn_once_from_default_rng():
    scn = load_scenario("test-1", {"duration": 2.0, "sensor.resolution_deg": 0.0,
                                   "sensor.seed": 5})
    inp = prepare(scn)
    expected = np.random.default_rng(5).standard_normal(scn.n_samples)
    assert np.array_equal(inp.noise, expected)
    assert inp.sigma == math.radians(0.2)


def test_divergence_keeps_the_rows():
    scn = load_scenario("test-1", {"observer.eps": 0.005})  # Euler, Ts/ε = 4: unstable
    with pytest.raises(SimulationDiverged) as info:
        simulate(scn, warn=False)
    partial = info.value.result
    n = len(partial.t)
    assert 1 < n < scn.n_samples
    assert np.all(np.isfinite(partial.theta[:-1]))
    assert "diverged" in str(info.value) and "\n" not in str(info.value)


def test_unstable_setting_warns():
    from esoarm.scenario import ScenarioWarning

    with pytest.warns(ScenarioWarning, match="negative real axis"):
        simulate("test-1", {"observer.eps": 0.015, "duration": 0.5})
