"""Issue 30: the held-out calibration rigs that ``esoarm identify`` wrote confidently wrong on
the frozen commit 45e3d9f (seeds 7,000,000 … 7,000,199 and 8,000,000 … 8,000,119), and the
pieces of the estimator changed for them.

* 7000064 (1 kHz, AR(1) φ 0.79 noise, 2-sample delay, 7 ms lag): written as a 4-sample delay
  [4, 4] with a 5.2 ms lag that missed (the delay was chosen before the stiction was fitted,
  and only one neighbour was tried again with it), and every interval white-noise narrow
  (segments too long for the AR noise's restricted likelihood);
* 7000106 (50 Hz, 27 ms lag): the noise σ written 0.145° [0.141, 0.149] against 0.133°: each
  segment started its lag state at the previous torque, a model error the σ absorbed;
* 8000019 (50 Hz, no stiction): a stiction of 0.003 N·m, poorly determined, kept, and the
  gravity term written ±1e-4 missing by 3.4 standard errors.

Each slow test below was run on the code before this change (main at 5627e07, the same
estimator as 45e3d9f) and failed: all three rigs came out ``wrong`` there, exactly as in the
held-out dumps.  The fast tests check the new pieces against independent references.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from esoarm.studies.identification.experiment.calibration import draw_rig, run_rig


def test_the_lag_state_at_a_segment_start_is_the_twins():
    """lag_state(src, k0, T, h, nsub) equals τ after running the twin's own plant step
    (esoarm.plants.lever_arm.advance) over the torques before k0, from rest; the old start
    (the previous torque) is far off for a lag of more than a sample."""
    from esoarm.plants.lever_arm import LAG, advance
    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.data import IdentLog, lag_state
    from esoarm.studies.identification.fit import Problem, limits_from_data

    scn = load_scenario("test-1")
    fs = 50.0
    rng = np.random.default_rng(30)
    src = rng.normal(0.0, 0.3, 400)
    t = np.arange(len(src)) / fs
    log = IdentLog("x", t, np.zeros_like(t), src, None, 1.0 / fs)
    prob = Problem(scn, [log], 50, 0, 0, [], {  # the design vector as identify builds it
        "rig.inertia_scale": 1.0, "plant.m2": scn.plant.m2, "rig.coulomb_friction": 0.0,
        "rig.viscous_friction": 0.01, "actuator.lag": 0.027, "motor.torque_constant": 0.0,
        "rig.stiction": 0.0}, limits_from_data(scn, [log]))
    design, _src = prob.design(np.zeros(2 * prob.n_seg))
    h, nsub = prob.h, prob.nsub
    lag = float(design[1 + LAG])
    assert lag == pytest.approx(0.027)
    x = np.zeros(3)
    u = np.empty(1)
    taus = [0.0]
    for k in range(len(src)):
        u[0] = src[k]
        advance(x, u, k / fs, h, nsub, design)
        taus.append(float(x[2]))
    for k0 in (1, 7, 150, 399):
        assert lag_state(src, k0, lag, h, nsub) == pytest.approx(taus[k0], abs=1e-12)
    old_error = max(abs(src[k0 - 1] - taus[k0]) for k0 in (150, 399))
    assert old_error > 0.05  # the old start was model error of this size [N·m]


def test_the_ar_sandwich_by_filtering_equals_the_dense_one():
    """_ar_filter_sandwich (columns filtered by 1/A backwards) equals (JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹
    with Σ = σ_e² A⁻¹A⁻ᵀ built densely, A the AR(2) filter from rest on each segment."""
    from esoarm.studies.identification.identify import _ar_filter_sandwich

    rng = np.random.default_rng(7)
    n, p = 300, 3
    seg_start, seg_len = np.array([0, 120]), np.array([120, 180])
    jac = rng.normal(size=(n, p))
    ar = [0.6, 0.2]
    resid = rng.normal(size=n)
    prob = SimpleNamespace(mask=np.ones(n, dtype=bool), seg_start=seg_start, seg_len=seg_len)
    sol = SimpleNamespace(jac=jac, fun=-resid)
    got = _ar_filter_sandwich(prob, sol, ar)
    a_inv = np.linalg.inv(jac.T @ jac)
    b = np.zeros((p, p))
    e2, n_e = 0.0, 0
    for k0, ln in zip(seg_start, seg_len, strict=True):
        a = np.eye(ln)
        for i, c in enumerate(ar, start=1):
            a -= c * np.eye(ln, k=-i)
        e = (a @ resid[k0:k0 + ln])[len(ar):]
        e2 += float(e @ e)
        n_e += len(e)
        cov = np.linalg.inv(a) @ np.linalg.inv(a).T
        js = jac[k0:k0 + ln]
        b += js.T @ cov @ js
    want = a_inv @ (b * e2 / n_e) @ a_inv
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_an_alternative_model_widens_every_written_interval_to_its_values():
    """_join_alternatives: each written interval joined with itself moved to the
    alternative's value; withheld ones, the delay and the noise are left alone."""
    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.identify import (
        Estimate,
        IdentResult,
        _join_alternatives,
        _withhold,
    )

    scn = load_scenario("test-1")
    est = {"rig.inertia_scale": Estimate("rig.inertia_scale", 1.0, (0.99, 1.02), "1", "I"),
           "plant.m2": Estimate("plant.m2", 0.55, (0.549, 0.551), "kg", "m2"),
           "actuator.lag": _withhold(Estimate("actuator.lag", 0.01, (0.009, 0.011), "s",
                                              "T"), "why"),
           "actuator.delay_samples": Estimate("actuator.delay_samples", 1.0, (1.0, 1.0),
                                              "samples", "d")}
    grav = Estimate("gravity_coefficient", 0.0, (0.0, 0.0), "N·m", "G")
    res = IdentResult(scn, est, grav, 99.0, {}, 0.001, {1: 1.0}, 100, 2.0, 1.0, 1, [], [])
    _join_alternatives(res, [{"rig.inertia_scale": 0.95, "plant.m2": 0.5505,
                              "actuator.lag": 0.5, "actuator.delay_samples": 4.0}],
                       "advice", "method")
    assert res.estimates["rig.inertia_scale"].ci95 == pytest.approx((0.94, 1.02))
    assert res.estimates["plant.m2"].ci95 == pytest.approx((0.549, 0.5515))  # moved by 5e-4
    assert res.estimates["actuator.lag"].ci95 == (0.009, 0.011)
    assert res.estimates["actuator.delay_samples"].ci95 == (1.0, 1.0)
    assert "method: rig.inertia_scale" in res.interval_method


@pytest.mark.slow
@pytest.mark.parametrize("seed", [7000064, 7000106, 8000019])
def test_held_out_rigs_written_confidently_wrong_before_are_not_now(seed, tmp_path):
    """Run as a user would (esoarm excite, then esoarm identify --json, calibration.run_rig).
    On 5627e07 (estimator of 45e3d9f) all three were 'wrong'; 7000064 and 7000106 are
    recovered now, 8000019 misses its gravity term only near (inside the 99.9 % extension)."""
    out = run_rig(draw_rig(seed), tmp_path)
    assert out.verdict in ("recovered", "flagged", "missed"), (out.verdict, out.missed,
                                                              out.params)
    if seed != 8000019:
        assert out.verdict == "recovered", (out.missed, out.params)
    if seed == 7000064:  # the delay's interval spans the ridge and holds the truth
        _t, value, lo, hi, _w = out.params["actuator.delay_samples"]
        assert lo <= 2.0 <= hi, (value, lo, hi)
        assert math.isfinite(out.params["actuator.lag"][2])
