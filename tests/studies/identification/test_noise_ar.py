"""The residual's AR model (Yule-Walker, AIC) and the sensor-noise verdict, on known series."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_toeplitz

from esoarm.plants.noise import NoiseModel, ar_autocovariance, draws
from esoarm.studies.identification.noise_ar import fit_ar, levinson_durbin, noise_verdict


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
@pytest.mark.parametrize("truth_sets, coloured", [
    ({"sensor.noise_ar": [0.7], "sensor.noise_deg": 0.3}, True),
    ({"rig.backlash_deg": 2.0}, False),  # model error the rigid model cannot explain
])
def test_identify_writes_an_ar_noise_only_when_it_is_one(tmp_path, truth_sets: dict,
                                                         coloured: bool) -> None:
    """Never written wrong: a coloured noise, if written, is the truth's (φ within 0.1);
    the residual of a rig with backlash fitted by the rigid model is never written as noise."""
    from esoarm.hardware.excite import excite_twin
    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.data import read_ident_log
    from esoarm.studies.identification.excitation import ExcitationPlan
    from esoarm.studies.identification.identify import FitFailed, identify

    fine = {"sensor.resolution_deg": 0.001, "sensor.seed": 3}
    truth = load_scenario("test-1", {**fine, **truth_sets})
    excite_twin(truth, ExcitationPlan(), tmp_path / "ex.csv")
    nominal = load_scenario("test-1", fine)
    log = read_ident_log(tmp_path / "ex.csv", nominal.actuator.torque_limit, None)
    try:
        res = identify(nominal, [log])
    except FitFailed as exc:  # refused: nothing written
        assert exc.result is None or exc.result.coloured_noise() is None or coloured
        return
    spec = res.validation["noise_spectrum"]
    assert spec["order"] >= 0 and len(spec["noise_ar"]) == spec["order"]
    written = res.fitted_scenario().sensor.noise_ar
    if coloured:
        assert not written or written[0] == pytest.approx(0.7, abs=0.1), spec
    else:
        assert written == [], spec
