"""The Arduino sketch, compiled for the host against a stub Arduino core.

``firmware/host_test/firmware_sim.cpp`` runs ``esoarm_rig.ino`` with a
simulated clock, encoder and serial port; the frames it sends are decoded here
with the Python parser.  This checks the sketch's logic (handshake, sampling
grid, quadrature decoding, duty output, watchdog, stop, bad frames), not its
timing on a real board.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from esoarm.hardware import protocol as P

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware"

pytestmark = pytest.mark.skipif(shutil.which("g++") is None,
                                reason="g++ not found: the sketch is not checked on the host")


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("fw") / "firmware_sim"
    subprocess.run(
        ["g++", "-std=c++11", "-Wall", "-Wextra", "-Werror", "-x", "c++",
         "-include", str(FIRMWARE / "host_test" / "arduino_stub.h"),
         "-I", str(FIRMWARE / "esoarm_rig"), "-I", str(FIRMWARE / "host_test"),
         str(FIRMWARE / "esoarm_rig" / "esoarm_rig.ino"), "-x", "none",
         str(FIRMWARE / "host_test" / "firmware_sim.cpp"), "-o", str(exe)],
        check=True, capture_output=True, text=True)
    return exe


class Script:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.seq = 0

    def send(self, kind: int, *fields) -> Script:
        self.lines.append(f"send {P.encode(kind, self.seq, *fields).hex()}")
        self.seq += 1
        return self

    def raw(self, data: bytes) -> Script:
        self.lines.append(f"send {data.hex()}")
        return self

    def advance(self, us: int) -> Script:
        self.lines.append(f"advance {us}")
        return self

    def enc(self, steps: int) -> Script:
        self.lines.append(f"enc {steps}")
        return self

    def print(self) -> Script:
        self.lines.append("print")
        return self

    def run(self, exe: Path) -> list[tuple[list[P.Frame], tuple[int, int, int]]]:
        out = subprocess.run([str(exe)], input="\n".join(self.lines) + "\n", text=True,
                             capture_output=True, check=True).stdout.splitlines()
        parser = P.Parser()
        steps = []
        for tx, motor in zip(out[::2], out[1::2], strict=True):
            hexdata = tx.split()[1]
            frames = parser.feed(bytes.fromhex("" if hexdata == "-" else hexdata))
            steps.append((frames, tuple(int(v) for v in motor.split()[1:])))
        assert parser.bad_frames == 0 and parser.pending == 0
        return steps


def _samples(frames):
    return [f.fields() for f in frames if f.kind == P.SAMPLE]


def test_handshake_sampling_duty_watchdog_stop(sim):
    s = Script()
    s.send(P.HELLO, 1).print()                                   # 0
    s.send(P.START).print()                                      # 1
    s.send(P.DUTY, 0, 100).enc(8).advance(20000).print()         # 2
    s.send(P.DUTY, 1, -50).enc(-3).advance(20000).print()        # 3
    s.advance(120000).print()                                    # 4 no commands: watchdog
    s.send(P.DUTY, 9, 100).print()                               # 5 ignored after the trip
    s.send(P.STOP).advance(100000).print()                       # 6
    steps = s.run(sim)

    (info,), motor = steps[0]
    assert P.Info.from_frame(info) == P.Info(P.PROTOCOL_VERSION, 0, 2400, 255, 20000)
    assert motor == (0, 0, 0)
    assert _samples(steps[1][0]) == [(0, 0, 0)]
    assert _samples(steps[2][0]) == [(1, 20000, 8)]
    assert steps[2][1] == (100, 1, 0)            # PWM 100 forward (IN1 high)
    assert _samples(steps[3][0]) == [(2, 40000, 5)]
    assert steps[3][1] == (50, 0, 1)             # PWM 50 reverse (IN2 high)
    faults = [f.fields() for f in steps[4][0] if f.kind == P.FAULT]
    assert faults and faults[0][0] == P.FAULT_WATCHDOG
    assert steps[4][1] == (0, 0, 0)              # motor zeroed by the watchdog
    assert [k for k, _, _ in _samples(steps[4][0])] == list(range(3, 9))  # the grid goes on
    assert steps[5][1] == (0, 0, 0)              # stays off until the next START
    kinds = [f.kind for f in steps[6][0]]
    assert P.STOPPED in kinds and steps[6][1] == (0, 0, 0)
    assert not _samples(steps[6][0][kinds.index(P.STOPPED) + 1:])  # no samples after stop


def test_bad_frames_and_bad_commands(sim):
    s = Script()
    s.send(P.START).print()                                      # 0
    good = bytearray(P.encode(P.DUTY, 5, 0, 200))
    good[7] ^= 0x10                                              # corrupted duty: ignored
    s.raw(b"\x00\xa5\x11garbage" + bytes(good)).print()          # 1
    s.send(P.DUTY, 0, 300).print()                               # 2 out of range
    s.send(P.TORQUE, 0, 0.5).print()                             # 3 emulator only
    s.send(P.DUTY, 0, -255).advance(1000).print()                # 4 still works
    steps = s.run(sim)
    assert steps[1][1] == (0, 0, 0) and not steps[1][0]
    for i in (2, 3):
        (fault,) = [f for f in steps[i][0] if f.kind == P.FAULT]
        assert fault.fields()[0] == P.FAULT_BAD_COMMAND
    assert steps[4][1] == (255, 0, 1)
