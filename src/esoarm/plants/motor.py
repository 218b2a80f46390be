"""DC motor and driver: torque command <-> signed PWM duty (optional ``[motor]``).

Armature inductance neglected (electrical time constant ≪ Ts), N the gear
ratio, Kt the torque constant (= back-EMF constant in SI), R the winding
resistance, Vs the supply, ω the arm rate:

    i = (Vs·d − N·Kt·ω) / R,     τ_arm = N·Kt·i = (N·Kt·Vs/R)·d − ((N·Kt)²/R)·ω

so at the arm the motor is a torque source (N·Kt·Vs/R)·d plus a viscous
back-EMF damping (N·Kt)²/R.  The host inverts this with the estimated rate ẑ2
(:func:`torque_to_duty`); the plant integrates the same law by adding the
damping to the rig's viscous friction (see the plant kind's ``design``) and
applying the rate-independent :func:`source_torque` of the duty.

The driver has a deadband δ (fraction of full duty): a duty fraction d' acts as
d = sign(d')·max(0, (|d'| − δ)/(1 − δ)); the host pre-compensates with
d' = sign(d)·(δ + (1 − δ)|d|) for d ≠ 0.  Duty counts are integers in
[−pwm_max, pwm_max]; ±pwm_max is full ±Vs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from esoarm._jit import jitable
from esoarm.contract import Vector

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["MotorParams", "duty_to_torque", "effective_fraction", "source_torque",
           "torque_to_duty"]

# Layout of the motor block of the actuator vector (esoarm.plants.actuator).
STALL_GAIN, DAMPING, PWM_MAX, DEADBAND = range(4)


@jitable
def torque_to_duty(torque: float, omega: float, m: Vector) -> float:
    """Duty counts (a whole number) that produce ``torque`` [N·m] at arm rate ``omega`` [rad/s].

    Saturates at ±pwm_max (full supply); includes the deadband
    pre-compensation; a non-finite request gives 0.  ``m`` is the motor block
    (stall gain, damping, pwm_max, deadband).

    Parameters
    ----------
    torque : float
        Requested arm torque [N·m], positive in the direction of positive arm rate.
    omega : float
        Arm rate [rad/s] (the host uses the estimate ẑ2) for the back-EMF compensation.
    m : ndarray or tuple
        Motor block (stall gain N·Kt·Vs/R [N·m], damping (N·Kt)²/R [N·m·s/rad], pwm_max
        [counts], deadband δ [1]), :attr:`MotorParams.block`.

    Returns
    -------
    float
        Signed duty [counts], a whole number in [−pwm_max, pwm_max]; positive duty gives
        positive torque.
    """
    frac = (torque + m[DAMPING] * omega) / m[STALL_GAIN]
    if not math.isfinite(frac):
        return 0.0
    if frac > 1.0:
        frac = 1.0
    elif frac < -1.0:
        frac = -1.0
    if frac != 0.0:
        db = m[DEADBAND]
        frac = math.copysign(db + (1.0 - db) * abs(frac), frac)
    # round half to even, exactly like Python's round()
    return float(np.rint(frac * m[PWM_MAX]))


@jitable
def effective_fraction(duty: float, m: Vector) -> float:
    """Fraction of Vs the driver actually applies for ``duty`` counts (deadband).

    Parameters
    ----------
    duty : float
        Signed duty [counts].
    m : ndarray or tuple
        Motor block (stall gain N·Kt·Vs/R [N·m], damping (N·Kt)²/R [N·m·s/rad], pwm_max
        [counts], deadband δ [1]), :attr:`MotorParams.block`.

    Returns
    -------
    float
        d = sign(d')·max(0, (|d'| − δ)/(1 − δ)), clipped to [−1, 1], d' = duty/pwm_max.
    """
    frac = duty / m[PWM_MAX]
    db = m[DEADBAND]
    mag = (abs(frac) - db) / (1.0 - db)
    if mag <= 0.0:
        return 0.0
    return math.copysign(min(mag, 1.0), frac)


@jitable
def source_torque(duty: float, m: Vector) -> float:
    """The rate-independent arm torque N·Kt·Vs·d/R [N·m] of ``duty`` (what drives the twin).

    Parameters
    ----------
    duty : float
        Signed duty [counts].
    m : ndarray or tuple
        Motor block (stall gain N·Kt·Vs/R [N·m], damping (N·Kt)²/R [N·m·s/rad], pwm_max
        [counts], deadband δ [1]), :attr:`MotorParams.block`.

    Returns
    -------
    float
        Arm torque at rest [N·m], the sign of ``duty`` (0 inside the deadband).
    """
    return m[STALL_GAIN] * effective_fraction(duty, m)


@jitable
def duty_to_torque(duty: float, omega: float, m: Vector) -> float:
    """Arm torque [N·m] that ``duty`` gives at arm rate ``omega`` [rad/s].

    Parameters
    ----------
    duty : float
        Signed duty [counts].
    omega : float
        Arm rate [rad/s]; positive rate opposes positive torque (back-EMF).
    m : ndarray or tuple
        Motor block (stall gain N·Kt·Vs/R [N·m], damping (N·Kt)²/R [N·m·s/rad], pwm_max
        [counts], deadband δ [1]), :attr:`MotorParams.block`.

    Returns
    -------
    float
        N·Kt·Vs·d/R − (N·Kt)²/R · ω [N·m].
    """
    return source_torque(duty, m) - m[DAMPING] * omega


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
    def from_scenario(cls, scn: Scenario) -> MotorParams | None:
        """The scenario's motor, or None for an ideal torque source.

        Parameters
        ----------
        scn : Scenario
            A validated scenario.

        Returns
        -------
        MotorParams or None
            The ``[motor]`` table's constants, or None when the scenario has none.
        """
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

    @property
    def block(self) -> np.ndarray:
        """(stall gain, damping, pwm_max, deadband): the argument ``m`` of the functions."""
        return np.array([self.stall_gain, self.damping, float(self.pwm_max), self.deadband])

    def torque_to_duty(self, torque: float, omega: float) -> int:
        """Duty counts that produce ``torque`` [N·m] at arm rate ``omega`` [rad/s].

        Parameters
        ----------
        torque : float
            Requested arm torque [N·m].
        omega : float
            Arm rate [rad/s].

        Returns
        -------
        int
            Signed duty [counts] in [−pwm_max, pwm_max] (:func:`torque_to_duty`).

        Examples
        --------
        >>> m = MotorParams(12.0, 2.0, 0.5, 1.0, 255, 0.0)
        >>> m.stall_gain, m.torque_to_duty(1.5, 0.0), m.torque_to_duty(99.0, 0.0)
        (3.0, 128, 255)
        """
        return int(torque_to_duty(torque, omega, self.block))

    def effective_fraction(self, duty: int) -> float:
        """Fraction of Vs the driver actually applies for ``duty`` counts.

        Parameters
        ----------
        duty : int
            Signed duty [counts].

        Returns
        -------
        float
            Signed fraction of Vs in [−1, 1] after the deadband.
        """
        return float(effective_fraction(float(duty), self.block))

    def duty_to_torque(self, duty: int, omega: float) -> float:
        """Arm torque [N·m] that ``duty`` gives at arm rate ``omega`` [rad/s].

        Parameters
        ----------
        duty : int
            Signed duty [counts].
        omega : float
            Arm rate [rad/s].

        Returns
        -------
        float
            Arm torque [N·m], source torque minus back-EMF damping · omega.
        """
        return float(duty_to_torque(float(duty), omega, self.block))

    def source_torque(self, duty: int) -> float:
        """The rate-independent part N·Kt·Vs·d/R [N·m] (the twin's applied torque).

        Parameters
        ----------
        duty : int
            Signed duty [counts].

        Returns
        -------
        float
            Arm torque at rest [N·m].
        """
        return float(source_torque(float(duty), self.block))
