"""On-board mode on the simulated Uno: the rig firmware runs the generated controller itself.

:func:`onboard_firmware` generates the scenario's controller for the AVR and
builds the rig firmware with it (``make -C firmware l298n ONBOARD=DIR
SAMPLE_PERIOD_US=… BAUD=…``): at every sample the firmware's Timer2 interrupt
reads the encoder, steps the generated observer and controller on
y = count·2π/counts and writes the duty, and streams CHIP_SAMPLE frames (y as
the count, u, the estimate, the duty; docs/protocol.md); HEARTBEAT frames from
the host feed the firmware's watchdog.  :func:`onboard_run` runs that firmware
in simavr with the twin on its pins (:class:`esoarm.hardware.hil.twin.PinTwin`,
one RK4 step of ``rig.step`` at a time) and a scripted host that sends START, a
HEARTBEAT every 20 ms of AVR time and records every sample and fault the chip
streams.  The Python host proper is ``esoarm run SCENARIO --port PATH --onboard``
(:func:`esoarm.hardware.realtime.run_rig`) against ``esoarm hil SCENARIO --onboard``.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from esoarm.codegen import CodegenError
from esoarm.codegen.generate import generate, write_sources
from esoarm.hardware import protocol as P
from esoarm.hardware.hil.build import ToolchainMissing, _cache_dir, default_firmware_dir
from esoarm.scenario import Scenario

__all__ = ["OVERHEAD_CYCLES", "OnboardRun", "SumsChoice", "check_stream", "choose_sums",
           "onboard_firmware", "onboard_run", "stream_every", "sums_fit"]

#: Baud rate of the on-board builds: a 37-byte CHIP_SAMPLE frame (370 bits) every 1 ms
#: needs 370 kbit/s; 115200 would carry one sample in four at 1 kHz.
BAUD = 1_000_000
#: Bits on the wire of one CHIP_SAMPLE frame (7 bytes of framing + 30 of payload, 10 bits a byte)
CHIP_FRAME_BITS = 10 * (P.HEADER_SIZE + P.PAYLOAD_SIZES[P.CHIP_SAMPLE] + P.CRC_SIZE)
#: The host's heartbeat period [s] (the firmware's watchdog trips after 100 ms without one):
#: parsing a frame per sample would cost the chip ~3k cycles of its 16k at 1 kHz.
HEARTBEAT_S = 0.02


#: Cycles a sample of the on-board firmware costs on the ATmega328P beyond the controller
#: step as PIL times it, streaming every sample at 1 Mbit/s: measured with
#: ``python benchmarks/bench_onboard.py --seconds 3`` (uno-rig, 1 kHz, plain sums, 3 s with
#: the first move): busy cycles per 1 ms, median 14 785, less PIL's median step, 5398
#: (``esoarm pil uno-rig --target avr --set sensor.rate_hz=1000 --plain-sums``): 9387
#: (9276 with the generator before the reference's move-local time).  It holds the
#: interrupt's entry, the encoder, the motor pins, the CHIP_SAMPLE frame (CRC, queue, 37 UART
#: interrupts) and the step running slower inside the interrupt than alone in PIL (the UART
#: interrupts land in it).
#: Since the reference left the step (the C API takes θd, θ̇d, θ̈d; the firmware evaluates
#: the scenario's moves with esoarm_reference_next), PIL no longer times the reference, and
#: this overhead, measured before, holds it: uno-rig's PIL median with compensated sums was
#: 7271 cycles with the reference in the step and is 7238 without it at 50 Hz (the tunable
#: gains now read from RAM cost about what its two moves did).  A reference with many moves
#: costs more on board than this allows for: re-measure with benchmarks/bench_onboard.py.
#: A learned feedforward table is inside the step, so PIL times it.  Re-measured after the
#: cheaper actuator maps and quintic reference (11:05 UTC, 6 December; ``bench_onboard.py
#: --table``): the default build's busy median 13 948 less PIL's plain median 4562 at 1 kHz,
#: 9386.  The decimated polled stream (``--stream-every 10 --baud 115200 --stream-polled``)
#: costs less, about 3.9k cycles (busy median 8456 less 4562), so this value is conservative
#: for it: with the learned table at 1 kHz (PIL median 6301) ``--sums auto`` refuses a build
#: that runs with 33 % of the period free at p99.
OVERHEAD_CYCLES = 9400
#: The share of the period the predicted median load may use (the rest: bursts, heartbeats).
LOAD_LIMIT = 0.97


@dataclass(frozen=True)
class SumsChoice:
    """The observer sums chosen for an on-board build, and why.

    Attributes
    ----------
    compensated : bool
        Compensated (Kahan) float32 sums, else plain.
    reason : str
        One line with the PIL numbers the choice rests on.
    """

    compensated: bool
    reason: str

    @property
    def name(self) -> str:
        """``"compensated"`` or ``"plain"``."""
        return "compensated" if self.compensated else "plain"


def _pil_cycles(scn: Scenario, compensated: bool,
                say: Callable[[str], None] | None = None) -> dict:
    """PIL on the AVR for ``scn`` (cycles, agreement), cached by the generated C.

    The run ends at the first step over the sample period (it cannot fit: no need to run
    the rest); ``say`` gets a progress line every 5 s.
    """
    import hashlib
    import json
    import time

    from esoarm.codegen.pil import run_pil

    gen = generate(scn, "avr", "float32", compensated)
    code = hashlib.sha256((gen.header + gen.source).encode()).hexdigest()[:16]
    path = _cache_dir() / f"esoarm-pil-{code}.json"  # the C itself: a new generator re-times
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError):
        pass
    name = "compensated" if compensated else "plain"
    start = time.monotonic()
    last = [start]
    if say is not None:
        say(f"timing the {name} observer sums with PIL on the simulated ATmega328P "
            f"({scn.n_samples} samples at most; cached for the next run)")

    def progress(k: int) -> None:
        now = time.monotonic()
        if say is not None and now - last[0] >= 5.0:
            last[0] = now
            say(f"  PIL ({name}): {k} of {scn.n_samples} samples ({now - start:.0f} s)")

    rep = run_pil(scn, "avr", "float32", compensated, stop_over_budget=True,
                  progress=progress)
    out = {"cycles": rep.cycles, "agrees": rep.agrees, "max_rel_du": rep.run.max_rel_du,
           "budget": rep.budget_cycles, "steps": rep.run.steps}
    try:
        path.write_text(json.dumps(out))
    except OSError:
        pass
    return out


def _judge(scn: Scenario, compensated: bool, say: Callable[[str], None] | None
           ) -> tuple[bool, str]:
    """(fits, one line of numbers) for one observer sum on board."""
    from esoarm.hardware.hil.board import F_CPU

    budget = round(F_CPU * scn.sample_time)
    r = _pil_cycles(scn, compensated, say)
    c = r["cycles"]
    load = c["median"] + OVERHEAD_CYCLES
    name = "compensated" if compensated else "plain"
    steps = r.get("steps", scn.n_samples)
    fits = bool(r["agrees"]) and c["max"] <= budget and load <= LOAD_LIMIT * budget
    text = (f"{name}: PIL median {c['median']} + {OVERHEAD_CYCLES} on-board = {load}"
            f" {'≤' if load <= LOAD_LIMIT * budget else '>'} {LOAD_LIMIT:g} × "
            f"{budget} cycles, worst step {c['max']}"
            + (f" (over the period at step {steps - 1}: PIL stopped there)"
               if c["max"] > budget and steps < scn.n_samples else "")
            + ("" if r["agrees"] else f", max_rel_du {r['max_rel_du']:.2g} too large"))
    return fits, text


def sums_fit(scn: Scenario, compensated: bool,
             say: Callable[[str], None] | None = None) -> tuple[bool, str]:
    """Whether one observer sum fits the ATmega328P's period on board, and the numbers.

    Parameters
    ----------
    scn : Scenario
        The scenario to build.
    compensated : bool
        The sums to judge.
    say : callable, optional
        Gets progress lines while PIL times the code (not cached yet).

    Returns
    -------
    (bool, str)
        Fits, and one line with the PIL numbers.
    """
    return _judge(scn, compensated, say)


def choose_sums(scn: Scenario, say: Callable[[str], None] | None = None) -> SumsChoice:
    """Compensated sums where they fit the ATmega328P's period on board, else plain.

    Each variant is timed by PIL (``esoarm pil SCENARIO --target avr [--plain-sums]``,
    cached, ended at the first step over the period).  A variant fits when it agrees with
    the float64 reference, its worst step fits the period, and its median step plus
    :data:`OVERHEAD_CYCLES` stays within :data:`LOAD_LIMIT` of the period.  Measured at
    1 kHz on uno-rig: compensated 7271 + 9400 > 0.97 · 16 000 (and on board it overran when
    the first move began), plain 5398 + 9400 fits (and held over the 20 s run).

    Parameters
    ----------
    scn : Scenario
        The scenario to build (its ``sensor.rate_hz`` sets the period).
    say : callable, optional
        Gets progress lines while PIL runs.

    Returns
    -------
    SumsChoice

    Raises
    ------
    CodegenError
        Neither variant fits: the rate is too high for this chip on board.
    """
    notes = []
    for compensated in (True, False):
        fits, text = _judge(scn, compensated, say)
        notes.append(text)
        if fits:
            return SumsChoice(compensated, "; ".join(notes))
    raise CodegenError(f"at {scn.sensor.rate_hz:g} Hz neither observer sum fits the "
                       f"ATmega328P's period on board ({'; '.join(notes)}): lower "
                       "sensor.rate_hz")


def stream_every(rate_hz: float, baud: int = BAUD) -> int:
    """Samples per streamed CHIP_SAMPLE frame: the firmware's STREAM_EVERY.

    The frames may use at most 90 % of the line, so the firmware streams every n-th
    sample with n = ceil(CHIP_FRAME_BITS · rate_hz / (0.9 · baud)) (the same integer
    formula as ``firmware/esoarm_rig/esoarm_rig.ino``).

    Parameters
    ----------
    rate_hz : float
        Sample rate [Hz] (a whole number of µs per sample).
    baud : int
        Line rate [bit/s].
    """
    period_us = round(1e6 / rate_hz)
    num = CHIP_FRAME_BITS * 1_000_000 * 10
    den = 9 * baud * period_us
    return max(1, -(-num // den))


#: The largest error of the line rate the ATmega328P's UART makes at 16 MHz (U2X, the
#: divisor the firmware computes) that is accepted: 115200 bit/s is 2.1 % fast, as on every
#: Uno; 230400 (3.5 %) is refused.
BAUD_ERROR = 0.025


def check_stream(rate_hz: float, baud: int = BAUD, every: int | None = None) -> int:
    """Check an on-board build's stream settings; the samples per streamed frame.

    Parameters
    ----------
    rate_hz : float
        Sample rate [Hz].
    baud : int
        Line rate [bit/s]: one the ATmega328P at 16 MHz makes within :data:`BAUD_ERROR`
        (the firmware's divisor ``(F_CPU / 4 / BAUD − 1) / 2`` with U2X).
    every : int, optional
        Stream every ``every``-th sample (default: the fewest the line needs,
        :func:`stream_every`).

    Returns
    -------
    int
        The firmware's STREAM_EVERY [samples per CHIP_SAMPLE frame].

    Raises
    ------
    CodegenError
        One line naming the setting: a line rate the UART cannot make, or frames more
        often than the line carries (or ``every`` over 65535).
    """
    from esoarm.hardware.hil.board import F_CPU

    if baud <= 0 or F_CPU // 4 // baud < 1:
        raise CodegenError(f"--baud {baud}: the ATmega328P at 16 MHz makes line rates up to "
                           "2000000 bit/s (e.g. 115200, 250000, 500000, 1000000)")
    ubrr = (F_CPU // 4 // baud - 1) // 2
    actual = F_CPU / (8 * (ubrr + 1))
    if abs(actual / baud - 1.0) > BAUD_ERROR:
        raise CodegenError(f"--baud {baud}: the ATmega328P at 16 MHz makes {actual:.0f} bit/s "
                           f"for it ({100 * (actual / baud - 1):+.1f} %, more than "
                           f"{100 * BAUD_ERROR:g} % off); use e.g. 115200, 250000, 500000 "
                           "or 1000000")
    least = stream_every(rate_hz, baud)
    if every is None:
        return least
    if not least <= every <= 65535:
        raise CodegenError(f"--stream-every {every}: at {baud} bit/s and {rate_hz:g} Hz a "
                           f"CHIP_SAMPLE frame every {every} sample(s) is more than the line "
                           f"carries; give N >= {least} (at most 65535)")
    return every


def onboard_firmware(scn: Scenario, firmware_dir: Path | None = None,
                     compensated: bool | None = None, baud: int = BAUD,
                     every: int | None = None, polled: bool = False) -> Path:
    """Generate ``scn``'s controller for the AVR and build the rig firmware with it.

    Parameters
    ----------
    scn : Scenario
        A one-joint scenario with a ``[motor]`` table; its ``sensor.rate_hz`` sets the
        firmware's sample period (a whole number of µs).
    firmware_dir : Path, optional
        ``firmware/`` of the checkout (default: the one this package runs from).
    compensated : bool, optional
        Observer sums of the generated code (default: compensated).
    baud : int
        Line rate [bit/s] of the build (sets the stream decimation, :func:`stream_every`).
    every : int, optional
        Stream every ``every``-th sample (the firmware's STREAM_EVERY; default: the fewest
        the line needs, :func:`stream_every`).  The chip still controls at every sample;
        fewer frames leave more of the period free (docs/on-the-chip.md, "The cycle budget").
    polled : bool
        Feed the line from ``loop()`` a byte at a time, each CHIP_SAMPLE frame built as it
        goes, instead of the transmit interrupt (the firmware's STREAM_POLLED): a frame's cost
        spreads over the samples it spans.

    Returns
    -------
    Path
        The firmware ELF.
    """
    fw = firmware_dir or default_firmware_dir()
    if fw is None:
        raise ToolchainMissing("the firmware sources (firmware/ of the esoarm checkout) "
                               "were not found")
    if shutil.which("make") is None:
        raise ToolchainMissing("make not found: apt-get install make")
    period_us = round(1e6 / scn.sensor.rate_hz)
    if abs(period_us - 1e6 / scn.sensor.rate_hz) > 1e-6 or period_us % 4:
        raise CodegenError(f"sensor.rate_hz = {scn.sensor.rate_hz:g}: on board the sample "
                           "period must be a whole multiple of 4 µs (the firmware's Timer2 tick)")
    check_stream(scn.sensor.rate_hz, baud, every)
    gen = generate(scn, "avr", "float32", compensated)
    root = _cache_dir() / (f"esoarm-onboard-{gen.digest}-{'c' if gen.compensated else 'p'}"
                           f"-{baud}" + (f"-n{every}" if every is not None else "")
                           + ("-polled" if polled else ""))
    write_sources(gen, root / "controller")
    out_dir = root / "build"
    cmd = ["make", "-s", "--no-print-directory", "-C", str(fw), "l298n",
           f"VARIANT_DIR={out_dir}", f"ONBOARD={root / 'controller'}",
           f"SAMPLE_PERIOD_US={period_us}", f"BAUD={baud}"]
    if every is not None:
        cmd.append(f"STREAM_EVERY={every}")
    if polled:
        cmd.append("STREAM_POLLED=1")
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        raise ToolchainMissing("on-board firmware build failed: "
                               + (lines[-1] if lines else f"exit {res.returncode}"))
    return out_dir / "esoarm_rig.elf"


@dataclass
class OnboardRun:
    """What the chip streamed during an on-board run.

    Attributes
    ----------
    k : ndarray
        Sample indices of the SAMPLE frames received, in order.
    t_us : ndarray
        Device time of each sample since START [µs].
    y : ndarray
        Measured angle q·count [rad].
    theta : ndarray
        The twin's true angle when each sample frame was complete [rad].
    u : ndarray
        Torque the chip's observer was updated with [N·m].
    zhat : ndarray (N, 3)
        The chip's estimate at each sample.
    duty : ndarray
        Duty the chip wrote [counts].
    faults : list of tuple
        FAULT frames (code, sample).
    expected : int
        Samples due in the run's length.
    """

    k: np.ndarray
    t_us: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    zhat: np.ndarray
    duty: np.ndarray
    faults: list[tuple] = field(default_factory=list)
    expected: int = 0

    @property
    def every_sample(self) -> bool:
        """Every due sample arrived, in order."""
        return len(self.k) >= self.expected and bool(
            np.array_equal(self.k, np.arange(len(self.k))))


def onboard_run(scn: Scenario, elf: Path, seconds: float | None = None) -> OnboardRun:
    """Run the on-board firmware ``elf`` in simavr with ``scn``'s twin on its pins.

    Parameters
    ----------
    scn : Scenario
        The scenario the firmware was generated from (twin, motor, encoder).
    elf : Path
        From :func:`onboard_firmware`.
    seconds : float, optional
        AVR time after START [s] (default: the scenario's duration).

    Returns
    -------
    OnboardRun
    """
    from esoarm.hardware.hil.board import F_CPU, Board
    from esoarm.hardware.hil.twin import PinTwin

    seconds = scn.duration if seconds is None else seconds
    twin = PinTwin(scn, F_CPU)
    q = 2.0 * np.pi / twin.counts_per_rev
    board = Board(elf)
    parser = P.Parser()
    ks: list[int] = []
    ts: list[int] = []
    counts: list[int] = []
    thetas: list[float] = []
    rows: list[P.ChipSample] = []
    faults: list[tuple] = []
    seq = 1
    try:
        board.set_encoder(twin.levels)
        board.run(round(0.05 * F_CPU))
        board.send(P.encode(P.START, 0))
        started = False
        end = None
        beat_every = round(HEARTBEAT_S * F_CPU)
        next_beat = 0
        give_up = board.cycle + F_CPU  # no sample within 1 s of START: the firmware is stuck
        while (board.cycle < end) if end is not None else (board.cycle < give_up):
            c0 = board.cycle
            duty = board.motor().duty
            cycles, levels = twin.step(duty, c0) if started else (np.zeros(0, np.uint64),
                                                                 np.zeros(0, np.uint8))
            board.run(c0 + twin.step_cycles, cycles, levels)
            data, _ = board.take()
            for f in parser.feed(data):
                if f.kind == P.CHIP_SAMPLE:
                    row = P.ChipSample.from_frame(f)
                    if not started:  # the first sample follows START: the twin starts
                        started = True
                        twin.start()
                        end = board.cycle + round(seconds * F_CPU)
                        next_beat = board.cycle
                    ks.append(row.k)
                    ts.append(row.t_us)
                    counts.append(row.encoder_count)
                    thetas.append(twin.theta)
                    rows.append(row)
                    if board.cycle >= next_beat:  # the watchdog's heartbeat (100 ms)
                        board.send(P.encode(P.HEARTBEAT, seq, row.k))
                        seq = (seq + 1) & 0xFF
                        next_beat = board.cycle + beat_every
                elif f.kind == P.FAULT:
                    faults.append(tuple(f.fields()))
    finally:
        board.close()
    table = np.array([(r.u, r.z1, r.z2, r.z3, r.duty) for r in rows],
                     dtype=float).reshape(-1, 5)
    return OnboardRun(np.asarray(ks), np.asarray(ts), q * np.asarray(counts, dtype=float),
                      np.asarray(thetas), table[:, 0], table[:, 1:4], table[:, 4].astype(int),
                      faults, int(round(seconds * scn.sensor.rate_hz)))
