"""``run_rig(..., onboard=True)`` in-process against a scripted on-board chip (no pty).

The chip streams CHIP_SAMPLE frames of its own controller; the host must log exactly
those (not host-side values), say when the stream is decimated, keep its supervisor,
and end every fault with STOP and every received row in the log.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.codegen.generate import scenario_hash
from esoarm.hardware import protocol as P
from esoarm.hardware.host_control import DeploymentController
from esoarm.hardware.realtime import LOG_COLUMNS, RigFault, SafetyLimits, run_rig
from esoarm.hardware.replay import read_log
from esoarm.scenario import ScenarioError, load_scenario


def _frame(kind: int, *fields) -> P.Frame:
    return P.Frame(kind, 0, P.encode(kind, 0, *fields)[5:-2])


class FakeChip:
    """An on-board device in-process: after START every receive() yields the next sample(s).

    The chip's values are made up but distinct per sample (u_k = 1e-3 k, ẑ = (y, 2 k, -k)),
    so the test can check that the log holds the chip's numbers.  ``every`` is its stream
    decimation; ``fault_at`` sends FAULT(code) instead of that sample; ``silent_from`` stops
    streaming there; ``nan_at`` makes u NaN there; ``offset_from`` adds an angle [counts].
    """

    def __init__(self, scn, every=1, digest=None, fault_at=None, code=P.FAULT_OVERRUN,
                 silent_from=None, nan_at=None, offset_from=None, flags=P.FLAG_ONBOARD):
        self.port = "fake"
        self.scn = scn
        self.ctl = DeploymentController(scn)
        self.q = math.radians(scn.sensor.resolution_deg)
        self.every = every
        self.digest = (digest or scenario_hash(scn)[:8]).encode()
        self.fault_at, self.code, self.silent_from = fault_at, code, silent_from
        self.nan_at, self.offset_from = nan_at, offset_from
        self.info = P.Info(P.PROTOCOL_VERSION, flags, round(360 / scn.sensor.resolution_deg),
                           255, round(1e6 * scn.sample_time))
        self.parser = P.Parser()
        self.rx_lost = 0
        self.sent: list[tuple] = []
        self.k = None
        self.stopped = False
        self.streamed: list[P.ChipSample] = []

    def handshake(self):
        return self.info

    def chip_info(self, timeout=1.0):
        return P.ChipInfo(self.every, P.SUMS_PLAIN, self.digest.decode())

    def send(self, kind, *fields):
        self.sent.append((kind, *fields))
        if kind == P.START:
            self.k = 0

    def receive(self, timeout):
        if self.stopped:
            return [P.Frame(P.STOPPED, 0, b"")]
        if self.k is None or self.k >= self.ctl.n_samples + self.every:
            return []
        k = self.k
        if self.silent_from is not None and k >= self.silent_from:
            return []
        self.k += self.every
        if k == self.fault_at:
            self.k = None
            return [_frame(P.FAULT, self.code, k)]
        count = round(self.ctl.reference(k) / self.q)
        if self.offset_from is not None and k >= self.offset_from:
            count += 2000
        u = math.nan if k == self.nan_at else 1e-3 * k
        row = (k, k * round(1e6 * self.scn.sample_time), count, u, self.q * count, 2.0 * k,
               -1.0 * k, k % 100)
        frame = _frame(P.CHIP_SAMPLE, *row)
        self.streamed.append(P.ChipSample.from_frame(frame))  # as the wire has it: float32
        return [frame]

    def stop(self):
        self.sent.append((P.STOP,))
        self.stopped = True


@pytest.fixture
def scn():
    return load_scenario("uno-rig", {"duration": 1.0})


def _rows(path):
    return np.genfromtxt(path, delimiter=",", names=True, skip_header=1)


def test_logs_the_chips_samples(scn, tmp_path):
    chip = FakeChip(scn)
    notes: list[str] = []
    log = tmp_path / "run.csv"
    s = run_rig(scn, chip, log, onboard=True, notice=notes.append)
    assert s.onboard and s.stream_every == 1 and s.observer_sums == "plain"
    assert s.samples == 50 and s.lost_samples == 0 and s.stop_acknowledged
    assert len(notes) == 1 and "every sample (50 Hz)" in notes[0]
    text = log.read_text()
    assert text.startswith("# on board: logging the chip's samples")
    assert text.splitlines()[1] == ",".join(LOG_COLUMNS)
    d = _rows(log)
    sent = np.array([r.k for r in chip.streamed[:50]])
    assert np.array_equal(d["k"], sent)
    # the chip's float32 values, exactly as streamed (no host-side control law)
    assert np.array_equal(d["u"], np.array([r.u for r in chip.streamed[:50]]))
    assert np.array_equal(d["z2"], np.array([r.z2 for r in chip.streamed[:50]]))
    assert np.array_equal(d["duty"], np.array([r.duty for r in chip.streamed[:50]]))
    assert np.isnan(d["latency"]).all()
    kinds = {c[0] for c in chip.sent}
    assert P.HEARTBEAT in kinds and P.DUTY not in kinds and P.TORQUE not in kinds
    assert chip.sent[-1][0] == P.STOP
    # the log reads back through the shared reader (the comment line is skipped)
    t, theta, u, ts = read_log(log)
    assert len(t) == 50 and ts == pytest.approx(0.02)


def test_decimated_stream_is_said(scn, tmp_path):
    chip = FakeChip(scn, every=4)
    notes: list[str] = []
    log = tmp_path / "run.csv"
    s = run_rig(scn, chip, log, onboard=True, notice=notes.append)
    assert s.stream_every == 4 and s.samples == 13 and s.lost_samples == 0
    assert "DECIMATED: every 4th sample (12.5 Hz of 50 Hz)" in notes[0]
    assert log.read_text().splitlines()[0] == f"# {notes[0]}"
    assert np.array_equal(_rows(log)["k"], np.arange(0, 50, 4))


def test_refuses_another_scenarios_controller(scn, tmp_path):
    chip = FakeChip(scn, digest="00000000")
    with pytest.raises(ScenarioError, match="another scenario"):
        run_rig(scn, chip, tmp_path / "run.csv", onboard=True)
    assert not [c for c in chip.sent if c[0] == P.START]


def test_mode_mismatch_is_refused(scn):
    with pytest.raises(ScenarioError, match="add --onboard"):
        run_rig(scn, FakeChip(scn), None)
    with pytest.raises(ScenarioError, match="runs no controller of its own"):
        run_rig(scn, FakeChip(scn, flags=0), None, onboard=True)


@pytest.mark.parametrize(("kw", "message", "rows"), [
    ({"fault_at": 30}, "the chip reported a fault: overrun at sample 30", 30),
    ({"fault_at": 12, "code": P.FAULT_WATCHDOG}, "heartbeat watchdog at sample 12", 12),
    ({"silent_from": 20}, "watchdog: no sample from the chip", 20),
    ({"nan_at": 7}, "NaN guard", 7),
    ({"offset_from": 25}, "encoder jump", 25),
])
def test_faults_stop_and_keep_the_rows(scn, tmp_path, kw, message, rows):
    chip = FakeChip(scn, **kw)
    log = tmp_path / "run.csv"
    with pytest.raises(RigFault, match=message) as err:
        run_rig(scn, chip, log, SafetyLimits(watchdog=0.05), onboard=True)
    assert chip.sent[-1][0] == P.STOP and chip.stopped
    assert err.value.summary.samples == rows
    assert len(_rows(log)) == rows
    assert f"{rows} rows in {log}" in str(err.value)
