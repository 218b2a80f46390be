"""The streaming engine: a run block by block gives the reference engine's rows bit for bit,
its metrics to round-off, and holds memory flat whatever the run's length."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest

from esoarm.engines import stream as streaming
from esoarm.engines.simulation import SimulationDiverged, prepare, run_reference
from esoarm.scenario import load_scenario

#: Relative tolerance of the accumulated metrics against NumPy's pairwise sums of the
#: whole run (the block sums are added exactly; a sum of N squares in pairwise order is
#: off by O(log N · ε) relative).
RTOL = 1e-12

CASES = {
    "test-1": {},
    "pid, delay 3": {"controller.kind": "pid", "actuator.delay_samples": 3},
    "coloured noise, lag": {"sensor.noise_ar": [0.8], "actuator.lag": 0.01},
    "motor": {"motor.gear_ratio": 30.0},
    "two-link": "two-link",
}


def _scenario(case):
    spec = CASES[case]
    if isinstance(spec, str):
        return load_scenario(spec, {"duration": 1.0})
    return load_scenario("test-1", {"duration": 3.0, **spec})


def _streamed(scn, block, compiled=False):
    parts = []
    run = streaming.stream(scn, sink=parts.append, block=block, compiled=compiled)
    return run, np.concatenate([p.table() for p in parts])


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("block", [7, 64])
def test_rows_are_the_reference_bits_and_metrics_equal_to_round_off(case, block):
    scn = _scenario(case)
    ref = run_reference(scn, prepare(scn))
    run, table = _streamed(scn, block)
    assert np.array_equal(table, ref.table(), equal_nan=True)
    assert run.samples == len(ref.t) == scn.n_samples
    for name, value in ref.metrics.items():
        if math.isnan(value):
            assert math.isnan(run.metrics[name]), name
        else:
            assert run.metrics[name] == pytest.approx(value, rel=RTOL, abs=1e-300), name
    assert run.summary().keys() == ref.summary().keys()


def test_one_sample_blocks_and_a_block_longer_than_the_run():
    scn = load_scenario("test-1", {"duration": 0.2, "controller.kind": "pid"})
    ref = run_reference(scn, prepare(scn)).table()
    for block in (1, 10_000):
        assert np.array_equal(_streamed(scn, block)[1], ref, equal_nan=True)


def test_memory_does_not_grow_with_the_run():
    """Peak traced memory of a run 8 times longer stays within a few percent."""
    def peak(duration):
        scn = load_scenario("test-1", {"duration": duration})
        tracemalloc.start()
        streaming.stream(scn, block=256, compiled=False)
        _, top = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        return top

    short, long = peak(5.0), peak(40.0)  # 250 and 2,000 samples
    assert long < 1.2 * short + 50_000, (short, long)


def test_divergence_raises_with_the_last_block():
    scn = load_scenario("test-1", {"duration": 5.0, "observer.eps": 0.001})
    with pytest.raises(SimulationDiverged) as ref:
        run_reference(scn, prepare(scn))
    with pytest.raises(SimulationDiverged) as got:
        streaming.stream(scn, block=3, compiled=False)
    assert str(got.value) == str(ref.value)
    k = len(ref.value.result.t)
    assert got.value.result.t[-1] == ref.value.result.t[-1]
    assert np.array_equal(got.value.result.table(), ref.value.result.table()[-len(
        got.value.result.t):], equal_nan=True)
    assert len(got.value.result.t) <= 3 and k > 3


def test_figure_rows_keep_evenly_spaced_samples():
    scn = load_scenario("test-1", {"duration": 10.0})
    ref = run_reference(scn, prepare(scn))
    run = streaming.stream(scn, block=33, compiled=False, figure_rows=100)
    assert run.stride == 5
    assert np.array_equal(run.series.table(), ref.table()[::5], equal_nan=True)
    assert run.series.metrics == run.metrics


# ---------------------------------------------------------------------------
# esoarm simulate of a long run streams (the Python blocks here; compiled: slow tier)


@pytest.fixture
def python_blocks(monkeypatch):
    monkeypatch.setattr(streaming, "STREAM_SAMPLES", 100)
    monkeypatch.setattr(streaming, "_compiled_runner", lambda inp: None)
    monkeypatch.setattr(streaming, "PYTHON_BLOCK", 64)


def test_simulate_streams_a_long_run_to_its_csv(python_blocks, run_cli, tmp_path):
    import json

    out = tmp_path / "long.csv"
    res = run_cli("simulate", "test-1", "--set", "duration=10", "--out", str(out))
    assert res.exit_code == 0, res.stderr
    assert "block by block" in res.stderr
    scn = load_scenario("test-1", {"duration": 10.0})
    ref = run_reference(scn, prepare(scn))
    ref_csv = tmp_path / "ref.csv"
    ref.to_csv(ref_csv)
    assert out.read_text() == ref_csv.read_text()
    res = run_cli("simulate", "test-1", "--set", "duration=10", "--json")
    assert res.exit_code == 0, res.stderr
    got = json.loads(res.stdout)
    assert got["samples"] == 500
    assert got["rms_error"] == pytest.approx(ref.metrics["rms_error"], rel=RTOL)


def test_simulate_streamed_divergence_keeps_the_rows(python_blocks, run_cli, tmp_path):
    out = tmp_path / "d.csv"
    res = run_cli("simulate", "test-1", "--set", "duration=10", "--set", "observer.eps=0.001",
                  "--out", str(out))
    assert res.exit_code == 1
    assert "diverged" in res.stderr and str(out) in res.stderr
    scn = load_scenario("test-1", {"duration": 10.0, "observer.eps": 0.001})
    with pytest.raises(SimulationDiverged) as ref:
        run_reference(scn, prepare(scn))
    rows = out.read_text().strip().splitlines()
    assert len(rows) == 1 + len(ref.value.result.t)


@pytest.mark.slow
def test_compiled_blocks_give_the_reference_bits():
    for case in ("test-1", "pid, delay 3", "two-link"):
        scn = _scenario(case)
        ref = run_reference(scn, prepare(scn)).table()
        run, table = _streamed(scn, 50, compiled=None)
        assert run.compiled
        if case == "two-link":  # Pinocchio in the reference, the compiled rigid body here
            assert np.allclose(table, ref, rtol=1e-9, atol=1e-9)
        else:
            assert np.array_equal(table, ref, equal_nan=True)


def test_sweep_metrics_of_a_long_run_are_streamed(python_blocks, monkeypatch):
    from esoarm.engines import simulation
    from esoarm.engines.metrics import METRICS

    monkeypatch.setattr(streaming, "STREAM_SAMPLES", 100)
    calls = []
    real = streaming.stream
    monkeypatch.setattr(streaming, "stream", lambda scn, **kw: calls.append(scn) or real(scn,
                                                                                         **kw))
    ok = load_scenario("test-1", {"duration": 4.0})
    bad = load_scenario("test-1", {"duration": 4.0, "observer.eps": 0.001})
    table = streaming.with_long_runs(simulation.reference_metrics, [ok, bad])
    assert len(calls) == 2
    ref_ok = run_reference(ok, prepare(ok)).metrics
    with pytest.raises(SimulationDiverged) as info:
        run_reference(bad, prepare(bad))
    for row, ref in zip(table.values, (ref_ok, info.value.result.metrics), strict=True):
        for j, name in enumerate(METRICS):
            assert row[j] == pytest.approx(ref[name], rel=RTOL, nan_ok=True), name


def test_ctrl_c_keeps_the_rows_streamed(python_blocks, monkeypatch, run_cli, tmp_path):
    class Flag:  # Ctrl-C during the second block: seen before the third
        checks = 0

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return None

        @property
        def hit(self):
            Flag.checks += 1
            return Flag.checks > 2

    monkeypatch.setattr(streaming, "_SigintFlag", Flag)
    out = tmp_path / "part.csv"
    res = run_cli("simulate", "test-1", "--set", "duration=10", "--out", str(out))
    assert res.exit_code == 130
    assert f"the 128 rows run are in {out}" in res.stderr
    scn = load_scenario("test-1", {"duration": 10.0})
    ref = tmp_path / "ref.csv"
    run_reference(scn, prepare(scn)).to_csv(ref)
    assert out.read_text().splitlines() == ref.read_text().splitlines()[:129]


def test_only_runs_worth_the_compile_are_compiled():
    short = load_scenario("test-1", {"duration": 1e4})  # 5·10⁵ samples: not streamed
    long = load_scenario("test-1", {"duration": 1.1e4})
    assert streaming.worth_compiling(short) is False
    assert streaming.worth_compiling(long) is None


def test_long_runs_keep_their_place_among_short_ones_and_seeds(python_blocks, monkeypatch):
    """with_long_runs: the streamed rows land where the engine would put them
    (point-major, seed fastest), the short runs go to the engine, progress counts all."""
    from esoarm.engines import simulation

    monkeypatch.setattr(streaming, "STREAM_SAMPLES", 100)
    pts = [load_scenario("test-1", {"duration": d}) for d in (1.0, 3.0, 1.5)]  # 50, 150, 75
    done = []
    table = streaming.with_long_runs(simulation.reference_metrics, pts, [0, 3],
                                     progress=done.append)
    whole = simulation.reference_metrics(pts, [0, 3])
    assert table.values.shape == whole.values.shape == (6, whole.values.shape[1])
    np.testing.assert_allclose(table.values, whole.values, rtol=RTOL)
    assert sum(done) == 6
