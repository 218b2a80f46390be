"""``esoarm log import`` of files laid out as other benchmarks lay them out.

Without time stamps (the Silverbox benchmark's CSV: only V1, V2, each line ending in a
comma), and with the signals as columns of one matrix (a Simulink ``data`` array, as in
the HSM150 motor records).
"""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.hardware.logimport import import_log
from esoarm.scenario import ScenarioError


def _silverbox_like(path, n=50):
    rng = np.random.default_rng(3)
    v1, v2 = rng.normal(size=n), rng.normal(size=n)
    lines = ['"V1","V2",'] + [f"{a:.7g},{b:.7g}," for a, b in zip(v1, v2, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return v1, v2


def test_csv_with_trailing_commas_and_a_rate_instead_of_stamps(tmp_path):
    src = tmp_path / "SNLS80mV.csv"
    v1, v2 = _silverbox_like(src)
    log = import_log(src, {"y": "V2", "u": "V1"}, rate_hz=610.35)
    assert list(log.columns) == ["t", "y", "u"]
    np.testing.assert_array_equal(log.columns["t"], np.arange(50) / 610.35)
    np.testing.assert_allclose(log.columns["y"], v2, rtol=1e-6)
    np.testing.assert_allclose(log.columns["u"], v1, rtol=1e-6)
    assert log.rate_hz == 610.35 and log.jitter == 0.0


def test_rate_and_a_time_column_are_one_too_many(tmp_path):
    src = tmp_path / "a.csv"
    src.write_text("t,y,u\n0,0,1\n0.001,0,1\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match="give one"):
        import_log(src, {"t": "t", "y": "y", "u": "u"}, rate_hz=1000.0)
    with pytest.raises(ScenarioError, match="rate -1: must be a sample rate > 0"):
        import_log(src, {"y": "y", "u": "u"}, rate_hz=-1.0)
    with pytest.raises(ScenarioError, match="give t"):
        import_log(src, {"y": "y", "u": "u"})


def test_matrix_columns_of_a_mat_file(tmp_path):
    from scipy.io import savemat

    n = 100
    data = np.column_stack([np.arange(n) * 1e-3, np.zeros(n), np.linspace(0, 1, n),
                            np.full(n, 7.0), np.full(n, 0.05)])
    src = tmp_path / "idf.mat"
    savemat(src, {"data": data, "J": 1.2e-4})
    log = import_log(src, {"t": "data:1", "y": "data:3", "u": "data:5"})
    np.testing.assert_array_equal(log.columns["y"], data[:, 2])
    np.testing.assert_array_equal(log.columns["u"], data[:, 4])
    assert log.rate_hz == 1000.0
    with pytest.raises(ScenarioError, match=r"data \(for t\) is a matrix of 5 columns: name one "
                                            r"as data:1 … data:5"):
        import_log(src, {"t": "data", "y": "data:3", "u": "data:5"})
    with pytest.raises(ScenarioError, match="no such variable; the file has data:j"):
        import_log(src, {"t": "time", "y": "data:3", "u": "data:5"})


def test_cli_rate_option(run_cli, tmp_path):
    src = tmp_path / "SNLS80mV.csv"
    _silverbox_like(src)
    out = tmp_path / "log.csv"
    res = run_cli("log", "import", str(src), "--map", "y=V2,u=V1", "--rate", "610.35",
                  "--out", str(out))
    assert res.exit_code == 0, res.stderr
    assert "50 samples at 610.35 Hz" in res.stderr
    assert out.read_text(encoding="utf-8").splitlines()[0] == "t,y,u"
