"""The shared reader of run logs (esoarm.hardware.logfile)."""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.hardware.replay import read_arm_log, read_log
from esoarm.scenario import ScenarioError
from esoarm.studies.identification.data import read_ident_log

NEED = "need t [s], theta [rad], u [N·m]"


def _log(tmp_path, text, name="log.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _read(path, lost_ok=("theta",)):
    return read_log_columns(path, ["t", "theta", "u"], NEED, lost_ok=lost_ok)


def test_reads_the_picked_columns_in_order_skipping_blank_lines(tmp_path):
    path = _log(tmp_path, "u, extra ,t,theta,extra\n1,9,0,0.5,8\n\n2,9,0.1,nan,8\n")
    names, data = _read(path)
    assert names == ["t", "theta", "u"]
    np.testing.assert_array_equal(data[:, [0, 2]], [[0.0, 1.0], [0.1, 2.0]])
    assert data[0, 1] == 0.5 and np.isnan(data[1, 1])


def test_pick_may_choose_from_the_header(tmp_path):
    path = _log(tmp_path, "t,theta,y,u\n0,5,1,0\n")
    names, data = read_log_columns(path, lambda h: ["t", "y" if "y" in h else "theta"], NEED)
    assert names == ["t", "y"] and data.tolist() == [[0.0, 1.0]]


@pytest.mark.parametrize("text, words", [
    ("", ["empty file"]),
    ("\n0,0,0\n", ["empty file"]),
    ("t,theta,u\n", ["no data rows"]),
    ("t,theta,u\n\n\n", ["no data rows"]),
    ("t,theta\n0,0\n", ["missing column(s) u", NEED]),
    ("theta\n0\n", ["missing column(s) t, u"]),
    ("t,theta,u,t\n0,0,0,5\n", ["column t appears 2 times in the header"]),
    ("t,theta,u\n0,0,0\n0.1,x,0\n", ["line 3", "expected numbers in columns t, theta, u"]),
    ("t,theta,u\n0,0,0\n\n0.1,0\n", ["line 4", "expected numbers"]),  # a short row
    ("t,theta,u\n0,0,0\n0.1,0,nan\n", ["line 3", "u = nan", "only theta may be nan"]),
    ("t,theta,u\n0,0,0\nnan,0,0\n", ["line 3", "t = nan"]),
    ("t,theta,u\n0,0,0\n0.1,inf,0\n", ["line 3", "theta = inf"]),
    ("t,theta,u\n0,0,0\n0.1,0,-inf\n", ["line 3", "u = -inf"]),
    ("t,theta,u\n0,nan,0\n0.1,0,0\n", ["line 2", "theta must be finite in the first row"]),
])
def test_bad_logs_are_one_line_naming_the_file(tmp_path, text, words):
    path = _log(tmp_path, text, "bad.csv")
    with pytest.raises(ScenarioError) as info:
        _read(path)
    msg = str(info.value)
    assert msg.startswith(f"log '{path}': ") and "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_nan_is_bad_in_every_column_without_lost_ok(tmp_path):
    path = _log(tmp_path, "t,theta,u\n0,0,0\n0.1,nan,0\n")
    with pytest.raises(ScenarioError, match="line 3: non-finite value theta = nan "
                                            r"\(every value must be a finite number\)"):
        _read(path, lost_ok=())


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(ScenarioError, match=r"log '.*nope.csv': no such file$"):
        _read(tmp_path / "nope.csv")
    with pytest.raises(ScenarioError, match="is a directory"):
        _read(tmp_path)


def test_undecodable_file_is_a_one_line_error(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"t,theta,u\n\xff\xfe,0,0\n")
    with pytest.raises(ScenarioError, match="not a text CSV.*esoarm log import"):
        _read(path)


@pytest.mark.parametrize("t, words", [
    ([0.0], "at least 2 rows, has 1"),
    ([0.0, 0.1, 0.3], "uniformly spaced and increasing (steps from 0.1 to 0.2 s)"),
    ([0.2, 0.1, 0.0], "uniformly spaced and increasing"),
    ([0.0, 0.0, 0.0], "uniformly spaced and increasing"),
])
def test_sample_period_rejects(t, words):
    with pytest.raises(ScenarioError) as info:
        sample_period(np.array(t), "x.csv")
    assert str(info.value).startswith("log 'x.csv': ") and words in str(info.value)


def test_sample_period_of_a_uniform_column():
    assert sample_period(0.02 * np.arange(500), "x.csv") == pytest.approx(0.02)


# the three consumers go through the same reader and give the same messages

CONSUMERS = {
    "replay": read_log,
    "arm replay": lambda p: read_arm_log(p, 1),
    "identify": lambda p: read_ident_log(p, 2.0),
}


@pytest.mark.parametrize("consumer", sorted(CONSUMERS))
@pytest.mark.parametrize("text, words", [
    (None, "no such file"),
    ("t,theta,u\n", "no data rows"),
    ("t,theta\n0,0\n0.02,0\n", "missing column(s) u"),
    ("t,theta,u\n0,0,0\n0.02,0,nan\n", "line 3: non-finite value u = nan"),
    ("t,theta,u\n0,nan,0\n0.02,0,0\n", "line 2: theta must be finite in the first row"),
    ("t,theta,u\n0,0,nan\n0.02,0,nan\n", "column u is nan in every row"),
])
def test_every_consumer_gives_the_shared_messages(tmp_path, consumer, text, words):
    path = tmp_path / "log.csv"
    if text is not None:
        path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        CONSUMERS[consumer](path)
    assert words in str(info.value) and str(info.value).startswith(f"log '{path}'")


def test_a_column_nan_in_every_row_is_named_with_the_consumers_why(tmp_path):
    path = _log(tmp_path, "t,theta,u\n0,0,nan\n0.02,0,nan\n0.04,0,nan\n")
    with pytest.raises(ScenarioError) as info:
        read_log_columns(path, ["t", "theta", "u"], "need u", all_nan_why={"u": "log u"})
    assert str(info.value) == f"log '{path}': column u is nan in every row: log u"
    one_row = _log(tmp_path, "t,theta,u\n0,0,nan\n")  # one row: the line is named
    with pytest.raises(ScenarioError, match="line 2: non-finite value u = nan"):
        read_log_columns(one_row, ["t", "theta", "u"], "need u")


def test_arm_log_names_the_joint_column(tmp_path):
    path = _log(tmp_path, "t,theta_1,theta_2,u_1,u_2\n0,0,0,0,0\n0.02,0,inf,0,0\n")
    with pytest.raises(ScenarioError, match="line 3: non-finite value theta_2 = inf"):
        read_arm_log(path, 2)
    path = _log(tmp_path, "t,theta_1,u_1,u_2\n0,0,0,0\n")
    with pytest.raises(ScenarioError, match="missing column.*theta_2; an arm of 2 joints"):
        read_arm_log(path, 2)


def test_arm_log_keeps_lost_samples_after_the_first_row(tmp_path):
    path = _log(tmp_path, "t,y_1,y_2,u_1,u_2,theta_1,theta_2\n"
                          "0,1,2,0,0,9,9\n0.02,nan,2,0,0,9,9\n0.04,1,nan,0,0,9,9\n")
    t, theta, u, ts = read_arm_log(path, 2)
    assert ts == pytest.approx(0.02) and theta[0].tolist() == [1.0, 2.0]
    assert np.isnan(theta[1, 0]) and np.isnan(theta[2, 1])
