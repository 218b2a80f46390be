"""Binary serial protocol between the host and the rig (see ``docs/protocol.md``).

Frame layout (all integers little-endian)::

    0xA5 0x5A | type u8 | seq u8 | len u8 | payload (len bytes) | crc u16

``crc`` is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no
final xor) over ``type, seq, len, payload``.  Every message type has a fixed
payload length; a header whose length does not match its type is rejected.
``seq`` counts the frames each side sends (mod 256) so a receiver can count
lost frames.

Parsing rule (identical in :class:`Parser` and the C header
``firmware/esoarm_rig/esoarm_protocol.h``, checked with shared vectors): a
frame is recognised at position p when the sync bytes, a known type with its
length, and the CRC all match; scanning then continues after the frame.  If
anything fails, the byte at p is discarded and scanning resumes at p + 1.  A
frame still incomplete at the end of the input waits for more bytes, so the
result does not depend on how the stream is split into reads.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass
from typing import NamedTuple

__all__ = [
    "CHIP_INFO",
    "CHIP_SAMPLE",
    "FAULT",
    "HEARTBEAT",
    "HELLO",
    "INFO",
    "PROTOCOL_VERSION",
    "SAMPLE",
    "START",
    "STOP",
    "STOPPED",
    "DUTY",
    "TORQUE",
    "ChipInfo",
    "ChipSample",
    "Frame",
    "Info",
    "Parser",
    "crc16",
    "encode",
]

#: 2: on-board mode (FLAG_ONBOARD, HEARTBEAT, CHIP_INFO, CHIP_SAMPLE)
PROTOCOL_VERSION = 2
SYNC = b"\xa5\x5a"
HEADER_SIZE = 5  # sync (2) + type + seq + len
CRC_SIZE = 2

# host -> device
HELLO = 0x01  # payload: version u8
START = 0x02  # payload: none; the device resets its clock and starts sampling
DUTY = 0x03  # payload: k u32 (sample answered), duty i16 in [-pwm_max, pwm_max]
TORQUE = 0x04  # payload: k u32, torque f64 [N·m]; only if INFO flags has FLAG_TORQUE
STOP = 0x05  # payload: none; motor off, sampling stops
HEARTBEAT = 0x06  # payload: k u32 (newest sample logged); on-board devices only: the watchdog
# device -> host
INFO = 0x81  # payload: version u8, flags u8, counts_per_rev u32, pwm_max u16, period_us u32
SAMPLE = 0x82  # payload: k u32, t_us u32 (device clock), count i32 (encoder)
STOPPED = 0x85  # payload: none; acknowledges STOP, motor is off
FAULT = 0x86  # payload: code u8, detail u32
# device -> host, on-board devices only (INFO flags has FLAG_ONBOARD)
CHIP_INFO = 0x87  # payload: stream_every u16, sums u8, scenario hash 8 ASCII hex digits
CHIP_SAMPLE = 0x88  # payload: k u32, t_us u32, count i32, u f32, z1 f32, z2 f32, z3 f32, duty i16

#: INFO flags
FLAG_TORQUE = 0x01  # device accepts TORQUE (ideal torque source: the emulator without [motor])
FLAG_LOCKSTEP = 0x02  # device advances one sample per command (emulator --lockstep)
FLAG_ONBOARD = 0x04  # the device runs its own (generated) controller: it sends CHIP_INFO after
#                      INFO, streams CHIP_SAMPLE instead of SAMPLE and takes HEARTBEAT, not DUTY

#: CHIP_INFO sums
SUMS_PLAIN = 0
SUMS_COMPENSATED = 1

#: FAULT codes
FAULT_WATCHDOG = 1  # no valid command within 100 ms; motor zeroed
FAULT_OVERRUN = 2  # the device missed its own sample deadline
FAULT_BAD_COMMAND = 3  # duty out of range or a command type the device does not accept
FAULT_ENCODER = 4  # both encoder lines changed between two reads: counts were lost

#: struct format of each payload (fixed length per type)
FORMATS: dict[int, str] = {
    HELLO: "<B",
    START: "<",
    DUTY: "<Ih",
    TORQUE: "<Id",
    STOP: "<",
    HEARTBEAT: "<I",
    INFO: "<BBIHI",
    SAMPLE: "<IIi",
    STOPPED: "<",
    FAULT: "<BI",
    CHIP_INFO: "<HB8s",
    CHIP_SAMPLE: "<IIiffffh",
}
NAMES: dict[int, str] = {
    HELLO: "HELLO", START: "START", DUTY: "DUTY", TORQUE: "TORQUE", STOP: "STOP",
    HEARTBEAT: "HEARTBEAT", INFO: "INFO", SAMPLE: "SAMPLE", STOPPED: "STOPPED",
    FAULT: "FAULT", CHIP_INFO: "CHIP_INFO", CHIP_SAMPLE: "CHIP_SAMPLE",
}
STRUCTS: dict[int, struct.Struct] = {t: struct.Struct(f) for t, f in FORMATS.items()}
PAYLOAD_SIZES: dict[int, int] = {t: s.size for t, s in STRUCTS.items()}
_CRC = struct.Struct("<H")
MAX_PAYLOAD = max(PAYLOAD_SIZES.values())
MAX_FRAME = HEADER_SIZE + MAX_PAYLOAD + CRC_SIZE


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (poly 0x1021, init 0xFFFF)."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode(kind: int, seq: int, *fields: int | float | bytes) -> bytes:
    """One complete frame of type ``kind`` with sequence number ``seq``.

    Parameters
    ----------
    kind : int
        Message type (e.g. :data:`SAMPLE`).
    seq : int
        Sequence number, taken mod 256.
    *fields
        Payload fields in the order of :data:`FORMATS`.
    """
    payload = STRUCTS[kind].pack(*fields)
    body = bytes((kind, seq & 0xFF, len(payload))) + payload
    return SYNC + body + _CRC.pack(binascii.crc_hqx(body, 0xFFFF))


class Frame(NamedTuple):
    """A received frame: type, sequence number and raw payload."""

    kind: int
    seq: int
    payload: bytes

    def fields(self) -> tuple:
        """The payload decoded with :data:`FORMATS`."""
        return STRUCTS[self.kind].unpack(self.payload)


@dataclass(frozen=True)
class Info:
    """The device's answer to HELLO (the version handshake).

    Attributes
    ----------
    version : int
        Protocol version of the device.
    flags : int
        :data:`FLAG_TORQUE`, :data:`FLAG_LOCKSTEP`.
    counts_per_rev : int
        Encoder counts per revolution (after quadrature decoding).
    pwm_max : int
        Largest |duty|; duty ±pwm_max is full supply voltage.
    period_us : int
        Sample period [µs].
    """

    version: int
    flags: int
    counts_per_rev: int
    pwm_max: int
    period_us: int

    @classmethod
    def from_frame(cls, frame: Frame) -> Info:
        """Decode an INFO frame."""
        return cls(*frame.fields())

    @property
    def accepts_torque(self) -> bool:
        """The device takes float64 torque commands (ideal torque source)."""
        return bool(self.flags & FLAG_TORQUE)

    @property
    def lockstep(self) -> bool:
        """The device advances one sample per command."""
        return bool(self.flags & FLAG_LOCKSTEP)

    @property
    def onboard(self) -> bool:
        """The device runs its own controller (firmware built with ``ONBOARD=DIR``)."""
        return bool(self.flags & FLAG_ONBOARD)


@dataclass(frozen=True)
class ChipInfo:
    """What an on-board device says about its controller (CHIP_INFO, after INFO).

    Attributes
    ----------
    stream_every : int
        The device streams every this-many-th sample (1: every sample); more when the
        link's baud cannot carry a CHIP_SAMPLE frame per sample.
    sums : int
        Observer sums of the generated code: :data:`SUMS_PLAIN` or :data:`SUMS_COMPENSATED`.
    scenario_hash : str
        The first 8 hex digits of the hash of the scenario the controller was generated
        from (``esoarm.codegen.generate.scenario_hash``).
    """

    stream_every: int
    sums: int
    scenario_hash: str

    @classmethod
    def from_frame(cls, frame: Frame) -> ChipInfo:
        """Decode a CHIP_INFO frame."""
        every, sums, digest = frame.fields()
        return cls(int(every), int(sums), bytes(digest).decode("ascii", errors="replace"))

    @property
    def sums_name(self) -> str:
        """``"plain"`` or ``"compensated"``."""
        return "compensated" if self.sums == SUMS_COMPENSATED else "plain"


class ChipSample(NamedTuple):
    """One sample of an on-board device (CHIP_SAMPLE): what its controller measured and did.

    Attributes
    ----------
    k : int
        Sample index since START.
    t_us : int
        Device time of the sample [µs since START, wraps at 2³²].
    encoder_count : int
        Encoder count ``count`` of the frame; y = q · count [rad].
    u : float
        Torque the observer was updated with [N·m] (float32 on the chip).
    z1, z2, z3 : float
        The estimate the controller used [rad, rad/s, rad/s²].
    duty : int
        PWM duty written to the driver [counts].
    """

    k: int
    t_us: int
    encoder_count: int
    u: float
    z1: float
    z2: float
    z3: float
    duty: int

    @classmethod
    def from_frame(cls, frame: Frame) -> ChipSample:
        """Decode a CHIP_SAMPLE frame."""
        return cls(*frame.fields())


class Parser:
    """Incremental frame parser: feed bytes, get whole valid frames.

    Corrupted, unknown or partial frames never raise: they are counted and
    skipped (see the module docstring for the exact rule).

    Attributes
    ----------
    frames : int
        Valid frames returned so far.
    crc_errors : int
        Candidates with a valid header whose CRC did not match.
    header_errors : int
        Candidates (sync found) with an unknown type or a wrong length.
    skipped : int
        Bytes discarded while resynchronising.
    """

    __slots__ = ("_buf", "crc_errors", "frames", "header_errors", "skipped")

    def __init__(self) -> None:
        self._buf = bytearray()
        self.frames = 0
        self.crc_errors = 0
        self.header_errors = 0
        self.skipped = 0

    @property
    def pending(self) -> int:
        """Bytes waiting for the rest of a frame."""
        return len(self._buf)

    @property
    def bad_frames(self) -> int:
        """Rejected frame candidates (CRC plus header errors)."""
        return self.crc_errors + self.header_errors

    def feed(self, data: bytes | bytearray) -> list[Frame]:
        """Append ``data`` and return every frame completed by it, in order."""
        buf = self._buf
        buf += data
        out: list[Frame] = []
        pos = 0
        n = len(buf)
        while pos < n:
            idx = buf.find(SYNC, pos)
            if idx < 0:
                # keep a trailing first sync byte: it may start a frame
                keep = n - 1 if buf[n - 1] == SYNC[0] else n
                self.skipped += keep - pos
                pos = keep
                break
            self.skipped += idx - pos
            pos = idx
            if n - pos < HEADER_SIZE:
                break
            kind, length = buf[pos + 2], buf[pos + 4]
            if PAYLOAD_SIZES.get(kind, -1) != length:
                self.header_errors += 1
                self.skipped += 1
                pos += 1
                continue
            end = pos + HEADER_SIZE + length + CRC_SIZE
            if end > n:
                break
            crc = buf[end - 2] | (buf[end - 1] << 8)
            if crc16(buf[pos + 2 : end - 2]) != crc:
                self.crc_errors += 1
                self.skipped += 1
                pos += 1
                continue
            out.append(Frame(kind, buf[pos + 3], bytes(buf[pos + HEADER_SIZE : end - 2])))
            self.frames += 1
            pos = end
        del buf[:pos]
        return out


def vector_messages() -> list[tuple[int, int, tuple]]:
    """Representative messages of every type (the shared test vectors' inputs)."""
    return [
        (HELLO, 0, (PROTOCOL_VERSION,)),
        (START, 1, ()),
        (DUTY, 2, (7, -255)),
        (DUTY, 255, (0xFFFFFFFF, 32767)),
        (DUTY, 17, (123456, -32768)),
        (TORQUE, 3, (0, 0.0)),
        (TORQUE, 4, (42, -1.2345678901234567)),
        (TORQUE, 5, (1000, 2.0)),
        (TORQUE, 6, (9, 5e-324)),
        (STOP, 7, ()),
        (HEARTBEAT, 8, (0,)),
        (HEARTBEAT, 9, (0xFFFFFFFF,)),
        (INFO, 0, (PROTOCOL_VERSION, FLAG_TORQUE | FLAG_LOCKSTEP, 7200, 255, 20000)),
        (INFO, 1, (PROTOCOL_VERSION, 0, 2400, 1023, 1000)),
        (SAMPLE, 2, (0, 0, 0)),
        (SAMPLE, 3, (1, 20000, -1)),
        (SAMPLE, 200, (0xFFFFFFFF, 0xFFFFFFFF, -(2**31))),
        (SAMPLE, 201, (5000, 100000000, 2**31 - 1)),
        (STOPPED, 9, ()),
        (FAULT, 10, (FAULT_WATCHDOG, 57)),
        (FAULT, 11, (FAULT_BAD_COMMAND, 0xDEADBEEF)),
        (INFO, 12, (PROTOCOL_VERSION, FLAG_ONBOARD, 2400, 255, 1000)),
        (CHIP_INFO, 13, (1, SUMS_PLAIN, b"b956682a")),
        (CHIP_INFO, 14, (65535, SUMS_COMPENSATED, b"0123abcd")),
        (CHIP_SAMPLE, 15, (0, 0, 0, 0.0, 0.0, 0.0, 0.0, 0)),
        (CHIP_SAMPLE, 16, (19999, 19999000, -1234, -1.5, 0.25, -3.0e-7, 1.0e6, -255)),
        (CHIP_SAMPLE, 17, (0xFFFFFFFF, 0xFFFFFFFF, 2**31 - 1, float("inf"), 1e-45, -0.0,
                           3.4028234663852886e38, 32767)),
    ]


def vector_lines() -> list[str]:
    """The shared test vectors as text: ``TYPE SEQ PAYLOAD FRAME NAME`` (hex; '-' empty).

    ``firmware/test_vectors.txt`` is this output; regenerate it with
    ``python -m esoarm.hardware.protocol > firmware/test_vectors.txt`` (only
    when the protocol changes on purpose: the tests compare against the file).
    """
    lines = ["# esoarm protocol test vectors: TYPE SEQ PAYLOAD FRAME NAME (hex, '-' = empty)",
             "# regenerate: python -m esoarm.hardware.protocol > firmware/test_vectors.txt"]
    for kind, seq, fields in vector_messages():
        payload = struct.pack(FORMATS[kind], *fields)
        frame = encode(kind, seq, *fields)
        lines.append(f"{kind:02x} {seq} {payload.hex() or '-'} {frame.hex()} {NAMES[kind]}")
    return lines


if __name__ == "__main__":  # pragma: no cover
    print("\n".join(vector_lines()))
