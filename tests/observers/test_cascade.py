"""The cascade ESO (observer kind "cascade") against the authors' equations and the linear ESO."""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.contract import PlantDesign
from esoarm.engines.simulation import simulate
from esoarm.observers import cascade, linear
from esoarm.observers.linear import DISCRETIZATIONS, design_observer
from esoarm.scenario import ScenarioError, load_scenario

TS, B0 = 0.02, 1.0 / 0.0225


def _plant() -> PlantDesign:
    return PlantDesign(np.zeros(1), np.zeros(3), 1, np.array([B0]))


def _inputs(n: int = 300, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS
    y = np.sin(2.0 * t) + 0.01 * rng.standard_normal(n)
    u = 0.3 * np.cos(3.0 * t) + 0.05 * rng.standard_normal(n)
    return y, u


def _run_steps(scn, y: np.ndarray, u: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """ẑ_k of the kind's step functions over (y, u)."""
    mod = cascade if scn.observer.kind == "cascade" else linear
    d = mod.design(scn, _plant(), TS)
    z = np.zeros(d.n_state)
    zhat = np.zeros(3)
    mod.initialize(z, y[:1], d.vector)
    out = np.empty((len(y), 3))
    for k in range(len(y)):
        mod.estimate(z, y[k:k + 1], d.vector, zhat)
        out[k] = zhat
        mod.advance(z, zhat, y[k:k + 1], u[k:k + 1], d.vector)
    return out


def _scn(disc: str, levels: int = 2, ratio: float = 2.0, eps: float = 0.05):  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {"observer.kind": "cascade", "observer.eps": eps,
                                    "observer.levels": levels, "observer.ratio": ratio,
                                    "observer.discretization": disc})


def test_euler_is_the_authors_continuous_cascade_stepped_with_euler() -> None:
    """Independent reference: the continuous CESO of Łakomy & Madonski (their cesoObserverP3),
    z⁺ = z + Ts·ż, written here level by level with plain numpy."""
    y, u = _inputs()
    eps = 0.05
    levels, ratio = 3, 2.0
    got = _run_steps(_scn("euler", levels, ratio, eps), y, u)
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    bvec = np.array([0.0, 1.0, 0.0])
    w = [1.0 / (eps * ratio ** (levels - 1 - i)) for i in range(levels)]
    gains = [np.array([3 * wi, 3 * wi**2, wi**3]) for wi in w]
    zs = [np.array([y[0], 0.0, 0.0]) for _ in range(levels)]
    for k in range(len(y)):
        est = np.array([zs[-1][0], zs[-1][1], sum(z[2] for z in zs)])
        np.testing.assert_allclose(got[k], est, rtol=1e-9, atol=1e-9)
        dots = []
        for i in range(levels):
            meas = y[k] if i == 0 else zs[i - 1][0]
            known = sum(zs[j][2] for j in range(i))
            dots.append(a @ zs[i] + bvec * (B0 * u[k] + known) + gains[i] * (meas - zs[i][0]))
        zs = [z + TS * d for z, d in zip(zs, dots, strict=True)]


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_one_level_is_the_linear_eso(disc: str) -> None:
    y, u = _inputs()
    got = _run_steps(_scn(disc, levels=1), y, u)
    ref = _run_steps(load_scenario("test-1", {"observer.eps": 0.05,
                                              "observer.discretization": disc}), y, u)
    if disc == "euler":  # grouped as Φ z + Ts β e instead of z + Ts (A z + β e)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    else:
        assert np.array_equal(got, ref)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("levels", [1, 2, 3, 5])
def test_linear_model_is_the_step_functions(disc: str, levels: int) -> None:
    """analyze's matrices reproduce the step functions' estimates sample by sample."""
    scn = _scn(disc, levels, 1.7)
    y, u = _inputs()
    got = _run_steps(scn, y, u)
    pm, qm, gm, hz, hy = cascade.linear_model(scn, B0, TS)
    d = cascade.design(scn, _plant(), TS)
    z = np.zeros(d.n_state)
    cascade.initialize(z, y[:1], d.vector)
    for k in range(len(y)):
        np.testing.assert_allclose(hz @ z + hy[:, 0] * y[k], got[k], rtol=1e-9, atol=1e-9)
        z = pm @ z + qm[:, 0] * y[k] + gm[:, 0] * u[k]


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_poles_are_the_levels_poles(disc: str) -> None:
    scn = _scn(disc, 3, 2.0)
    pm = cascade.linear_model(scn, B0, TS)[0]
    want = np.sort(np.concatenate([design_observer(e, TS, B0, disc).poles
                                   for e in cascade.level_eps(0.05, 3, 2.0)]))
    # a triple pole is ill-conditioned (the eigenvalues split by ~cbrt(1e-16))
    np.testing.assert_allclose(np.sort(np.abs(np.linalg.eigvals(pm))), want, atol=2e-4)


def test_bad_keys_are_refused() -> None:
    with pytest.raises(ScenarioError, match="levels"):
        load_scenario("test-1", {"observer.kind": "cascade", "observer.levels": 6})
    with pytest.raises(ScenarioError, match="ratio"):
        load_scenario("test-1", {"observer.kind": "cascade", "observer.ratio": 1.0})


def test_cuts_control_chatter_on_test1_with_encoder_noise() -> None:
    """Issue check: test-1, 0.5° encoder noise, ε = 0.05 s, four seeds; the cascade at its
    defaults (2 levels, α = 1.8) cuts rms_du ≥ 30 % at ≤ 1.1× the linear ESO's rms_error."""
    def mean(kind: str) -> tuple[float, float]:
        rows = [simulate("test-1", {"observer.kind": kind, "observer.eps": 0.05,
                                    "sensor.noise_deg": 0.5, "sensor.seed": s},
                         warn=False).metrics for s in range(4)]
        return (float(np.mean([r["rms_error"] for r in rows])),
                float(np.mean([r["rms_du"] for r in rows])))

    lin_e, lin_du = mean("linear")
    cas_e, cas_du = mean("cascade")
    assert cas_du <= 0.7 * lin_du
    assert cas_e <= 1.1 * lin_e
