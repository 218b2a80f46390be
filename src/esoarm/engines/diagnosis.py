"""Why a run diverged: what left the finite range, and the likely causes in the scenario.

A run stops as diverged when |θ| or |ẑ1| exceeds the divergence limit or any
of θ, ẑ, u is not finite (docs/semantics.md, "The sampled-data loop").  The
one-line message then says which quantity left the range first and names the
settings of the scenario that plausibly drove it there, most likely first, so
that a user is not told to check ε when the initial angle was 10⁹ rad.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from esoarm.contract import ROTARY_UNITS, Units

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["SATURATION_WARNING", "divergence_causes", "saturation_warning", "what_left"]

#: Warn when the command sat at ±torque_limit for more than this share of a run's samples.
SATURATION_WARNING = 0.5


def what_left(theta: float, z1: float, z2: float, z3: float, u: float, limit: float,
              units: Units = ROTARY_UNITS) -> str:
    """The first quantity of the last logged row that is out of range, with its value.

    Parameters
    ----------
    theta : float
        True angle θ [rad].
    z1, z2, z3 : float
        Estimate ẑ: angle [rad], rate [rad/s], total perturbation [rad/s²].
    u : float
        Command u [N·m].
    limit : float
        Divergence limit on |θ| and |ẑ1| [rad].
    units : Units, optional
        The plant's units (:func:`esoarm.kinds.units`; m, m/s, N on a prismatic axis).

    Returns
    -------
    str
        E.g. ``"the angle θ = 2e+06 rad"``; ``"the state"`` if every value is in range.

    Examples
    --------
    >>> what_left(0.1, float("nan"), 0.0, 0.0, 0.0, 1e6)
    'the angle estimate ẑ1 = nan rad'
    """
    word = units.position_word
    for name, value, unit, bounded in (
            (f"the {word} θ", theta, units.position, True),
            (f"the {word} estimate ẑ1", z1, units.position, True),
            ("the rate estimate ẑ2", z2, units.velocity, False),
            ("the perturbation estimate ẑ3", z3, units.acceleration, False),
            ("the control u", u, units.force, False)):
        if not math.isfinite(value) or (bounded and abs(value) >= limit):
            return f"{name} = {value:.3g} {unit}"
    return "the state"


def divergence_causes(scn: Scenario, limit: float) -> list[str]:
    """Settings of ``scn`` that plausibly make a run diverge, most likely first.

    Each item names the key and its value.  Empty when nothing in the
    scenario stands out.

    Parameters
    ----------
    scn : Scenario
        The scenario of the diverged run.
    limit : float
        Divergence limit on |θ| and |ẑ1| [rad].

    Returns
    -------
    list of str
        One phrase per plausible cause, most likely first.
    """
    from esoarm._schema import joint_values, show_joint_values
    from esoarm.kinds import observer_warnings, units

    causes: list[str] = []
    ts = scn.sample_time
    inertia = getattr(scn.plant, "inertia", None)
    if inertia is not None and 1.0 / inertia >= limit:
        causes.append(f"plant.inertia = {inertia:g} kg·m² (the input gain 1/I0 = "
                      f"{1.0 / inertia:.3g})")
    rig, sensor = scn.rig, scn.sensor
    if abs(rig.theta0) >= limit / 10:
        causes.append(f"rig.theta0 = {rig.theta0:g} rad (the initial angle)")
    sigma = math.radians(sensor.noise_deg)
    if sigma >= limit / 1e3:
        causes.append(f"sensor.noise_deg = {sensor.noise_deg:g} (noise of {sigma:.3g} rad)")
    d = abs(rig.disturbance.amplitude)
    if d * scn.duration**2 >= limit / 10:
        causes.append(f"rig.disturbance.amplitude = {rig.disturbance.amplitude:g} rad/s²")
    obs = scn.observer
    unstable = [m for m in observer_warnings(scn) if "unstable" in m]
    eps, disc = getattr(obs, "eps", None), getattr(obs, "discretization", None)
    if unstable and eps is not None and disc is not None:  # the ESO kinds: name ε
        causes.append(f"observer.eps = {show_joint_values(eps)} s, an unstable observer at "
                      f"Ts = {ts:g} s with '{disc}'")
    elif unstable:  # another kind: its own message
        causes.append(f"an unstable observer (observer.kind = '{obs.kind}'): {unstable[0]}")
    if not 0.1 <= rig.inertia_scale <= 10:
        causes.append(f"rig.inertia_scale = {rig.inertia_scale:g} (the controller's model is "
                      "far from the rig)")
    # explicit error dynamics at Ts: k1·Ts or k2·Ts² beyond ~2 cannot be sampled stably
    # (the FLC and computed-torque kinds; a PID has kp, ki, kd instead)
    k1, k2 = getattr(scn.controller, "k1", None), getattr(scn.controller, "k2", None)
    if k1 is not None and k2 is not None and (
            max(joint_values(k1)) * ts > 2 or max(joint_values(k2)) * ts * ts > 4):
        causes.append(f"controller.k1 = {show_joint_values(k1)} 1/s, k2 = "
                      f"{show_joint_values(k2)} 1/s² (too fast for Ts = {ts:g} s)")
    ref = scn.reference
    if ref.kind == "quintic-steps":
        targets = [abs(m[2]) for m in getattr(ref, "moves", []) if len(m) == 3]
        amplitude = max([*targets, abs(getattr(ref, "start", 0.0))])
    else:
        amplitude = abs(getattr(ref, "offset", 0.0)) + sum(
            abs(a) for a in getattr(ref, "amplitudes", []))
    if amplitude >= limit / 10:
        causes.append(f"a reference of {amplitude:g} {units(scn).position}")
    return causes


def saturation_warning(fraction: float, torque_limit: float,
                       units: Units = ROTARY_UNITS) -> str | None:
    """A one-line warning when the command was saturated for most of a run, else None.

    Parameters
    ----------
    fraction : float
        Share of the samples with the command at ±torque_limit, in [0, 1] (NaN: none).
    torque_limit : float
        The actuator's limit [N·m] (a force [N] on a prismatic axis).
    units : Units, optional
        The plant's units (:func:`esoarm.kinds.units`).

    Returns
    -------
    str or None
        The warning when ``fraction`` > :data:`SATURATION_WARNING`, else None.
    """
    if not fraction > SATURATION_WARNING:  # also None for NaN
        return None
    return (f"the command sat at the {units.force_word} limit ±{torque_limit:g} {units.force} in "
            f"{100 * fraction:.3g} % of the samples (saturated_fraction = {fraction:.3g}): the "
            "loop is not the unsaturated one the controller was designed for; raise "
            "actuator.torque_limit or ask for a gentler reference")
