"""What the fourth newcomer trial (benchmarks/newcomer_trial.py) found not clean, each fixed:
a range without its spacing, --samples without --robust, a binary log or scenario file, an
empty scenario file, a Gymnasium action that is not a number."""

from __future__ import annotations

import numpy as np
import pytest


def _one_error(res, *words: str) -> str:  # type: ignore[no-untyped-def]
    assert res.exit_code == 2, (res.exit_code, res.stderr, res.exception)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("esoarm: error:"), res.stderr
    assert "Traceback" not in res.stderr and "Warning" not in res.stderr
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.mark.parametrize("command", ["sweep", "analyze"])
@pytest.mark.parametrize("spec", ["0.05:0.1:3", "a:b:3"])
def test_a_range_without_its_spacing_says_lin_or_geom(run_cli, command, spec):
    # was: "key 'observer.eps' = '0.05:0.1:3': input should be a valid number"
    res = run_cli(command, "test-1", "--vary", f"observer.eps={spec}")
    _one_error(res, "observer.eps", "lin:START:STOP:NUM", "geom:START:STOP:NUM", "comma list")


def test_a_list_and_a_spaced_range_still_parse():
    from esoarm.studies.sweeps.grid import parse_vary

    assert parse_vary("observer.eps=lin:0.05:0.1:3").values == (0.05, 0.07500000000000001, 0.1)
    assert parse_vary("observer.eps=0.05,0.1").values == (0.05, 0.1)
    assert parse_vary("observer.discretization=euler,zoh").values == ("euler", "zoh")


def test_tune_samples_without_robust_is_refused(run_cli):
    # was: accepted, the 5 never used, and the tune ran
    res = run_cli("tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--samples", "5")
    _one_error(res, "--samples 5", "--robust")


@pytest.mark.parametrize("command", [("replay",), ("identify",),
                                     ("learn-map",)])
def test_a_binary_log_points_at_log_import(run_cli, tmp_path, command):
    # was: "cannot read: 'utf-8' codec can't decode byte 0x80 in position 128: ..."
    log = tmp_path / "bin.csv"
    log.write_bytes(bytes(range(256)) * 4)
    extra = ["test-1", "--out", str(tmp_path / "m.toml")] if command[0] == "learn-map" else []
    res = run_cli(*command, str(log), *extra)
    msg = _one_error(res, "bin.csv", "not a text CSV", "esoarm log import")
    assert "codec" not in msg


def test_an_empty_scenario_file_is_refused(run_cli, tmp_path):
    # was: exit 0, every key at its default, under the file's name
    for text in ("", "# nothing yet\n"):
        path = tmp_path / "my-rig.toml"
        path.write_text(text)
        _one_error(run_cli("simulate", str(path)), "my-rig.toml", "sets no key",
                   "esoarm show")


def test_a_binary_scenario_file_says_so(run_cli, tmp_path):
    path = tmp_path / "rig.toml"
    path.write_bytes(bytes(range(256)) * 2)
    msg = _one_error(run_cli("simulate", str(path)), "rig.toml", "not a text TOML file")
    assert "codec" not in msg


@pytest.mark.parametrize("action", ["up", None, {"u": 1}])
def test_an_action_that_is_not_a_number_names_the_action_space(action):
    pytest.importorskip("gymnasium")
    from esoarm.envs import LeverArmEnv

    env = LeverArmEnv()
    env.reset(seed=3)
    if action is None:  # NumPy makes None a NaN: the finite check names it
        with pytest.raises(ValueError, match="must be a finite torque"):
            env.step(action)
        return
    with pytest.raises(ValueError, match=r"must be a number array of shape \(1,\)"):
        env.step(action)
    obs, *_ = env.step(np.array([0.05]))  # the episode goes on
    assert np.all(np.isfinite(obs))
