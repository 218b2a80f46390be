"""What the two device servers share: the pseudo-terminal and the timed faults.

``esoarm emulate`` (:mod:`esoarm.hardware.emulator`, the twin speaking the
protocol itself) and ``esoarm hil`` (:mod:`esoarm.hardware.hil.server`, the
firmware in simavr with the twin on its pins) both offer the host a new
pseudo-terminal, :class:`PtyDevice`, and both inject faults given as
``KIND@SECONDS`` of twin time, :class:`TimedFault`.  What they do with the
bytes differs: the emulator answers the frames, the HIL server passes them to
the firmware's UART.
"""

from __future__ import annotations

import math
import os
import select
import time
import tty
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from esoarm.scenario import ScenarioError

__all__ = ["PtyDevice", "TimedFault", "due_faults", "parse_timed_fault"]


class PtyDevice:
    """The device end of a new pseudo-terminal (raw, non-blocking); the host opens :attr:`path`.

    A host that hangs up and a full output buffer (nobody reading) are not
    errors: reads return ``b""`` and writes report the bytes as lost, as on a
    real serial line.
    """

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        #: the port's path, e.g. /dev/pts/3
        self.path = os.ttyname(self.slave)
        self.closed = False

    def read(self, timeout: float) -> bytes:
        """The host's bytes, waiting up to ``timeout`` [s]; ``b""`` when there are none.

        With no host on the other side (EIO) it waits a little (at most 10 ms)
        so that a caller's loop does not spin; once closed it just waits.
        """
        if self.closed:
            if timeout > 0:
                time.sleep(timeout)
            return b""
        try:
            ready, _, _ = select.select([self.master], [], [], timeout)
        except (OSError, ValueError):
            return b""
        if not ready:
            return b""
        try:
            return os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:  # no host on the other side (EIO): wait for one
            time.sleep(min(0.01, max(timeout, 0.001)))
            return b""

    def write(self, data: bytes) -> bool:
        """Send ``data`` to the host; False when the bytes were lost (buffer full, closed)."""
        if self.closed:
            return False
        try:
            os.write(self.master, data)
        except OSError:  # BlockingIOError included: nobody reading
            return False
        return True

    def close(self) -> None:
        """Close both ends (the port goes away); idempotent."""
        if self.closed:
            return
        self.closed = True
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


@dataclass(frozen=True)
class TimedFault:
    """A fault to inject: ``kind`` at twin time ``at`` [s]."""

    kind: str
    at: float


def parse_timed_fault(text: str, kinds: Sequence[str], label: str = "--fault") -> TimedFault:
    """Parse ``KIND@SECONDS`` with KIND one of ``kinds``.

    Raises a :class:`ScenarioError` with one line starting ``{label} '{text}'``.
    """
    kind, sep, when = text.partition("@")
    if not sep or kind not in kinds:
        raise ScenarioError(
            f"{label} '{text}': expected KIND@SECONDS with KIND one of {', '.join(kinds)}")
    try:
        at = float(when)
    except ValueError:
        at = math.nan
    if not (math.isfinite(at) and at >= 0):
        raise ScenarioError(f"{label} '{text}': SECONDS must be a finite number >= 0")
    return TimedFault(kind, at)


def due_faults(faults: list[TimedFault], t: float,
               echo: Callable[[str], None]) -> Iterator[TimedFault]:
    """Remove from ``faults`` (sorted by time) and yield those due at twin time ``t`` [s].

    Each is announced through ``echo`` ("fault injected: KIND at t = ... s").
    """
    while faults and faults[0].at <= t + 1e-12:
        fault = faults.pop(0)
        echo(f"fault injected: {fault.kind} at t = {t:.4g} s")
        yield fault
