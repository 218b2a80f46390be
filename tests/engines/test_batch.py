"""The compiled batch engine against the reference engine (the sampled-data loop), run by run.

Contract: every time series and metric equal to ``run_reference`` within
rtol = 1e-12 (atol 1e-12 for values that cross zero); in practice the two
engines agree bit for bit, which :func:`test_bit_identical_builtin` requires
for the built-in scenarios.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from esoarm.engines import batch
from esoarm.engines.metrics import METRICS, pairwise_sum
from esoarm.engines.simulation import SimulationDiverged, prepare, run_reference
from esoarm.scenario import builtin_names, load_scenario

RTOL = 1e-12
ATOL = 1e-12
SHORT = {"duration": 3.0}  # keeps the plain-Python reference quick

# every setting the sampled-data loop distinguishes, each on a short run
CASES = {
    "default": {},
    "no-noise": {"sensor.noise_deg": 0.0},
    "no-quantization": {"sensor.resolution_deg": 0.0},
    "noise-free-exact": {"sensor.noise_deg": 0.0, "sensor.resolution_deg": 0.0},
    "lag": {"actuator.lag": 0.03},
    "delay": {"actuator.delay_samples": 3},
    "lag+delay": {"actuator.lag": 0.01, "actuator.delay_samples": 1},
    "saturation": {"actuator.torque_limit": 0.05},
    "model-compensation": {"controller.compensation": "model"},
    "theta0-seed": {"rig.theta0": 0.3, "sensor.seed": 7},
    "fine-step": {"rig.step": 0.0005, "sensor.rate_hz": 100.0},
    "eps-0.05": {"observer.eps": 0.05},
    "motor": {"motor.pwm_max": 1023, "motor.deadband": 0.05, "actuator.delay_samples": 1},
    "motor+lag": {"motor.supply_voltage": 6.0, "actuator.lag": 0.02},
    "stiction": {"rig.stiction": 0.15, "rig.stribeck_velocity": 0.05},
    "ar-noise": {"sensor.noise_ar": [0.7, 0.1], "sensor.noise_deg": 0.3},
    "vibration": {"sensor.vibration_deg": 0.1, "sensor.vibration_hz": 7.0},
    "ar+vibration": {"sensor.noise_ar": [0.5], "sensor.vibration_deg": 0.05,
                     "sensor.vibration_damping": 0.02},
    "backlash": {"rig.backlash_deg": 2.0},
    "backlash+lag+stiction": {"rig.backlash_deg": 1.0, "actuator.lag": 0.02,
                              "rig.stiction": 0.1, "rig.gear_damping": 0.0},
    "pwm": {"actuator.pwm_bits": 8},
    "pwm+delay": {"actuator.pwm_bits": 6, "actuator.delay_samples": 2},
}
DISCRETIZATIONS = ("euler", "zoh", "current")


def _scenario(name: str, disc: str, extra: dict) -> object:
    if load_scenario(name).motor is not None:  # a motor's pwm_max is its PWM resolution
        extra = {k: v for k, v in extra.items() if k != "actuator.pwm_bits"}
    return load_scenario(name, {**SHORT, "observer.discretization": disc, **extra})


def _assert_same(fast, ref) -> None:  # type: ignore[no-untyped-def]
    for attr in ("t", "theta", "theta_ref", "error", "u", "z", "f_true", "omega", "y",
                 "saturated"):
        np.testing.assert_allclose(getattr(fast, attr), getattr(ref, attr), rtol=RTOL, atol=ATOL,
                                   err_msg=attr)
    for key, value in ref.metrics.items():
        np.testing.assert_allclose(fast.metrics[key], value, rtol=RTOL, atol=0, err_msg=key)


@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))
@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_series_match_reference(name: str, disc: str) -> None:
    scns = [_scenario(name, disc, extra) for extra in CASES.values()]
    fast = batch.simulate_many(scns)
    for scn, res in zip(scns, fast, strict=True):
        _assert_same(res, run_reference(scn, prepare(scn)))


@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))
def test_metrics_match_reference(name: str) -> None:
    scns = [_scenario(name, disc, extra) for disc in DISCRETIZATIONS
            for extra in CASES.values()]
    table = batch.run_metrics(scns, chunk=7, series=False)
    assert table.values.shape == (len(scns), len(batch.METRICS))
    for i, scn in enumerate(scns):
        ref = run_reference(scn, prepare(scn))
        row = table.row(i)
        # the metrics' definitions, written out here independently of esoarm.engines.metrics
        expected = {
            "rms_error": float(np.sqrt(np.mean(ref.error**2))),
            "rms_u": float(np.sqrt(np.mean(ref.u**2))),
            "max_abs_error": float(np.max(np.abs(ref.error))),
            "max_abs_u": float(np.max(np.abs(ref.u))),
            "rms_f_error": float(np.sqrt(np.mean((ref.z[:, 2] - ref.f_true) ** 2))),
            "rms_rate_error": float(np.sqrt(np.mean((ref.z[:, 1] - ref.omega) ** 2))),
            "rms_du": float(np.sqrt(np.mean(np.diff(ref.u) ** 2))),
            # with a [motor] table u is the duty's torque, not the clipped command: the flag
            # of the clipped command is the definition there
            "saturated_fraction": float(np.mean(np.abs(ref.u) == scn.actuator.torque_limit))
            if scn.motor is None else float(np.mean(ref.saturated)),
            "samples": float(len(ref.t)),
            "diverged": 0.0,
        }
        assert ref.metrics == pytest.approx(expected, rel=1e-15, abs=0)
        for key, value in expected.items():
            np.testing.assert_allclose(row[key], value, rtol=RTOL, atol=0, err_msg=key)


@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))
def test_bit_identical_builtin(name: str) -> None:
    """Full-length built-in runs: the two engines give the very same floats."""
    scn = load_scenario(name)
    ref = run_reference(scn, prepare(scn))
    (fast,) = batch.simulate_many([scn])
    for attr in ("theta", "u", "z", "f_true", "omega", "y", "saturated"):
        assert np.array_equal(getattr(fast, attr), getattr(ref, attr)), attr
    assert fast.metrics == ref.metrics
    row = batch.run_metrics([scn]).row(0)
    assert {k: row[k] for k in ref.metrics} == ref.metrics


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_blocked_metrics_bit_identical_every_case(disc: str) -> None:
    """The vectorized block kernel (stiction on and off, lag, motor, ...) changes no bit."""
    scns = [_scenario("test-1", disc, extra) for extra in CASES.values()]
    table = batch.run_metrics(scns, seeds=[3, 4, 5], series=False)
    for i, scn in enumerate(scns):
        for j, seed in enumerate((3, 4, 5)):
            one = scn.with_overrides({"sensor.seed": seed})
            ref = run_reference(one, prepare(one))
            row = table.row(3 * i + j)
            assert {k: row[k] for k in ref.metrics} == ref.metrics, list(CASES)[i]


@pytest.mark.parametrize("disc", ["euler", "zoh"])
def test_divergence_rule(disc: str) -> None:
    # Euler is unstable for Ts/ε ≥ 2; a tiny ε with "zoh" rings up through saturation-free
    # high gains -- either way the run must end at the same sample as the reference
    over = {"observer.eps": 0.004, "duration": 5.0}
    if disc == "zoh":
        over = {"observer.eps": 0.02, "actuator.torque_limit": 1e12, "actuator.delay_samples": 3,
                "duration": 20.0}
    scn = load_scenario("test-1", {"observer.discretization": disc, **over})
    with pytest.raises(SimulationDiverged) as ref_exc:
        run_reference(scn, prepare(scn))
    with pytest.raises(SimulationDiverged) as fast_exc:
        batch.simulate_many([scn])
    assert str(fast_exc.value) == str(ref_exc.value)
    ref, fast = ref_exc.value.result, fast_exc.value.result
    assert len(fast.t) == len(ref.t) < scn.n_samples
    for attr in ("theta", "u", "z", "f_true", "omega"):
        np.testing.assert_array_equal(getattr(fast, attr), getattr(ref, attr))
    row = batch.run_metrics([scn]).row(0)
    assert row["diverged"] == 1.0
    assert row["samples"] == len(ref.t)
    for key, value in ref.metrics.items():
        np.testing.assert_array_equal(row[key], value)


def test_diverged_run_does_not_stop_the_others() -> None:
    good = load_scenario("test-1", SHORT)
    bad = load_scenario("test-1", {**SHORT, "observer.eps": 0.004})
    table = batch.run_metrics([good, bad, good])
    assert list(table.column("diverged")) == [0.0, 1.0, 0.0]
    np.testing.assert_array_equal(table.values[0], table.values[2])


def test_seeds_are_sensor_seed() -> None:
    base = load_scenario("test-1", SHORT)
    pts = [base, load_scenario("test-1", {**SHORT, "observer.eps": 0.2})]
    seeds = [0, 3, 11]
    table = batch.run_metrics(pts, seeds=seeds)
    i = 0
    for scn in pts:
        for seed in seeds:
            one = scn.with_overrides({"sensor.seed": seed})
            ref = run_reference(one, prepare(one))
            assert table.row(i)["rms_error"] == ref.metrics["rms_error"]
            i += 1
    # different seeds give different noise
    assert len(set(table.column("rms_error")[:3])) == 3


def test_identical_whatever_workers_and_chunks() -> None:
    pts = [load_scenario("test-2", {**SHORT, "observer.eps": e}) for e in (0.04, 0.09, 0.3)]
    a = batch.run_metrics(pts, seeds=range(5), workers=1, chunk=1)
    b = batch.run_metrics(pts, seeds=range(5), workers=2, chunk=4)
    c = batch.run_metrics(pts, seeds=range(5))
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(a.values, c.values)


def test_mixed_lengths_in_one_batch() -> None:
    scns = [
        load_scenario("test-1", {"duration": 1.0}),
        load_scenario("test-2", {"duration": 2.5, "sensor.rate_hz": 100.0}),
        load_scenario("test-1", {"duration": 0.5, "rig.step": 0.005}),
    ]
    fast = batch.simulate_many(scns)
    for scn, res in zip(scns, fast, strict=True):
        assert len(res.t) == scn.n_samples
        _assert_same(res, run_reference(scn, prepare(scn)))


def test_noise_drawn_once_per_seed() -> None:
    pts = [load_scenario("test-1", {**SHORT, "observer.eps": e}) for e in (0.05, 0.1, 0.2, 0.3)]
    runs = [(i, s) for i in range(len(pts)) for s in (0, 1)]
    pack = batch._pack(pts, runs)
    assert pack.noises.shape[0] == 2  # two seeds, not eight runs
    assert pack.refs.shape[0] == 1  # one reference trajectory shared by all points


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=700))
def test_pairwise_sum_is_numpy_order(values: list[float]) -> None:
    x = np.square(np.array(values))
    assert pairwise_sum(x, len(x)) == np.add.reduce(x)
    assert math.isclose(pairwise_sum(x, len(x)), math.fsum(x), rel_tol=1e-12)


def test_disk_cache_is_keyed_on_the_physics_sources() -> None:
    """Editing rig.py (or any physics module) must not reuse a stale compiled kernel."""
    for kernel in (batch._metrics_kernel, batch._blocked_metrics_kernel, batch._run):
        locator = kernel._cache._impl.locator
        assert type(locator).__name__.startswith("EsoarmPhysics")
        assert locator.get_source_stamp().endswith(batch._physics_stamp())


def test_kinds_that_do_not_compile_run_in_processes(monkeypatch) -> None:
    """A kind with JIT = False: the batch engine falls back to the reference engine."""
    from esoarm.controllers import flc

    pts = [load_scenario("test-1", {**SHORT, "observer.eps": e}) for e in (0.05, 0.2)]
    compiled = batch.run_metrics(pts, seeds=[0, 1])
    monkeypatch.setattr(flc, "JIT", False)
    fallback = batch.run_metrics(pts, seeds=[0, 1], workers=2)
    np.testing.assert_array_equal(fallback.values, compiled.values)
    (series,) = batch.simulate_many(pts[:1])
    assert series.metrics == run_reference(pts[0], prepare(pts[0])).metrics


@pytest.mark.parametrize("joints", [1, 2, 3, 7])
def test_joints_metrics_is_combine_joints(joints: int) -> None:
    """The kernels' metrics of an arm's log are the result's (every joint), bit for bit."""
    from esoarm.engines.metrics import NROW, SAT, joints_metrics
    from esoarm.result import SimResult

    scn = load_scenario("test-1", {"duration": 0.5})
    n = scn.n_samples
    rng = np.random.default_rng(joints)
    log = rng.normal(size=(NROW * joints, n))
    for j in range(joints):
        log[j * NROW + SAT] = rng.random(n) < 0.3
    for rows, diverged in ((n, False), (n - 7, True), (1, True)):
        res = SimResult.from_log(scn, np.arange(rows) * scn.sample_time, log[:, :rows],
                                 diverged=diverged)
        out = np.empty(len(METRICS))
        joints_metrics(log, joints, rows, diverged, out)
        assert [res.metrics[m] for m in METRICS] == list(out)


@pytest.mark.parametrize("error", [OSError(28, "No space left on device"),
                                   TypeError("cannot pickle '_dynfunc._Closure' object")])
def test_a_kernel_numba_cannot_save_still_runs(error: Exception) -> None:
    """numba's cache write failing (a full disk; a function value it cannot pickle, as after
    the arm kernels in one process) leaves the kernel uncached, not the run failed."""
    from numba.core import caching

    import esoarm.engines.batch  # noqa: F401  (installs the tolerant save)

    class Failing:
        def _guard_against_spurious_io_errors(self):  # type: ignore[no-untyped-def]
            import contextlib

            return contextlib.nullcontext()

        def _save_overload(self, sig, data):  # type: ignore[no-untyped-def]
            raise error

    assert getattr(caching.Cache.save_overload, "_esoarm_tolerant", False)
    caching.Cache.save_overload(Failing(), (), None)  # no exception
