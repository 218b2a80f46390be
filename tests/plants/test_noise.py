"""Coloured measurement noise: AR encoder noise and arm vibration against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines.simulation import prepare
from esoarm.plants.noise import (
    NoiseModel,
    NoiseStream,
    ar_autocovariance,
    ar_spectrum,
    draws,
    noise_model,
    sequence_scale,
    vibration_ar,
)
from esoarm.plants.sensor import noise_sequence
from esoarm.scenario import ScenarioError, load_scenario

TS = 0.02


def _model(sigma_deg: float = 0.5, ar: tuple[float, ...] = (), vib_deg: float = 0.0,
           f0: float = 10.0, zeta: float = 0.05) -> NoiseModel:
    return NoiseModel(math.radians(sigma_deg), ar, math.radians(vib_deg), f0, zeta, TS)


def _acf(x: np.ndarray, lags: int) -> np.ndarray:
    x = x - 0.0  # zero-mean by construction: no mean removal (it would bias the check)
    return np.array([np.mean(x[: len(x) - h] * x[h:]) for h in range(lags + 1)])


def test_ar1_autocovariance_closed_form() -> None:
    # AR(1) with unit innovation: γ(h) = φ^h / (1 − φ²)
    phi = 0.8
    expected = phi ** np.arange(6) / (1 - phi**2)
    np.testing.assert_allclose(ar_autocovariance([phi], 5), expected, rtol=1e-12)


def test_ar2_autocovariance_solves_yule_walker() -> None:
    # the Yule-Walker equations γ(h) = φ1 γ(h−1) + φ2 γ(h−2) (h ≥ 1), γ(0) = φ1γ1 + φ2γ2 + 1
    p1, p2 = 1.2, -0.5
    g = ar_autocovariance([p1, p2], 6)
    assert g[0] == pytest.approx(p1 * g[1] + p2 * g[2] + 1.0, rel=1e-12)
    assert g[1] == pytest.approx(p1 * g[0] + p2 * g[1], rel=1e-12)
    for h in range(2, 7):
        assert g[h] == pytest.approx(p1 * g[h - 1] + p2 * g[h - 2], rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("ar", [(0.6,), (1.2, -0.5), (0.3, 0.2, 0.1)])
def test_sample_variance_and_autocorrelation_match_theory(ar: tuple[float, ...]) -> None:
    """Stationary std = noise_deg whatever φ; autocorrelation ρ(h) = γ(h)/γ(0)."""
    n = 200_000
    m = _model(0.5, ar)
    w = draws(m, 11, n)
    sigma = math.radians(0.5)
    g = ar_autocovariance(ar, 5)
    # std error of a sample variance of a correlated series: ~ sqrt(2 Σ ρ²/n)
    assert np.std(w) == pytest.approx(sigma, rel=0.02)
    rho = _acf(w, 5) / sigma**2
    np.testing.assert_allclose(rho, g / g[0], atol=0.02)


def test_stationary_from_the_first_sample() -> None:
    """The initial state is drawn stationary: sample 0's variance over many seeds is σ²."""
    m = _model(1.0, (0.95,))
    first = np.array([draws(m, s, 1)[0] for s in range(4000)])
    assert np.var(first) == pytest.approx(math.radians(1.0) ** 2, rel=0.08)


def test_vibration_spectrum_peaks_at_its_frequency() -> None:
    m = _model(0.0, (), vib_deg=0.2, f0=7.0, zeta=0.02)
    w = draws(m, 5, 2**16)
    assert np.std(w) == pytest.approx(math.radians(0.2), rel=0.05)
    spec = np.abs(np.fft.rfft(w)) ** 2
    freqs = np.fft.rfftfreq(len(w), TS)
    assert freqs[np.argmax(spec)] == pytest.approx(7.0, abs=0.3)
    # the closed-form AR(2) spectrum peaks there too, and integrates to γ(0)
    phi = vibration_ar(7.0, 0.02, TS)
    f = np.linspace(0, 0.5 / TS, 20001)
    s = ar_spectrum(phi, f, TS)
    assert f[np.argmax(s)] == pytest.approx(7.0, abs=0.05)
    assert np.trapezoid(s, f) == pytest.approx(ar_autocovariance(phi, 0)[0], rel=1e-3)


def test_vibration_poles_are_the_sampled_mode() -> None:
    f0, zeta = 10.0, 0.05
    p1, p2 = vibration_ar(f0, zeta, TS)
    poles = np.roots([1.0, -p1, -p2])
    s = np.log(poles) / TS
    w0 = 2 * math.pi * f0
    np.testing.assert_allclose(sorted(s.imag), [-w0 * math.sqrt(1 - zeta**2),
                                                w0 * math.sqrt(1 - zeta**2)], rtol=1e-12)
    np.testing.assert_allclose(s.real, [-zeta * w0] * 2, rtol=1e-12)


def test_white_model_is_the_historical_sequence() -> None:
    m = _model(0.2)
    assert m.white and sequence_scale(m) == math.radians(0.2)
    assert np.array_equal(draws(m, 4, 300), noise_sequence(4, 300, 0.2))
    scn = load_scenario("test-1")
    inp = prepare(scn)
    assert inp.sigma == math.radians(scn.sensor.noise_deg)
    assert np.array_equal(inp.noise, noise_sequence(0, scn.n_samples, scn.sensor.noise_deg))


def test_coloured_innovations_are_the_white_draws() -> None:
    """With φ1 tiny the AR sequence is σ·(the white model's draws) to first order."""
    a = draws(_model(0.5, (1e-9,)), 2, 1000)
    b = math.radians(0.5) * noise_sequence(2, 1000, 0.5)
    np.testing.assert_allclose(a[1:], b[1:], rtol=0, atol=1e-9 * math.radians(0.5) * 10)


@pytest.mark.parametrize("joints", [1, 3])
def test_stream_gives_the_same_bits_in_any_blocks(joints: int) -> None:
    m = _model(0.3, (0.7, 0.1), vib_deg=0.05, f0=6.0)
    whole = draws(m, 9, 900 * joints, joints)
    for block in (1, 7, 4096):
        s = NoiseStream(m, 9, joints, block)
        assert np.array_equal([s.next() for _ in range(900 * joints)], whole)


def test_joints_have_independent_processes() -> None:
    m = _model(0.5, (0.9,))
    w = draws(m, 1, 2 * 50_000, 2).reshape(-1, 2)
    c = np.corrcoef(w[:, 0], w[:, 1])[0, 1]
    assert abs(c) < 0.05
    # each joint on its own has the AR(1) lag-1 correlation
    for j in range(2):
        assert np.corrcoef(w[:-1, j], w[1:, j])[0, 1] == pytest.approx(0.9, abs=0.02)


def test_deterministic() -> None:
    m = _model(0.3, (0.5,), vib_deg=0.1)
    assert np.array_equal(draws(m, 3, 500), draws(m, 3, 500))
    assert not np.array_equal(draws(m, 3, 500), draws(m, 4, 500))


def test_scenario_keys_make_the_model() -> None:
    scn = load_scenario("test-1", {"sensor.noise_ar": [0.5, 0.2], "sensor.vibration_deg": 0.1,
                                   "sensor.vibration_hz": 5.0, "sensor.vibration_damping": 0.1})
    m = noise_model(scn)
    assert m == NoiseModel(math.radians(0.2), (0.5, 0.2), math.radians(0.1), 5.0, 0.1, 0.02)
    inp = prepare(scn)
    assert inp.sigma == 1.0
    assert np.array_equal(inp.noise, draws(m, 0, scn.n_samples))


@pytest.mark.parametrize("over, key", [
    ({"sensor.noise_ar": [1.0]}, "sensor.noise_ar"),
    ({"sensor.noise_ar": [0.5, 0.6]}, "sensor.noise_ar"),
    ({"sensor.noise_ar": [0.1] * 21}, "sensor.noise_ar"),
    ({"sensor.vibration_deg": 0.1, "sensor.vibration_hz": 25.0}, "sensor.vibration_hz"),
    ({"sensor.vibration_deg": 0.1, "sensor.vibration_hz": 0.001}, "sensor.vibration_damping"),
    ({"sensor.vibration_damping": 1.0}, "sensor.vibration_damping"),
    ({"sensor.vibration_deg": -0.1}, "sensor.vibration_deg"),
])
def test_bad_keys_are_one_line_errors(over: dict, key: str) -> None:
    with pytest.raises(ScenarioError) as err:
        load_scenario("test-1", over)
    msg = str(err.value)
    assert f"'{key}" in msg and "\n" not in msg
