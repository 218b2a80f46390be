"""The emulator's device behaviour, in-process over its pseudo-terminal."""

from __future__ import annotations

import math
import threading
import time

import pytest

from esoarm.hardware import protocol as P
from esoarm.hardware.emulator import Emulator, encoder_counts_per_rev, parse_fault
from esoarm.hardware.link import LinkError, SerialLink
from esoarm.scenario import ScenarioError, load_scenario

from .rig_helpers import needs_pty

pytestmark = needs_pty


@pytest.fixture
def device(request):
    """An emulator served from a thread; yields (emulator, link, messages)."""
    lockstep, sets = request.param
    messages: list[str] = []
    emu = Emulator(load_scenario("test-1", sets), lockstep=lockstep, once=True,
                   echo=messages.append)
    done = threading.Event()
    thread = threading.Thread(target=emu.serve, kwargs={"until": done.is_set}, daemon=True)
    thread.start()
    link = SerialLink(emu.path)
    yield emu, link, messages
    done.set()
    thread.join(5)
    link.close()
    emu.close()


def _wait_for(link, kind, timeout=1.0):
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        for frame in link.receive(left):
            if frame.kind == kind:
                return frame
    raise AssertionError(f"no {P.NAMES[kind]} within {timeout} s")


@pytest.mark.parametrize("device", [(True, ["duration=1"])], indirect=True)
def test_lockstep_device(device):
    emu, link, messages = device
    info = link.handshake()
    assert info == P.Info(P.PROTOCOL_VERSION, P.FLAG_TORQUE | P.FLAG_LOCKSTEP, 7200, 255, 20000)
    link.send(P.START)
    assert _wait_for(link, P.SAMPLE).fields()[:2] == (0, 0)
    link.send(P.TORQUE, 5, 0.1)              # answers no sample the device sent: ignored
    assert not [f for f in link.receive(0.1) if f.kind == P.SAMPLE]
    assert emu.bad_commands == 1
    link.send(P.TORQUE, 0, 0.1)
    assert _wait_for(link, P.SAMPLE).fields()[:2] == (1, 20000)
    link.send(P.DUTY, 1, 300)                # beyond pwm_max
    assert _wait_for(link, P.FAULT).fields()[0] == P.FAULT_BAD_COMMAND
    link.send(P.STOP)
    _wait_for(link, P.STOPPED)
    assert any("stop received" in m for m in messages)
    assert emu.twin.motor_on is False


@pytest.mark.parametrize("device", [(False, ["duration=1"])], indirect=True)
def test_real_time_device_watchdog(device):
    emu, link, messages = device
    link.handshake()
    link.send(P.START)
    t0 = time.monotonic()
    # no command ever sent; the generous timeout only matters on a starved machine
    fault = _wait_for(link, P.FAULT, timeout=30.0)
    elapsed = time.monotonic() - t0
    assert fault.fields()[0] == P.FAULT_WATCHDOG
    assert elapsed >= 0.09  # not before the device's 100 ms watchdog (minus clock slack)
    assert emu.twin.motor_on is False
    # it keeps sampling on the 20 ms grid with the motor off (wait for 3 samples, not a time)
    samples: list = []
    end = time.monotonic() + 30.0
    while len(samples) < 3 and (left := end - time.monotonic()) > 0:
        samples += [f.fields() for f in link.receive(min(left, 0.1)) if f.kind == P.SAMPLE]
    assert len(samples) >= 3
    assert all(b[0] == a[0] + 1 for a, b in zip(samples, samples[1:], strict=False))
    assert any("watchdog" in m for m in messages)


def test_nothing_answers_on_a_silent_pty():
    import os
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        link = SerialLink(os.ttyname(slave))
        with pytest.raises(LinkError, match="no answer"):
            link.handshake(timeout=0.05, attempts=2)
        link.close()
    finally:
        os.close(master)
        os.close(slave)


def test_counts_per_rev_and_fault_specs():
    assert encoder_counts_per_rev(load_scenario("test-1")) == 7200
    assert encoder_counts_per_rev(
        load_scenario("test-1", ["sensor.resolution_deg=0.15"])) == 2400
    with pytest.raises(ScenarioError, match="whole number"):
        encoder_counts_per_rev(load_scenario("test-1", ["sensor.resolution_deg=0.07"]))
    assert parse_fault("glitch@1.5").at == 1.5
    for bad in ("glitch", "melt@1", "drop@x", "drop@nan", "drop@-2"):
        with pytest.raises(ScenarioError, match="fault"):
            parse_fault(bad)
    assert math.isfinite(parse_fault("stall@0").at)
