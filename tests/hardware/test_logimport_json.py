"""Logs as they come (issue 30, item 6): JSON records or columns, irregular stamps resampled
on request (saying how far apart they were), offset, scale and sign per column."""

from __future__ import annotations

import json

import numpy as np
import pytest

from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.hardware.logimport import MAX_RESAMPLE_GAP, import_log, write_log
from esoarm.scenario import ScenarioError

M = {"t": "t", "y": "pos", "u": "cmd"}


def _signals(n=200, rate=100.0):
    t = np.arange(n) / rate
    return t, np.sin(2 * np.pi * t), np.cos(3 * t)


def test_json_records_and_columns_give_the_same_log(tmp_path):
    t, pos, cmd = _signals()
    rec = tmp_path / "rec.json"
    rec.write_text(json.dumps([{"t": a, "pos": b, "cmd": c, "note": "ok"}
                               for a, b, c in zip(t, pos, cmd, strict=True)]))
    col = tmp_path / "col.json"
    col.write_text(json.dumps({"t": t.tolist(), "pos": pos.tolist(), "cmd": cmd.tolist(),
                               "gain": 2.5}))
    a = import_log(rec, M)
    b = import_log(col, M, {"u": "gain"})
    assert a.rate_hz == b.rate_hz == 100.0
    np.testing.assert_array_equal(a.columns["y"], pos)  # JSON floats round-trip exactly
    np.testing.assert_array_equal(b.columns["u"], cmd * 2.5)
    with pytest.raises(ScenarioError, match=r"note \(for u\) is str \('ok'\) at position 1, "
                                            "not numbers"):
        import_log(rec, {"t": "t", "y": "pos", "u": "note"})


@pytest.mark.parametrize(("text", "said"), [
    ("{", "not JSON: Expecting property name"),
    ("3", "holds a int; expected a list of records"),
    ("[]", "an empty list"),
    ("[1, 2]", "record 1 is int, not an object"),
    ('[{"t": 0, "pos": 0, "cmd": 0}, {"t": 0.01, "cmd": 0}]', "pos (for y) is missing from "
                                                              "record 2 of 2"),
    ('{"t": [0, 0.01], "pos": [0, null], "cmd": [0, 0]}', "pos (for y) is nan at row 2"),
])
def test_bad_json_is_one_line_naming_the_cause(tmp_path, text, said):
    src = tmp_path / "x.json"
    src.write_text(text)
    with pytest.raises(ScenarioError, match=_re(said)):
        import_log(src, M)


def _re(text):
    import re

    return re.escape(text)


def test_irregular_stamps_are_refused_then_resampled_on_request(tmp_path):
    """A logger writing every 0.8-1.2 ms: refused without --resample (pointing at it); with
    it, linear interpolation onto the grid, exact for a linear signal, and a note of how far
    the stamps were apart."""
    rng = np.random.default_rng(7)
    dt = rng.uniform(0.8e-3, 1.2e-3, 999)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    src = tmp_path / "irr.json"
    src.write_text(json.dumps({"t": t.tolist(), "pos": (3.0 * t + 1.0).tolist(),
                               "cmd": np.sin(t).tolist()}))
    with pytest.raises(ScenarioError, match=r"--resample HZ"):
        import_log(src, M)
    log = import_log(src, M, resample_hz=1000.0)
    grid = log.columns["t"]
    assert grid[0] == 0.0 and grid[-1] <= t[-1] and len(grid) == int(t[-1] * 1000) + 1
    np.testing.assert_allclose(log.columns["y"], 3.0 * grid + 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(log.columns["u"], np.sin(grid), atol=1e-6)  # |f''| h² / 8
    assert log.resampled and log.jitter == 0.0
    note = log.notes[-1]
    assert note.startswith("resampled linearly from 1000 stamps ")
    assert f"from {dt.min() * 1e3:.4g} to {dt.max() * 1e3:.4g} ms" in note
    assert "jitter" not in log.summary()
    out = tmp_path / "o.csv"
    write_log(log, out)
    _names, data = read_log_columns(out, ["t", "y"], "need t, y")
    assert sample_period(data[:, 0], out) == pytest.approx(1e-3, rel=1e-9)


def test_resampling_refuses_a_long_gap_and_a_repeated_stamp(tmp_path):
    t = np.arange(100) / 100.0
    t[50:] += 0.5   # 50 samples missing
    src = tmp_path / "gap.json"
    src.write_text(json.dumps({"t": t.tolist(), "pos": t.tolist(), "cmd": t.tolist()}))
    with pytest.raises(ScenarioError, match=f"more than {MAX_RESAMPLE_GAP:g} would invent"):
        import_log(src, M, resample_hz=100.0)
    t2 = np.arange(10) / 100.0
    t2[5] = t2[4]
    src.write_text(json.dumps({"t": t2.tolist(), "pos": t2.tolist(), "cmd": t2.tolist()}))
    with pytest.raises(ScenarioError, match="row 6 .* is not after row 5"):
        import_log(src, M, resample_hz=100.0)
    with pytest.raises(ScenarioError, match="resample 1e\\+300"):
        import_log(src, M, resample_hz=1e300)


def test_offset_scale_and_sign_per_column(tmp_path):
    """value = sign · scale · raw + offset; an offset or scale may name a scalar of the file."""
    t, pos, cmd = _signals(50)
    src = tmp_path / "c.json"
    src.write_text(json.dumps({"t": t.tolist(), "pos": pos.tolist(), "cmd": cmd.tolist(),
                               "zero": 0.25, "kv": 4.0}))
    log = import_log(src, M, scales={"y": 2.0, "u": "kv"}, offsets={"y": "zero", "u": -1.0},
                     signs={"y": "-1"})
    np.testing.assert_array_equal(log.columns["y"], -2.0 * pos + 0.25)
    np.testing.assert_array_equal(log.columns["u"], 4.0 * cmd - 1.0)
    assert log.offsets == {"y": 0.25, "u": -1.0} and log.signs == {"y": -1.0}
    with pytest.raises(ScenarioError, match=r"sign y=2: must be \+1 or -1"):
        import_log(src, M, signs={"y": 2})
    with pytest.raises(ScenarioError, match="offset theta_ref: not a mapped column"):
        import_log(src, M, offsets={"theta_ref": 1})
    with pytest.raises(ScenarioError, match="offset y=nope: neither a number nor a scalar"):
        import_log(src, M, offsets={"y": "nope"})


def test_the_command_reads_json_and_applies_the_options(run_cli, tmp_path):
    t, pos, cmd = _signals(100)
    src = tmp_path / "c.json"
    src.write_text(json.dumps([{"t": a, "pos": b, "cmd": c}
                               for a, b, c in zip(t, pos, cmd, strict=True)]))
    out = tmp_path / "log.csv"
    res = run_cli("log", "import", str(src), "--map", "t=t,y=pos,u=cmd", "--sign", "y=-1",
                  "--offset", "u=0.5", "--out", str(out), "--json")
    assert res.exit_code == 0, res.stderr
    info = json.loads(res.stdout)
    assert info["sign"] == {"y": -1.0} and info["offset"] == {"u": 0.5}
    assert info["resampled"] is False and info["samples"] == 100
    _names, data = read_log_columns(out, ["y", "u"], "need y, u")
    np.testing.assert_array_equal(data[:, 0], -pos)
    np.testing.assert_array_equal(data[:, 1], cmd + 0.5)
