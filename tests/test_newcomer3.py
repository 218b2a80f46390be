"""What a newcomer still trips on (third round): options dropped or ignored without a word,
settings that do nothing, messages naming the wrong cause, progress that misleads."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

# ---------------------------------------------------------------------------
# analyze --bandwidth with --vary: refused, not silently dropped


def test_analyze_bandwidth_with_vary_is_refused(run_cli):
    res = run_cli("analyze", "test-1", "--bandwidth", "10", "--vary", "observer.eps=0.05,0.09")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert "--bandwidth" in line and "--vary" in line


# ---------------------------------------------------------------------------
# tune: --plot with --no-plot refused; no figure unless one is asked for


def test_tune_plot_and_no_plot_is_refused(run_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = run_cli("tune", "test-1", "--vary", "observer.eps=0.03:0.1", "--plot", "p.png",
                  "--no-plot")
    assert res.exit_code == 2
    assert "--plot" in res.stderr and "--no-plot" in res.stderr
    assert list(tmp_path.iterdir()) == []


def test_tune_writes_no_figure_unless_asked(run_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = run_cli("tune", "test-1", "--vary", "observer.eps=0.03:0.1", "--set", "duration=0.5",
                  "--maxiter", "1", "--popsize", "2", "--seeds", "1", "--json")
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["plot"] is None
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------
# simulate: a PWM so coarse that the arm is never driven; a gear play beyond any gear


def test_coarse_pwm_is_warned_before_and_after_the_run(run_cli):
    res = run_cli("simulate", "test-1", "--set", "actuator.pwm_bits=1", "--set", "duration=2",
                  "--json")
    assert res.exit_code == 0
    assert json.loads(res.stdout)["rms_u"] == 0.0
    assert "actuator.pwm_bits = 1" in res.stderr and "rounded to 0" in res.stderr
    assert "every command was rounded to 0" in res.stderr
    quiet = run_cli("simulate", "test-1", "--set", "actuator.pwm_bits=8", "--set",
                    "duration=2", "--json")
    assert "pwm_bits" not in quiet.stderr


@pytest.mark.parametrize(("value", "code"), [("1e6", 2), ("20.5", 2), ("20", 0), ("2", 0)])
def test_backlash_has_a_physical_upper_bound(run_cli, value, code):
    res = run_cli("show", "test-1", "--set", f"rig.backlash_deg={value}")
    assert res.exit_code == code, res.stderr
    if code:
        line, = res.stderr.strip().splitlines()
        assert "rig.backlash_deg" in line and "20" in line


# ---------------------------------------------------------------------------
# analyze: what the linear model leaves out is named (backlash, as for a motor)


def test_analyze_names_the_backlash_it_leaves_out(run_cli):
    res = run_cli("analyze", "test-1", "--set", "rig.backlash_deg=2")
    assert res.exit_code == 0, res.stderr
    assert "left out" in res.stdout and "rig.backlash_deg = 2" in res.stdout
    res = run_cli("analyze", "test-1", "--set", "rig.backlash_deg=2", "--json")
    assert "backlash" in json.loads(res.stdout)["left_out"][0]
    res = run_cli("analyze", "test-1")
    assert "backlash" not in res.stdout


# ---------------------------------------------------------------------------
# --set motor.KEY on a scenario without [motor]: said; run --json's mode is what was measured


def test_a_motor_key_on_a_scenario_without_motor_says_it_adds_one(run_cli):
    res = run_cli("show", "test-1", "--set", "motor.gear_ratio=30")
    assert res.exit_code == 0
    assert "has no [motor] table" in res.stderr and "motor.gear_ratio" in res.stderr
    assert "[motor]" in res.stdout
    res = run_cli("show", "uno-rig", "--set", "motor.gear_ratio=30")
    assert "has no [motor] table" not in res.stderr


def test_run_json_mode_is_what_was_measured():
    from esoarm.cli.rig import _json_summary

    def summary(mode):
        return SimpleNamespace(samples=1000, mode=mode, stream_every=1, onboard=False,
                               to_dict=lambda: {"samples": 1000, "mode": mode})

    fast = _json_summary("test-1", summary("real time"), 8.3, 0.02)
    assert fast["mode"] == "not real time" and fast["mode_requested"] == "real time"
    assert "not paced in real time" in fast["pace_warning"]
    paced = _json_summary("test-1", summary("real time"), 20.4, 0.02)
    assert paced["mode"] == "real time" and "mode_requested" not in paced


# ---------------------------------------------------------------------------
# analyze --bandwidth: the real cause when there is no recommendation


def test_a_bandwidth_too_low_names_the_reach_not_nyquist(run_cli):
    res = run_cli("analyze", "test-1", "--bandwidth", "0.001")
    assert res.exit_code == 0
    last = res.stdout.strip().splitlines()[-1]
    assert "Nyquist" not in last and "[motor]" not in last
    assert "at least" in last and "ask for more" in last
    res = run_cli("analyze", "test-1", "--bandwidth", "0.001", "--json")
    assert "ask for more" in json.loads(res.stdout)["recommendation_note"]


def test_a_bandwidth_too_high_names_the_sample_rate(run_cli):
    res = run_cli("analyze", "test-1", "--bandwidth", "1000")
    last = res.stdout.strip().splitlines()[-1]
    assert "at most" in last and "sensor.rate_hz" in last


def test_a_motor_scenario_says_the_recommendation_is_not_modelled(run_cli):
    res = run_cli("analyze", "uno-rig", "--bandwidth", "10", "--tracking")
    assert res.exit_code == 0
    last = res.stdout.strip().splitlines()[-1]
    assert "Nyquist" not in last and "(or a [motor]" not in last
    assert "does not model a [motor] table" in last


# ---------------------------------------------------------------------------
# an unknown key of a kind: suggestions among the keys of the kind in force only


@pytest.mark.parametrize(("key", "wanted", "unwanted"), [
    ("observer.foo", "observer kind 'linear' has the keys kind, eps, discretization",
     "observer.ratio"),
    ("observer.esp", "did you mean 'observer.eps'", "observer.ratio"),
    ("controller.k3", "did you mean 'controller.k2'", None),
])
def test_unknown_kind_key_suggests_only_keys_of_the_kind_in_force(run_cli, key, wanted, unwanted):
    res = run_cli("show", "test-1", "--set", f"{key}=1")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert wanted in line
    if unwanted:
        assert unwanted not in line


def test_unknown_key_of_another_kind_in_force(run_cli):
    res = run_cli("show", "test-1", "--set", "observer.kind=cascade", "--set", "observer.rati=2")
    assert "did you mean 'observer.ratio'" in res.stderr


# ---------------------------------------------------------------------------
# Ctrl-C during analyze: says what was kept


def test_ctrl_c_during_analyze_says_nothing_was_written(run_cli, monkeypatch, tmp_path):
    from esoarm.studies.frequency import margins

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(margins, "analyze", interrupted)
    res = run_cli("analyze", "test-1", "--plot", str(tmp_path / "b.png"))
    assert res.exit_code == 130
    assert "interrupted" in res.stderr and "nothing written" in res.stderr
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.09")
    assert res.exit_code == 130
    assert "after 0 of 2 points" in res.stderr and "nothing written" in res.stderr
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------
# progress: no time-left estimate until it has settled


def test_progress_lines_show_no_estimate_before_it_settles(monkeypatch, capsys):
    from esoarm.cli import _common

    clock = [0.0]
    monkeypatch.setattr("time.monotonic", lambda: clock[0])
    monkeypatch.setattr(_common, "stderr_is_tty", lambda: False)
    lines = []
    with _common.progress(1000, "simulating", "samples") as advance:
        clock[0] = 30.0  # 30 s of compiling, then a small first step
        advance(1)
        for _ in range(4):  # then 100 samples every 10 s: 1,000 in ~100 s
            clock[0] += 10.0
            advance(100)
            lines.append(capsys.readouterr().err)
    text = "".join(lines)
    first = [ln for ln in text.splitlines() if "simulating" in ln]
    assert "estimating" in first[0] and "left," not in first[0]
    estimates = [float(ln.split("about ")[1].split(" s left")[0].replace(",", ""))
                 for ln in first if "about" in ln]
    assert estimates, text
    # the samples left at 10 a second (before: the 30 s of compiling counted, ~360 s)
    assert estimates == [80.0, 70.0, 60.0][-len(estimates):], estimates


def test_settled_needs_both_share_and_time():
    from esoarm.cli._common import settled

    assert not settled(0.01, 100.0) and not settled(0.5, 1.0) and settled(0.05, 3.0)


# ---------------------------------------------------------------------------
# the report page counts what the progress counted; the Bode figure's labels stay inside


def test_report_says_how_many_runs_in_all():
    from esoarm.studies.reproduction.data import Reproduction

    rep = Reproduction(scenarios={}, runs={}, n_simulated=41)
    assert rep.runs_text() == "41 simulated runs"
    rep.n_simulated_all = 95
    assert rep.runs_text().startswith("41 simulated runs for these tables and claims (95 in all")


def test_bode_labels_stay_inside_their_axes():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from esoarm.scenario import load_scenario
    from esoarm.studies.frequency.margins import analyze
    from esoarm.studies.frequency.plots import figure_frequency

    fig = figure_frequency(analyze(load_scenario("test-1")))
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    labels = 0
    for ax in fig.axes:
        box = ax.get_window_extent(renderer)
        for text in ax.texts:
            if not text.get_text():
                continue
            labels += 1
            ext = text.get_window_extent(renderer)
            assert (box.x0 <= ext.x0 and ext.x1 <= box.x1 and box.y0 <= ext.y0
                    and ext.y1 <= box.y1), text.get_text()
    assert labels >= 3


def test_ctrl_c_during_reproduce_says_what_was_kept(run_cli, monkeypatch, tmp_path):
    from esoarm.studies.reproduction import run as reproduction

    def interrupted(overrides, progress=None, **kwargs):
        for key in ("a", "b", "c"):
            progress(key)
        raise KeyboardInterrupt

    monkeypatch.setattr(reproduction, "run_reproduction", interrupted)
    out = tmp_path / "rep"
    res = run_cli("reproduce", "--out", str(out))
    assert res.exit_code == 130
    line, = res.stderr.strip().splitlines()
    assert "after 3 of about" in line and f"nothing written to {out}" in line
    assert not out.exists()


def test_progress_gives_the_estimate_once_a_quarter_is_done(monkeypatch, capsys):
    from esoarm.cli import _common

    clock = [0.0]
    monkeypatch.setattr("time.monotonic", lambda: clock[0])
    monkeypatch.setattr(_common, "stderr_is_tty", lambda: False)
    with _common.progress(1000, "simulating", "samples") as advance:
        advance(1)
        clock[0] = 12.0
        advance(400)  # the first line, 40 % done: no earlier estimate to agree with
        line = capsys.readouterr().err
    assert "about 18 s left" in line, line
