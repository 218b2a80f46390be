"""``esoarm hil``: the compiled firmware on a simulated Uno, the twin on its pins.

One loop, one RK4 step of the twin (``rig.step``) per turn:

1. read the motor driver pins (:meth:`Board.motor`), advance the twin one step
   with that duty (:class:`~esoarm.hardware.hil.twin.PinTwin`), and run the
   AVR over the same interval with the encoder edges at their cycles;
2. pass the bytes the firmware wrote to its UART to the pseudo-terminal, and
   the host's bytes from the pseudo-terminal to the UART's receiver.

Pacing.  simavr runs the firmware faster than real time, but the host's
latency must count in the AVR's time: from the moment a device frame is passed
to the host until the host answers, the AVR runs no faster than the wall
clock; between the answer and the next device frame it runs free.  When no run
is in progress it runs at real time (an idle board does not spin the CPU).
``realtime=True`` paces everything to the wall clock (needed when the host
measures period jitter).  Where the simulation falls more than
:data:`SLIP_S` behind the wall clock (a loaded machine), it does not race to
catch up -- that would hand the host a burst of frames and measure the
simulator, not the firmware -- but carries on from the wall clock's now; each
such slip is counted (``slips``, ``worst_slip``) and reported.  In the
host-paced mode the AVR's time runs ahead of the wall clock on a free core and
falls behind it on a busy one; how far behind it falls during a run is tracked
at every SAMPLE frame (``lags``, ``worst_lag``, see :meth:`HilServer._track_lag`)
and reported: the host's deadline misses and period jitter then measure the
simulator, not the host.

Faults (``KIND@SECONDS``, twin time after START): ``encoder-break`` channel A
stuck high (a broken wire with its pull-up); ``encoder-noise`` glitches of
1-20 µs on A, B or both at random times, 2000 per second; ``driver`` the motor pins no
longer reach the motor; ``brownout`` the MCU resets; ``unplug`` the serial link
goes away (the MCU runs on).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from esoarm.hardware import protocol as P
from esoarm.hardware.device import PtyDevice, TimedFault, due_faults, parse_timed_fault
from esoarm.hardware.hil.board import F_CPU, Board
from esoarm.hardware.hil.twin import PinTwin
from esoarm.scenario import Scenario

__all__ = ["HIL_FAULTS", "HilFault", "HilServer", "parse_hil_fault"]

HIL_FAULTS = ("encoder-break", "encoder-noise", "driver", "brownout", "unplug")
#: encoder-noise: glitch widths [s] and rate [1/s]
GLITCH_MIN, GLITCH_MAX = 1e-6, 20e-6
GLITCH_RATE = 2000.0
#: boot time of the firmware before the pseudo-terminal is offered [s]
BOOT_TIME = 0.05


#: A pin-level fault ``kind`` (one of :data:`HIL_FAULTS`) at twin time ``at`` [s].
HilFault = TimedFault


def parse_hil_fault(text: str) -> HilFault:
    """Parse ``KIND@SECONDS``; raises :class:`ScenarioError` with one line."""
    return parse_timed_fault(text, HIL_FAULTS)


#: realtime: a lag behind the wall clock beyond this [s] is a slip (counted, not repaid);
#: host-paced: a sample this far behind the run's most-ahead one is counted (``lags``).
SLIP_S = 0.005


@dataclass
class FrameRecord:
    """A device frame with the cycles of its first and last byte written to UDR0."""

    frame: P.Frame
    first_cycle: int
    last_cycle: int


@dataclass
class HilLog:
    """What the server saw, for tests and timing measurements."""

    device_frames: list[FrameRecord] = field(default_factory=list)
    host_frames: list[tuple[P.Frame, int]] = field(default_factory=list)
    #: (cycle, duty) at every change of the duty on the motor pins
    duty_changes: list[tuple[int, int]] = field(default_factory=list)
    start_cycle: int | None = None
    keep_frames: bool = False


class HilServer:
    """The firmware in simavr behind a new pseudo-terminal, the twin on its pins.

    Parameters
    ----------
    scn : Scenario
        The twin (rig, motor, encoder resolution).
    elf : Path
        Firmware built for the Uno.
    faults : sequence of HilFault
        Faults to inject (twin time after START).
    realtime : bool
        Pace the AVR to the wall clock all the time.
    echo : callable
        Receives one-line status messages.
    record : bool
        Keep every frame and duty change in :attr:`log` (tests, timing).
    """

    def __init__(self, scn: Scenario, elf: Path, *,
                 faults: list[HilFault] | tuple[HilFault, ...] = (), realtime: bool = False,
                 echo: Callable[[str], None] = print, record: bool = False) -> None:
        self.scn = scn
        self.twin = PinTwin(scn, F_CPU)
        self.board = Board(elf)
        self.faults = sorted(faults, key=lambda f: f.at)
        self.realtime = realtime
        self.echo = echo
        self.log = HilLog(keep_frames=record)
        self.port = PtyDevice()
        self.path = self.port.path
        self.closed = False
        self.unplugged = False
        self.rx_parser = P.Parser()   # host -> device (watched, not consumed)
        self.tx_parser = P.Parser()   # device -> host
        self._tx_first: int | None = None
        self.run_active = False
        self.encoder_break = False
        self.noise = False
        self._rng = np.random.default_rng(scn.sensor.seed)
        self._awaiting: tuple[float, int] | None = None  # (wall, cycle) of the last device frame
        self._last_host_wall = -math.inf
        self._last_host_cycle = 0
        self._wall0 = time.perf_counter()
        self._cycle0 = 0
        self.slips = 0  # realtime: times the simulation fell behind the wall clock
        self.worst_slip = 0.0  # [s]
        # host-paced: samples of a run sent more than SLIP_S behind the wall clock, counted
        # from the run's most-ahead sample (see _track_lag)
        self.lags = 0
        self.worst_lag = 0.0  # [s]
        self.samples_tracked = 0
        self._drift_min = math.inf  # [s] smallest wall − AVR time at a sample of this run
        self.motor_duty = 0
        self.unplug_cycle: int | None = None  # AVR cycle at which the link went away
        self.device_faults: list[str] = []  # FAULT frames the firmware sent, by name
        self.stop_seen = False    # the host sent STOP after the last START
        self.count_error = 0      # device count − arm position [counts] at the last sample
        self.count_error_max = 0
        self.board.set_encoder(self.twin.levels)  # the lines show where the disc is
        self.board.run(round(BOOT_TIME * F_CPU))
        self.board.isr_clear()

    # -- pins ------------------------------------------------------------------
    def _edges(self, cycle0: int) -> tuple[np.ndarray, np.ndarray]:
        """Encoder edges of the next step, with the faults applied at pin level."""
        before = self._encoder_level()
        cycles, levels = self.twin.step(self.motor_duty, cycle0)
        if self.encoder_break:
            levels = levels | 0b10  # A stuck high
        if self.noise:
            n = int(self._rng.poisson(GLITCH_RATE * self.twin.h))
            if n:
                # a glitch flips A, B or both for 1-20 µs, then the true level returns
                wmax = round(GLITCH_MAX * F_CPU)
                width = self._rng.integers(round(GLITCH_MIN * F_CPU), wmax, n).astype(np.uint64)
                # glitches start and end inside this step
                at = np.sort(self._rng.integers(0, self.twin.step_cycles - wmax, n))
                at = at.astype(np.uint64)
                mask = self._rng.integers(1, 4, n).astype(np.uint8)
                at += np.uint64(cycle0)

                def level_at(c: np.ndarray) -> np.ndarray:
                    idx = np.searchsorted(cycles, c, side="right")
                    return np.where(idx > 0, levels[np.maximum(idx - 1, 0)] if len(levels)
                                    else before, before).astype(np.uint8)

                cs = np.concatenate([cycles, at, at + width])
                ls = np.concatenate([levels, level_at(at) ^ mask, level_at(at + width)])
                order = np.argsort(cs, kind="stable")
                cycles, levels = cs[order], ls[order].astype(np.uint8)
        return cycles, levels

    # -- bytes -----------------------------------------------------------------
    def _pump_out(self) -> None:
        data, cycles = self.board.take()
        if not data:
            return
        for frame in self._split_frames(data, cycles):
            self._on_device_frame(frame)
        self.port.write(data)  # lost when nobody reads or unplugged, as on a real line

    def _split_frames(self, data: bytes, cycles: np.ndarray) -> list[FrameRecord]:
        out = []
        for b, c in zip(data, cycles.tolist(), strict=True):
            first = c if self._tx_first is None else self._tx_first
            self._tx_first = first
            for f in self.tx_parser.feed(bytes((b,))):
                out.append(FrameRecord(f, first, c))
                self._tx_first = None
        return out

    def _on_device_frame(self, rec: FrameRecord) -> None:
        if self.log.keep_frames:
            self.log.device_frames.append(rec)
        kind = rec.frame.kind
        if kind in (P.SAMPLE, P.CHIP_SAMPLE) and self.twin.running:
            # the device's count against the disc (the arm moves a count or two while
            # the frame is on the wire)
            count = rec.frame.fields()[2]
            self.count_error = count - (self.twin.position - self.twin.start_position)
            self.count_error_max = max(self.count_error_max, abs(self.count_error))
        if kind in (P.SAMPLE, P.CHIP_SAMPLE, P.FAULT, P.INFO, P.CHIP_INFO, P.STOPPED):
            wall = time.perf_counter()
            self._awaiting = (wall, self.board.cycle)
            if kind in (P.SAMPLE, P.CHIP_SAMPLE) and self.run_active and not self.realtime:
                self._track_lag(wall, rec.first_cycle)
        if kind == P.FAULT:
            code, detail = rec.frame.fields()
            name = {P.FAULT_WATCHDOG: "watchdog", P.FAULT_OVERRUN: "overrun",
                    P.FAULT_BAD_COMMAND: "bad command",
                    P.FAULT_ENCODER: "encoder"}.get(code, f"code {code}")
            self.device_faults.append(name)
            self.echo(f"device fault: {name} (detail {detail}) at t = {self.twin.t:.4g} s")
        if kind == P.STOPPED:
            self.run_active = False

    def _pump_in(self, timeout: float = 0.0) -> None:
        data = self.port.read(timeout)  # waits out the timeout when unplugged or closed
        if not data:
            return
        self.board.send(data)
        self._last_host_wall = time.perf_counter()
        self._last_host_cycle = self.board.cycle
        self._awaiting = None
        for frame in self.rx_parser.feed(data):
            if self.log.keep_frames:
                self.log.host_frames.append((frame, self.board.cycle))
            if frame.kind == P.START:
                self.twin.start()
                self.stop_seen = False
                self.run_active = True
                self.log.start_cycle = self.board.cycle
                self._drift_min = math.inf
                self._apply_faults(at_start=True)
            elif frame.kind == P.STOP:
                self.run_active = False
                self.stop_seen = True

    # -- faults ----------------------------------------------------------------
    def _apply_faults(self, at_start: bool = False) -> None:
        if not self.twin.running:
            return
        t = self.twin.t
        for fault in due_faults(self.faults, t, self.echo):
            if fault.kind == "encoder-break":
                self.encoder_break = True
            elif fault.kind == "encoder-noise":
                self.noise = True
            elif fault.kind == "driver":
                self.twin.ignore_motor = True
            elif fault.kind == "brownout":
                self.board.reset()
                self.board.set_encoder(self._encoder_level())
            elif fault.kind == "unplug":
                self.unplug()

    def _encoder_level(self) -> int:
        return self.twin.levels | (0b10 if self.encoder_break else 0)

    def unplug(self) -> None:
        """The serial link goes away; the MCU keeps running."""
        if self.unplugged:
            return
        self.unplugged = True
        self.unplug_cycle = self.board.cycle
        self.port.close()

    # -- pacing ----------------------------------------------------------------
    def _track_lag(self, wall: float, cycle: int) -> None:
        """Host-paced: how far behind the wall clock the AVR is at a sample of a run.

        ``wall`` [s] is when the frame goes to the host, ``cycle`` the AVR cycle of its
        first byte.  The lag is wall − AVR time, less its smallest value so far in
        this run: the host takes the device clock's offset from the earliest arrival
        it has seen, so a sample this far behind reaches it this much later than its
        deadline assumes.  Running ahead (the AVR runs free between an answer and the
        next sample) lowers the reference instead.
        """
        drift = wall - cycle / F_CPU
        self._drift_min = min(self._drift_min, drift)
        lag = drift - self._drift_min
        self.samples_tracked += 1
        if lag > SLIP_S:
            self.lags += 1
            self.worst_lag = max(self.worst_lag, lag)

    def _pace(self, next_cycle: int) -> None:
        now = time.perf_counter()
        if self.realtime:
            due = self._wall0 + (next_cycle - self._cycle0) / F_CPU
            if now - due > SLIP_S:  # behind: carry on from now rather than race
                self.slips += 1
                self.worst_slip = max(self.worst_slip, now - due)
                self._wall0, self._cycle0 = now, next_cycle
                due = now
        elif self._awaiting is not None:
            w, c = self._awaiting
            due = w + (next_cycle - c) / F_CPU
        elif not self.run_active and now - self._last_host_wall > 0.2:
            # idle: real time from here on
            self._wall0, self._cycle0 = now, next_cycle
            self._awaiting = (now, self.board.cycle)
            due = now
        else:
            due = now
        wait = due - now
        self._pump_in(wait if wait > 0 else 0.0)
        while (left := due - time.perf_counter()) > 0:
            self._pump_in(left)

    # -- main loop -------------------------------------------------------------
    def serve(self, until: Callable[[], bool] = lambda: False,
              max_seconds: float | None = None) -> None:
        """Run until ``until()`` is true (or ``max_seconds`` of AVR time have passed)."""
        board, twin = self.board, self.twin
        step = twin.step_cycles
        self._wall0, self._cycle0 = time.perf_counter(), board.cycle
        end = None if max_seconds is None else board.cycle + round(max_seconds * F_CPU)
        prev_duty = None
        debug = bool(os.environ.get("ESOARM_HIL_DEBUG"))
        t_prev = time.perf_counter()
        while not self.closed and not until():
            if debug:
                t_now = time.perf_counter()
                if t_now - t_prev > 0.1:
                    self.echo(f"debug: {t_now - t_prev:.3f} s for one step at "
                              f"t = {self.twin.t:.4g} s")
                t_prev = t_now
            c0 = board.cycle
            if end is not None and c0 >= end:
                break
            self._pace(c0 + step)
            self._apply_faults()
            pins = board.motor()
            self.motor_duty = pins.duty
            if pins.duty != prev_duty:
                self._on_duty_change(prev_duty, pins.duty, c0)
                prev_duty = pins.duty
            cycles, levels = self._edges(c0)
            board.run(c0 + step, cycles, levels)
            self._pump_out()

    def _on_duty_change(self, old: int | None, new: int, cycle: int) -> None:
        if self.log.keep_frames:
            self.log.duty_changes.append((cycle, new))
        if old not in (None, 0) and new == 0:
            since = (cycle - self._last_host_cycle) / F_CPU * 1e3
            self.echo(f"motor off at t = {self.twin.t:.4g} s "
                      f"({since:.0f} ms after the last byte from the host)")

    def host_quiet(self, seconds: float) -> bool:
        """True when no byte came from the host for ``seconds`` of wall time."""
        return time.perf_counter() - self._last_host_wall > seconds

    def close(self) -> None:
        """Close the pseudo-terminal and free the MCU."""
        if not self.closed:
            self.closed = True
            self.port.close()
            self.board.close()
