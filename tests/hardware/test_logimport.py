"""Logs from elsewhere: esoarm.hardware.logimport and ``esoarm log import``."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io
from click.testing import CliRunner

from esoarm.cli import cli
from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.hardware.logimport import MAX_JITTER, check_time, import_log, write_log
from esoarm.scenario import ScenarioError


def _float32_stamps(n: int = 5000, rate: float = 1000.0) -> np.ndarray:
    """Stamps of a 1 kHz grid stored in single precision (the EMPS data's jitter)."""
    return (np.arange(n) / rate).astype(np.float32).astype(float)


def _mat(tmp_path, t, name="rec.mat"):
    rng = np.random.default_rng(3)
    n = len(t)
    path = tmp_path / name
    scipy.io.savemat(path, {"time": t.reshape(-1, 1), "pos": np.cumsum(rng.normal(size=n))
                            .reshape(-1, 1) * 1e-4, "volt": rng.normal(size=(n, 1)),
                            "gain": np.array([[35.15]])})
    return path


def test_float32_stamps_are_refused_by_the_log_reader_but_imported():
    t = _float32_stamps(25000)
    with pytest.raises(ScenarioError, match="uniformly spaced"):
        sample_period(t, "x.csv")  # the reader's 1e-6 tolerance: the first case
    ts, jitter, rms = check_time(t, "t")
    assert ts == pytest.approx(1e-3, rel=1e-9)
    assert 0 < rms <= jitter < 1e-2


def test_mat_import_maps_scales_and_writes_the_uniform_grid(tmp_path):
    t = _float32_stamps(3000)
    src = _mat(tmp_path, t)
    log = import_log(src, {"t": "time", "u": "volt", "y": "pos"}, {"u": "gain"})
    assert log.rate_hz == 1000.0 and list(log.columns) == ["t", "y", "u"]
    raw = scipy.io.loadmat(src)
    np.testing.assert_array_equal(log.columns["u"], raw["volt"].ravel() * 35.15)
    np.testing.assert_array_equal(log.columns["t"], np.arange(3000) / 1000.0)
    out = tmp_path / "log.csv"
    write_log(log, out)
    names, data = read_log_columns(out, ["t", "y", "u"], "need t, y, u")
    assert sample_period(data[:, 0], out) == pytest.approx(1e-3, rel=1e-12)
    np.testing.assert_array_equal(data[:, 1], raw["pos"].ravel())  # exact round trip
    np.testing.assert_array_equal(data[:, 2], log.columns["u"])


def test_a_gap_is_refused_naming_the_worst_one(tmp_path):
    t = np.arange(2000) / 1000.0
    t[700:] += 0.002   # 2 samples lost at row 700
    t[1500:] += 0.010  # 10 lost at row 1500: the worst
    with pytest.raises(ScenarioError, match=r"a gap of 0\.011 s .* row 1500 \(t = 1\.501 s\) "
                                            r"and row 1501; the worst of 2"):
        import_log(_mat(tmp_path, t), {"t": "time", "u": "volt", "y": "pos"})


def test_jitter_up_to_the_tolerance_passes_and_beyond_is_a_gap():
    rng = np.random.default_rng(0)
    k = np.arange(4000)
    jitter = rng.uniform(-0.4, 0.4, size=k.size) * MAX_JITTER / 1000.0
    ts, worst, _ = check_time(k / 1000.0 + jitter, "t")
    assert ts == pytest.approx(1e-3, rel=1e-6) and worst <= 0.45 * MAX_JITTER
    t = k / 1000.0
    t[10:] += 0.3e-3
    with pytest.raises(ScenarioError, match="not a uniform grid"):
        check_time(t, "t")


def test_time_must_increase():
    with pytest.raises(ScenarioError, match=r"time must increase; row 3"):
        check_time(np.array([0.0, 0.001, 0.001, 0.003]), "t")


def test_csv_with_a_byte_order_mark(tmp_path):
    path = tmp_path / "in.csv"
    rows = "\n".join(f"{k * 0.01:.6f},{k * 1e-3},{(-1) ** k}" for k in range(50))
    path.write_text("\ufefftime_s,angle,torque\n" + rows + "\n", encoding="utf-8")
    log = import_log(path, {"t": "time_s", "y": "angle", "u": "torque"})
    assert log.rate_hz == 100.0 and log.n == 50


@pytest.mark.parametrize(("mapping", "scale", "match"), [
    ({"t": "time", "y": "pos"}, {}, "give u"),
    ({"t": "time", "y": "pos", "u": "nope"}, {}, "nope \\(for u\\): no such variable"),
    ({"t": "time", "y": "pos", "u": "gain"}, {}, "a scalar, not a column"),
    ({"t": "time", "y": "pos", "u": "volt"}, {"u": "kv"}, "neither a number nor a scalar"),
    ({"t": "time", "y": "pos", "u": "volt"}, {"q": "2"}, "scale q: not a mapped column"),
    ({"t": "time", "y": "pos", "u": "volt", "w": "pos"}, {}, "map w: not an esoarm log column"),
])
def test_bad_mappings_are_one_line_errors(tmp_path, mapping, scale, match):
    with pytest.raises(ScenarioError, match=match):
        import_log(_mat(tmp_path, np.arange(100) / 100.0), mapping, scale)


def test_cli_reports_rate_and_jitter_and_refuses_a_gap_with_exit_2(tmp_path):
    src = _mat(tmp_path, _float32_stamps(2000))
    out = tmp_path / "o.csv"
    runner = CliRunner()
    res = runner.invoke(cli, ["log", "import", str(src), "--map", "t=time,y=pos,u=volt",
                              "--scale", "u=gain", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.stdout)
    assert report["rate_hz"] == 1000.0 and 0 < report["jitter_samples"] < 0.01
    assert report["scale"] == {"u": 35.15} and out.exists()
    t = np.arange(2000) / 1000.0
    t[500:] += 0.05
    gap = _mat(tmp_path, t, "gap.mat")
    out2 = tmp_path / "o2.csv"
    res = runner.invoke(cli, ["log", "import", str(gap), "--map", "t=time,y=pos,u=volt",
                              "--out", str(out2)])
    assert res.exit_code == 2 and "a gap of 0.051 s" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not out2.exists()
