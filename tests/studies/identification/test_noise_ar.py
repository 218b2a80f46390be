"""The residual's AR model (Yule-Walker, AIC) and the sensor-noise verdict, on known series."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_toeplitz

from esoarm.plants.noise import NoiseModel, ar_autocovariance, draws
from esoarm.studies.identification.residual.noise_ar import fit_ar, levinson_durbin, noise_verdict


def _ar(phi: tuple[float, ...], n: int, seed: int, deg: float = 0.3) -> np.ndarray:
    return draws(NoiseModel(math.radians(deg), phi, 0.0, 10.0, 0.05, 0.02), seed, n)


@pytest.mark.parametrize("phi", [(0.5,), (1.2, -0.5), (0.3, 0.2, 0.1)])
def test_levinson_durbin_solves_the_yule_walker_equations(phi: tuple[float, ...]) -> None:
    g = ar_autocovariance(phi, 4)
    p = len(phi)
    coef, s2 = levinson_durbin(g, p)
    np.testing.assert_allclose(coef, solve_toeplitz(g[:p], g[1:p + 1]), rtol=1e-12)
    np.testing.assert_allclose(coef, phi, rtol=1e-10)  # the true autocovariances: exact
    assert s2 == pytest.approx(1.0, rel=1e-10)  # unit innovation


@pytest.mark.parametrize("phi", [(0.7,), (1.2, -0.5), (0.5, 0.0, 0.3)])
def test_recovers_ar_coefficients_and_order(phi: tuple[float, ...]) -> None:
    x = _ar(phi, 20_000, 3)
    fit = fit_ar(x)
    assert fit.order >= len(phi)
    np.testing.assert_allclose(fit.phi[: len(phi)], phi, atol=0.03)
    assert all(abs(c) < 0.05 for c in fit.phi[len(phi):])
    assert math.sqrt(fit.variance) == pytest.approx(math.radians(0.3), rel=0.05)


def test_white_noise_is_order_zero_mostly() -> None:
    orders = [fit_ar(np.random.default_rng(s).standard_normal(2000)).order for s in range(20)]
    assert orders.count(0) >= 14  # AIC overfits now and then, not usually


def test_coloured_noise_in_closed_loop_is_sensor_noise() -> None:
    """Noise fed back into u by a PD (as the excitation's guard does): the prewhitened
    residual is still uncorrelated with the past input."""
    n = 5000
    w = _ar((0.7,), n, 1)
    rng = np.random.default_rng(2)
    excitation = rng.standard_normal(n)
    u = np.zeros(n)
    for k in range(1, n):
        u[k] = excitation[k] - 40.0 * w[k - 1] - 20.0 * (w[k - 1] - w[k - 2])  # feedback
    v = noise_verdict(w, u)
    assert v.is_sensor_noise, v.to_dict()
    assert v.fit.phi[0] == pytest.approx(0.7, abs=0.05)


def test_input_driven_residual_is_model_error() -> None:
    n = 5000
    rng = np.random.default_rng(4)
    u = rng.standard_normal(n)
    missed = np.convolve(u, [0.0, 0.02, 0.01, 0.005])[:n] * 1e-2  # a filtered input
    v = noise_verdict(missed + _ar((0.5,), n, 5, deg=0.005), u)
    assert not v.is_sensor_noise
    assert v.input_statistic > 31.41  # one large correlation (lag 1) fails the portmanteau
    assert v.to_dict()["meaning"].startswith("model error")


def test_verdict_is_deterministic() -> None:
    x = _ar((0.6,), 3000, 9)
    u = np.random.default_rng(1).standard_normal(3000)
    assert noise_verdict(x, u).to_dict() == noise_verdict(x, u).to_dict()


@pytest.mark.slow
@pytest.mark.parametrize("truth_sets, expect", [
    ({"sensor.noise_ar": [0.7], "sensor.noise_deg": 0.3}, [0.7]),
    ({"sensor.noise_ar": [1.2, -0.5], "sensor.noise_deg": 0.3}, [1.2, -0.5]),
    ({"sensor.noise_deg": 0.3}, []),  # white
    ({"rig.backlash_deg": 2.0}, None),  # model error the rigid model cannot explain
])
def test_identify_writes_an_ar_noise_only_when_it_is_one(tmp_path, truth_sets: dict,
                                                         expect: list | None) -> None:
    """Twin logs (sensor.seed 3): coloured encoder noise is written as sensor.noise_ar with
    each φ within 0.05 of the truth and inside its 95 % interval, and its RMS within 10 %;
    white noise is written white; the residual of a rig with backlash fitted by the rigid
    model is never written as noise.  (A Yule-Walker fit of the segments' residual gave
    φ̂ = 0.645 on the AR(1) log: the segments' initial-state fit removes the slow part.)"""
    from esoarm.hardware.excite import excite_twin
    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.data import read_ident_log
    from esoarm.studies.identification.experiment.excitation import ExcitationPlan
    from esoarm.studies.identification.identify import FitFailed, identify

    fine = {"sensor.resolution_deg": 0.001, "sensor.seed": 3}
    truth = load_scenario("test-1", {**fine, **truth_sets})
    excite_twin(truth, ExcitationPlan(), tmp_path / "ex.csv")
    nominal = load_scenario("test-1", fine)
    log = read_ident_log(tmp_path / "ex.csv", nominal.actuator.torque_limit, None)
    try:
        res = identify(nominal, [log])
    except FitFailed as exc:  # refused: nothing written
        assert expect is None, str(exc)
        assert exc.result is None or not exc.result.coloured_noise()
        return
    spec = res.validation["noise_spectrum"]
    assert len(spec["noise_ar"]) == spec["order"] == len(spec["noise_ar_ci95"])
    written = res.fitted_scenario().sensor
    if expect is None:
        assert written.noise_ar == [], spec
        return
    assert written.noise_ar == pytest.approx(expect, abs=0.05), spec
    for value, (lo, hi) in zip(expect, spec["noise_ar_ci95"], strict=True):
        assert lo <= value <= hi, spec
    assert written.noise_deg == pytest.approx(0.3, rel=0.1), spec
    lo, hi = spec["noise_std_ci95_deg"]
    assert lo <= 0.3 <= hi, spec


# -- the segmented residual (restricted likelihood) -----------------------------------------

def _segments(w: np.ndarray, n: int = 100, inputs: np.ndarray | None = None):
    """Split w into segments of n samples and fit each one's offset and slope away (as the
    identification's initial angle and rate do)."""
    from esoarm.studies.identification.residual.noise_ar import SegmentResidual

    t = np.arange(n) * 0.02
    x = np.stack([np.ones(n), t], axis=1)
    u = np.random.default_rng(77).standard_normal(len(w)) if inputs is None else inputs
    out = []
    for s in range(len(w) // n):
        ws = w[s * n:(s + 1) * n]
        r = ws - x @ np.linalg.lstsq(x, ws, rcond=None)[0]
        out.append(SegmentResidual(r, x, u[s * n:(s + 1) * n], np.arange(n)))
    return out


@pytest.mark.parametrize("phi", [(0.7,), (1.2, -0.5), (0.5, 0.0, 0.3)])
def test_correlation_from_partial_autocorrelations_is_the_ar_autocovariance(phi):
    from esoarm.studies.identification.residual.noise_ar import (
        _ar_correlation,
        _kappa_to_phi,
        _phi_to_kappa,
    )

    g = ar_autocovariance(phi, 40)
    kappa = _phi_to_kappa(np.array(phi))
    np.testing.assert_allclose(_ar_correlation(kappa, 40), g / g[0], atol=1e-14)
    np.testing.assert_allclose(_kappa_to_phi(kappa), phi, atol=1e-14)


def test_restricted_likelihood_removes_the_bias_of_the_initial_state_fit():
    """Per-segment offset and slope fitted away (segments of 100 samples) bias Yule-Walker
    low by about (2 + 4φ)/100; the restricted likelihood does not see that part and its
    interval covers the truth."""
    from esoarm.studies.identification.residual.noise_ar import reml_ar

    w = _ar((0.7,), 3000, 11)
    segs = _segments(w)
    yw = fit_ar(np.concatenate([s.r for s in segs]), 1)
    fit, _lik = reml_ar(segs)
    assert yw.phi[0] < 0.7 - 0.03  # the bias this fixes (0.653 here)
    assert fit.order == 1
    lo, hi = fit.phi_ci[0]
    assert lo <= 0.7 <= hi and hi - lo < 0.08, fit
    assert fit.phi[0] == pytest.approx(0.7, abs=0.03)
    s_lo, s_hi = fit.std_ci
    assert s_lo <= math.radians(0.3) <= s_hi, fit


def test_quantization_is_held_apart():
    """AR(1) noise of 0.3° read through 0.6° counts: the white quantization q²/12 is held in
    the model, so φ and the AR std are the noise's, not those of noise plus rounding."""
    from esoarm.studies.identification.residual.noise_ar import reml_ar

    q = math.radians(0.6)
    w = np.round(_ar((0.7,), 3000, 12) / q) * q
    fit, _lik = reml_ar(_segments(w), q * q / 12.0, max_order=2)
    naive, _ = reml_ar(_segments(w), 0.0, max_order=2)
    assert fit.phi_ci[0][0] <= 0.7 <= fit.phi_ci[0][1], fit
    assert naive.phi[0] < fit.phi_ci[0][0]  # without it, φ is pulled toward white


def test_segmented_white_noise_is_white_sensor_noise():
    from esoarm.studies.identification.residual.noise_ar import segment_verdict

    w = np.random.default_rng(6).standard_normal(2000) * math.radians(0.2)
    v = segment_verdict(_segments(w))
    assert v.is_sensor_noise and v.fit.order == 0, v.to_dict()
    assert v.to_dict()["noise_std_ci95_deg"][0] <= 0.2 <= v.to_dict()["noise_std_ci95_deg"][1]


def test_segmented_input_driven_residual_is_model_error():
    from esoarm.studies.identification.residual.noise_ar import segment_verdict

    n = 2000
    u = np.random.default_rng(4).standard_normal(n)
    missed = np.convolve(u, [0.0, 0.02, 0.01, 0.005])[:n] * 1e-2
    v = segment_verdict(_segments(missed + _ar((0.5,), n, 5, deg=0.005), inputs=u))
    assert not v.is_sensor_noise
    assert v.to_dict()["input_cross_correlation_chi2"] > 31.41


def test_segment_verdict_is_deterministic():
    from esoarm.studies.identification.residual.noise_ar import segment_verdict

    segs = _segments(_ar((0.6,), 1000, 9))
    a, b = segment_verdict(segs).to_dict(), segment_verdict(segs).to_dict()
    assert a == b
