"""Issue 32's newcomer cases in replay, the Gymnasium environment and the lost-sample bridge.

Each fails on the code before the stepper: replay of a diverging observer wrote a CSV of
NaN with a NumPy overflow warning and exit 0; replay took a log in degrees, a rotary log
on a prismatic axis, and a rate set on the command line that the log contradicts, without
a word; the environment took an action of the wrong shape; a lost sample assumed z[0] is
the angle.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from esoarm.scenario import load_scenario


@pytest.fixture(scope="module")
def log(tmp_path_factory):  # type: ignore[no-untyped-def]
    """A 20 s closed-loop run of test-1 (y, u, ...), as ``simulate --out`` writes it."""
    from esoarm.engines.simulation import simulate

    path = tmp_path_factory.mktemp("logs") / "run.csv"
    simulate("test-1", {"duration": 20.0}, warn=False).to_csv(path)
    return path


def _lines(res):  # type: ignore[no-untyped-def]
    return [ln for ln in res.stderr.strip().splitlines() if not ln.startswith("esoarm: warning:")]


def test_replay_of_a_diverging_observer_says_so(run_cli, log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "rep.csv"
    res = run_cli("replay", str(log), "--set", "observer.eps=0.001", "--out", str(out))
    assert res.exit_code == 1, (res.stdout, res.stderr)
    assert "RuntimeWarning" not in res.stderr and "overflow" not in res.stderr
    lines = _lines(res)
    assert len(lines) == 1 and "diverged at row" in lines[0] and "unstable" in lines[0]
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert 0 < len(rows) < 1000  # the rows up to the divergence, kept
    assert all(math.isfinite(float(r["z1"])) for r in rows[:-1])


def test_replay_refuses_a_log_in_degrees(run_cli, log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    deg = tmp_path / "deg.csv"
    with log.open() as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    with deg.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(head)
        for r in rows[1:]:
            w.writerow([repr(math.degrees(float(v))) if head[i] in ("theta", "y") else v
                        for i, v in enumerate(r)])
    res = run_cli("replay", str(deg), "--out", str(tmp_path / "rep.csv"))
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = _lines(res)
    assert len(lines) == 1 and "units look wrong" in lines[0] and "degrees" in lines[0]
    assert not (tmp_path / "rep.csv").exists()
    assert run_cli("replay", str(log), "--out", str(tmp_path / "ok.csv")).exit_code == 0


def test_replay_refuses_a_rotary_log_on_a_prismatic_axis(run_cli, log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("replay", str(log), "--scenario", "emps", "--out", str(tmp_path / "r.csv"))
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = _lines(res)
    assert len(lines) == 1 and "units look wrong" in lines[0] and "this plant" in lines[0]


def test_replay_refuses_a_rate_the_log_contradicts(run_cli, log, tmp_path) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("replay", str(log), "--set", "sensor.rate_hz=100",
                  "--out", str(tmp_path / "r.csv"))
    assert res.exit_code == 2
    lines = _lines(res)
    assert len(lines) == 1 and "sensor.rate_hz = 100 Hz" in lines[0] and "50 Hz" in lines[0]
    ok = run_cli("replay", str(log), "--set", "sensor.rate_hz=50", "--out",
                 str(tmp_path / "r.csv"))
    assert ok.exit_code == 0, ok.stderr


@pytest.mark.parametrize("action", [np.array([1.0, 2.0]), np.zeros((1, 1, 2)), np.array([])])
def test_env_refuses_an_action_of_the_wrong_shape(action) -> None:  # type: ignore[no-untyped-def]
    from esoarm.envs import LeverArmEnv

    env = LeverArmEnv("test-1", {"duration": 1.0})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action of shape .*must be shape \(1,\)"):
        env.step(action)
    env.step(np.array([0.1]))  # the episode is unchanged and goes on
    env.step(0.1)


def test_a_lost_sample_asks_the_observer_kind_not_z0() -> None:
    """The cascade's estimate comes from its last level: bridging with the kind's predict
    gives zero innovation in the level the measurement enters (z[0] happens to be it; the
    stepper never reads z[0] itself, it asks the kind)."""
    from esoarm.engines.stepper import Stepper

    calls = []
    for kind in ("linear", "nonlinear", "cascade"):
        scn = load_scenario("test-1", {"observer.kind": kind})
        st = Stepper.observer_of(scn)
        predict = st.kinds.observer.predict

        def spy(z, zhat, p, y, predict=predict, kind=kind):  # type: ignore[no-untyped-def]
            calls.append(kind)
            predict(z, zhat, p, y)

        st.kinds = st.kinds._replace(observer=_with_predict(st.kinds.observer, spy))
        st.estimate(0.2)
        st.observe(0.0)
        zhat = st.bridge(0.0)
        assert np.all(np.isfinite(zhat)) and abs(zhat[0] - 0.2) < 0.05
    assert calls == ["linear", "nonlinear", "cascade"]


def _with_predict(module, predict):  # type: ignore[no-untyped-def]
    import types

    out = types.SimpleNamespace(**{k: getattr(module, k) for k in dir(module)
                                   if not k.startswith("__")})
    out.predict = predict
    return out
