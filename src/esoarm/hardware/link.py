"""Serial transport to a rig (real or emulated) through pyserial.

:class:`SerialLink` frames outgoing messages, parses incoming bytes with
:class:`~esoarm.hardware.protocol.Parser` (bad frames are counted, never
raised) and performs the version handshake.  pyserial is the ``rig`` extra and
is imported only when a link is opened.
"""

from __future__ import annotations

import errno
import os
import select
import time

from esoarm.hardware import protocol as P

__all__ = ["LinkError", "SerialLink"]

BAUDRATE = 115200


class LinkError(RuntimeError):
    """The link failed (port missing or gone, no answer); one-line message."""


def _serial_module():  # type: ignore[no-untyped-def]
    try:
        import serial
    except ImportError:  # pragma: no cover - depends on the environment
        raise LinkError(
            "the serial link needs pyserial: pip install 'esoarm[rig]'"
        ) from None
    return serial


class SerialLink:
    """A framed, checksummed connection to the device on ``port``.

    Parameters
    ----------
    port : str
        Serial device path (``/dev/ttyACM0``, or the path printed by
        ``esoarm emulate``).
    baudrate : int
        Line rate; ignored by pseudo-terminals and USB CDC devices.

    Attributes
    ----------
    parser : Parser
        Counters of valid and rejected frames.
    rx_lost : int
        Frames missing according to the device's sequence numbers.
    """

    def __init__(self, port: str, baudrate: int = BAUDRATE) -> None:
        serial = _serial_module()
        self.port = port
        try:
            self._ser = serial.Serial(port, baudrate=baudrate, timeout=0, write_timeout=0.5,
                                      exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"cannot open port '{port}': {_reason(exc)}") from None
        self._serial_exc = serial.SerialException
        self._fd = self._ser.fileno()
        self.parser = P.Parser()
        self.seq = 0
        self.rx_lost = 0
        self._rx_seq: int | None = None
        self._backlog: list[P.Frame] = []  # frames read with INFO, after it

    def send(self, kind: int, *fields: int | float) -> None:
        """Send one frame; raises :class:`LinkError` if the port is gone."""
        frame = P.encode(kind, self.seq, *fields)
        self.seq = (self.seq + 1) & 0xFF
        try:
            self._ser.write(frame)
        except (self._serial_exc, OSError) as exc:
            raise LinkError(f"port '{self.port}': write failed: {_reason(exc)}") from None

    def receive(self, timeout: float) -> list[P.Frame]:
        """Frames that arrive within ``timeout`` [s] (empty list if none)."""
        if self._backlog:
            frames, self._backlog = self._backlog, []
            return frames
        try:
            ready, _, _ = select.select([self._fd], [], [], max(0.0, timeout))
            if not ready:
                return []
            data = self._ser.read(4096)
        except (self._serial_exc, OSError, ValueError) as exc:
            raise LinkError(f"port '{self.port}' went away: {_reason(exc)}") from None
        frames = self.parser.feed(data)
        for frame in frames:
            if self._rx_seq is not None:
                self.rx_lost += (frame.seq - self._rx_seq - 1) & 0xFF
            self._rx_seq = frame.seq
        return frames

    def handshake(self, timeout: float = 1.0, attempts: int = 3) -> P.Info:
        """Send HELLO until the device answers with INFO; return it."""
        for _ in range(attempts):
            self.send(P.HELLO, P.PROTOCOL_VERSION)
            deadline = time.perf_counter() + timeout
            while (left := deadline - time.perf_counter()) > 0:
                frames = self.receive(left)
                for i, frame in enumerate(frames):
                    if frame.kind == P.INFO:
                        self._backlog = frames[i + 1:]
                        info = P.Info.from_frame(frame)
                        if info.version != P.PROTOCOL_VERSION:
                            raise LinkError(
                                f"device on '{self.port}' speaks protocol version "
                                f"{info.version}; this esoarm speaks {P.PROTOCOL_VERSION}")
                        return info
        raise LinkError(f"no answer from a device on '{self.port}' "
                        f"({attempts} HELLO within {timeout:g} s each)")

    def chip_info(self, timeout: float = 1.0) -> P.ChipInfo:
        """The CHIP_INFO an on-board device sends after INFO (call after :meth:`handshake`)."""
        deadline = time.perf_counter() + timeout
        while (left := deadline - time.perf_counter()) > 0:
            for frame in self.receive(left):
                if frame.kind == P.CHIP_INFO:
                    return P.ChipInfo.from_frame(frame)
        raise LinkError(f"the on-board device on '{self.port}' sent no CHIP_INFO within "
                        f"{timeout:g} s of INFO")

    def stop(self) -> None:
        """Best-effort STOP (never raises: used on the way out of a fault)."""
        try:
            self.send(P.STOP)
            self._ser.flush()
        except (LinkError, self._serial_exc, OSError):
            pass

    def close(self) -> None:
        """Close the port (never raises)."""
        try:
            self._ser.close()
        except (self._serial_exc, OSError):
            pass


def _reason(exc: BaseException) -> str:
    errno_ = getattr(exc, "errno", None)
    if isinstance(errno_, int) and errno_ > 0:  # pyserial repeats the errno and the path
        if errno_ == errno.ENOENT:
            return "no such device (is the rig plugged in, or 'esoarm emulate' running?)"
        return os.strerror(errno_)
    text = str(exc).strip().splitlines()
    if text and f"({errno.ENOTTY}," in text[0]:  # pyserial's termios error on a plain file
        return "not a serial device (a terminal's settings cannot be applied to it)"
    return text[0] if text else type(exc).__name__
