"""DC motor and driver: torque command <-> signed PWM duty (optional ``[motor]``).

Armature inductance neglected (electrical time constant ≪ Ts), N the gear
ratio, Kt the torque constant (= back-EMF constant in SI), R the winding
resistance, Vs the supply, ω the arm rate:

    i = (Vs·d − N·Kt·ω) / R,     τ_arm = N·Kt·i = (N·Kt·Vs/R)·d − ((N·Kt)²/R)·ω

so at the arm the motor is a torque source (N·Kt·Vs/R)·d plus a viscous
back-EMF damping (N·Kt)²/R.  The host inverts this with the estimated rate ẑ2
(:func:`torque_to_duty`); the emulator integrates the same law by adding the
damping to the rig's viscous friction (:func:`twin_rig_vector`).

The driver has a deadband δ (fraction of full duty): a duty fraction d' acts as
d = sign(d')·max(0, (|d'| − δ)/(1 − δ)); the host pre-compensates with
d' = sign(d)·(δ + (1 − δ)|d|) for d ≠ 0.  Duty counts are integers in
[−pwm_max, pwm_max]; ±pwm_max is full ±Vs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from esoarm.plants.lever_arm import VISC

__all__ = ["MotorParams", "twin_rig_vector"]


@dataclass(frozen=True)
class MotorParams:
    """Motor and driver constants (from a scenario's ``[motor]`` table).

    Attributes
    ----------
    supply_voltage : float
        Vs [V].
    resistance : float
        R [Ω].
    torque_constant : float
        Kt [N·m/A] (= back-EMF constant [V·s/rad]).
    gear_ratio : float
        N [1]; arm torque = N · motor torque, motor rate = N · arm rate.
    pwm_max : int
        Duty counts for full supply.
    deadband : float
        Driver deadband δ as a fraction of full duty [1].
    """

    supply_voltage: float
    resistance: float
    torque_constant: float
    gear_ratio: float
    pwm_max: int
    deadband: float

    @classmethod
    def from_scenario(cls, scn) -> MotorParams | None:  # type: ignore[no-untyped-def]
        """The scenario's motor, or None for an ideal torque source."""
        m = scn.motor
        if m is None:
            return None
        return cls(m.supply_voltage, m.resistance, m.torque_constant, m.gear_ratio,
                   m.pwm_max, m.deadband)

    @property
    def stall_gain(self) -> float:
        """Arm torque per unit duty fraction at rest, N·Kt·Vs/R [N·m]."""
        return self.gear_ratio * self.torque_constant * self.supply_voltage / self.resistance

    @property
    def damping(self) -> float:
        """Back-EMF damping at the arm, (N·Kt)²/R [N·m·s/rad]."""
        return (self.gear_ratio * self.torque_constant) ** 2 / self.resistance

    def torque_to_duty(self, torque: float, omega: float) -> int:
        """Duty counts that produce ``torque`` [N·m] at arm rate ``omega`` [rad/s].

        Saturates at ±pwm_max (full supply); includes the deadband
        pre-compensation.
        """
        frac = (torque + self.damping * omega) / self.stall_gain
        if not math.isfinite(frac):
            return 0
        if frac > 1.0:
            frac = 1.0
        elif frac < -1.0:
            frac = -1.0
        if frac != 0.0:
            db = self.deadband
            frac = math.copysign(db + (1.0 - db) * abs(frac), frac)
        return int(round(frac * self.pwm_max))

    def effective_fraction(self, duty: int) -> float:
        """Fraction of Vs the driver actually applies for ``duty`` counts."""
        frac = duty / self.pwm_max
        db = self.deadband
        mag = (abs(frac) - db) / (1.0 - db)
        if mag <= 0.0:
            return 0.0
        return math.copysign(min(mag, 1.0), frac)

    def duty_to_torque(self, duty: int, omega: float) -> float:
        """Arm torque [N·m] that ``duty`` gives at arm rate ``omega`` [rad/s]."""
        return self.stall_gain * self.effective_fraction(duty) - self.damping * omega

    def source_torque(self, duty: int) -> float:
        """The rate-independent part N·Kt·Vs·d/R [N·m] (the twin's applied torque)."""
        return self.stall_gain * self.effective_fraction(duty)


def twin_rig_vector(rig: np.ndarray, motor: MotorParams | None) -> np.ndarray:
    """Rig parameter vector with the motor's back-EMF damping added to viscous friction.

    With this vector, :func:`esoarm.plants.lever_arm.rig_advance` driven by
    :meth:`MotorParams.source_torque` integrates exactly the motor law of the
    module docstring.
    """
    if motor is None:
        return rig
    vec = np.array(rig, dtype=float)
    vec[VISC] += motor.damping
    vec.setflags(write=False)
    return vec
