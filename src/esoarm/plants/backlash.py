"""Gear backlash between motor and arm: the dead-zone model of a gear with play.

With ``rig.backlash_deg`` = 2α > 0 the lever arm's rigid gear becomes a two-mass
drive train (Nordin & Gutman, "Controlling mechanical systems with backlash — a
survey", Automatica 38, 2002, the "dead-zone model" of section 2): the motor side,
with inertia Jm reflected to the arm (``rig.motor_inertia`` = N²·J_rotor), turns
freely inside a gap of ±α; in contact the gear is a spring k (``rig.gear_stiffness``)
with damping c (``rig.gear_damping``).  With Δ = θm − θ the transmitted torque is

    τs = 0                            |Δ| ≤ α          (in the gap)
    τs = max(0, k(Δ − α) + c Δ̇)       Δ > α            (driving forwards)
    τs = min(0, k(Δ + α) + c Δ̇)       Δ < −α           (driving backwards)

(the clamp keeps the damper from pulling the teeth together as they part), and

    I θ̈  = τs − G(θ) − F(θ̇) + I d(t)          (the arm: its gravity and friction)
    Jm θ̈m = τa − τs                          (the motor side: the actuator's torque τa)

τa is the actuator's torque at the arm (after the lag, :mod:`esoarm.plants.lever_arm`).
The arm's friction stays on the arm; the motor side has no friction of its own (with a
``[motor]`` table the back-EMF damping, part of the arm's viscous friction, is kept
there: an approximation that is exact outside the gap).  The state of the lever arm
grows from (θ, θ̇, τ) to (θ, θ̇, τ, θm, θ̇m), with θm(0) = θ(0), θ̇m(0) = 0 (the gear
centred in its play).  The encoder reads the arm's θ.

Accuracy: the contact is a stiff spring; the plant's RK4 step h must resolve its
frequency ωn = √(k (1/Jm + 1/I)): the scenario is refused unless h·ωn ≤ 0.5
(:func:`step_limit`).  Backlash 0 is the rigid gear of the historical plant (the gear
keys are then unused; every result is the same bits).
"""

from __future__ import annotations

import math

from esoarm._jit import jitable

__all__ = ["MAX_STEP_OMEGA", "contact_frequency", "gear_torque", "step_limit"]

#: Largest h·ωn accepted for the RK4 step h against the contact frequency ωn.
MAX_STEP_OMEGA = 0.5


@jitable
def gear_torque(delta: float, ddelta: float, alpha: float, k: float, c: float) -> float:
    """Torque τs [N·m] a gear with play ±α transmits from the motor side to the arm.

    Parameters
    ----------
    delta : float
        Δ = θm − θ, motor-side angle minus arm angle (both at the arm) [rad].
    ddelta : float
        Δ̇ [rad/s].
    alpha : float
        Half the play α = backlash/2 [rad].
    k : float
        Contact stiffness [N·m/rad].
    c : float
        Contact damping [N·m·s/rad].

    Returns
    -------
    float
        τs [N·m]: 0 in the gap, else the spring-damper torque clamped to the side of contact.

    Examples
    --------
    >>> gear_torque(0.01, 5.0, 0.02, 50.0, 0.1), round(gear_torque(0.03, 0.0, 0.02, 50.0, 0.1), 12)
    (0.0, 0.5)
    >>> gear_torque(0.021, -1.0, 0.02, 50.0, 0.1)   # parting: the damper does not pull
    0.0
    """
    if delta > alpha:
        ts = k * (delta - alpha) + c * ddelta
        return ts if ts > 0.0 else 0.0
    if delta < -alpha:
        ts = k * (delta + alpha) + c * ddelta
        return ts if ts < 0.0 else 0.0
    return 0.0


def contact_frequency(stiffness: float, motor_inertia: float, arm_inertia: float) -> float:
    """ωn = √(k (1/Jm + 1/I)) [rad/s], the two masses' frequency in contact.

    Parameters
    ----------
    stiffness : float
        k [N·m/rad].
    motor_inertia : float
        Jm [kg·m²] (reflected to the arm).
    arm_inertia : float
        I [kg·m²].

    Returns
    -------
    float
        ωn [rad/s].
    """
    return math.sqrt(stiffness * (1.0 / motor_inertia + 1.0 / arm_inertia))


def step_limit(stiffness: float, motor_inertia: float, arm_inertia: float) -> float:
    """Largest RK4 step [s] accepted with backlash: :data:`MAX_STEP_OMEGA` / ωn.

    Parameters
    ----------
    stiffness : float
        k [N·m/rad].
    motor_inertia : float
        Jm [kg·m²].
    arm_inertia : float
        I [kg·m²].

    Returns
    -------
    float
        h_max [s].
    """
    return MAX_STEP_OMEGA / contact_frequency(stiffness, motor_inertia, arm_inertia)
