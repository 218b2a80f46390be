"""What the emulator and the HIL server share (esoarm.hardware.device)."""

from __future__ import annotations

import os
import tty

import pytest

from esoarm.hardware.device import PtyDevice, TimedFault, due_faults, parse_timed_fault
from esoarm.hardware.emulator import parse_fault
from esoarm.hardware.hil.server import parse_hil_fault
from esoarm.scenario import ScenarioError


def test_pty_device_passes_bytes_both_ways():
    port = PtyDevice()
    host = os.open(port.path, os.O_RDWR | os.O_NOCTTY)
    try:
        tty.setraw(host)
        assert port.read(0.0) == b""  # nothing sent yet
        os.write(host, b"\x00hello")
        assert port.read(1.0) == b"\x00hello"
        assert port.write(b"\xffworld")
        assert os.read(host, 100) == b"\xffworld"
    finally:
        os.close(host)
        port.close()


def test_pty_device_after_close_loses_writes_and_reads_nothing():
    port = PtyDevice()
    port.close()
    port.close()  # idempotent
    assert port.closed and not port.write(b"x") and port.read(0.01) == b""


def test_pty_device_with_nobody_reading_reports_lost_bytes():
    port = PtyDevice()
    try:
        sent = [port.write(b"x" * 4096) for _ in range(1000)]  # far beyond the pty buffer
        assert sent[0] and not all(sent)
    finally:
        port.close()


def test_parse_timed_fault():
    assert parse_timed_fault("b@1.5", ("a", "b")) == TimedFault("b", 1.5)
    for bad, words in (("c@1", "KIND one of a, b"), ("a", "KIND@SECONDS"),
                       ("a@x", "finite number >= 0"), ("a@inf", "finite"), ("a@-1", ">= 0")):
        with pytest.raises(ScenarioError) as info:
            parse_timed_fault(bad, ("a", "b"))
        assert str(info.value).startswith(f"--fault '{bad}': ") and words in str(info.value)


def test_both_servers_parse_their_own_fault_kinds():
    assert parse_fault("stall@2") == TimedFault("stall", 2.0)
    assert parse_hil_fault("unplug@0.5") == TimedFault("unplug", 0.5)
    with pytest.raises(ScenarioError, match="one of drop, corrupt"):
        parse_fault("unplug@0.5")
    with pytest.raises(ScenarioError, match="one of encoder-break"):
        parse_hil_fault("stall@2")


def test_due_faults_pops_in_time_order_and_announces_each():
    faults = [TimedFault("a", 0.1), TimedFault("b", 0.2), TimedFault("c", 0.5)]
    said: list[str] = []
    assert list(due_faults(faults, 0.05, said.append)) == []
    assert [f.kind for f in due_faults(faults, 0.2, said.append)] == ["a", "b"]
    assert faults == [TimedFault("c", 0.5)]
    assert said == ["fault injected: a at t = 0.2 s", "fault injected: b at t = 0.2 s"]
