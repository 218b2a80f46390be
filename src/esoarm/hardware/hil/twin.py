"""The arm behind the pins: the twin's physics, an encoder disc and a motor driver.

:class:`PinTwin` advances the digital twin one RK4 step of ``rig.step`` at a
time with the plant step every engine uses (the scenario's plant kind:
``design`` and ``advance``, :mod:`esoarm.plants.lever_arm`, whose design adds
the motor's back-EMF damping) driven by the motor's torque
(:func:`esoarm.plants.motor.source_torque`); nothing of the physics is written
again here.  What it adds is the geometry of the sensor and
the timing of the pins:

- Encoder: position p = floor(θ/q + 1/2) in counts (q = 360°/counts per rev,
  the same rounding as the simulator's quantizer), output as the quadrature
  Gray code AB = 00, 01, 11, 10 for p = 0, 1, 2, 3 (mod 4); counting up means θ
  increasing.  Within a step θ is interpolated linearly between the RK4 end
  points, and each edge is placed at the cycle where θ crosses (p ± 1/2)·q.
- Motor: the duty on the driver pins is read at the start of each step and held
  over it (a duty change reaches the arm at most one step late).

Before the first START reaches the UART the arm is held at rest at
``rig.theta0``; START puts it back there and starts the twin's clock (t = 0),
as the emulator does.
"""

from __future__ import annotations

import math

import numpy as np

from esoarm.kinds import kinds_of
from esoarm.plants.actuator import motor_of
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["GRAY", "PinTwin"]

#: quadrature levels AB (bit 1 = A, bit 0 = B) for position p mod 4
GRAY = (0b00, 0b01, 0b11, 0b10)


class PinTwin:
    """The digital twin of ``scn`` seen through encoder and driver pins.

    Parameters
    ----------
    scn : Scenario
        Needs a ``[motor]`` table (the firmware drives a PWM duty) and a
        ``sensor.resolution_deg`` that divides 360° (the encoder's counts).
    f_cpu : int
        CPU clock [Hz]: edges are placed on this cycle grid.
    """

    def __init__(self, scn: Scenario, f_cpu: int) -> None:
        motor = motor_of(scn)
        if motor is None:
            raise ScenarioError(
                "the firmware drives a PWM duty: the scenario needs a [motor] table "
                "(see 'esoarm show uno-rig')")
        res = scn.sensor.resolution_deg
        cpr = round(360.0 / res) if res > 0 else 0
        if cpr < 4 or abs(cpr * res - 360.0) > 1e-9 * 360.0:
            raise ScenarioError(
                f"sensor.resolution_deg = {res:g}: must be 360° divided by the encoder's "
                "counts per revolution (0.15 for 600 pulses/rev decoded x4)")
        for key, value, off in (("sensor.noise_ar", scn.sensor.noise_ar, []),
                                ("sensor.vibration_deg", scn.sensor.vibration_deg, 0.0)):
            if value != off:
                raise ScenarioError(
                    f"key '{key}': the hil engine does not model coloured noise or vibration "
                    "(its encoder pins count the true angle); remove it or use 'esoarm "
                    "emulate', whose twin applies it")
        self.motor = motor
        self.plant = kinds_of(scn).plant
        self.design = self.plant.design(scn)
        if self.design.n_joints != 1:
            raise ScenarioError(
                f"plant.kind = '{scn.plant.kind}' has {self.design.n_joints} joints: the Uno "
                "firmware reads one encoder and drives one motor")
        self.h = scn.rig.step
        self.q = math.radians(res)
        self.counts_per_rev = cpr
        self.f_cpu = f_cpu
        self.step_cycles = round(self.h * f_cpu)
        self.running = False
        self.steps = 0
        self.x = np.array(self.design.x0)  # (θ, θ̇, τ)
        self._u = np.zeros(1)
        self.position = self._count(self.theta)
        self.start_position = self.position
        self._phase_offset = 0
        self.duty = 0
        self.torque = 0.0
        self.ignore_motor = False  # driver fault: the pins no longer reach the motor

    @property
    def theta(self) -> float:
        """Arm angle θ [rad]."""
        return float(self.x[0])

    @property
    def omega(self) -> float:
        """Arm rate θ̇ [rad/s]."""
        return float(self.x[1])

    @property
    def t(self) -> float:
        """Twin time since START [s] (whole steps of h)."""
        return self.steps * self.h

    def _count(self, theta: float) -> int:
        return math.floor(theta / self.q + 0.5)

    @property
    def levels(self) -> int:
        """Current encoder levels AB."""
        return GRAY[(self.position + self._phase_offset) % 4]

    def start(self) -> None:
        """START reached the device: the arm at rest at theta0, the clock at t = 0.

        The encoder lines keep their levels (the arm is set back, not swept back).
        """
        old = self.levels
        self.steps = 0
        self.x = np.array(self.design.x0)
        self.position = self._count(self.theta)
        self.start_position = self.position
        self._phase_offset = GRAY.index(old) - self.position % 4
        self.running = True

    def step(self, duty: int, cycle0: int) -> tuple[np.ndarray, np.ndarray]:
        """Advance one step h with ``duty`` held; return the encoder edges in it.

        Parameters
        ----------
        duty : int
            Signed duty counts on the driver pins at the start of the step.
        cycle0 : int
            CPU cycle at which the step starts.

        Returns
        -------
        cycles, levels : ndarray
            Cycle of each encoder edge in [cycle0, cycle0 + step_cycles) and the
            AB levels from then on.
        """
        self.duty = 0 if self.ignore_motor else duty
        if not self.running:
            return _NO_CYCLES, _NO_LEVELS
        self.torque = self.motor.source_torque(self.duty)
        theta0 = self.theta
        self._u[0] = self.torque
        self.plant.advance(self.x, self._u, self.t, self.h, 1, self.design.vector)
        self.steps += 1
        theta1 = self.theta
        p0, p1 = self.position, self._count(theta1)
        if p1 == p0:
            return _NO_CYCLES, _NO_LEVELS
        direction = 1 if p1 > p0 else -1
        n = abs(p1 - p0)
        positions = p0 + direction * np.arange(1, n + 1)
        crossings = (positions - 0.5 * direction) * self.q  # θ where the count changes
        frac = (crossings - theta0) / (theta1 - theta0)
        cycles = cycle0 + np.minimum(np.floor(frac * self.step_cycles),
                                     self.step_cycles - 1).astype(np.uint64)
        gray = np.asarray(GRAY, dtype=np.uint8)
        levels = gray[(positions + self._phase_offset) % 4]
        self.position = p1
        return cycles, levels


_NO_CYCLES = np.zeros(0, dtype=np.uint64)
_NO_LEVELS = np.zeros(0, dtype=np.uint8)
