"""The scenario's schema: its tables as pydantic models, and a dict of keys made a Scenario.

:class:`Scenario` is the validated, immutable description of one closed-loop run; its
``[plant]``, ``[observer]`` and ``[controller]`` tables are the registered kinds' ``Params``
(:mod:`esoarm.kinds`), its ``[reference]`` one of :data:`esoarm.reference.REFERENCE_KINDS`.
:func:`build` merges keys over the defaults, validates them and runs the consistency checks
(:mod:`esoarm.scenario.checks`); every failure is one :class:`ScenarioError` line naming the
key.  Reading files and built-in names is :mod:`esoarm.scenario.loading`.
"""

from __future__ import annotations

import copy
import difflib
import functools
import os
import re
import tomllib
import typing
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, TypeAlias

from pydantic import BaseModel, Field, ValidationError

from esoarm import kinds as _kinds
from esoarm._limits import MAX_BACKLASH_DEG
from esoarm._schema import PER_JOINT_KEYS, Actuator
from esoarm._schema import Section as _Section
from esoarm._schema import unit as _unit
from esoarm._toml import to_toml
from esoarm.reference import REFERENCE_KINDS, QuinticSteps, Reference
from esoarm.scenario.checks import check_consistency
from esoarm.scenario.errors import ScenarioError

__all__ = ["KIND_SECTIONS", "PATH_KEYS", "Motor", "Scenario", "build", "parse_override",
           "valid_keys"]


#: ``[plant]``, ``[observer]``, ``[controller]``: one table per component, its keys
#: those of the kind named by ``kind`` (the registered kinds, :mod:`esoarm.kinds`).
#: :data:`KIND_SECTIONS` maps every such table (and ``reference``) to its kinds' models.
if TYPE_CHECKING:  # statically: any registered kind's Params (each kind narrows its own)
    Plant: TypeAlias = Any
    Observer: TypeAlias = Any
    Controller: TypeAlias = Any
else:
    Plant = _kinds.tagged_union(_kinds.PLANTS)
    Observer = _kinds.tagged_union(_kinds.OBSERVERS)
    Controller = _kinds.tagged_union(_kinds.CONTROLLERS)
KIND_SECTIONS: dict[str, tuple[type[BaseModel], ...]] = {
    "plant": tuple(m.Params for m in _kinds.PLANTS),
    "observer": tuple(m.Params for m in _kinds.OBSERVERS),
    "controller": tuple(m.Params for m in _kinds.CONTROLLERS),
}


class Disturbance(_Section):
    """External disturbance d(t) = amplitude · sin(frequency · t) (paper eq. 6)."""

    kind: Literal["sine"] = Field("sine", description="disturbance shape")
    amplitude: float = Field(0.2, description="amplitude", json_schema_extra=_unit("rad/s²"))
    frequency: float = Field(
        0.5, ge=0, description="angular frequency", json_schema_extra=_unit("rad/s")
    )


class Cogging(_Section):
    """A position-periodic torque on the arm τ_cog = A cos(n θ + φ) (cogging, gear eccentricity)."""

    amplitude: float = Field(0.0, ge=0, description="amplitude A (0: none)",
                             json_schema_extra=_unit("N·m"))
    periods: int = Field(1, ge=1, le=1000, description="n, periods per revolution of the arm",
                         json_schema_extra=_unit("1"))
    phase: float = Field(0.0, description="phase φ", json_schema_extra=_unit("rad"))


class Rig(_Section):
    """The true system: the digital twin of the paper's rig (the sampled-data loop)."""

    inertia_scale: float = Field(
        1.1, gt=0, description="true inertia / nominal inertia", json_schema_extra=_unit("1")
    )
    coulomb_friction: float = Field(
        0.05, ge=0, description="Coulomb friction torque Fc", json_schema_extra=_unit("N·m")
    )
    friction_velocity: float = Field(
        0.01, gt=0, description="tanh smoothing velocity vs of Coulomb friction",
        json_schema_extra=_unit("rad/s"),
    )
    viscous_friction: float = Field(
        0.01, ge=0, description="viscous friction b", json_schema_extra=_unit("N·m·s/rad")
    )
    stiction: float = Field(
        0.0, ge=0, description="breakaway (static) friction above Coulomb, Fst = Fs − Fc",
        json_schema_extra=_unit("N·m"),
    )
    stribeck_velocity: float = Field(
        0.1, gt=0, description="Stribeck velocity vst over which the stiction decays",
        json_schema_extra=_unit("rad/s"),
    )
    backlash_deg: float = Field(
        0.0, ge=0, le=MAX_BACKLASH_DEG, description="total play 2α of the gear between motor "
        "and arm, a two-mass dead-zone model (0: rigid gear); plausible 0.5 … 3 for small "
        "spur/planetary gearmotors, < 0.25 for precision gearheads, a few degrees for a worn "
        f"toy gear train; at most {MAX_BACKLASH_DEG:g} (docs/noise-model.md)",
        json_schema_extra=_unit("deg"),
    )
    motor_inertia: float = Field(
        1e-3, gt=0, description="motor-side inertia Jm reflected to the arm, N²·J_rotor (with "
        "backlash); plausible 1e-4 … 1e-2", json_schema_extra=_unit("kg·m²"),
    )
    gear_stiffness: float = Field(
        50.0, gt=0, description="contact stiffness k of the gear (with backlash); rig.step "
        "must resolve √(k(1/Jm + 1/I))", json_schema_extra=_unit("N·m/rad"),
    )
    gear_damping: float = Field(
        0.05, ge=0, description="contact damping c of the gear (with backlash)",
        json_schema_extra=_unit("N·m·s/rad"),
    )
    step: float = Field(0.001, gt=0, description="RK4 step h", json_schema_extra=_unit("s"))
    theta0: float = Field(0.0, description="initial angle θ(0)", json_schema_extra=_unit("rad"))
    disturbance: Disturbance = Field(default_factory=Disturbance)
    cogging: Cogging = Field(default_factory=Cogging)
    end_stops: list[float] = Field(
        default_factory=list, max_length=2, description="hard end stops [lower, upper] of the "
        "arm: the arm stops dead there (an inelastic stop) and is held while the torque "
        "pushes into it ([] none)", json_schema_extra=_unit("rad"),
    )


class Sensor(_Section):
    """Encoder model: sampling, Gaussian noise (white or AR), arm vibration, quantization."""

    rate_hz: float = Field(
        50.0, gt=0, description="sample rate 1/Ts", json_schema_extra=_unit("Hz")
    )
    resolution_deg: float = Field(
        0.05, ge=0, description="quantization step q (0: none)", json_schema_extra=_unit("deg")
    )
    noise_deg: float = Field(
        0.2, ge=0, description="std dev of Gaussian noise before quantization",
        json_schema_extra=_unit("deg"),
    )
    seed: int = Field(0, ge=0, description="seed of numpy.random.default_rng for the noise")
    noise_ar: list[float] = Field(
        default_factory=list,
        description="AR coefficients φ1…φp of the encoder noise, n_k = φ1 n_{k−1} + … + "
        "φp n_{k−p} + e_k, scaled so its stationary std is noise_deg ([]: white); "
        "stationary (poles inside |z| < 0.999), at most 20; plausible φ1 = exp(−Ts/τc) for "
        "a correlation time τc (e.g. [0.6] at 50 Hz: τc = 40 ms, cable drag, a filtered "
        "magnetic encoder); see docs/noise-model.md",
        json_schema_extra=_unit("1"),
    )
    vibration_deg: float = Field(
        0.0, ge=0, description="RMS of band-limited arm vibration seen by the encoder (a "
        "white-noise-driven mode, added to the encoder noise; 0: none); plausible 0 … 0.2 "
        "for a bolted lever arm (docs/noise-model.md)",
        json_schema_extra=_unit("deg"),
    )
    vibration_hz: float = Field(
        10.0, gt=0, description="natural frequency f0 of the vibration mode; below rate_hz/2 "
        "(a faster mode: give its alias)", json_schema_extra=_unit("Hz"),
    )
    vibration_damping: float = Field(
        0.05, gt=0, lt=1, description="damping ratio ζ of the vibration mode; plausible "
        "0.005 … 0.1 (bolted metal structures, docs/noise-model.md)",
        json_schema_extra=_unit("1"),
    )


KIND_SECTIONS["reference"] = REFERENCE_KINDS

#: Keys naming files, resolved against the scenario file's directory when relative.
PATH_KEYS: tuple[tuple[str, str], ...] = (("plant", "file"),)


def _resolve_paths(data: dict[str, Any], base: Path) -> None:
    for section, key in PATH_KEYS:
        table = data.get(section)
        if isinstance(table, dict) and isinstance(table.get(key), str) and table[key]:
            path = Path(table[key]).expanduser()
            if not path.is_absolute():
                table[key] = os.path.normpath(base / path)


class Motor(_Section):
    """Optional DC motor and driver model: maps the torque command to a PWM duty.

    Without a ``[motor]`` table the actuator is an ideal torque source (the sampled-data loop).
    With one, the real-time loop sends a duty computed from the torque and the
    estimated rate (back-EMF), and the emulator models the same motor (see
    :mod:`esoarm.plants.motor`).  Torque and back-EMF constants are equal in
    SI units.
    """

    supply_voltage: float = Field(
        12.0, gt=0, description="driver supply voltage Vs", json_schema_extra=_unit("V")
    )
    resistance: float = Field(
        2.0, gt=0, description="winding resistance R", json_schema_extra=_unit("Ω")
    )
    torque_constant: float = Field(
        0.02, gt=0, description="motor torque constant Kt (= back-EMF constant)",
        json_schema_extra=_unit("N·m/A"),
    )
    gear_ratio: float = Field(
        50.0, gt=0, description="gear ratio N (arm torque = N · motor torque)",
        json_schema_extra=_unit("1"),
    )
    pwm_max: int = Field(
        255, ge=1, le=32767, description="PWM resolution: duty ±pwm_max is full ±Vs",
        json_schema_extra=_unit("counts"),
    )
    deadband: float = Field(
        0.0, ge=0, lt=1, description="driver deadband as a fraction of full duty",
        json_schema_extra=_unit("1"),
    )


class Scenario(_Section):
    """A complete, validated closed-loop experiment (the scenario format).

    Build one with :func:`load_scenario`; the object is immutable.  Use
    :meth:`with_overrides` for variations.
    """

    name: str = Field("test-1", description="scenario name")
    duration: float = Field(20.0, gt=0, description="run length", json_schema_extra=_unit("s"))
    plant: Plant = Field(default_factory=_kinds.PLANTS[0].Params)
    rig: Rig = Field(default_factory=Rig)
    sensor: Sensor = Field(default_factory=Sensor)
    actuator: Actuator = Field(default_factory=Actuator)
    observer: Observer = Field(default_factory=_kinds.OBSERVERS[0].Params)
    controller: Controller = Field(default_factory=_kinds.CONTROLLERS[0].Params)
    reference: Reference = Field(default_factory=QuinticSteps)
    motor: Motor | None = Field(
        None, description="DC motor + driver (torque -> PWM duty); absent: ideal torque source"
    )

    # -- derived quantities -------------------------------------------------
    @property
    def sample_time(self) -> float:
        """Sample period Ts = 1/rate_hz [s]."""
        return 1.0 / self.sensor.rate_hz

    @property
    def n_samples(self) -> int:
        """Number of control samples N = round(duration · rate_hz)."""
        return int(round(self.duration * self.sensor.rate_hz))

    @property
    def substeps(self) -> int:
        """RK4 steps per sample, Ts / rig.step (validated to be an integer)."""
        return int(round(self.sample_time / self.rig.step))

    def with_overrides(self, overrides: dict[str, Any] | list[str]) -> Scenario:
        """Return a new scenario with dotted-key overrides applied and validated.

        ``overrides`` is a mapping ``{"observer.eps": 0.05}`` or a list of
        ``"KEY=VALUE"`` strings as given to ``--set``.

        Parameters
        ----------
        overrides : dict or list of str
            Dotted keys and values, e.g. ``{"observer.eps": 0.05}`` or ``["observer.eps=0.05"]``.

        Returns
        -------
        Scenario
            A new, validated scenario; ``self`` is unchanged.

        Raises
        ------
        ScenarioError
            An unknown key or an invalid value, in one line naming the key.
        """
        return build(self.to_dict(), overrides, source=f"scenario '{self.name}'")

    def to_dict(self) -> dict[str, Any]:
        """The fully resolved scenario as plain nested dicts.

        Returns
        -------
        dict
            Every key of every table, with defaults filled in (JSON- and TOML-ready).
        """
        return self.model_dump()

    def to_toml(self) -> str:
        """The fully resolved scenario as TOML text (all keys).

        Returns
        -------
        str
            TOML that :func:`esoarm.scenario.load_scenario` reads back to an equal scenario.
        """
        return to_toml(self.to_dict())


# ---------------------------------------------------------------------------
# building: keys over the defaults, validated


def _kinds_changed() -> None:
    """A kind was (un)registered (:func:`esoarm.kinds.register`): rebuild the kind tables."""
    for name, kinds in (("plant", _kinds.PLANTS), ("observer", _kinds.OBSERVERS),
                        ("controller", _kinds.CONTROLLERS)):
        KIND_SECTIONS[name] = tuple(m.Params for m in kinds)
        Scenario.model_fields[name].annotation = _kinds.tagged_union(kinds)
    Scenario.model_rebuild(force=True)
    _valid_keys_cached.cache_clear()


_kinds.on_change(_kinds_changed)


def _allowed(annotation: Any, value: Any) -> bool:
    """False for a value a ``Literal`` key of another kind cannot take (it is not carried)."""
    if typing.get_origin(annotation) is typing.Literal:
        return value in typing.get_args(annotation)
    return True


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``base`` updated by ``over``, table by table; neither is modified.

    The tables along the way are new dicts and the values from ``over`` are
    copied; untouched values of ``base`` are shared (validation copies them
    again), which keeps checking a large sweep grid quick.
    """
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            old_kind = out[key].get("kind")
            new_kind = value.get("kind", old_kind)
            if key in KIND_SECTIONS and new_kind != old_kind:
                # another kind: its own defaults, keeping the values of the keys both share
                # (e.g. observer.eps from "linear" to "nonlinear")
                models = [m for m in KIND_SECTIONS[key]
                          if m.model_fields["kind"].default == new_kind]
                shared = set(models[0].model_fields) - {"kind"} if models else set()
                # a key whose meaning is the new kind's own (json_schema_extra "own_meaning",
                # e.g. the PID's compensation, not the FLC's) starts from its default
                shared = {k for k in shared if not isinstance(
                    extra := models[0].model_fields[k].json_schema_extra, dict)
                    or not extra.get("own_meaning")}
                kept = {k: v for k, v in out[key].items()
                        if k in shared and _allowed(models[0].model_fields[k].annotation, v)}
                out[key] = _merge(kept, value)
            else:
                out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


@functools.cache
def _defaults_cached() -> dict[str, Any]:
    return Scenario().model_dump()


def _defaults() -> dict[str, Any]:
    return copy.deepcopy(_defaults_cached())


def parse_override(item: str) -> tuple[str, Any]:
    """Parse one ``KEY=VALUE`` override; VALUE as TOML, else as a string.

    Messages speak of the override (``override 'x': …``); the command line
    words them for its ``--set`` option.

    Parameters
    ----------
    item : str
        ``"KEY=VALUE"``, e.g. ``"observer.eps=0.05"`` or ``"observer.discretization=zoh"``.

    Returns
    -------
    (str, object)
        The dotted key and its value (a number, bool, list or string).

    Raises
    ------
    ScenarioError
        Not a string, no ``=``, or an empty key.

    Examples
    --------
    >>> parse_override("observer.eps=0.05"), parse_override("observer.discretization=zoh")
    (('observer.eps', 0.05), ('observer.discretization', 'zoh'))
    """
    if not isinstance(item, str):
        raise ScenarioError(f"override {item!r}: expected a 'KEY=VALUE' string")
    if "=" not in item:
        raise ScenarioError(f"override '{item}': expected KEY=VALUE, e.g. observer.eps=0.05")
    key, raw = item.split("=", 1)
    key = key.strip()
    raw = raw.strip()
    if not key:
        raise ScenarioError(f"override '{item}': empty key")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value


def _nest(key: str, value: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    node = out
    parts = key.split(".")
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    return out


@functools.cache
def _valid_keys_cached() -> tuple[str, ...]:
    return tuple(_walk_keys())


def valid_keys() -> list[str]:
    """Every dotted key a scenario accepts (all kinds' keys included), sorted.

    Returns
    -------
    list of str
        Dotted keys such as ``"observer.eps"``; a kind table lists the keys of all its kinds.
    """
    return list(_valid_keys_cached())


def _walk_keys() -> list[str]:
    keys: list[str] = []

    def walk(model: type[BaseModel], prefix: str) -> None:
        for name, field in model.model_fields.items():
            ann = field.annotation
            if name == "motor":  # optional section: Motor | None
                ann = Motor
            if name in KIND_SECTIONS:
                continue
            if isinstance(ann, type) and issubclass(ann, BaseModel):
                walk(ann, prefix + name + ".")
            else:
                keys.append(prefix + name)

    walk(Scenario, "")
    for section, models in KIND_SECTIONS.items():
        for model in models:
            keys.extend(f"{section}.{name}" for name in model.model_fields)
    return sorted(set(keys))


def build(data: dict[str, Any], overrides: dict[str, Any] | list[str], source: str) -> Scenario:
    """Merge ``data`` over the defaults, apply ``overrides``, validate and check: the edge.

    Parameters
    ----------
    data : dict
        Nested tables as read from TOML (missing keys take their defaults).
    overrides : dict or list of str
        Dotted keys applied after ``data`` (see :func:`parse_override`).
    source : str
        Where ``data`` came from, named in every message.

    Returns
    -------
    Scenario
        The validated, immutable scenario.

    Raises
    ------
    ScenarioError
        One line naming the offending key and its source (file or override).
    """

    if isinstance(overrides, list | tuple):
        pairs = [parse_override(item) for item in overrides]
    elif isinstance(overrides, dict):
        pairs = list(overrides.items())
    else:
        raise ScenarioError(f"overrides: expected a dict {{'observer.eps': 0.05}} or a list of "
                            f"'KEY=VALUE' strings, got {type(overrides).__name__}")
    merged = _merge(_defaults_cached(), data)
    for key, value in pairs:
        if not isinstance(key, str):
            raise ScenarioError(f"override {key!r}: a key is a dotted string, e.g. 'observer.eps'")
        _check_key(key, source="override")
        merged = _merge(merged, _nest(key, value))
    _resolve_paths(merged, Path.cwd())  # a path given with --set: relative to where we run
    overridden = {key for key, _ in pairs}

    def origin(key: str) -> str:  # blame the override when it set the offending key
        return "override" if key.split("[")[0] in overridden else source

    try:
        scn = Scenario.model_validate(merged)
    except ValidationError as exc:
        raise ScenarioError(_format_validation_error(exc, source, origin)) from None
    check_consistency(scn, source, origin)
    return scn


def _check_key(key: str, source: str) -> None:
    valid = valid_keys()
    if key in valid:
        return
    if not key.strip():
        raise ScenarioError(f"{source}: empty key; give a dotted key such as 'observer.eps'")
    # a whole table given to --set is not allowed either: say so and name its keys
    inside = [k for k in valid if k.startswith(key + ".")]
    if inside:
        shown = ", ".join(inside[:6]) + (", ..." if len(inside) > 6 else "")
        raise ScenarioError(f"{source}: key '{key}' is a table; set its keys one at a time "
                            f"({shown})")
    section, _, name = key.partition(".")
    if section in KIND_SECTIONS and name and "." not in name:
        return  # a kind's key: judged once the kind in force is known (validation)
    close = difflib.get_close_matches(key, valid, n=1, cutoff=0.5)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise ScenarioError(f"{source}: unknown key '{key}'{hint}")


_UNION_MEMBER = re.compile(r"^(constrained-)?(float|int|str|bool)$|^list\[.*\]$")


#: Errors that only say the input is not of a union member's type (a list is not a number).
_TYPE_MISMATCH = ("float_type", "int_type", "list_type", "string_type", "bool_type",
                  "float_parsing", "int_parsing")


def _first_error(exc: ValidationError) -> Any:
    """The error to report: for a number-or-list key, the one of the member the input is.

    A per-joint list ``[0.05, -1]`` fails both members of ``float | list[float]``; the
    float member's "not a valid number" hides the list member's error at entry 1.
    """
    errors = exc.errors()
    first = errors[0]
    if first["type"] in _TYPE_MISMATCH:
        base = [p for p in first["loc"] if not _UNION_MEMBER.match(str(p))]
        for other in errors[1:]:
            loc = other["loc"]
            same_key = [p for p in loc if not _UNION_MEMBER.match(str(p))
                        and not isinstance(p, int)] == base
            # an error at an entry of the list, or a member's error other than its type
            if same_key and (isinstance(loc[-1], int) and isinstance(first.get("input"), list)
                             or other["type"] not in _TYPE_MISMATCH):
                return other
    return first


def _format_validation_error(exc: ValidationError, source: str,
                             origin: Callable[[str], str] | None = None) -> str:
    err = _first_error(exc)
    loc = [str(p) for p in err["loc"] if not isinstance(p, int)]
    # drop the discriminator tag pydantic inserts for tagged unions
    section = loc[0] if loc else ""
    tags = {m.model_fields["kind"].default: m for m in KIND_SECTIONS.get(section, ())}
    tag_in_loc = [p for p in loc[1:2] if p in tags]
    loc = [p for i, p in enumerate(loc) if not (i == 1 and p in tags)]
    # and the member names of a plain union (a number or a per-joint list: "float", "list[…]")
    loc = [p for p in loc if not _UNION_MEMBER.match(p)]
    idx = [p for p in err["loc"] if isinstance(p, int)]
    key = ".".join(loc)
    keys = {tuple(str(p) for p in e["loc"] if not isinstance(p, int)
                  and not _UNION_MEMBER.match(str(p))) for e in exc.errors()}
    more = len(keys) - 1
    tail = f" (and {more} more error{'s' if more > 1 else ''})" if more else ""
    kind = err["type"]
    if origin is not None:
        source = origin(key if kind != "union_tag_invalid" else key + ".kind")
    if kind == "extra_forbidden":
        valid = valid_keys()
        if key in valid and tag_in_loc:  # a key of another kind of this section
            model = tags[tag_in_loc[0]]
            return (f"{source}: key '{key}' does not apply to {section} kind "
                    f"'{tag_in_loc[0]}' (its keys: {', '.join(model.model_fields)}){tail}")
        if tag_in_loc:  # suggest only the keys of the kind in force
            model = tags[tag_in_loc[0]]
            own = list(model.model_fields)
            close = difflib.get_close_matches(key.rsplit(".", 1)[-1], own, n=1, cutoff=0.5)
            hint = (f"; did you mean '{section}.{close[0]}'?" if close
                    else f"; {section} kind '{tag_in_loc[0]}' has the keys {', '.join(own)}")
            return f"{source}: unknown key '{key}'{hint}{tail}"
        close = difflib.get_close_matches(key, valid, n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        return f"{source}: unknown key '{key}'{hint}{tail}"
    where = f"{key}[{']['.join(map(str, idx))}]" if idx else key
    joint = ""
    if idx and key.rsplit(".", 1)[-1] in PER_JOINT_KEYS and section in ("observer", "controller"):
        joint = f" (joint {idx[0]}, counting from 0)"
    value = err.get("input")
    msg = err["msg"]
    if kind in ("finite_number",):
        msg = "must be a finite number (no NaN or inf)"
    elif kind.startswith(("float", "int", "string", "list", "bool", "model")):
        msg = f"{msg.lower()}"
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        allowed = ", ".join(f"'{t}'" for t in tags)
        return f"{source}: key '{key}.kind' must be one of {allowed}{tail}"
    shown = repr(value) if not isinstance(value, dict) else "a table"
    return f"{source}: key '{where}'{joint} = {shown}: {msg}{tail}"
