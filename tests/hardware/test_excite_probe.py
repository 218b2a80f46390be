"""An excitation that knows when it failed (issue 30, item 3): the breakaway probe, the
multisine scaled to break away within the torque limit, the stuck share and velocity
reversals measured as the run goes, and the log header that records them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.hardware.logfile import read_log_columns
from esoarm.scenario import load_scenario
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.experiment.probe import (
    BREAKAWAY_FACTOR,
    HEADER_KEYS,
    MotionStats,
    ProbingExcitation,
    read_header,
)


def _run(sets, plan=None, probe=6.0, log=None):
    scn = load_scenario("test-1", sets)
    ctl = ProbingExcitation(scn, plan or ExcitationPlan(duration=20.0), probe)
    _summary, preview = excite_twin(scn, None, log, controller=ctl)
    return ctl, preview["probe"]


def test_motion_stats_against_a_hand_made_path():
    """Stuck share and reversals of a noiseless path, counted by hand."""
    st = MotionStats(threshold=0.01, window=5)
    rest = [0.0] * 20                          # 20 samples at rest
    up = list(np.linspace(0.0, 1.0, 21)[1:])   # 0.05 rad per sample: moving
    down = list(np.linspace(1.0, 0.5, 11)[1:])
    for y in rest + up + down + [0.5] * 10:
        st.update(y)
    assert st.reversals == 1
    # windows of 5 steps wholly at rest: 15 at the start, 6 at the end (the ramp down ends
    # at 0.5, so 11 samples rest there); the windows reaching into motion move 0.05 rad
    assert st.samples == 60 - 5 and st.stuck == 15 + 6
    st.update(math.nan)  # a lost sample changes nothing
    assert st.samples == 55


def test_noise_at_rest_is_not_motion():
    """White noise of σ under the threshold (3√2 σ): stuck almost always, no reversals."""
    sigma = 0.2 * math.pi / 180
    st = MotionStats(threshold=3 * math.sqrt(2) * sigma)
    rng = np.random.default_rng(5)
    for y in rng.normal(0.0, sigma, 3000):
        st.update(float(y))
    assert st.stuck_fraction > 0.99 and st.reversals == 0


@pytest.mark.parametrize("coulomb", [0.05, 0.15, 0.3])
def test_probe_finds_the_breakaway_torque_of_the_twin(coulomb):
    """The mean of the two directions is Coulomb friction (the gravity torque at rest adds to
    one and takes from the other); the ramp overshoots by at most 30 %."""
    _ctl, rep = _run([f"rig.coulomb_friction={coulomb}"], ExcitationPlan(duration=2.0))
    assert rep.broke_away
    mean = 0.5 * (rep.breakaway_pos + rep.breakaway_neg)
    assert coulomb <= mean <= 1.3 * coulomb + 0.03, (rep.breakaway_pos, rep.breakaway_neg)


def test_a_sticking_arm_is_unstuck_by_the_scaled_multisine():
    """Coulomb 0.2 N·m against the default 0.2 N·m RMS: without the probe the arm is stuck
    most of the time; with it the multisine is raised to twice the breakaway and it moves."""
    sets = ["rig.coulomb_friction=0.2"]
    _ctl, bare = _run(sets, ExcitationPlan(duration=30.0), probe=0.0)
    assert bare.stuck_fraction > 0.5 and bare.amplitude == 0.2
    _ctl, probed = _run(sets, ExcitationPlan(duration=30.0))
    b = max(probed.breakaway_pos, probed.breakaway_neg)
    assert probed.amplitude == pytest.approx(BREAKAWAY_FACTOR * b)
    assert probed.stuck_fraction < 0.3 < bare.stuck_fraction
    assert probed.reversals > bare.reversals


def test_the_torque_limit_caps_the_multisine_and_says_so():
    """Coulomb 1.9 N·m with a 2 N·m limit: no breakaway within 0.9 × the limit; the multisine's
    peak stays within the limit; the header says it did not break away."""
    ctl, rep = _run(["rig.coulomb_friction=1.9"], ExcitationPlan(duration=10.0))
    assert not rep.broke_away and rep.limited
    peak = rep.amplitude * ctl._crest
    assert peak == pytest.approx(2.0)
    assert rep.stuck_fraction > 0.9


def test_the_log_header_records_the_probe_and_the_motion(tmp_path):
    log = tmp_path / "ex.csv"
    ctl, rep = _run(["rig.coulomb_friction=0.15"], ExcitationPlan(duration=4.0), log=log)
    head = read_header(log)
    assert set(head) == set(HEADER_KEYS)
    assert head["breakaway_pos"] == rep.breakaway_pos and head["amplitude"] == rep.amplitude
    assert head["stuck_fraction"] == rep.stuck_fraction and head["reversals"] == rep.reversals
    assert head["probe_s"] == 6.0 and head["excitation_start_s"] == 6.0
    assert head["samples"] == 200 - 5  # 4 s at 50 Hz, less the first window
    names, data = read_log_columns(log, ["t", "u"], "need t, u")  # readers skip the header
    assert len(data) == 300 + 200
    assert read_header(tmp_path / "missing.csv") == {}


def test_excite_plan_shows_the_probe_and_the_log_has_the_header(run_esoarm, tmp_path):
    res = run_esoarm("excite", "test-1", "--plan", "--duration", "10", "--set",
                     "rig.coulomb_friction=0.15")
    assert res.exit_code == 0, res.stderr
    assert "probe (6 s): breakaway" in res.stdout and "multisine RMS" in res.stdout
    assert "velocity reversals" in res.stdout and "stuck" in res.stdout
    res = run_esoarm("excite", "test-1", "--twin", "--duration", "4", "--probe", "2",
                     "--log", "ex.csv", cwd=tmp_path)
    assert res.exit_code == 0, res.stderr
    first = (tmp_path / "ex.csv").read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# esoarm excite: probe_s=2.0 ")
    res = run_esoarm("excite", "test-1", "--plan", "--probe", "0.05")
    assert res.exit_code == 2 and "probe 0.05 s: at least" in res.stderr


def test_the_stuck_share_means_the_same_speed_at_any_rate():
    """The window is 0.1 s (5 samples at 50 Hz, 100 at 1 kHz): the same sticking twin gives
    the same stuck share at both rates (a window of 5 samples at 1 kHz would call the arm
    stuck unless it moved 0.85° in 5 ms, 170°/s)."""
    plan = ExcitationPlan(duration=20.0)
    _c, slow = _run(["rig.coulomb_friction=0.2"], plan, probe=0.0)
    _c, fast = _run(["rig.coulomb_friction=0.2", "sensor.rate_hz=1000"], plan, probe=0.0)
    assert slow.window == 5 and fast.window == 100
    assert slow.threshold_rad == fast.threshold_rad
    assert abs(slow.stuck_fraction - fast.stuck_fraction) < 0.1, (slow.stuck_fraction,
                                                                   fast.stuck_fraction)
    assert slow.stuck_fraction > 0.5
