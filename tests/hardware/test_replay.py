"""Offline ESO over logs (esoarm.hardware.replay)."""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, simulate
from esoarm.hardware.replay import read_log, replay
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.plants.sensor import measure
from esoarm.scenario import ScenarioError, load_scenario

from .rig_helpers import esoarm


def _measured_log(path, sets):
    """A log of a simulated run with the measured angle, as a rig would record it."""
    scn = load_scenario("test-2", sets)
    inp = prepare(scn)
    res = simulate(scn, warn=False)
    y = [measure(th, n, inp.sigma, inp.q) for th, n in zip(res.theta, inp.noise, strict=True)]
    np.savetxt(path, np.column_stack([res.t, y, res.u]), delimiter=",", header="t,theta,u",
               comments="", fmt="%.17g")
    return scn, res


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_replay_recovers_the_controllers_estimates(tmp_path, disc):
    sets = ["duration=3", f"observer.discretization={disc}"]
    scn, res = _measured_log(tmp_path / "log.csv", sets)
    t, theta, u, ts = read_log(tmp_path / "log.csv")
    assert ts == scn.sample_time
    rep = replay(scn, t, theta, u, ts)
    assert np.array_equal(rep.z, res.z)


@pytest.mark.slow
def test_replay_cli(tmp_path):
    sets = ["duration=2", "observer.eps=0.05"]
    _, res = _measured_log(tmp_path / "log.csv", sets)
    out = tmp_path / "z.csv"
    args = ["replay", str(tmp_path / "log.csv"), "--scenario", "test-2"]
    for s in sets:
        args += ["--set", s]
    r = esoarm(*args, "--out", str(out), "--plot", str(tmp_path / "z.png"))
    assert r.returncode == 0, r.stderr
    z = np.genfromtxt(out, delimiter=",", names=True)
    assert np.array_equal(np.column_stack([z["z1"], z["z2"], z["z3"]]), res.z)
    assert (tmp_path / "z.png").stat().st_size > 0


@pytest.mark.parametrize("text, match", [
    ("t,theta\n0,0\n0.02,0\n", "missing column.*u"),
    ("t,theta,u\n0,0,0\n", "at least 2 rows"),
    ("t,theta,u\n0,0,0\n0.02,0,0\n0.05,0,0\n", "uniformly spaced"),
    ("t,theta,u\n0,0,0\n0.02,x,0\n", "line 3"),
    ("t,theta,u\n0,nan,0\n0.02,0,0\n", "theta must be finite"),
    ("", "empty file"),
])
def test_bad_logs(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=match):
        read_log(path)


def test_bad_log_cli_is_exit_2(tmp_path):
    r = esoarm("replay", str(tmp_path / "missing.csv"))
    assert r.returncode == 2 and "no such file" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_replay_says_how_many_rows_were_bridged(tmp_path):
    log = tmp_path / "gaps.csv"
    log.write_text("t,theta,u\n0,0,0\n0.02,nan,0\n0.04,nan,0.1\n0.06,0.01,0\n", encoding="utf-8")
    r = esoarm("replay", str(log), "--out", str(tmp_path / "z.csv"))
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "2 of 4 rows" in lines[0] and "bridged" in lines[0]
    quiet = esoarm("replay", str(log), "--out", str(tmp_path / "z.csv"), "--quiet")
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_replay_reads_the_measured_angle_y_when_the_file_has_it(tmp_path):
    """A simulated series' theta is the true angle: replay must use its y column."""
    log = tmp_path / "both.csv"
    log.write_text("t,theta,u,y\n0,5,0,0\n0.02,5,0,0.01\n0.04,5,0,0.02\n", encoding="utf-8")
    t, theta, u, ts = read_log(log)
    assert list(theta) == [0.0, 0.01, 0.02] and ts == pytest.approx(0.02)
