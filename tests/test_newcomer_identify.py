"""What a newcomer trips on in ``esoarm identify`` (issue 32): each case refused in one line
naming the cause and the fix, exit 2, no numpy warning."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def lever_log(tmp_path_factory) -> Path:
    """A 20 s excitation log of test-1's twin (the columns of 'esoarm excite')."""
    from esoarm.hardware.excite import excite_twin
    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.experiment.excitation import ExcitationPlan

    path = tmp_path_factory.mktemp("newcomer") / "ex.csv"
    excite_twin(load_scenario("test-1"), ExcitationPlan(duration=20.0, seed=1), path)
    return path


def _rewrite(src: Path, dst: Path, column: str, factor: float) -> Path:
    with open(src, encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    j = rows[0].index(column)
    with open(dst, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0])
        for r in rows[1:]:
            r[j] = repr(float(r[j]) * factor)
            w.writerow(r)
    return dst


def _one_line(res) -> str:  # type: ignore[no-untyped-def]
    lines = [ln for ln in res.stderr.strip().splitlines() if ln.startswith("esoarm: error")]
    assert len(lines) == 1, res.stderr
    return lines[0]


def test_huge_torque_gives_no_numpy_warning(lever_log, tmp_path, run_esoarm):
    big = _rewrite(lever_log, tmp_path / "big.csv", "u", 1e200)
    res = run_esoarm("identify", str(big))
    assert res.exit_code == 2, res.stderr
    assert "Warning" not in res.stderr and "overflow" not in res.stderr, res.stderr
    assert "big.csv" in _one_line(res)


def test_a_segment_shorter_than_five_samples_is_refused(lever_log, run_cli):
    res = run_cli("identify", str(lever_log), "--segment", "0.01")
    assert res.exit_code == 2
    line = _one_line(res)
    assert "--segment 0.01" in line and "0.1 s" in line


def test_too_many_segments_are_refused_before_the_fit():
    from types import SimpleNamespace

    from esoarm.cli._common import BadInput
    from esoarm.cli.identify import _check_segment

    log = SimpleNamespace(n=3000, ts=0.02, path="x.csv")  # 60 s at 50 Hz, 45 s fitted
    _check_segment(2.0, [log], [], 0.25)  # the default: 22 segments
    with pytest.raises(BadInput, match=r"--segment 0.1: cuts the 45 s .* into 450 segments"):
        _check_segment(0.1, [log], [], 0.25)


def test_a_validation_log_that_is_also_fitted_is_refused(lever_log, run_cli):
    res = run_cli("identify", str(lever_log), "--validate", str(lever_log))
    assert res.exit_code == 2
    assert "also given to fit" in _one_line(res)
    assert "not used for fitting" not in res.stdout


def test_the_same_log_twice_is_refused(lever_log, run_cli):
    res = run_cli("identify", str(lever_log), str(lever_log))
    assert res.exit_code == 2
    assert "given twice" in _one_line(res)
    assert "not used for fitting" not in res.stdout


def test_a_lever_arm_log_is_not_fitted_as_a_prismatic_axis(lever_log, run_cli):
    res = run_cli("identify", str(lever_log), "--scenario", "emps", "--set",
                  "sensor.rate_hz=50", "--set", "rig.step=0.001")
    assert res.exit_code == 2, res.stdout
    line = _one_line(res)
    assert "rotary" in line and "prismatic" in line
    assert "mass" not in res.stdout


def test_a_log_stamped_in_milliseconds_is_named_so(lever_log, tmp_path, run_cli):
    ms = _rewrite(lever_log, tmp_path / "ms.csv", "t", 1000.0)
    res = run_cli("identify", str(ms))
    assert res.exit_code == 2
    line = _one_line(res)
    assert "milliseconds" in line and "--scale t=0.001" in line
    assert "sensor.rate_hz=0.05" not in line


def test_a_mat_file_points_at_log_import(tmp_path, run_cli):
    mat = tmp_path / "log.mat"
    mat.write_bytes(b"MATLAB 5.0 MAT-file, Platform: GLNXA64 \xf0\x9f" + bytes(100))
    res = run_cli("identify", str(mat))
    assert res.exit_code == 2
    line = _one_line(res)
    assert "esoarm log import" in line and "utf-8" not in line
