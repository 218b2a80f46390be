"""Checks and warnings of a scenario: validation messages, consistency, computability, timing.

:func:`esoarm.scenario.load_scenario` runs :func:`check_consistency` on every scenario it
builds (a failure is a :class:`~esoarm.scenario.ScenarioError` naming the key);
:func:`scenario_warnings` lists legal but risky settings, one line each.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm import kinds as _kinds
from esoarm._limits import COMPILED_STREAM_SAMPLES, MAX_SAMPLES
from esoarm._schema import PER_JOINT_KEYS
from esoarm.plants.backlash import contact_frequency, step_limit
from esoarm.plants.noise import check_noise
from esoarm.reference import Multisine, PerJoint, QuinticSteps, RangeMoves
from esoarm.scenario.errors import ScenarioError

if TYPE_CHECKING:
    from esoarm.scenario.schema import Scenario

__all__ = ["angle_key_warnings", "check_consistency", "scenario_warnings", "timing_warnings"]


def check_consistency(scn: Scenario, source: str,
                       origin: Callable[[str], str] | None = None) -> None:
    """Check what no single key can: the keys of one scenario against each other.

    Parameters
    ----------
    scn : Scenario
        The scenario, already valid key by key.
    source : str
        Where the keys came from ("file 'x.toml'", "built-in scenario 'test-1'"), for the message.
    origin : callable, optional
        Maps an offending key to the source to blame (an override that set it, else ``source``).

    Raises
    ------
    ScenarioError
        One line naming the key: a step that does not divide Ts, a run too long or shorter
        than a sample, reference moves out of order or out of range, a kind's own check, or
        numbers double precision cannot compute with.
    """

    def fail(key: str, msg: str) -> None:
        where = origin(key) if origin else source
        raise ScenarioError(f"{where}: key '{key}': {msg}")

    ts = scn.sample_time
    ratio = ts / scn.rig.step
    if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        fail(
            "rig.step",
            f"{scn.rig.step:g} s must divide the sample period Ts = 1/rate_hz = {ts:g} s "
            "into a whole number of RK4 steps",
        )
    _check_computable(scn, fail)
    bad_noise = check_noise(scn)
    if bad_noise is not None:
        fail(*bad_noise)
    _check_drive(scn, fail)
    samples = scn.duration * scn.sensor.rate_hz
    if not samples <= MAX_SAMPLES:  # also catches an overflow to inf
        fail("duration", f"{scn.duration:g} s at {scn.sensor.rate_hz:g} Hz is {samples:.3g} "
             f"samples; at most {MAX_SAMPLES:.0e} are allowed")
    if scn.n_samples < 1:
        fail("duration", f"{scn.duration:g} s is shorter than one sample period ({ts:g} s)")
    ref = scn.reference
    parts = ([(f"reference.joints[{i}]", r) for i, r in enumerate(ref.joints)]
             if isinstance(ref, PerJoint) else [("reference", ref)])
    for where, part in parts:
        if isinstance(part, QuinticSteps | RangeMoves):
            _check_moves(part, where, fail)
        else:
            n = len(part.amplitudes)
            if len(part.frequencies) != n:
                fail(f"{where}.frequencies", f"needs one entry per amplitude ({n})")
            if part.phases and len(part.phases) != n:
                fail(f"{where}.phases", f"needs one entry per amplitude ({n}) or none")
    kinds = _kinds.kinds_of(scn)
    for module in kinds:  # a kind's own checks against the rest of the scenario
        check = getattr(module, "check", None)
        message = check(scn) if check is not None else None
        if message:
            raise ScenarioError(f"{source}: {message}")
    joint_names = getattr(kinds.plant, "joint_names", None)
    names = joint_names(scn) if joint_names is not None else ()
    if len(names) > 1:  # an arm: the observer kind must take its joints
        per_joint = _kinds.observers_for(len(names))
        if scn.observer.kind not in per_joint:
            fail("observer.kind", f"'{scn.observer.kind}' is designed for one joint, and plant "
                 f"kind '{scn.plant.kind}' has {len(names)} joints ({', '.join(names)}); use "
                 f"one of {', '.join(repr(k) for k in per_joint)} (one ESO per joint)")
    if not hasattr(kinds.plant, "joint_limits"):  # one joint, no limits (the lever arm)
        if isinstance(ref, RangeMoves):
            fail("reference.kind", f"'range' moves through joint limits; plant kind "
                 f"'{scn.plant.kind}' has none (use quintic-steps or multisine)")
        if isinstance(ref, PerJoint) and len(ref.joints) != 1:
            fail("reference.joints", f"{len(ref.joints)} entries, but plant kind "
                 f"'{scn.plant.kind}' has one joint")
        for section in ("observer", "controller"):  # a per-joint list: one entry
            values = getattr(scn, section).model_dump()
            for key in PER_JOINT_KEYS:
                value = values.get(key)
                if isinstance(value, list) and len(value) != 1:
                    fail(f"{section}.{key}", f"{len(value)} entries, but plant kind "
                         f"'{scn.plant.kind}' has one joint (give one number)")


def _check_drive(scn: Scenario, fail: Callable[[str, str], None]) -> None:
    """Gear backlash only on a plant kind that models it, with a step that resolves it;
    a PWM resolution only without a motor (whose pwm_max is the resolution)."""
    rig = scn.rig
    if rig.cogging.amplitude > 0.0 and not getattr(_kinds.kinds_of(scn).plant, "COGGING_MODEL",
                                                   False):
        fail("rig.cogging.amplitude", f"plant.kind = '{scn.plant.kind}' does not model a "
             "position-periodic torque (plant kinds that do: 'lever-arm'); set it to 0")
    if rig.backlash_deg > 0.0:
        plant = _kinds.kinds_of(scn).plant
        if not getattr(plant, "BACKLASH_MODEL", False):
            fail("rig.backlash_deg", f"plant.kind = '{scn.plant.kind}' does not model gear "
                 "backlash (plant kinds that do: 'lever-arm'); set it to 0")
        arm = rig.inertia_scale * scn.plant.inertia
        h_max = step_limit(rig.gear_stiffness, rig.motor_inertia, arm)
        if rig.step > h_max:
            wn = contact_frequency(rig.gear_stiffness, rig.motor_inertia, arm)
            fail("rig.step", f"{rig.step:g} s does not resolve the gear's contact frequency "
                 f"√(k(1/Jm + 1/I)) = {wn:.4g} rad/s with backlash: use a step ≤ {h_max:.3g} s "
                 "that divides Ts, or a "
                 "softer rig.gear_stiffness / heavier rig.motor_inertia")
    if scn.actuator.pwm_bits > 0 and scn.motor is not None:
        fail("actuator.pwm_bits", "a [motor] table sets the PWM resolution itself "
             "(motor.pwm_max = 2^bits − 1); set actuator.pwm_bits = 0")
    _check_stops(scn, fail)


def _check_stops(scn: Scenario, fail: Callable[[str, str], None]) -> None:
    """End stops: two angles around θ(0), on a plant kind that models them, no backlash; the
    ESO's gate at a stop needs the stops."""
    rig = scn.rig
    if rig.end_stops:
        if not getattr(_kinds.kinds_of(scn).plant, "END_STOPS_MODEL", False):
            fail("rig.end_stops", f"plant.kind = '{scn.plant.kind}' does not model end stops "
                 "(plant kinds that do: 'lever-arm'); set it to []")
        elif len(rig.end_stops) != 2 or not rig.end_stops[0] < rig.theta0 < rig.end_stops[1]:
            fail("rig.end_stops", f"{rig.end_stops}: give [lower, upper] [rad] with lower < "
                 f"rig.theta0 ({rig.theta0:g}) < upper")
        elif rig.backlash_deg > 0.0:
            fail("rig.end_stops", "end stops with gear backlash are not modelled; set "
                 "rig.backlash_deg = 0 or rig.end_stops = []")
    if scn.actuator.stop_gate > 0.0 and not rig.end_stops:
        fail("actuator.stop_gate", "gates the ESO at the rig's end stops: set rig.end_stops "
             "= [lower, upper] [rad], or stop_gate = 0")


def _check_moves(ref: QuinticSteps | RangeMoves, where: str, fail: Any) -> None:
    what = "position −1…1" if isinstance(ref, RangeMoves) else "target rad"
    end = -math.inf
    for i, move in enumerate(ref.moves):
        key = f"{where}.moves[{i}]"
        if len(move) != 3:
            fail(key, f"each move is [start s, duration s, {what}]")
        t0, dur, target = move
        if not all(math.isfinite(v) for v in move):
            fail(key, "must be finite numbers")
        if dur <= 0:
            fail(key, f"duration {dur:g} s must be > 0")
        if t0 < 0:
            fail(key, f"start {t0:g} s must be >= 0")
        if t0 < end - 1e-12:
            fail(key, f"starts at {t0:g} s, before the previous move ends ({end:g} s): "
                 "moves must be in time order and not overlap")
        if isinstance(ref, RangeMoves) and not -1.0 <= target <= 1.0:
            fail(key, f"position {target:g} must be within −1…1 (the joint's limits)")
        end = t0 + dur


def _check_computable(scn: Scenario, fail: Callable[[str, str], None]) -> None:
    """Values each legal alone whose derived quantities overflow double precision.

    The input gain 1/I0, the true inertia, the observer gains up to 1/ε³, the
    gravity torque and the tanh friction slope 1/vs must be finite and the
    divisors non-zero; otherwise the engines would compute inf or NaN (or fail)
    from the first sample on.
    """
    p, rig, obs, ctl = scn.plant, scn.rig, scn.observer, scn.controller
    checks: list[tuple[str, Callable[[], float], str, bool]] = [  # key, value, what, divisor
        ("plant.inertia", lambda: 1.0 / p.inertia, "1/plant.inertia (the input gain b0)", True),
        ("rig.inertia_scale", lambda: p.inertia * rig.inertia_scale,
         "plant.inertia · rig.inertia_scale (the true inertia)", True),
        ("rig.inertia_scale", lambda: 1.0 / (p.inertia * rig.inertia_scale),
         "1/(plant.inertia · rig.inertia_scale)", True),
        ("observer.eps", lambda: 1.0 / np.float64(  # an empty list: its length is checked later
            min(obs.eps, default=1.0) if isinstance(obs.eps, list) else obs.eps) ** 3,
         "the observer gain β3 = 1/ε³", True),
        ("plant.g", lambda: (p.m1 * p.l1 - p.m2 * p.l2) * p.g, "the gravity torque amplitude",
         False),
        ("rig.friction_velocity", lambda: rig.coulomb_friction / rig.friction_velocity,
         "the friction slope Fc/vs", False),
        ("actuator.lag", lambda: 1.0 / scn.actuator.lag if scn.actuator.lag else 0.0,
         "1/actuator.lag", False),
        ("controller.k2", lambda: ctl.k2 * p.inertia * 10.0, "the control gain I0 · k2", False),
    ]
    for key, compute, what, divisor in checks:
        try:
            with np.errstate(all="ignore"):
                value = float(compute())
        except AttributeError:  # another plant, observer or controller kind: not its key
            continue
        except ZeroDivisionError:
            value = math.inf
        if not (math.isfinite(value) and (value != 0 or not divisor)):
            fail(key, f"out of the range double precision can compute with: {what} "
                 f"is {value:g}")


def scenario_warnings(scn: Scenario) -> list[str]:
    """Legal but risky settings of ``scn``, as one-line messages.

    What the observer kind finds doubtful at this sample rate (its ``warnings``,
    :func:`esoarm.kinds.observer_warnings`: for the ESO, error poles unstable or
    poorly damped, or faster than the samples support); and settings that
    silently do nothing or less than asked (:func:`timing_warnings`).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        One message per risky setting; empty when there is none.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> scenario_warnings(load_scenario("test-1"))
    []
    """
    return [*_kinds.observer_warnings(scn), *timing_warnings(scn), *angle_key_warnings(scn),
            *actuator_warnings(scn)]


#: Coarsest PWM drive without a warning: below this many bits the torque's steps are so
#: coarse (≥ torque_limit/7) that a small command is rounded to nothing.
MIN_QUIET_PWM_BITS = 4


def actuator_warnings(scn: Scenario) -> list[str]:
    """A PWM drive so coarse that small commands are rounded to zero torque.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        One message when ``actuator.pwm_bits`` is 1 … :data:`MIN_QUIET_PWM_BITS` − 1.
    """
    bits = scn.actuator.pwm_bits
    if not 0 < bits < MIN_QUIET_PWM_BITS or scn.motor is not None:
        return []
    limit = scn.actuator.torque_limit
    step = limit / (2**bits - 1)
    return [f"actuator.pwm_bits = {bits}: the torque steps by torque_limit/(2^{bits} − 1) = "
            f"{step:.3g} N·m, so a command below {step / 2:.3g} N·m is rounded to 0 and the arm "
            "gets no torque at all (Arduino analogWrite has 8 bits)"]


def angle_key_warnings(scn: Scenario) -> list[str]:
    """The sensor's angle keys [deg] set on a plant whose position is not an angle.

    ``sensor.noise_deg``, ``sensor.resolution_deg`` and ``sensor.vibration_deg`` are
    converted from degrees to radians and added to the measured position.  On a plant whose
    position is in metres (a prismatic axis) that is σ·π/180 m: a number nobody meant.
    The default sensor (0.2° of noise, 0.05° steps) is such a case unless the scenario
    sets them to 0, as the built-in ``emps`` does.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        One message per such key; empty for a plant measured in rad.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> angle_key_warnings(load_scenario("emps")), angle_key_warnings(load_scenario("test-1"))
    ([], [])
    """
    unit = _kinds.units(scn).position
    if unit == "rad":
        return []
    out = []
    for key in ("noise_deg", "resolution_deg", "vibration_deg"):
        value = getattr(scn.sensor, key)
        if value != 0.0:
            out.append(f"sensor.{key} = {value:g} is an angle [deg], but this plant's position "
                       f"is in {unit}: it acts as {math.radians(value):.3g} {unit}; set it to 0 "
                       f"(or to the wanted value in {unit} × 180/π)")
    return out


def timing_warnings(scn: Scenario) -> list[str]:
    """Settings that the run's length or sample rate makes (partly) ineffective.

    A transport delay as long as the run (no command ever acts), a reference
    move that starts after the run has ended, a multisine tone at or above
    the Nyquist frequency of the samples, and a duration that is not a whole
    number of sample periods (the run is rounded to N samples).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        One message per setting the timing makes ineffective; empty when there is none.
    """
    out: list[str] = []
    ts, n = scn.sample_time, scn.n_samples
    end = n * ts
    delay = scn.actuator.delay_samples
    if delay >= n:
        out.append(f"actuator.delay_samples = {delay} ({delay * ts:g} s) is as long as the run "
                   f"({n} samples, {end:g} s): no command ever reaches the arm")
    ref = scn.reference
    if isinstance(ref, QuinticSteps | RangeMoves):
        late = [i for i, move in enumerate(ref.moves) if len(move) == 3 and move[0] >= end]
        if late:
            i = late[0]
            more = f" (and {len(late) - 1} later moves)" if len(late) > 1 else ""
            out.append(f"reference.moves[{i}] starts at {ref.moves[i][0]:g} s, when the run has "
                       f"ended ({end:g} s): it is never tracked{more}; raise duration")
    elif isinstance(ref, Multisine):
        nyquist = math.pi / ts
        fast = [i for i, w in enumerate(ref.frequencies) if abs(w) >= nyquist]
        if fast:
            i = fast[0]
            out.append(f"reference.frequencies[{i}] = {ref.frequencies[i]:g} rad/s is at or above "
                       f"the Nyquist frequency of the samples (π·rate_hz = {nyquist:g} rad/s): "
                       "the loop sees an aliased reference")
    steps = n * scn.substeps
    if scn.substeps > 10_000 or steps > 100_000_000:
        # ~40 µs a step on the reference engine; a long run of compiled kinds is streamed
        # through the compiled engine (COMPILED_STREAM_SAMPLES): ~0.5-1 µs a step, measured
        compiled = n > COMPILED_STREAM_SAMPLES and _kinds.kinds_of(scn).jit
        hours = steps * (1e-6 if compiled else 40e-6) / 3600
        if scn.substeps > 20:
            fix = f"a step of about Ts/20 = {ts / 20:g} s is usually enough"
        else:  # the step is already coarse: the run itself is long
            fix = "shorten duration"
        out.append(f"rig.step = {scn.rig.step:g} s is {scn.substeps:,} RK4 steps per sample, "
                   f"{steps:,} for the run: that takes about {hours:,.1f} h in esoarm simulate; "
                   f"{fix}")
    if abs(end - scn.duration) > 1e-9 * max(scn.duration, 1.0):
        out.append(f"duration = {scn.duration:g} s is not a whole number of sample periods "
                   f"(Ts = {ts:g} s): the run has {n} samples ({end:g} s)")
    return out
