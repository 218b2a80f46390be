"""The noise budget of analyze against a Monte Carlo run of the same LTI loop and the twin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from esoarm.cli import cli
from esoarm.engines.simulation import simulate
from esoarm.scenario import load_scenario
from esoarm.studies.frequency.linearization import linearize
from esoarm.studies.frequency.noise import noise_budget

# (scenario, overrides): measured within 10 % of the twin (docs/frequency.md)
TWIN_CASES = {
    "test-1 eps 0.05, 0.5 deg": ("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5}),
    "test-1 defaults": ("test-1", {}),
    "test-1 cascade eps 0.05": ("test-1", {"observer.kind": "cascade", "observer.eps": 0.05,
                                           "sensor.noise_deg": 0.5}),
    "test-2 eps 0.05": ("test-2", {"observer.eps": 0.05, "sensor.noise_deg": 0.5}),
    "test-1 zoh 1 deg": ("test-1", {"observer.eps": 0.05, "observer.discretization": "zoh",
                                    "sensor.noise_deg": 1.0}),
    # coloured encoder noise (esoarm.plants.noise): the budget's augmented Lyapunov equation
    "test-1 AR(1) 0.7": ("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5,
                                    "sensor.noise_ar": [0.7]}),
    "test-1 AR(2) resonant": ("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5,
                                         "sensor.noise_ar": [1.2, -0.5]}),
    "test-1 vibration 12 Hz": ("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.2,
                                          "sensor.vibration_deg": 0.3,
                                          "sensor.vibration_hz": 12.0,
                                          "sensor.vibration_damping": 0.1}),
}


def test_budget_is_the_lti_loop_driven_by_white_noise() -> None:
    """Independent of the Lyapunov solve: 200 000 samples of the closed loop, seeded."""
    scn = load_scenario("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5})
    b = noise_budget(scn)
    lin = linearize(scn)
    ap, bp, cp, _ = lin.plant
    ak, bk, ck, dk = lin.controller
    xp, xk = np.zeros(ap.shape[0]), np.zeros(ak.shape[0])
    rng = np.random.default_rng(7)
    n = rng.standard_normal(200_000) * math.radians(0.5)
    u = np.empty(n.size)
    th = np.empty(n.size)
    for k in range(n.size):
        theta = cp[0] @ xp
        y = theta + n[k]
        u[k] = -(ck[0] @ xk + dk[0, 0] * y)
        th[k] = theta
        xp = ap @ xp + bp[:, 0] * u[k]
        xk = ak @ xk + bk[:, 0] * y
    u, th = u[1000:], th[1000:]
    assert np.sqrt(np.mean(u**2)) == pytest.approx(b.rms_u, rel=0.02)
    assert np.sqrt(np.mean(np.diff(u) ** 2)) == pytest.approx(b.rms_du, rel=0.02)
    assert np.sqrt(np.mean(th**2)) == pytest.approx(b.rms_error, rel=0.03)


@pytest.mark.parametrize("over", [
    {"sensor.noise_ar": [0.7]},
    {"sensor.noise_ar": [1.2, -0.5], "sensor.vibration_deg": 0.3, "sensor.vibration_hz": 5.0},
    {"sensor.noise_deg": 0.0, "sensor.vibration_deg": 0.4, "sensor.vibration_hz": 8.0,
     "sensor.vibration_damping": 0.1},
])
def test_coloured_budget_is_the_lti_loop_driven_by_that_noise(over: dict) -> None:
    """The augmented Lyapunov solve against 200 000 samples of the LTI loop driven by the
    very sequence the engines take (esoarm.plants.noise.draws), seeded."""
    from esoarm.plants.noise import draws, noise_model

    scn = load_scenario("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5, **over})
    b = noise_budget(scn)
    lin = linearize(scn)
    ap, bp, cp, _ = lin.plant
    ak, bk, ck, dk = lin.controller
    xp, xk = np.zeros(ap.shape[0]), np.zeros(ak.shape[0])
    n = draws(noise_model(scn), 7, 200_000)
    assert b.noise_rms == pytest.approx(np.std(n), rel=0.05)
    u = np.empty(n.size)
    th = np.empty(n.size)
    for k in range(n.size):
        theta = cp[0] @ xp
        y = theta + n[k]
        u[k] = -(ck[0] @ xk + dk[0, 0] * y)
        th[k] = theta
        xp = ap @ xp + bp[:, 0] * u[k]
        xk = ak @ xk + bk[:, 0] * y
    u, th = u[1000:], th[1000:]
    assert np.sqrt(np.mean(u**2)) == pytest.approx(b.rms_u, rel=0.03)
    assert np.sqrt(np.mean(np.diff(u) ** 2)) == pytest.approx(b.rms_du, rel=0.03)
    assert np.sqrt(np.mean(th**2)) == pytest.approx(b.rms_error, rel=0.05)


def test_white_budget_is_unchanged_by_the_noise_model_code() -> None:
    """A white scenario takes the historical path; an AR with φ ≈ 0 agrees with it."""
    scn = load_scenario("test-1", {"observer.eps": 0.05, "sensor.noise_deg": 0.5})
    near = scn.with_overrides({"sensor.noise_ar": [1e-9]})
    a, b = noise_budget(scn), noise_budget(near)
    assert b.rms_u == pytest.approx(a.rms_u, rel=1e-6)
    assert b.rms_du == pytest.approx(a.rms_du, rel=1e-6)
    assert b.rms_error == pytest.approx(a.rms_error, rel=1e-6)


@pytest.mark.parametrize("case", sorted(TWIN_CASES))
def test_budget_predicts_the_twins_noise_driven_control(case: str) -> None:
    """The twin's u with noise minus u without (seeds 0-2): RMS u and RMS Δu within 10 %."""
    name, over = TWIN_CASES[case]
    b = noise_budget(load_scenario(name, over))
    du, ddu = [], []
    for seed in range(3):
        noisy = simulate(name, {**over, "sensor.seed": seed}, warn=False)
        clean = simulate(name, {**over, "sensor.seed": seed, "sensor.noise_deg": 0.0,
                                "sensor.vibration_deg": 0.0}, warn=False)
        d = noisy.u - clean.u
        du.append(np.mean(d**2))
        ddu.append(np.mean(np.diff(d) ** 2))
    assert b.rms_u == pytest.approx(math.sqrt(np.mean(du)), rel=0.10)
    assert b.rms_du == pytest.approx(math.sqrt(np.mean(ddu)), rel=0.10)


def test_analyze_reports_the_budget_or_says_why_not() -> None:
    res = CliRunner().invoke(cli, ["analyze", "test-1", "--set", "sensor.noise_deg=0.5"])
    assert res.exit_code == 0, res.output
    assert "noise budget" in res.output and "RMS Δu" in res.output
    res = CliRunner().invoke(cli, ["analyze", "uno-rig"])
    assert res.exit_code == 0, res.output
    assert "noise budget: not modelled" in res.output


def test_recommended_eps_reaches_the_bandwidth_and_ranks_by_chatter() -> None:
    from esoarm.studies.frequency.noise import perturbation_bandwidth, recommend_eps

    scn = load_scenario("test-1", {"sensor.noise_deg": 0.5})
    recs = recommend_eps(scn, 10.0)
    assert [r.kind for r in recs] == ["cascade", "linear"]
    for r in recs:
        point = scn.with_overrides({"observer.kind": r.kind, "observer.eps": r.eps})
        assert perturbation_bandwidth(point) == pytest.approx(10.0, rel=1e-4)
    # the twin agrees on the chatter ranking (seed 0)
    du = [simulate("test-1", {"sensor.noise_deg": 0.5, "observer.kind": r.kind,
                              "observer.eps": r.eps}, warn=False).metrics["rms_du"] for r in recs]
    assert du[0] < du[1]
    assert recs[0].budget.rms_du < recs[1].budget.rms_du


def test_tracking_needs_a_bandwidth() -> None:
    res = CliRunner().invoke(cli, ["analyze", "test-1", "--tracking"])
    assert res.exit_code == 2
    assert "--tracking: needs --bandwidth" in res.output and "Traceback" not in res.output
