"""The opt-in fast engine against the exact engine.

Contract (docs/benchmarks.md, ``esoarm.engines.fast``): relative difference ≤ 1e-9 on
every metric wherever no quantization boundary is crossed (checked with
``sensor.resolution_deg = 0`` over every discretization and setting); with a
quantizing encoder, a run may differ when a measurement lands on the other
side of a quantization step -- how often, and by how much, is measured here
and must stay rare and small.  Diverged runs are the exact engine's.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from esoarm.engines import batch, fast
from esoarm.scenario import builtin_names, load_scenario

pytestmark = pytest.mark.skipif(not fast.available(),
                                reason="the fast engine's C kernel does not build here")

RTOL = 1e-9
SEEDS = range(4)
# every setting the loop distinguishes (short runs keep the exact engine quick)
SETTINGS = {
    "default": {},
    "no-noise": {"sensor.noise_deg": 0.0},
    "lag": {"actuator.lag": 0.03},
    "delay": {"actuator.delay_samples": 3},
    "lag+delay": {"actuator.lag": 0.01, "actuator.delay_samples": 1},
    "saturation": {"actuator.torque_limit": 0.3},
    "model-compensation": {"controller.compensation": "model"},
    "theta0": {"rig.theta0": 0.3},
    "fine-step": {"rig.step": 0.0005, "sensor.rate_hz": 100.0},
    "no-disturbance": {"rig.disturbance.amplitude": 0.0},
    "ar-noise": {"sensor.noise_ar": [0.7, 0.1], "sensor.noise_deg": 0.3},
    "vibration": {"sensor.vibration_deg": 0.1, "sensor.vibration_hz": 7.0},
    "pwm": {"actuator.pwm_bits": 8},
    "pwm+delay+saturation": {"actuator.pwm_bits": 5, "actuator.delay_samples": 2,
                             "actuator.torque_limit": 0.3},
}
DISCRETIZATIONS = ("euler", "zoh", "current")


def _points(name: str, disc: str, resolution: float) -> list:  # type: ignore[type-arg]
    return [load_scenario(name, {"duration": 6.0, "observer.discretization": disc,
                                 "sensor.resolution_deg": resolution, "observer.eps": eps,
                                 **extra})
            for extra in SETTINGS.values() for eps in (0.03, 0.09, 0.25)]


def _rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(a - b) / np.maximum(np.abs(b), 1e-300)


def _computed(values: np.ndarray) -> np.ndarray:
    """The metric columns the fast engine computes (fast.COMPUTED: all of them)."""
    return values[:, list(fast.COMPUTED)]


COUNTS = [batch.METRICS.index("samples"), batch.METRICS.index("diverged")]
FLOATS = [i for i in range(len(batch.METRICS)) if i not in COUNTS]


@pytest.mark.parametrize("name", [n for n in builtin_names(plant="lever-arm")
                                  if load_scenario(n).motor is None])
@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_agrees_without_quantization(name: str, disc: str) -> None:
    pts = _points(name, disc, 0.0)
    exact = _computed(batch.run_metrics(pts, seeds=SEEDS).values)
    quick = _computed(fast.run_metrics(pts, seeds=SEEDS).values)
    assert not exact[:, -1].any()
    np.testing.assert_array_equal(quick[:, COUNTS], exact[:, COUNTS])  # samples, diverged
    np.testing.assert_allclose(quick[:, FLOATS], exact[:, FLOATS], rtol=RTOL, atol=0)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_quantization_boundaries_are_rare_and_small(disc: str) -> None:
    """With the default 0.05° encoder: at most 2 % of runs beyond 1e-9, none beyond 1e-3."""
    pts = _points("test-1", disc, 0.05)
    exact = _computed(batch.run_metrics(pts, seeds=SEEDS).values)
    quick = _computed(fast.run_metrics(pts, seeds=SEEDS).values)
    rel = _rel(quick[:, FLOATS], exact[:, FLOATS])
    differing = (rel > RTOL).any(axis=1)
    assert differing.mean() <= 0.02, differing.mean()
    rms = [batch.METRICS.index(m) for m in ("rms_error", "rms_u", "rms_f_error")]
    assert _rel(quick[:, rms], exact[:, rms]).max() < 1e-3


def test_diverged_runs_are_the_exact_engines() -> None:
    # Ts/eps = 2.5 > 2: the Euler observer is unstable and the run leaves the range
    pts = [load_scenario("test-1", {"duration": 4.0, "observer.eps": eps})
           for eps in (0.008, 0.09)]
    exact = _computed(batch.run_metrics(pts, seeds=SEEDS).values)
    quick = _computed(fast.run_metrics(pts, seeds=SEEDS).values)
    assert exact[:4, -1].all() and not exact[4:, -1].any()
    np.testing.assert_array_equal(quick[:4], exact[:4])
    np.testing.assert_allclose(quick[4:], exact[4:], rtol=1e-6)


def test_deterministic_whatever_the_threads_and_chunks() -> None:
    pts = [load_scenario("test-1", {"duration": 3.0, "observer.eps": e})
           for e in np.geomspace(0.03, 0.3, 7)]
    one = _computed(fast.run_metrics(pts, seeds=range(10), workers=1).values)
    two = _computed(fast.run_metrics(pts, seeds=range(10), workers=2, chunk=13).values)
    np.testing.assert_array_equal(one, two)


def test_mixed_structures_in_one_call() -> None:
    """Runs that cannot share a block (other N, step, disturbance) come back in order."""
    pts = [load_scenario("test-1", {"duration": 2.0}),
           load_scenario("test-2", {"duration": 3.0, "rig.step": 0.0005}),
           load_scenario("test-1", {"duration": 2.0, "rig.disturbance.frequency": 2.0}),
           load_scenario("test-1", {"duration": 2.0, "actuator.delay_samples": 2})]
    exact = _computed(batch.run_metrics(pts, seeds=range(3)).values)
    quick = _computed(fast.run_metrics(pts, seeds=range(3)).values)
    np.testing.assert_allclose(quick, exact, rtol=1e-9)


# gear backlash (esoarm.plants.backlash): the two-mass drive train in the C kernel
BACKLASH = {
    "backlash-1": {"rig.backlash_deg": 1.0},
    "backlash-2": {"rig.backlash_deg": 2.0},
    "backlash+delay+pwm": {"rig.backlash_deg": 1.5, "actuator.delay_samples": 2,
                           "actuator.pwm_bits": 8},
    "backlash+saturation": {"rig.backlash_deg": 1.0, "actuator.torque_limit": 0.3},
    "backlash+other-gear": {"rig.backlash_deg": 1.0, "rig.motor_inertia": 2e-3,
                            "rig.gear_stiffness": 80.0, "rig.gear_damping": 0.1},
}


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_backlash_agrees_without_quantization(disc: str) -> None:
    """The fast engine's geared plant against the exact engine's, to the same 1e-9.

    At observer.eps = 0.25 the closed loop with play is insensitive to round-off (the exact
    engine itself moves by < 1e-8 when θ0 moves by 1e-15 rad).  With a high-gain observer
    (eps = 0.03) the loop chatters in the gap and the exact engine's own metrics move by up
    to ~8 % for such a 1e-15 rad change, so no engine agrees there to 1e-9 (see
    ``test_backlash_high_gain_is_round_off_sensitive``).
    """
    pts = [load_scenario("test-1", {"duration": 6.0, "observer.discretization": disc,
                                    "sensor.resolution_deg": 0.0, "observer.eps": 0.25,
                                    **extra})
           for extra in BACKLASH.values()]
    assert all(fast.unsupported(p) is None for p in pts)
    exact = _computed(batch.run_metrics(pts, seeds=SEEDS).values)
    quick = _computed(fast.run_metrics(pts, seeds=SEEDS).values)
    assert not exact[:, -1].any()
    np.testing.assert_array_equal(quick[:, COUNTS], exact[:, COUNTS])
    np.testing.assert_allclose(quick[:, FLOATS], exact[:, FLOATS], rtol=RTOL, atol=0)
    # the play matters: the same runs with a rigid gear differ far beyond the tolerance
    rigid = [p.with_overrides({"rig.backlash_deg": 0.0}) for p in pts]
    stiff = _computed(fast.run_metrics(rigid, seeds=SEEDS).values)
    assert _rel(stiff[:, FLOATS], exact[:, FLOATS]).max() > 1e-3


def test_backlash_high_gain_is_round_off_sensitive() -> None:
    """Where the fast engine differs from the exact one with play, so does the exact engine
    from itself when θ0 moves by 1e-15 rad: the difference is round-off amplified by the
    gap's switching, not a model difference."""
    pts = [load_scenario("test-1", {"duration": 6.0, "sensor.resolution_deg": 0.0,
                                    "observer.eps": 0.03, "rig.backlash_deg": 2.0})]
    exact = _computed(batch.run_metrics(pts, seeds=SEEDS).values)
    moved = _computed(batch.run_metrics([pts[0].with_overrides({"rig.theta0": 1e-15})],
                                        seeds=SEEDS).values)
    quick = _computed(fast.run_metrics(pts, seeds=SEEDS).values)
    np.testing.assert_array_equal(quick[:, COUNTS], exact[:, COUNTS])
    own = _rel(moved[:, FLOATS], exact[:, FLOATS]).max()
    assert own > 1e-6  # the exact engine's own sensitivity here
    assert _rel(quick[:, FLOATS], exact[:, FLOATS]).max() < 10 * own


def test_backlash_zero_keeps_the_rigid_kernel() -> None:
    """rig.backlash_deg = 0 with other gear keys set is the rigid gear, bit for bit."""
    pts = [load_scenario("test-1", {"duration": 3.0, "observer.eps": e})
           for e in (0.05, 0.2)]
    geared = [p.with_overrides({"rig.gear_stiffness": 200.0, "rig.motor_inertia": 5e-3})
              for p in pts]
    np.testing.assert_array_equal(fast.run_metrics(geared, seeds=range(3)).values,
                                  fast.run_metrics(pts, seeds=range(3)).values)


def test_loading_the_kernel_keeps_subnormals() -> None:
    """Built with -ffast-math but not linked with it: no process-wide flush-to-zero."""
    fast.load_kernel()
    tiny = np.array([5e-324])
    assert (tiny * 1.0)[0] != 0.0
    assert ctypes.c_double(5e-324).value * 1.0 != 0.0


def test_scenario_that_needs_the_exact_engine() -> None:
    scn = load_scenario("test-1", {"motor.gear_ratio": 50.0})
    with pytest.raises(ValueError, match=r"\[motor\].*--engine exact"):
        fast.run_metrics([scn])
    scn = load_scenario("test-1", {"rig.stiction": 0.1})
    with pytest.raises(ValueError, match=r"rig.stiction.*--engine exact"):
        fast.run_metrics([scn])


def test_without_a_compiler_it_falls_back(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fast, "_LIB", None)
    monkeypatch.setattr(fast, "_LIB_ERROR", None)
    monkeypatch.setattr(fast, "_warned", False)
    monkeypatch.setattr(fast, "_compiler", lambda: None)
    scn = load_scenario("test-1", {"duration": 1.0})
    with pytest.warns(fast.FastEngineWarning, match="needs a C compiler"):
        got = fast.run_metrics([scn]).values
    np.testing.assert_array_equal(got, batch.run_metrics([scn]).values)


def test_tune_with_the_fast_engine_finds_the_same_optimum() -> None:
    from esoarm.studies.sweeps.tune import parse_bound, tune

    base = load_scenario("test-1", {"duration": 3.0, "sensor.resolution_deg": 0.0})
    bounds = [parse_bound("observer.eps=0.03:0.3", base)]
    kw = {"seeds": 2, "seed": 1, "maxiter": 4, "popsize": 5}
    exact = tune(base, bounds, **kw)  # type: ignore[arg-type]
    quick = tune(base, bounds, engine="fast", **kw)  # type: ignore[arg-type]
    assert quick.runs == exact.runs
    assert quick.best["observer.eps"] == pytest.approx(exact.best["observer.eps"], rel=1e-9)
    for key, value in exact.best_metrics.items():
        assert quick.best_metrics[key] == pytest.approx(value, rel=1e-9), key


def test_cli_engine_fast(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from click.testing import CliRunner

    from esoarm.cli import cli

    outs = {}
    for engine in ("exact", "fast"):
        outs[engine] = tmp_path / f"{engine}.csv"
        res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.05,0.1",
                                       "--seeds", "3", "--set", "duration=2.0",
                                       "--set", "sensor.resolution_deg=0", "--engine", engine,
                                       "--out", str(outs[engine])])
        assert res.exit_code == 0, res.output
    exact = np.loadtxt(outs["exact"], delimiter=",", skiprows=1)
    quick = np.loadtxt(outs["fast"], delimiter=",", skiprows=1)
    np.testing.assert_allclose(quick, exact, rtol=1e-9)
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.1",
                                   "--engine", "turbo"])
    assert res.exit_code == 2 and "--engine" in res.stderr
