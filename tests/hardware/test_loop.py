"""The run loop in-process against a scripted device (no pty): gaps, safety, log."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.hardware import protocol as P
from esoarm.hardware.emulator import Twin
from esoarm.hardware.host_control import DeploymentController
from esoarm.hardware.realtime import LOG_COLUMNS, RigFault, SafetyLimits, run_rig
from esoarm.hardware.replay import read_log, replay
from esoarm.scenario import ScenarioError, load_scenario


class FakeLink:
    """A lockstep device in-process: the twin answers each TORQUE with the next sample.

    ``lose`` holds sample indices the link loses (the device holds its command
    over the lost interval, as a real device does); ``count_offset`` adds to
    the encoder from a sample index on; ``fault_at`` makes the device report a
    FAULT instead of that sample.
    """

    def __init__(self, scn, lose=(), count_offset=None, fault_at=None, info=None):
        self.twin = Twin(scn)
        self.info = info or P.Info(1, P.FLAG_TORQUE | P.FLAG_LOCKSTEP,
                                   self.twin.counts_per_rev, 255, round(1e6 * scn.sample_time))
        self.lose, self.count_offset, self.fault_at = set(lose), count_offset, fault_at
        self.queue: list[P.Frame] = []
        self.parser = P.Parser()
        self.rx_lost = 0
        self.stopped = False
        self.sent: list[tuple] = []

    def handshake(self):
        return self.info

    def _emit(self):
        twin = self.twin
        count = twin.count()
        if self.count_offset and twin.k >= self.count_offset[0]:
            count += self.count_offset[1]
        if twin.k == self.fault_at:
            self.queue.append(P.Frame(P.FAULT, 0, P.encode(P.FAULT, 0, 1, twin.k)[5:-2]))
            return
        if twin.k in self.lose:
            twin.advance(self._u)
            self._emit()
            return
        payload = P.encode(P.SAMPLE, 0, twin.k, twin.k * 20000, count)[5:-2]
        self.queue.append(P.Frame(P.SAMPLE, 0, payload))

    def send(self, kind, *fields):
        self.sent.append((kind, *fields))
        if kind == P.START:
            self._u = 0.0
            self._emit()
        elif kind == P.TORQUE:
            self._u = fields[1]
            self.twin.advance(self._u)
            self._emit()

    def receive(self, timeout):
        out, self.queue = self.queue, []
        if self.stopped and not out:
            return [P.Frame(P.STOPPED, 0, b"")]
        return out

    def stop(self):
        self.stopped = True


def _log(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    assert data.dtype.names == LOG_COLUMNS
    return data


def test_lost_samples_are_bridged_and_replay_agrees(tmp_path):
    scn = load_scenario("test-1", ["duration=2"])
    link = FakeLink(scn, lose={30, 31, 70})
    log = tmp_path / "gap.csv"
    summary = run_rig(scn, link, log)
    data = _log(log)
    assert summary.samples == len(data) == 100 and summary.lost_samples == 3
    assert np.array_equal(np.flatnonzero(np.isnan(data["theta"])), [30, 31, 70])
    assert np.array_equal(data["k"], np.arange(100))
    # the held command is what the observer is updated with
    assert data["u"][30] == data["u"][29] == data["u"][31]
    # the offline replay bridges the same way and recovers the same estimates
    t, theta, u, ts = read_log(log)
    rep = replay(scn, t, theta, u, ts)
    assert np.array_equal(rep.z, np.column_stack([data["z1"], data["z2"], data["z3"]]))
    assert link.stopped and summary.stop_acknowledged


def test_angle_limit_and_jump_guard(tmp_path):
    scn = load_scenario("test-1", ["duration=2"])
    link = FakeLink(scn, count_offset=(40, 2000))  # +100° jump at sample 40
    with pytest.raises(RigFault, match="encoder jump.*sample 40"):
        run_rig(scn, link, tmp_path / "a.csv")
    assert link.stopped and len(_log(tmp_path / "a.csv")) == 40

    link = FakeLink(scn, count_offset=(40, 2000))
    with pytest.raises(RigFault, match="angle limit"):
        run_rig(scn, link, tmp_path / "b.csv",
                SafetyLimits(angle_limit=0.5, max_jump=10.0))
    assert link.stopped and len(_log(tmp_path / "b.csv")) == 40


def test_nan_guard(tmp_path, monkeypatch):
    scn = load_scenario("test-1", ["duration=1"])
    real_step = DeploymentController.step

    def step(self, k, y):
        return math.nan if k == 12 else real_step(self, k, y)

    monkeypatch.setattr(DeploymentController, "step", step)
    link = FakeLink(scn)
    with pytest.raises(RigFault, match="NaN guard.*sample 12"):
        run_rig(scn, link, tmp_path / "n.csv")
    assert link.stopped and len(_log(tmp_path / "n.csv")) == 12
    assert all(kind != P.TORQUE or fields[0] < 12 for kind, *fields in link.sent)


def test_device_fault_report_stops(tmp_path):
    scn = load_scenario("test-1", ["duration=1"])
    link = FakeLink(scn, fault_at=7)
    with pytest.raises(RigFault, match="device reported a fault: command watchdog"):
        run_rig(scn, link, tmp_path / "f.csv")
    assert link.stopped and len(_log(tmp_path / "f.csv")) == 7


def test_duty_device_needs_a_motor_table():
    scn = load_scenario("test-1", ["duration=1"])
    link = FakeLink(scn, info=P.Info(1, 0, 7200, 255, 20000))
    with pytest.raises(ScenarioError, match=r"\[motor\]"):
        run_rig(scn, link, None)
    assert not any(kind == P.START for kind, *_ in link.sent)


def test_status_ends_at_the_last_sample_logged(tmp_path):
    """The status is rate-limited; its last report is the last row of the log, after STOP."""
    scn = load_scenario("test-1", ["duration=2"])
    for link, name in ((FakeLink(scn), "end.csv"), (FakeLink(scn, count_offset=(40, 2000)),
                                                    "fault.csv")):
        seen: list[tuple[dict, bool]] = []

        def status(s, link=link, seen=seen):
            seen.append((s, link.stopped))

        try:
            run_rig(scn, link, tmp_path / name, status=status)
        except RigFault:
            pass
        data = _log(tmp_path / name)
        last, stopped = seen[-1]
        assert stopped  # reported after STOP went out, never before it
        assert last["k"] == data["k"][-1] == len(data) - 1 and last["n"] == 100
        assert (last["t"], last["theta"], last["error"], last["u"]) == (
            data["t"][-1], data["theta"][-1], data["error"][-1], data["u"][-1])
        assert len({s["k"] for s, _ in seen}) == len(seen)  # no sample reported twice
