"""The linear ESO's tunings ("half-gain") and its input delay against independent references.

pyadrc (``pyadrc.StateSpace``, G. Herbst's discrete ADRC, current-estimator form) is the
reference for the half-gain observer; the input delay and its predictor are checked against
the delay-free observer fed the shifted commands and against their own linear model.
"""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.contract import PlantDesign
from esoarm.observers import linear
from esoarm.observers.linear import DISCRETIZATIONS, design_observer
from esoarm.scenario import ScenarioError, load_scenario

pyadrc = pytest.importorskip("pyadrc")

TS, B0 = 0.02, 1.0 / 0.0225


def _plant() -> PlantDesign:
    return PlantDesign(np.zeros(1), np.zeros(3), 1, np.array([B0]))


def _inputs(n: int = 400, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS
    y = 0.8 * np.sin(1.3 * t) + 0.01 * rng.standard_normal(n)
    u = 0.4 * np.cos(2.1 * t) + 0.05 * rng.standard_normal(n)
    return y, u


def _scn(**keys: object):  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {f"observer.{k}": v for k, v in keys.items()})


def _run_steps(scn, y: np.ndarray, u: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """ẑ_k of the kind's step functions over (y, u)."""
    d = linear.design(scn, _plant(), TS)
    z = np.zeros(d.n_state)
    zhat = np.zeros(d.n_state)
    linear.initialize(z, y[:1], d.vector)
    out = np.empty((len(y), 3))
    for k in range(len(y)):
        linear.estimate(z, y[k:k + 1], d.vector, zhat)
        out[k] = zhat[:3]
        linear.advance(z, zhat, y[k:k + 1], u[k:k + 1], d.vector)
    return out


@pytest.mark.parametrize("eps", [0.03, 0.09, 0.3])
def test_half_gain_current_observer_is_pyadrc_to_round_off(eps: float) -> None:
    """pyadrc's second-order StateSpace with half_gain=(False, True): x̂_k = (Φ − L C Φ) x̂_{k−1}
    + (Γ − L C Γ) u_{k−1} + L y_k with L/2, zESO = exp(−k_eso·w_cl·Ts); w_cl = 1/ε, k_eso = 1
    puts its poles where ours are.  Same y and u: same estimates."""
    y, u = _inputs()
    got = _run_steps(_scn(eps=eps, discretization="current", tuning="half-gain"), y, u)
    ref = pyadrc.StateSpace(2, TS, B0, 1.0 / eps, 1.0, eso_init=(y[0], 0.0, 0.0),
                            half_gain=(False, True))
    want = np.empty_like(got)
    want[0] = (y[0], 0.0, 0.0)
    for k in range(1, len(y)):
        ref._update_eso(y[k], u[k - 1])
        want[k] = ref.xhat.ravel()
    scale = np.max(np.abs(want), axis=0)
    np.testing.assert_allclose(got / scale, want / scale, rtol=0, atol=1e-11)


def test_pyadrc_bandwidth_gain_is_our_current_gain() -> None:
    """pyadrc's closed form L = (1 − z³, 3/(2Ts)(1 − z)²(1 + z), (1 − z)³/Ts²) and our
    Ackermann gain Lc, and the half-gain vector is exactly half of it."""
    for eps in (0.03, 0.09, 0.3):
        ref = pyadrc.StateSpace(2, TS, B0, 1.0 / eps, 1.0)
        d = design_observer(eps, TS, B0, "current")
        np.testing.assert_allclose(d.gain, ref.L.ravel(), rtol=1e-12)
        h = design_observer(eps, TS, B0, "current", "half-gain")
        np.testing.assert_array_equal(h.gain, 0.5 * d.gain)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_half_gain_every_discretization(disc: str) -> None:
    """Euler: β/2 = (3/(2ε), 3/(2ε²), 1/(2ε³)), Herbst's continuous half-gain polynomial
    s³ + 1.5ω s² + 1.5ω² s + 0.5ω³; "zoh": Lp/2 with Lp = Φ·L(pyadrc) (the predictive form of
    the same observer); "current": pyadrc's L/2.  The half-gain observer stays stable."""
    eps = 0.09
    h = design_observer(eps, TS, B0, disc, "half-gain")
    ref_l = pyadrc.StateSpace(2, TS, B0, 1.0 / eps, 1.0, half_gain=(False, True)).L.ravel()
    if disc == "euler":
        w = 1.0 / eps
        np.testing.assert_allclose(h.beta, [1.5 * w, 1.5 * w**2, 0.5 * w**3], rtol=1e-14)
        np.testing.assert_allclose(h.gain, TS * h.beta, rtol=1e-14)
        a_minus_lc = np.array([[-h.beta[0], 1, 0], [-h.beta[1], 0, 1], [-h.beta[2], 0, 0]])
        np.testing.assert_allclose(np.poly(a_minus_lc), [1, 1.5 * w, 1.5 * w**2, 0.5 * w**3],
                                   rtol=1e-12)
    elif disc == "zoh":
        np.testing.assert_allclose(h.gain, h.phi @ ref_l, rtol=1e-12)
    else:
        np.testing.assert_allclose(h.gain, ref_l, rtol=1e-12)
    assert np.max(np.abs(h.poles)) < 1.0


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_bandwidth_tuning_is_unchanged(disc: str) -> None:
    """The default tuning is the paper's ESO bit for bit (the key's default)."""
    y, u = _inputs(120)
    a = _run_steps(_scn(discretization=disc), y, u)
    b = _run_steps(_scn(discretization=disc, tuning="bandwidth", input_delay=0), y, u)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("nd", [1, 3])
def test_input_delay_feeds_the_command_of_n_samples_ago(disc: str, nd: int) -> None:
    """ESO with input_delay = N over (y, u) == the delay-free ESO over (y, u shifted by N,
    zeros first), bit for bit."""
    y, u = _inputs(200)
    shifted = np.concatenate([np.zeros(nd), u[:-nd]])
    got = _run_steps(_scn(discretization=disc, input_delay=nd), y, u)
    want = _run_steps(_scn(discretization=disc), y, shifted)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("tuning", ["bandwidth", "half-gain"])
@pytest.mark.parametrize("form", ["input", "predictor"])
def test_linearization_reproduces_the_steps(disc: str, tuning: str, form: str) -> None:
    """The analysis model (z⁺ = P z + Q y + Γ u, ẑ = Hz z + Hy y, 3 + N states) gives the step
    functions' estimates sample by sample."""
    nd = 2
    scn = _scn(discretization=disc, tuning=tuning, input_delay=nd, delay_form=form)
    y, u = _inputs(150)
    got = _run_steps(scn, y, u)
    lin = linear.linearization(scn.observer, TS, B0)
    assert lin.p.shape == (3 + nd, 3 + nd)
    z = np.zeros(3 + nd)
    z[0] = y[0]
    want = np.empty_like(got)
    for k in range(len(y)):
        want[k] = lin.hz @ z + lin.hy[:, 0] * y[k]
        z = lin.p @ z + lin.q[:, 0] * y[k] + lin.gamma[:, 0] * u[k]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_predictor_is_exact_on_a_delayed_triple_integrator() -> None:
    """A plant that is the ESO's own model (ÿ = f + b0 u, f constant, u held) with a transport
    delay of N samples: once converged, the predictor's angle and rate at t_k are the plant's at
    t_{k+N} (the model being exact, only the observer's convergence is left)."""
    nd, f, n = 3, 0.7, 600
    rng = np.random.default_rng(1)
    u = 0.05 * rng.standard_normal(n)
    applied = np.concatenate([np.zeros(nd), u])
    x = np.zeros((n + nd + 1, 2))
    for k in range(n + nd):
        a = f + B0 * applied[k]
        x[k + 1] = (x[k, 0] + TS * x[k, 1] + 0.5 * TS * TS * a, x[k, 1] + TS * a)
    got = _run_steps(_scn(discretization="zoh", eps=0.05, input_delay=nd,
                          delay_form="predictor"), x[:n, 0], u)
    np.testing.assert_allclose(got[300:, 0], x[300 + nd:n + nd, 0], atol=1e-9)
    np.testing.assert_allclose(got[300:, 1], x[300 + nd:n + nd, 1], atol=1e-7)
    np.testing.assert_allclose(got[300:, 2], f, atol=1e-6)


def test_bad_keys_are_refused_naming_the_key() -> None:
    with pytest.raises(ScenarioError, match="observer.tuning"):
        _scn(tuning="half")
    with pytest.raises(ScenarioError, match="observer.input_delay"):
        _scn(input_delay=-1)


@pytest.mark.slow
@pytest.mark.parametrize("keys", [
    {"observer.tuning": "half-gain", "observer.discretization": "zoh"},
    {"observer.input_delay": 2, "actuator.delay_samples": 2},
    {"observer.input_delay": 3, "observer.delay_form": "predictor",
     "observer.discretization": "current", "actuator.delay_samples": 3},
])
def test_compiled_engine_is_the_reference_engine(keys: dict) -> None:
    """The batch engine runs the new settings bit for bit like the reference engine."""
    from esoarm.engines import batch
    from esoarm.engines.simulation import prepare, run_reference

    scn = load_scenario("test-1", {"duration": 3.0, **keys})
    (fast,) = batch.simulate_many([scn])
    ref = run_reference(scn, prepare(scn))
    assert np.array_equal(fast.table(), ref.table())


def test_fast_engine_refuses_the_input_delay() -> None:
    from esoarm.engines.fast import unsupported

    assert unsupported(_scn(input_delay=2)) == "observer.input_delay > 0"
    assert unsupported(_scn(tuning="half-gain")) is None


def test_noise_budget_models_the_half_gain_observer() -> None:
    """The linear noise budget sees the halved gains: about half the noise-driven RMS Δu at
    the same ε (the twin measured 0.0598 against 0.1444 N·m, Euler, ε = 0.05 s, 0.5°)."""
    from esoarm.studies.frequency.noise import noise_budget

    over = {"sensor.noise_deg": 0.5, "observer.eps": 0.05}
    full = noise_budget(load_scenario("test-1", over)).rms_du
    half = noise_budget(load_scenario("test-1", {**over, "observer.tuning": "half-gain"})).rms_du
    assert full == pytest.approx(0.1439, rel=0.02)
    assert half == pytest.approx(0.0609, rel=0.02)
