"""What a newcomer trips on with logs (issue 32): `log import` of files that are not what they
claim, a rate of 1e300, --out onto its own input, MAT variables that are not numbers, CSVs
from spreadsheets, too many tones for the run, Ctrl-C during `excite --twin`."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from esoarm.hardware.logimport import import_log
from esoarm.scenario import ScenarioError

MAP = ("--map", "t=t,y=y,u=u")


def _one_line(stderr: str) -> str:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    return lines[0]


def _csv(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_a_file_that_is_not_a_mat_file_is_bad_input(run_esoarm, tmp_path):
    """Was "internal error (scipy.io.matlab._miobase.MatReadError)", exit 1."""
    fake = _csv(tmp_path / "fake.mat", "t,y,u\n0,0,0\n")
    res = run_esoarm("log", "import", str(fake), *MAP, "--out", str(tmp_path / "o.csv"))
    line = _one_line(res.stderr)
    assert res.exit_code == 2
    assert "internal error" not in line and "not a MATLAB .mat file" in line
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("rate", ["1e300", "inf", "0", "2e6"])
def test_an_impossible_rate_is_refused(run_cli, tmp_path, rate):
    """Was accepted: "3000 samples at 1e+300 Hz"."""
    src = _csv(tmp_path / "a.csv", "y,u\n" + "".join(f"{k},0\n" for k in range(30)))
    res = run_cli("log", "import", str(src), "--map", "y=y,u=u", "--rate", rate, "--out",
                  str(tmp_path / "o.csv"))
    assert res.exit_code == 2, res.stdout
    assert "must be a sample rate > 0" in res.stderr and "1e+06 Hz" in res.stderr
    assert not (tmp_path / "o.csv").exists()


def test_out_onto_its_own_input_is_refused(run_cli, tmp_path):
    """Was: the source overwritten by its t, y, u columns (13 columns dropped)."""
    text = "t,y,u,extra\n" + "".join(f"{k / 100},{k},0,7\n" for k in range(20))
    src = _csv(tmp_path / "LOG.csv", text)
    res = run_cli("log", "import", str(src), *MAP, "--out", str(src))
    assert res.exit_code == 2 and "is FILE itself" in res.stderr
    assert src.read_text(encoding="utf-8") == text
    res = run_cli("log", "import", str(src), *MAP, "--out", str(tmp_path / "." / "LOG.csv"))
    assert res.exit_code == 2 and src.read_text(encoding="utf-8") == text


@pytest.mark.parametrize(("value", "said"), [
    (np.array(["volts"]), "is text ('volts'), not numbers"),
    (np.arange(5) + 1j, "is complex numbers"),
    (np.zeros((0, 0)), "is empty (0 values)"),
    ({"pos": np.arange(5.0), "gain": 2.0}, "is a struct with fields pos, gain: name one as "
                                           "v.pos"),
])
def test_mat_variables_that_are_not_numbers_are_named(tmp_path, value, said):
    """Was "no such variable" / "the file has no columns"."""
    src = tmp_path / "rec.mat"
    scipy.io.savemat(src, {"t": np.arange(5) / 100, "y": np.zeros(5), "v": value})
    with pytest.raises(ScenarioError, match=r"v \(for u\) " + _re(said)):
        import_log(src, {"t": "t", "y": "y", "u": "v"})


def _re(text: str) -> str:
    import re

    return re.escape(text)


def test_a_struct_field_is_a_column(tmp_path):
    src = tmp_path / "rec.mat"
    scipy.io.savemat(src, {"log": {"t": np.arange(5) / 100, "pos": np.arange(5.0),
                                   "cmd": np.ones(5), "gain": 2.0}})
    log = import_log(src, {"t": "log.t", "y": "log.pos", "u": "log.cmd"}, {"u": "log.gain"})
    np.testing.assert_array_equal(log.columns["y"], np.arange(5.0))
    np.testing.assert_array_equal(log.columns["u"], np.full(5, 2.0))


def test_a_semicolon_csv_is_read_and_said(run_cli, tmp_path):
    """Was "line 2: expected numbers": a spreadsheet's regional CSV (';', decimal commas)."""
    rows = "".join(f"{k / 1000:.3f};{k * 0.5};-1,5\n".replace(".", ",") for k in range(50))
    src = _csv(tmp_path / "excel.csv", "t;y;u\n" + rows)
    log = import_log(src, {"t": "t", "y": "y", "u": "u"})
    assert log.rate_hz == 1000.0
    np.testing.assert_allclose(log.columns["y"], np.arange(50) * 0.5)
    np.testing.assert_array_equal(log.columns["u"], np.full(50, -1.5))
    res = run_cli("log", "import", str(src), *MAP, "--out", str(tmp_path / "o.csv"))
    assert res.exit_code == 0, res.stderr
    assert "fields separated by ';'" in res.stderr


def test_a_csv_whose_time_is_text_names_the_cause_and_the_fix(run_cli, tmp_path):
    """A logger's clock-time column: was "line 2: expected numbers"."""
    rows = "".join(f"12:00:{k:02d}.000,{k},0\n" for k in range(20))
    src = _csv(tmp_path / "clock.csv", "time,pos,cmd\n" + rows)
    res = run_cli("log", "import", str(src), "--map", "t=time,y=pos,u=cmd", "--out",
                  str(tmp_path / "o.csv"))
    line = _one_line(res.stderr)
    assert res.exit_code == 2
    assert "time (for t) is text ('12:00:00.000'" in line
    assert "--rate HZ" in line and "expected numbers" not in line
    # not mapped, the text column is no obstacle: the rate gives the stamps
    res = run_cli("log", "import", str(src), "--map", "y=pos,u=cmd", "--rate", "1", "--out",
                  str(tmp_path / "o.csv"))
    assert res.exit_code == 0, res.stderr


def test_a_csv_without_a_t_column_says_what_to_map(run_cli, tmp_path):
    src = _csv(tmp_path / "nt.csv", "pos,cmd\n" + "".join(f"{k},0\n" for k in range(20)))
    res = run_cli("log", "import", str(src), "--map", "t=t,y=pos,u=cmd", "--out",
                  str(tmp_path / "o.csv"))
    line = _one_line(res.stderr)
    assert res.exit_code == 2
    assert "t (for t): no such variable; the file has cmd, pos" in line
    assert "give --rate HZ" in line


def test_a_csv_without_a_header_line_says_so(run_cli, tmp_path):
    src = _csv(tmp_path / "nohead.csv", "".join(f"{k / 100},{k},0\n" for k in range(20)))
    res = run_cli("log", "import", str(src), *MAP, "--out", str(tmp_path / "o.csv"))
    line = _one_line(res.stderr)
    assert res.exit_code == 2 and "the first line holds numbers" in line
    assert "add a header line" in line


def test_more_tones_than_the_run_resolves_are_refused(run_cli):
    """`excite test-1 --plan --tones 100000` was accepted; 60 s resolve 295 tones in
    0.1-5 Hz (1/60 Hz apart)."""
    res = run_cli("excite", "test-1", "--plan", "--tones", "100000")
    assert res.exit_code == 2
    assert "at most the 295 frequencies a 60 s run resolves" in _one_line(res.stderr)
    res = run_cli("excite", "test-1", "--plan", "--tones", "296")
    assert res.exit_code == 2


def test_ctrl_c_during_excite_twin_says_what_was_kept(run_cli, tmp_path, monkeypatch):
    """Was only "esoarm: interrupted" though the file and its rows stay."""
    from esoarm.hardware import emulator

    calls = {"n": 0}
    advance = emulator.Twin.advance

    def interrupted(self, *args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 123:
            raise KeyboardInterrupt
        return advance(self, *args, **kwargs)

    monkeypatch.setattr(emulator.Twin, "advance", interrupted)
    log = tmp_path / "ex.csv"
    res = run_cli("excite", "test-1", "--twin", "--duration", "10", "--log", str(log))
    line = _one_line(res.stderr)
    assert res.exit_code == 130
    assert line.startswith("esoarm: interrupted: twin experiment stopped at sample 122 of 800")
    assert f"the 122 rows logged (2.44 s of 16 s) are in {log}" in line
    lines = log.read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("# esoarm excite:") and len(lines) == 2 + 122
    assert all(len(ln.split(",")) == 16 for ln in lines[1:])


def test_a_binary_file_named_csv_says_it_is_not_text(tmp_path):
    src = tmp_path / "data.csv"
    src.write_bytes(b"t,y,u\n" + bytes(range(128, 256)))
    with pytest.raises(ScenarioError, match="not a text file .* export it as CSV"):
        import_log(src, {"t": "t", "y": "y", "u": "u"})


def test_a_scale_that_overflows_is_named_without_a_numpy_warning(tmp_path, recwarn):
    src = tmp_path / "big.json"
    src.write_text('{"t": [0, 0.01, 0.02], "y": [1e308, 1, 2], "u": [0, 0, 0]}')
    with pytest.raises(ScenarioError, match=r"y \(for y\) is inf at row 1"):
        import_log(src, {"t": "t", "y": "y", "u": "u"}, {"y": 1e10})
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


@pytest.mark.parametrize(("args", "said"), [
    (("--probe", "1e9"), "--probe 1e+09: must be >= 0 s, and with the duration at most 1e+08"),
    (("--duration", "1e9"), "--duration 1e+09: must be > 0 s and at most 2e+06 s"),
])
def test_an_experiment_too_long_to_hold_is_bad_input(run_cli, args, said):
    """Was "failed: out of memory", exit 1."""
    res = run_cli("excite", "test-1", "--plan", *args)
    assert res.exit_code == 2 and said in _one_line(res.stderr)
