"""The real-time run loop on a rig (``esoarm run``), with its safety layer.

The device is the clock: it sends sample k (device time, encoder count) every
Ts (or, in lockstep, after each command).  For every sample the host does
the sampled-data loop, steps 1-5 with :class:`~esoarm.hardware.host_control.DeploymentController`:

1. y_k = q · count_k   (q = radians(sensor.resolution_deg); exact, see emulator)
2.-3. ẑ_k, u_k = sat(FLC(ẑ_k, reference at t_k))
   send u_k: float64 TORQUE to an ideal-torque device, else a DUTY from
   :meth:`~esoarm.plants.motor.MotorParams.torque_to_duty` with the rate ẑ2
4. log row k (streamed to disk, one line per sample, flushed)
5. ESO update with the torque applied from t_k on

Safety: |u| ≤ torque_limit (the FLC saturates; checked again), |y| ≤ angle
limit, |y_k − y_{k−1}| ≤ max jump (encoder glitches), |y_k − θd(t_k)| ≤ max
following error (a dead driver or encoder line), a host watchdog on
incoming samples, and a NaN guard on u and ẑ.  Any fault, a device FAULT
report, a lost port or Ctrl-C ends the run the same way: STOP is sent (the
device turns the motor off; its own 100 ms watchdog does so too if the link is
dead), the log keeps every row written, and :class:`RigFault` or
:class:`RigInterrupted` carries the summary of the rows logged.

On-board mode (``onboard=True``, ``esoarm run --onboard``): the device runs the
generated controller itself (firmware built with ``ONBOARD=DIR``; INFO has
``FLAG_ONBOARD``).  The host switches its own control law off: it checks that
the chip's controller was generated from this very scenario (CHIP_INFO's hash),
sends START, feeds the chip's watchdog with a HEARTBEAT every
:data:`HEARTBEAT_S` of the chip's samples, and logs each CHIP_SAMPLE the
chip streams -- y, the u and the estimate the chip used, its duty -- as a row of :data:`LOG_COLUMNS`
(``latency`` nan: the host answers nothing).  Its supervisor stays: angle
limit, encoder jump, following error, NaN guard on u and ẑ, torque limit, the
watchdog on incoming samples, the chip's FAULT reports (overrun included).
Where the link cannot carry a frame per sample the chip streams every n-th
(CHIP_INFO ``stream_every``); the log's first line (a ``#`` comment) and the
``notice`` callback say so.

A sample that never arrives (a gap in the device's sample index) is bridged by
an observer prediction with zero innovation; its row has ``theta = nan`` and
is counted in ``lost_samples``.  Deadline: the command for sample k must leave
before t_dev,k + offset + Ts, offset the smallest arrival delay seen
(a host-side estimate of the device clock).
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from esoarm._io import OutputError, describe_os_error
from esoarm.engines.metrics import series_metrics
from esoarm.hardware import protocol as P
from esoarm.hardware.host_control import DeploymentController, SampleController
from esoarm.hardware.link import LinkError, SerialLink
from esoarm.plants.actuator import actuate_with_table, actuator_vector, motor_of
from esoarm.plants.motor import MotorParams
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["HEARTBEAT_S", "LOG_COLUMNS", "RigFault", "RigInterrupted", "RunSummary", "SafetyLimits",
           "check_device", "run_rig"]

#: Columns of the run log (docs/semantics.md, "Output files and columns"): the time-series
#: columns, but ``theta`` and ``error`` from the *measured* angle (a rig's true angle is
#: unknown) and no ``f_true``; then timing, the duty sent, and ``y``, the measured angle
#: under the name it has in every file (here equal to ``theta``).
LOG_COLUMNS = ("t", "theta", "theta_ref", "error", "u", "z1", "z2", "z3",
               "k", "t_device", "t_host", "latency", "late", "duty", "y")
#: On board: the host's HEARTBEAT period [s of the chip's samples] (its watchdog trips after
#: 100 ms without one: ten chances; at 20 ms a 1 kHz run in simavr tripped it once at
#: sample 8059 of 20000, the cause not found).
HEARTBEAT_S = 0.01


@dataclass(frozen=True)
class SafetyLimits:
    """Host-side safety limits.

    Attributes
    ----------
    angle_limit : float
        Largest allowed |θ| measured [rad].
    max_jump : float
        Largest allowed change of the measured angle between two samples [rad].
    watchdog : float
        Longest wait for the next sample [s].
    max_error : float
        Largest allowed following error |θ − θd| measured [rad]: a driver that no
        longer drives or an encoder line that no longer counts leaves the arm
        behind its reference. Off (inf) by default here; ``esoarm run`` sets it
        (``--max-error``, 0.5 rad).
    """

    angle_limit: float = math.pi
    max_jump: float = 0.5
    watchdog: float = 0.25
    max_error: float = math.inf


@dataclass
class RunSummary:
    """Metrics of a run over the samples received, on the measured angle (engines.metrics)."""

    samples: int = 0
    lost_samples: int = 0
    rms_error: float = math.nan
    rms_u: float = math.nan
    rms_du: float = math.nan
    max_abs_error: float = math.nan
    deadline_misses: int = 0
    jitter_p50_us: float = math.nan
    jitter_p99_us: float = math.nan
    latency_p50_us: float = math.nan
    latency_p99_us: float = math.nan
    bad_frames: int = 0
    lost_frames: int = 0
    mode: str = ""
    log: str = ""
    stop_acknowledged: bool = False
    onboard: bool = False
    stream_every: int = 1
    observer_sums: str = ""

    def to_dict(self) -> dict:
        """JSON-ready (NaN as None).

        Returns
        -------
        dict
            Every field by name.
        """
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in asdict(self).items()}


class RigFault(RuntimeError):
    """A run ended by a fault; STOP sent, log intact. ``summary`` covers the rows logged."""

    def __init__(self, message: str, summary: RunSummary) -> None:
        super().__init__(message)
        self.summary = summary


class RigInterrupted(RuntimeError):
    """A run ended by Ctrl-C; STOP sent, log intact."""

    def __init__(self, message: str, summary: RunSummary) -> None:
        super().__init__(message)
        self.summary = summary


def check_device(info: P.Info, scn: Scenario) -> float:
    """Check the device against the scenario; return the quantization step q [rad].

    Parameters
    ----------
    info : Info
        The device's INFO frame (its sample period and encoder counts per revolution).
    scn : Scenario
        The scenario run.

    Returns
    -------
    float
        q = radians(``sensor.resolution_deg``) [rad per count].

    Raises
    ------
    ScenarioError
        Bad input: the device's sample period or encoder resolution differs from
        ``sensor.rate_hz`` / ``sensor.resolution_deg``.
    """
    ts = scn.sample_time
    if abs(info.period_us * 1e-6 - ts) > 1e-6:
        raise ScenarioError(
            f"sensor.rate_hz = {scn.sensor.rate_hz:g} Hz does not match the device, which "
            f"samples every {info.period_us} µs ({1e6 / max(info.period_us, 1):g} Hz)")
    res = scn.sensor.resolution_deg
    dev = 360.0 / info.counts_per_rev if info.counts_per_rev else math.inf
    if not abs(dev - res) <= 1e-9 * dev:
        raise ScenarioError(
            f"sensor.resolution_deg = {res:g} does not match the device's "
            f"{info.counts_per_rev} counts/rev; use --set sensor.resolution_deg={dev!r}")
    return math.radians(res)


class _LogWriter:
    """CSV rows streamed to disk, one flushed line per sample.

    If the disk fills up (or any write fails) the run stops like any other
    fault, and the file is cut back to its last whole row.
    """

    def __init__(self, path: Path | None, columns: tuple[str, ...] = LOG_COLUMNS,
                 tee: Callable[[str], None] | None = None, preamble: str = "") -> None:
        self.path = path
        self.tee = tee  # e.g. the live scope: gets every row as written
        self.rows = 0
        self._fh = None
        self._good = 0  # bytes of whole rows written
        if path is not None:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                self._fh = open(path, "w", encoding="utf-8", newline="\n", buffering=1)  # noqa: SIM115
            except OSError as exc:
                raise OutputError(path, describe_os_error(exc)) from None
            if preamble:
                self.write(f"# {preamble}\n", row=False)
            self.write(",".join(columns) + "\n", row=False)

    def write(self, line: str, row: bool = True) -> None:
        if self._fh is not None:
            try:
                self._fh.write(line)
            except OSError as exc:
                self._fail(exc)
            self._good += len(line)  # ASCII: characters are bytes
        if row:
            self.rows += 1
            if self.tee is not None:
                self.tee(line)

    def _fail(self, exc: OSError) -> None:
        fh, self._fh = self._fh, None
        try:
            assert fh is not None
            fh.close()
        except OSError:
            pass
        try:
            os.truncate(str(self.path), self._good)
        except OSError:
            pass
        raise _Stop(f"cannot write the log '{self.path}': {describe_os_error(exc)} "
                    f"(log cut back to its last whole row)")

    def close(self) -> None:
        if self._fh is not None:
            try:
                self._fh.flush()
                self._fh.close()
            except OSError:
                try:
                    os.truncate(str(self.path), self._good)
                except OSError:
                    pass
            self._fh = None


class _SigintFlag:
    """Turn Ctrl-C into a flag checked between samples (never a half-written row)."""

    def __init__(self) -> None:
        self.hit = False
        self._old: Any = None

    def __enter__(self) -> _SigintFlag:
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame) -> None:  # type: ignore[no-untyped-def]
        self.hit = True

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


def _fault_name(code: int, watchdog: str) -> str:
    """A FAULT frame's code in words (``watchdog``: what that board's watchdog waits for)."""
    return {P.FAULT_WATCHDOG: watchdog, P.FAULT_OVERRUN: "overrun",
            P.FAULT_BAD_COMMAND: "bad command",
            P.FAULT_ENCODER: "encoder"}.get(code, f"code {code}")


class _Stop(Exception):
    def __init__(self, message: str, interrupted: bool = False) -> None:
        super().__init__(message)
        self.interrupted = interrupted


class _Supervisor:
    """What both real-time loops do around their control law, written once.

    The host's watchdog on incoming samples, the device's FAULT and STOPPED reports,
    the device clock (its 32-bit µs counter unwrapped), the limits on the measurement
    (encoder jump, angle, following error), and the bookkeeping of a logged sample (the
    error and u for the summary, the last sample for the final status, the live status
    ten times a second).  ``source`` names the other end in the messages ("the device",
    "the chip"); ``last`` is [k, y, k shown, e, u] of the last sample logged.
    """

    def __init__(self, link: SerialLink, limits: SafetyLimits, log: _LogWriter,
                 summary: RunSummary, status: Callable[[dict], None] | None,
                 t: Sequence[float], n: int, source: str) -> None:
        self.link, self.limits, self.log, self.summary = link, limits, log, summary
        self.status, self.t, self.n, self.source = status, t, n, source
        self.acc: dict[str, list[float]] = {"e": [], "u": []}  # of the samples received
        self.periods: list[float] = []
        self.last: list[Any] = [-1, math.nan, -1, math.nan, math.nan]
        self.y_prev = math.nan
        self.t_start = time.perf_counter()
        self.t_last_rx = self.t_start
        self.next_status = self.t_start
        self._t_us_last, self._wraps = 0, 0

    def receive(self, timeout: float, k_next: int, hint: str = "") -> tuple[list[P.Frame], float]:
        """The frames that came in within ``timeout`` [s], and when; the watchdog stops the run."""
        frames = self.link.receive(timeout)
        now = time.perf_counter()
        if not frames and now - self.t_last_rx > self.limits.watchdog:
            raise _Stop(f"watchdog: no sample from {self.source} for "
                        f"{(now - self.t_last_rx) * 1e3:.0f} ms at sample {k_next}{hint}")
        return frames, now

    def reports(self, frame: P.Frame, k_next: int, watchdog: str, at: str) -> None:
        """Stop on the device's FAULT (``at`` formats its detail) or an unexpected STOPPED."""
        kind = frame.kind
        if kind == P.FAULT:
            code, detail = frame.fields()
            name = _fault_name(code, watchdog)
            raise _Stop(f"{self.source} reported a fault: {name}{at.format(detail)}")
        if kind == P.STOPPED:
            raise _Stop(f"{self.source} stopped unexpectedly at sample {k_next}")

    def arrived(self, now: float, t_us: int) -> float:
        """A sample arrived at host time ``now``: the watchdog fed, the device time [s]."""
        self.t_last_rx = now
        if t_us < self._t_us_last:
            self._wraps += 1
        self._t_us_last = t_us
        return (t_us + self._wraps * 4294967296) * 1e-6

    def measurement(self, y: float, e: float, k: int, span: str) -> None:
        """Stop on an encoder jump (``span``: since which sample), the angle or following error."""
        limits = self.limits
        if abs(y - self.y_prev) > limits.max_jump:
            raise _Stop(f"encoder jump: θ changed by {y - self.y_prev:.4g} rad {span} "
                        f"at sample {k} (limit {limits.max_jump:g} rad)")
        if abs(y) > limits.angle_limit:
            raise _Stop(f"angle limit: measured θ = {y:.4g} rad at sample {k} "
                        f"(limit ±{limits.angle_limit:g} rad)")
        if abs(e) > limits.max_error:
            raise _Stop(f"following error: θ − θd = {e:.4g} rad at "
                        f"sample {k} (limit {limits.max_error:g} rad)")

    def logged(self, k: int, y: float, e: float, u: float, now: float) -> None:
        """Sample k was logged: its error and u kept, the live status ten times a second."""
        self.acc["e"].append(e)
        self.acc["u"].append(u)
        self.y_prev = y
        last = self.last
        last[0], last[1], last[3], last[4] = k, y, e, u
        if self.status is not None and now >= self.next_status:
            self.next_status = now + 0.1
            last[2] = k
            self.status({"t": self.t[k], "theta": y, "error": e, "u": u,
                         "deadline_misses": self.summary.deadline_misses, "k": k, "n": self.n})


def _supervised(link: SerialLink, sup: _Supervisor,
                loop: Callable[[_SigintFlag], None]) -> tuple[str | None, bool]:
    """Run ``loop`` under Ctrl-C as a flag; whatever ends it, STOP is sent and the log closed.

    Returns the message that ended the run early (None: it ran to the end) and whether
    it was Ctrl-C.
    """
    error_message, interrupted = None, False
    with _SigintFlag() as sigint:
        try:
            loop(sigint)
        except _Stop as exc:
            error_message, interrupted = str(exc), exc.interrupted
        except LinkError as exc:
            error_message = str(exc)
        finally:
            link.stop()
            sup.summary.stop_acknowledged = _wait_stopped(link, 0.5)
            sup.log.close()
    return error_message, interrupted


def _conclude(sup: _Supervisor, latencies: list[float], ts: float, log_path: Path | None,
              ended: tuple[str | None, bool], whose_watchdog: str) -> RunSummary:
    """The final status, the summary's metrics, and RigFault / RigInterrupted for an early end."""
    summary = sup.summary
    k_last, y_last, k_shown, e_last, u_last = sup.last
    if sup.status is not None and k_last > k_shown:
        # the status is rate-limited (10/s): once more with the last sample logged, after
        # STOP went out, so that a display ends where the log ends
        sup.status({"t": sup.t[k_last], "theta": y_last, "error": e_last, "u": u_last,
                    "deadline_misses": summary.deadline_misses, "k": k_last, "n": sup.n})
    _finish(summary, sup.acc, sup.periods, latencies, sup.log.rows, sup.link, ts)
    error_message, interrupted = ended
    if error_message is not None:
        kept = f"; {sup.log.rows} rows in {log_path}" if log_path else ""
        off = "stop sent, motor off" if summary.stop_acknowledged else \
            f"stop sent (not acknowledged; {whose_watchdog} turns the motor off)"
        text = f"{error_message}: {off}{kept}"
        if interrupted:
            raise RigInterrupted(text, summary)
        raise RigFault(text, summary)
    return summary


def run_rig(scn: Scenario, link: SerialLink, log_path: Path | None = None,
            limits: SafetyLimits | None = None,
            status: Callable[[dict], None] | None = None,
            controller: SampleController | None = None,
            monitor: Callable[[str], None] | None = None, onboard: bool = False,
            notice: Callable[[str], None] | None = None) -> RunSummary:
    """Drive the device on ``link`` through one run of ``scn``.

    The steps: the handshake and the device checked against the scenario
    (:func:`_check_mode`, :func:`check_device`, :func:`_drive_of`), then the loop under
    supervision (:func:`_loop`, or on board :func:`_run_onboard`), then the summary.

    Parameters
    ----------
    scn : Scenario
        Scenario (rate, duration, controller, reference, optional motor).
    link : SerialLink
        An open link (handshake not yet done).
    log_path : Path, optional
        CSV log (:data:`LOG_COLUMNS`), streamed and flushed per row.
    limits : SafetyLimits, optional
        Host safety limits.
    status : callable, optional
        Called about ten times a second with a dict (t, theta, error, u,
        deadline_misses, k, n) for a live display, and once more when the run
        ends (after STOP) with the last sample logged.
    controller : optional
        What computes u_k from y_k (``step``, ``commit``, ``predict``, ``zhat``,
        ``reference``, ``t``, ``n_samples``, ``ts``, ``torque_limit``); default the
        scenario's ESO + FLC.  The identification experiment passes its
        :class:`~esoarm.studies.identification.experiment.excitation.ExcitationController`.
    monitor : callable, optional
        Receives every log row (the CSV line of :data:`LOG_COLUMNS`) as it is
        written, e.g. :meth:`esoarm.hardware.scope.Scope.push`; it must not block.
    onboard : bool
        On-board mode (see the module docstring): the device runs the controller, the
        host supervises and logs the chip's samples.
    notice : callable, optional
        Receives one-line notices before the run starts (on board: what the chip
        streams, and whether it is every sample).

    Returns
    -------
    RunSummary

    Raises
    ------
    ScenarioError
        The device does not match the scenario (rate, resolution, protocol).
    RigFault, RigInterrupted
        The run ended early; STOP was sent and the log keeps every row.
    LinkError
        No device answered the handshake.
    """
    limits = limits or SafetyLimits()
    info = link.handshake()
    _check_mode(info, onboard, link)
    q = check_device(info, scn)
    if onboard:
        return _run_onboard(scn, link, info, q, log_path, limits, status, monitor, notice)
    motor = _drive_of(scn, info)
    ctl = controller if controller is not None else DeploymentController(scn)
    n, ts = ctl.n_samples, ctl.ts
    log = _LogWriter(log_path, tee=monitor)
    summary = RunSummary(mode="lockstep" if info.lockstep else "real time",
                         log=str(log_path) if log_path else "")
    sup = _Supervisor(link, limits, log, summary, status, ctl.t, n, "the device")
    latencies: list[float] = []
    ended = _supervised(link, sup, lambda sigint: _loop(
        scn, sup, ctl, q, motor, latencies, sigint, n, ts, info.lockstep))
    return _conclude(sup, latencies, ts, log_path, ended, "the device watchdog")


def _check_mode(info: P.Info, onboard: bool, link: SerialLink) -> None:
    """The device runs a controller of its own exactly when the run is on board."""
    if info.onboard and not onboard:
        raise ScenarioError(
            f"the device on '{link.port}' runs its own controller (firmware built with "
            "ONBOARD=DIR): add --onboard, or flash the firmware without ONBOARD")
    if onboard and not info.onboard:
        raise ScenarioError(
            f"--onboard: the device on '{link.port}' runs no controller of its own; build the "
            "firmware with the scenario's controller (make -C firmware ONBOARD=DIR, or "
            "'esoarm hil SCENARIO --onboard')")


def _drive_of(scn: Scenario, info: P.Info) -> MotorParams | None:
    """The scenario's motor when the device takes PWM duties; None for a torque device.

    Raises :class:`ScenarioError` where the scenario's ``[motor]`` and the device disagree.
    """
    motor = motor_of(scn)
    use_torque = info.accepts_torque and motor is None
    if not use_torque and motor is None:
        raise ScenarioError(
            "the device takes PWM duties, not torques: add a [motor] table to the scenario "
            "(supply_voltage, resistance, torque_constant, gear_ratio, pwm_max, deadband)")
    if motor is not None and info.accepts_torque:
        raise ScenarioError(
            "the scenario has a [motor] table but the device is an ideal torque source "
            "(an emulator started without [motor]): give both the same scenario")
    if motor is not None and motor.pwm_max != info.pwm_max:
        raise ScenarioError(
            f"motor.pwm_max = {motor.pwm_max} does not match the device's PWM range "
            f"±{info.pwm_max}")
    return motor


def _chip_check(scn: Scenario, link: SerialLink, info: P.Info) -> P.ChipInfo:
    """CHIP_INFO of an on-board device, checked against ``scn`` (ScenarioError if not it)."""
    from esoarm.codegen.generate import scenario_hash  # codegen sits beside hardware

    chip = link.chip_info()
    mine = scenario_hash(scn)[:8]
    if chip.scenario_hash != mine:
        raise ScenarioError(
            f"the chip on '{link.port}' runs the controller generated from another scenario "
            f"(hash {chip.scenario_hash}, this one {mine}): rebuild it from the same scenario "
            "and --set values ('esoarm hil SCENARIO --onboard', or 'esoarm codegen SCENARIO "
            "--target avr --out DIR' and make -C firmware ONBOARD=DIR)")
    if (motor_of(scn) is None) != info.accepts_torque:
        raise ScenarioError(
            "--onboard: the scenario needs a [motor] table (the chip drives PWM duties)"
            if motor_of(scn) is None else "--onboard: the chip drives an ideal torque source "
            "but the scenario has a [motor] table: give both the same scenario")
    if chip.stream_every < 1:
        raise LinkError(f"the chip on '{link.port}' reports stream_every = 0")
    return chip


def stream_notice(scn: Scenario, chip: P.ChipInfo) -> str:
    """One line: what an on-board run logs, and whether it is every sample.

    Parameters
    ----------
    scn : Scenario
        The scenario run.
    chip : ChipInfo
        The chip's CHIP_INFO (its scenario hash, observer sums and ``stream_every``).

    Returns
    -------
    str
    """
    rate = scn.sensor.rate_hz
    what = (f"the chip's samples (y, u, z1..z3, duty; float32 {chip.sums_name} observer sums, "
            f"scenario '{scn.name}' hash {chip.scenario_hash})")
    if chip.stream_every == 1:
        return f"on board: logging {what}, every sample ({rate:g} Hz)"
    return (f"on board: logging {what}, DECIMATED: every {chip.stream_every}th sample "
            f"({rate / chip.stream_every:g} Hz of {rate:g} Hz) -- as built (the link's baud "
            "cannot carry a frame per sample, or the firmware's STREAM_EVERY saves the chip "
            "the frames); the chip still controls at every sample")


def _run_onboard(scn: Scenario, link: SerialLink, info: P.Info, q: float,  # noqa: PLR0913
                 log_path: Path | None, limits: SafetyLimits,
                 status: Callable[[dict], None] | None, monitor: Callable[[str], None] | None,
                 notice: Callable[[str], None] | None) -> RunSummary:
    """:func:`run_rig` on board: supervise the chip's controller and log what it streams."""
    chip = _chip_check(scn, link, info)
    line = stream_notice(scn, chip)
    if notice is not None:
        notice(line)
    ctl = DeploymentController(scn)  # its reference and time grid only: no control law here
    n, ts = ctl.n_samples, ctl.ts
    log = _LogWriter(log_path, tee=monitor, preamble=line)
    summary = RunSummary(mode="on board", log=str(log_path) if log_path else "", onboard=True,
                         stream_every=chip.stream_every, observer_sums=chip.sums_name)
    sup = _Supervisor(link, limits, log, summary, status, ctl.t, n, "the chip")
    ended = _supervised(link, sup, lambda sigint: _loop_onboard(
        sup, ctl, q, chip.stream_every, sigint, n, ts, info.accepts_torque))
    return _conclude(sup, [], ts, log_path, ended, "the chip's watchdog")


def _loop_onboard(sup: _Supervisor, ctl: DeploymentController, q: float, every: int,
                  sigint: _SigintFlag, n: int, ts: float, torque: bool = False) -> None:
    """Supervise the chip: heartbeats out, each streamed CHIP_SAMPLE checked and logged."""
    fmt = repr
    isfinite = math.isfinite
    link, log, summary = sup.link, sup.log, sup.summary
    limit = ctl.torque_limit * (1 + 1e-6)  # the chip saturates in float32
    k_next = 0
    # Heartbeats follow the chip's samples, not the wall clock: a chip that streams nothing
    # gets none (its watchdog then stops the motor), and a simulated chip slower than real
    # time is not flooded (each frame costs it ~1k cycles to take in).
    beat_samples = max(1, round(HEARTBEAT_S / ts))
    k_beat = 0
    t_dev_prev = math.nan
    link.send(P.START)
    while k_next < n:
        if sigint.hit:
            raise _Stop(f"interrupted at sample {k_next}", interrupted=True)
        if k_next >= k_beat:  # the chip's watchdog, every HEARTBEAT_S of the chip's time
            link.send(P.HEARTBEAT, max(k_next - every, 0))
            k_beat = k_next + beat_samples
        frames, now = sup.receive(HEARTBEAT_S / 2, k_next, " (link lost?)")
        for frame in frames:
            sup.reports(frame, k_next, "heartbeat watchdog", " at sample {}")
            if frame.kind != P.CHIP_SAMPLE:
                continue
            r = P.ChipSample.from_frame(frame)
            if r.k < k_next:
                continue  # stale
            t_dev = sup.arrived(now, r.t_us)
            while k_next < r.k and k_next < n:  # a frame lost on the link: a row of nan
                log.write(f"{fmt(ctl.t[k_next])},nan,{fmt(ctl.reference(k_next))},nan,nan,nan,"
                          f"nan,nan,{k_next},nan,nan,nan,0,nan,nan\n")
                summary.lost_samples += 1
                k_next += every
            if r.k >= n:
                k_next = r.k
                break
            k = r.k
            y = q * r.encoder_count
            ref = ctl.reference(k)
            e = y - ref
            # -- the supervisor: the chip controls, the host still watches
            sup.measurement(y, e, k, "between streamed samples")
            if not (isfinite(r.u) and isfinite(r.z1) and isfinite(r.z2) and isfinite(r.z3)):
                raise _Stop(f"NaN guard: the chip's control or estimate is not finite at "
                            f"sample {k}")
            if abs(r.u) > limit:
                raise _Stop(f"torque limit: the chip's u = {r.u:.4g} N·m at sample {k}")
            # the chip's sample clock: late by more than a period is an overrun
            late = 1 if t_dev - k * ts > ts else 0
            summary.deadline_misses += late
            if t_dev_prev == t_dev_prev:
                sup.periods.append((t_dev - t_dev_prev) / every)
            t_dev_prev = t_dev
            u = r.u
            log.write(f"{fmt(ctl.t[k])},{fmt(y)},{fmt(ref)},{fmt(e)},{fmt(u)},{fmt(r.z1)},"
                      f"{fmt(r.z2)},{fmt(r.z3)},{k},{fmt(t_dev)},{fmt(now - sup.t_start)},nan,"
                      f"{late},{'nan' if torque else r.duty},{fmt(y)}\n")
            sup.logged(k, y, e, u, now)
            k_next = k + every


def _wait_stopped(link: SerialLink, timeout: float) -> bool:
    deadline = time.perf_counter() + timeout
    try:
        while (left := deadline - time.perf_counter()) > 0:
            if any(f.kind == P.STOPPED for f in link.receive(left)):
                return True
    except LinkError:
        return False
    return False


def _loop(scn: Scenario, sup: _Supervisor, ctl: SampleController, q: float,
          motor: MotorParams | None, latencies: list[float], sigint: _SigintFlag, n: int,
          ts: float, lockstep: bool) -> None:
    """The host's control law per sample: measure, check, command, send, log, update."""
    fmt = repr
    isfinite = math.isfinite
    perf = time.perf_counter
    link, log, summary = sup.link, sup.log, sup.summary
    limit = ctl.torque_limit
    act = actuator_vector(scn)
    k_next = 0
    u_last = 0.0
    offset = math.inf
    t_prev_rx = math.nan
    link.send(P.START)
    while k_next < n:
        if sigint.hit:
            raise _Stop(f"interrupted at sample {k_next}", interrupted=True)
        frames, now = sup.receive(0.05, k_next)
        for frame in frames:
            sup.reports(frame, k_next, "command watchdog", " (detail {})")
            if frame.kind != P.SAMPLE:
                continue
            k_dev, t_us, count = frame.fields()
            if k_dev < k_next:
                continue  # stale
            t_dev = sup.arrived(now, t_us)
            offset = min(offset, now - t_dev)
            if t_prev_rx == t_prev_rx:
                sup.periods.append(now - t_prev_rx)
            t_prev_rx = now
            while k_next < k_dev and k_next < n:  # lost samples: observer prediction
                z1, z2, z3 = ctl.predict(u_last)
                log.write(f"{fmt(ctl.t[k_next])},nan,{fmt(ctl.reference(k_next))},nan,"
                          f"{fmt(u_last)},{fmt(z1)},{fmt(z2)},{fmt(z3)},{k_next},nan,nan,nan,0,"
                          f"nan,nan\n")
                summary.lost_samples += 1
                k_next += 1
            if k_next >= n:
                break
            k = k_next
            y = q * count
            ref = ctl.reference(k)
            e = y - ref
            sup.measurement(y, e, k, "in one sample")  # -- safety on the measurement
            u = ctl.step(k, y)
            z1, z2, z3 = ctl.zhat
            if not (isfinite(u) and isfinite(z1) and isfinite(z2) and isfinite(z3)):
                raise _Stop(f"NaN guard: non-finite control or estimate at sample {k}")
            if abs(u) > limit:  # the FLC saturates; a violation is a bug: stop
                raise _Stop(f"torque limit: u = {u:.4g} N·m at sample {k}")
            # the actuator of every engine: with a motor, the duty and the torque it gives;
            # a learned table (controller.feedforward_map) in the drive, not in u_applied
            u_host, drive, d = actuate_with_table(u, z2, z1, act)
            u_applied = float(u_host)
            if motor is None:  # the torque the drive applies (rounded with actuator.pwm_bits)
                link.send(P.TORQUE, k, float(drive))
                duty = "nan"
            else:
                link.send(P.DUTY, k, int(d))
                duty = str(int(d))
            t_sent = perf()
            ctl.commit(u_applied)
            latency = t_sent - now
            late = 0 if lockstep or t_sent <= t_dev + offset + ts else 1
            summary.deadline_misses += late
            latencies.append(latency)
            log.write(f"{fmt(ctl.t[k])},{fmt(y)},{fmt(ref)},{fmt(e)},{fmt(u_applied)},"
                      f"{fmt(z1)},{fmt(z2)},{fmt(z3)},{k},{fmt(t_dev)},{fmt(now - sup.t_start)},"
                      f"{fmt(latency)},{late},{duty},{fmt(y)}\n")
            sup.logged(k, y, e, u_applied, now)
            u_last = u_applied
            k_next = k + 1


def _finish(summary: RunSummary, acc: dict[str, list[float]], periods: list[float],
            latencies: list[float], rows: int, link: SerialLink, ts: float) -> None:
    summary.samples = rows
    if acc["e"]:
        m = series_metrics(np.array(acc["e"]), np.array(acc["u"]))
        summary.rms_error = m["rms_error"]
        summary.rms_u = m["rms_u"]
        summary.rms_du = m["rms_du"]
        summary.max_abs_error = m["max_abs_error"]
    if periods and summary.mode != "lockstep":  # lockstep has no period to jitter around
        jit = np.abs(np.asarray(periods) - ts) * 1e6
        summary.jitter_p50_us = float(np.percentile(jit, 50))
        summary.jitter_p99_us = float(np.percentile(jit, 99))
    if latencies:
        lat = np.asarray(latencies) * 1e6
        summary.latency_p50_us = float(np.percentile(lat, 50))
        summary.latency_p99_us = float(np.percentile(lat, 99))
    summary.bad_frames = link.parser.bad_frames
    summary.lost_frames = link.rx_lost
