"""The digital twin as a serial device behind a pseudo-terminal (``esoarm emulate``).

The emulator speaks the protocol of :mod:`esoarm.hardware.protocol` exactly as
the firmware does, so the host loop cannot tell it from a rig.  Its physics is
the simulators': the plant kind's design and ``advance``, with the actuator's
transport delay (:func:`esoarm.plants.actuator.delayed_input`) and, with a
``[motor]`` table, the motor's torque (:func:`esoarm.plants.motor.source_torque`),
and the measurement leaves the device as an encoder count

    count_k = floor((θ(t_k) + σ n_k)/q + 1/2),   q = radians(resolution_deg)

so that the host's q·count_k is exactly ``quantize(θ + σ n_k, q)`` of
:mod:`esoarm.plants.sensor`; the noise n_k is drawn on the device side exactly as
:func:`esoarm.plants.sensor.noise_sequence` (one ``default_rng(seed)`` stream), and a
coloured noise model (AR encoder noise, arm vibration) exactly as
:func:`esoarm.plants.noise.draws` (σ n_k is then w_k with σ = 1).

Timing.  ``lockstep``: sample k+1 is integrated and sent when the command
answering sample k arrives, so a run over the link commands the same u
sequence as ``esoarm simulate``.  Real time: samples are sent every Ts of the
wall clock; the interval [t_k, t_{k+1}) is integrated at the tick t_{k+1} with
the newest command received by then (the host's latency inside the sample is
neglected; a command later than the next tick acts one sample late).  A
100 ms device watchdog zeroes the motor when no valid command arrives
(real time only: in lockstep the twin's time does not pass while it waits).

Faults (``KIND@SECONDS``, twin time): ``drop`` every outgoing frame is lost;
``corrupt`` every outgoing frame has a flipped byte; ``stall`` the device stops
reading and writing; ``disconnect`` the pseudo-terminal is closed; ``glitch``
the encoder count jumps by half a revolution.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from esoarm.engines.sample import Sampling, advance_plant, hold, new_work
from esoarm.hardware import protocol as P
from esoarm.hardware.device import PtyDevice, TimedFault, due_faults, parse_timed_fault
from esoarm.kinds import kinds_of
from esoarm.plants.actuator import motor_of
from esoarm.plants.noise import NoiseModel, noise_model, sequence_scale
from esoarm.plants.noise import NoiseStream as ColouredStream
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["FAULT_KINDS", "Emulator", "FaultSpec", "NoiseStream", "Twin", "parse_fault",
           "encoder_counts_per_rev"]

FAULT_KINDS = ("drop", "corrupt", "stall", "disconnect", "glitch")
#: device-side command watchdog [s] (as in the firmware)
DEVICE_WATCHDOG = 0.1
#: PWM range the emulator reports without a [motor] table (duty maps to ±torque_limit)
NOMINAL_PWM_MAX = 255


#: A fault to inject: ``kind`` from :data:`FAULT_KINDS` at twin time ``at`` [s].
FaultSpec = TimedFault


def parse_fault(text: str) -> FaultSpec:
    """Parse ``KIND@SECONDS``; raises :class:`ScenarioError` with one line."""
    return parse_timed_fault(text, FAULT_KINDS)


def encoder_counts_per_rev(scn: Scenario) -> int:
    """Counts per revolution of the emulated encoder, 360° / resolution_deg.

    Raises :class:`ScenarioError` unless the resolution divides 360° into a
    whole number of counts (an encoder cannot do otherwise).
    """
    res = scn.sensor.resolution_deg
    if res <= 0:
        raise ScenarioError(
            "sensor.resolution_deg = 0: the emulated device reports encoder counts, "
            "so it needs a resolution > 0 that divides 360°"
        )
    cpr = round(360.0 / res)
    if cpr < 1 or cpr > 2**31 - 1 or abs(cpr * res - 360.0) > 1e-9 * 360.0:
        raise ScenarioError(
            f"sensor.resolution_deg = {res:g}: must divide 360° into a whole number of "
            "encoder counts (e.g. 0.05 = 7200 counts/rev, 0.15 = 2400)"
        )
    return cpr


class NoiseStream:
    """n_0, n_1, … of the sensor noise drawn in blocks (:class:`esoarm.plants.noise.NoiseStream`).

    White noise: ``default_rng(seed).standard_normal``, whose first N values equal
    :func:`esoarm.plants.sensor.noise_sequence` (seed, N) (tested); with a coloured model
    (``model``, :func:`esoarm.plants.noise.noise_model`) the disturbance w_k [rad] of
    :func:`esoarm.plants.noise.draws`.  The stream continues past N if a host runs longer.

    Parameters
    ----------
    seed : int
        The sensor's seed.
    noise_deg : float
        Noise standard deviation [deg] (0 and no model: zeros).
    block : int
        Draws per call of the generator.
    model : NoiseModel, optional
        The measurement disturbance; default white noise of ``noise_deg``.
    """

    __slots__ = ("_stream",)

    def __init__(self, seed: int, noise_deg: float, block: int = 4096,
                 model: NoiseModel | None = None) -> None:
        if model is None:
            model = NoiseModel(math.radians(noise_deg), (), 0.0, 1.0, 0.5, 1.0)
        self._stream = ColouredStream(model, seed, 1, block)

    def next(self) -> float:
        """The next value (0.0 without noise).

        Returns
        -------
        float
            A standard-normal draw (white model, scaled by σ by the caller) or w_k [rad].
        """
        return self._stream.next()


class Twin:
    """Device-side state of the emulated rig: arm, actuator, encoder, motor.

    Parameters
    ----------
    scn : Scenario
        Rig, sensor, actuator and (optional) motor.
    """

    def __init__(self, scn: Scenario) -> None:
        self.scn = scn
        self.motor = motor_of(scn)
        self.plant = kinds_of(scn).plant
        self.design = self.plant.design(scn)
        self.ts = scn.sample_time
        self.h = scn.rig.step
        self.nsub = scn.substeps
        self.delay = scn.actuator.delay_samples
        self.q = math.radians(scn.sensor.resolution_deg)
        self.noise_model = noise_model(scn)
        self.sigma = sequence_scale(self.noise_model)
        self.sampling = Sampling(scn.n_samples, self.ts, self.h, self.nsub, self.delay,
                                 self.sigma, self.q)
        self.counts_per_rev = encoder_counts_per_rev(scn)
        self.pwm_max = self.motor.pwm_max if self.motor else NOMINAL_PWM_MAX
        self.reset()

    def reset(self) -> None:
        """Back to the initial state θ(0) = theta0, at rest, k = 0."""
        self.k = 0
        self.x = np.array(self.design.x0)
        self.noise = NoiseStream(self.scn.sensor.seed, self.scn.sensor.noise_deg,
                                 model=self.noise_model)
        self.work = new_work(self.scn.n_samples, 1, 0, 0)  # the plant half's arrays
        self.work.applied[0] = 0.0
        self.glitch_offset = 0
        self.motor_on = True

    @property
    def theta(self) -> float:
        """True angle θ(t_k) [rad]."""
        return float(self.x[0])

    @property
    def time(self) -> float:
        """Twin time t_k = k·Ts [s]."""
        return self.k * self.ts

    def count(self) -> int:
        """Encoder count for sample k (draws n_k): floor((θ + σ n_k)/q + 1/2)."""
        x = self.theta + self.sigma * self.noise.next()
        return math.floor(x / self.q + 0.5) + self.glitch_offset

    def torque_of_duty(self, duty: int) -> float:
        """Rate-independent torque [N·m] of a duty (see :mod:`esoarm.plants.motor`)."""
        if self.motor is not None:
            return self.motor.source_torque(duty)
        return self.scn.actuator.torque_limit * max(-1.0, min(1.0, duty / self.pwm_max))

    def advance(self, u: float) -> None:
        """Hold the drive torque u [N·m] over [t_k, t_{k+1}) (after the transport delay).

        The plant half of every engine's sample (:mod:`esoarm.engines.sample`):
        :func:`~esoarm.engines.sample.hold` (the transport delay), then
        :func:`~esoarm.engines.sample.advance_plant` (the plant kind's ``advance``).
        """
        if not self.motor_on or not math.isfinite(u):
            u = 0.0
        k = self.k
        w = self.work
        if k >= len(w.hist):  # a host running past N samples
            w = self.work = w._replace(hist=np.concatenate([w.hist, np.zeros(len(w.hist))]))
        w.drive[0] = u
        hold(w, k, self.delay)
        advance_plant(self.x, w, k, self.sampling, self.design.vector, self.plant.advance)
        self.k = k + 1


class Emulator:
    """The twin behind a new pseudo-terminal, speaking the rig protocol.

    Parameters
    ----------
    scn : Scenario
        The emulated rig.
    lockstep : bool
        One sample per command received (bit-exact against the simulator).
    faults : list of FaultSpec
        Faults to inject.
    once : bool
        Return from :meth:`serve` after the first STOP.
    echo : callable
        Receives one-line status messages (``print`` by default).
    """

    def __init__(self, scn: Scenario, *, lockstep: bool = False,
                 faults: list[FaultSpec] | tuple[FaultSpec, ...] = (), once: bool = False,
                 echo: Callable[[str], None] = print) -> None:
        self.twin = Twin(scn)
        self.lockstep = lockstep
        self.faults = sorted(faults, key=lambda f: f.at)
        self.once = once
        self.echo = echo
        self.port = PtyDevice()
        self.path = self.port.path
        self.parser = P.Parser()
        self.seq = 0
        self.period_us = round(1e6 * self.twin.ts)
        self.flags = (P.FLAG_LOCKSTEP if lockstep else 0) | (
            P.FLAG_TORQUE if self.twin.motor is None else 0)
        self.running = False
        self.active: set[str] = set()
        self.frames_lost = 0  # output buffer full (nobody reading)
        self.bad_commands = 0
        self._u = 0.0
        self._u_k = -1  # sample index of the newest command (real time)
        self.held_commands = 0  # samples that ran on an older command (it came too late)
        self._last_cmd = 0.0
        self._t0 = 0.0
        self._watchdog_tripped = False
        self._next_tick = 0.0
        #: optional sink for each sample sent: (t, θ true, θ encoder, θ̇, u applied) (live scope)
        self.monitor: Callable[[tuple[float, ...]], None] | None = None

    # -- output --------------------------------------------------------------
    def _send(self, kind: int, *fields: int | float) -> None:
        if "drop" in self.active or self.closed:
            return
        frame = P.encode(kind, self.seq, *fields)
        self.seq = (self.seq + 1) & 0xFF
        if "corrupt" in self.active:
            b = bytearray(frame)
            b[P.HEADER_SIZE] ^= 0xFF  # first payload byte: the CRC no longer matches
            frame = bytes(b)
        if not self.port.write(frame):
            self.frames_lost += 1

    def _send_sample(self) -> None:
        self._apply_faults()
        if self.closed or "stall" in self.active:
            return
        twin = self.twin
        if self.lockstep:
            t_us = round(twin.k * self.period_us)
        else:
            t_us = round((time.perf_counter() - self._t0) * 1e6)
        count = twin.count()
        self._send(P.SAMPLE, twin.k & 0xFFFFFFFF, t_us & 0xFFFFFFFF, count)
        if self.monitor is not None:
            self.monitor((twin.time, twin.theta, twin.q * count, float(twin.x[1]),
                          float(twin.work.applied[0])))

    def _apply_faults(self) -> None:
        t = self.twin.time
        for fault in due_faults(self.faults, t, self.echo):
            if fault.kind == "glitch":
                self.twin.glitch_offset += self.twin.counts_per_rev // 2
            elif fault.kind == "disconnect":
                self.close()
            else:
                self.active.add(fault.kind)

    # -- input ---------------------------------------------------------------
    def _handle(self, frame: P.Frame) -> None:
        kind = frame.kind
        if kind == P.HELLO:
            self._send(P.INFO, P.PROTOCOL_VERSION, self.flags, self.twin.counts_per_rev,
                       self.twin.pwm_max, self.period_us)
        elif kind == P.START:
            self.twin.reset()
            self.running = True
            self._watchdog_tripped = False
            self._t0 = self._last_cmd = time.perf_counter()
            self._next_tick = self._t0 + self.twin.ts
            self._u = 0.0
            self._u_k, self.held_commands = -1, 0
            self.echo(f"start: {'lockstep' if self.lockstep else 'real time'}, "
                      f"Ts = {self.twin.ts:g} s")
            self._send_sample()
        elif kind in (P.TORQUE, P.DUTY):
            k, value = frame.fields()
            if kind == P.TORQUE and self.twin.motor is not None:
                self.bad_commands += 1
                self._send(P.FAULT, P.FAULT_BAD_COMMAND, k)
                return
            if kind == P.DUTY and abs(value) > self.twin.pwm_max:
                self.bad_commands += 1
                self._u = 0.0  # as the firmware: motor off
                self._send(P.FAULT, P.FAULT_BAD_COMMAND, k)
                return
            if not self.running or self._watchdog_tripped:
                return
            u = float(value) if kind == P.TORQUE else self.twin.torque_of_duty(value)
            self._last_cmd = time.perf_counter()
            if self.lockstep:
                if k != self.twin.k:
                    self.bad_commands += 1  # a stale or future sample: ignored
                    return
                self.twin.advance(u)
                self._send_sample()
            else:
                self._u, self._u_k = u, k
        elif kind == P.STOP:
            self.twin.motor_on = False
            was = self.running
            self.running = False
            self._u = 0.0
            late = "" if self.lockstep or not was else \
                f"; {self.held_commands} samples ran on an older command (theirs came late)"
            self.echo(f"stop received at t = {self.twin.time:.4g} s: motor off"
                      + ("" if was else " (was not running)") + late)
            self._send(P.STOPPED)
            if self.once:
                time.sleep(0.2)  # let the host read STOPPED before the port goes away
                self.close()

    def _tick(self) -> None:
        """Real time: integrate [t_k, t_{k+1}) with the newest command, send sample k+1."""
        now = time.perf_counter()
        if not self._watchdog_tripped and now - self._last_cmd > DEVICE_WATCHDOG:
            self._watchdog_tripped = True
            self.twin.motor_on = False
            self.echo(f"watchdog: no command for {DEVICE_WATCHDOG * 1e3:.0f} ms at "
                      f"t = {self.twin.time:.4g} s: motor off")
            self._send(P.FAULT, P.FAULT_WATCHDOG, self.twin.k)
        if self._u_k != self.twin.k:
            self.held_commands += 1
        self.twin.advance(self._u)
        self._send_sample()

    # -- main loop -----------------------------------------------------------
    def serve(self, until: Callable[[], bool] = lambda: False) -> None:
        """Serve the protocol until closed (fault, ``once``) or ``until()`` is true."""
        while not self.closed and not until():
            if "stall" in self.active:
                time.sleep(0.05)  # the device hangs: no reads, no writes
                continue
            timeout = 0.05
            if self.running and not self.lockstep:
                timeout = max(0.0, min(timeout, self._next_tick - time.perf_counter()))
            for frame in self.parser.feed(self.port.read(timeout)):
                self._handle(frame)
                if self.closed:
                    return
            if self.running and not self.lockstep and "stall" not in self.active:
                now = time.perf_counter()
                if now >= self._next_tick:
                    self._tick()
                    self._next_tick += self.twin.ts
                    if now - self._next_tick > 10 * self.twin.ts:  # far behind: resynchronise
                        self._next_tick = now + self.twin.ts

    @property
    def closed(self) -> bool:
        """True once the port went away (``disconnect`` fault, ``once``, :meth:`close`)."""
        return self.port.closed

    def close(self) -> None:
        """Close the pseudo-terminal (the port goes away)."""
        self.port.close()
