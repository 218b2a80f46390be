"""Scenario files: the validated, immutable description of one closed-loop run.

A scenario is a TOML file (the scenario format).  Every key has a default; a file gives only
what differs.  Built-in scenarios ship in ``esoarm/scenarios/*.toml`` and are
addressed by name.  Validation happens here, once, at the edge: the numerics
trust a :class:`Scenario`.

Errors are raised as :class:`ScenarioError`, whose message is one line naming
the offending key or file and what is allowed.  Risky but legal settings give
:class:`ScenarioWarning` (see :func:`scenario_warnings`).
"""

from __future__ import annotations

import copy
import difflib
import functools
import math
import tomllib
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, TypeAlias

import numpy as np
from pydantic import BaseModel, Field, ValidationError

from esoarm import kinds as _kinds
from esoarm._schema import Section as _Section
from esoarm._schema import unit as _unit

__all__ = [
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "builtin_names",
    "load_scenario",
    "parse_override",
    "scenario_warnings",
    "to_toml",
]


from esoarm._limits import MAX_RUNS, MAX_SAMPLES  # noqa: E402, F401 - re-exported


class ScenarioError(ValueError):
    """Bad scenario input: the message is one line naming the key or file."""


class ScenarioWarning(UserWarning):
    """A legal but risky scenario setting (e.g. an observer too fast for Ts)."""


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
    step: float = Field(0.001, gt=0, description="RK4 step h", json_schema_extra=_unit("s"))
    theta0: float = Field(0.0, description="initial angle θ(0)", json_schema_extra=_unit("rad"))
    disturbance: Disturbance = Field(default_factory=Disturbance)


class Sensor(_Section):
    """Encoder model: sampling, Gaussian noise, quantization."""

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


class Actuator(_Section):
    """Torque saturation, first-order lag and transport delay."""

    torque_limit: float = Field(
        2.0, gt=0, description="saturation |u| ≤ torque_limit", json_schema_extra=_unit("N·m")
    )
    lag: float = Field(
        0.0, ge=0, description="first-order lag time constant T (0: none)",
        json_schema_extra=_unit("s"),
    )
    delay_samples: int = Field(
        0, ge=0, description="transport delay in samples", json_schema_extra=_unit("samples")
    )


class QuinticSteps(_Section):
    """Rest-to-rest quintic moves, the angle held between moves."""

    kind: Literal["quintic-steps"] = "quintic-steps"
    start: float = Field(
        0.0, description="angle before the first move", json_schema_extra=_unit("rad")
    )
    moves: list[list[float]] = Field(
        default_factory=lambda: [[1.0, 2.0, 1.0], [10.0, 2.0, 0.0]],
        description="[start s, duration s, target rad] per move, in time order",
    )


class Multisine(_Section):
    """θd(t) = offset + Σ amplitudes[i] · sin(frequencies[i] · t + phases[i])."""

    kind: Literal["multisine"] = "multisine"
    amplitudes: list[float] = Field(
        default_factory=lambda: [0.5], description="amplitudes", json_schema_extra=_unit("rad")
    )
    frequencies: list[float] = Field(
        default_factory=lambda: [0.5], description="angular frequencies",
        json_schema_extra=_unit("rad/s"),
    )
    phases: list[float] = Field(
        default_factory=list, description="phases (empty: all zero)", json_schema_extra=_unit("rad")
    )
    offset: float = Field(0.0, description="constant offset", json_schema_extra=_unit("rad"))


Reference = Annotated[QuinticSteps | Multisine, Field(discriminator="kind")]
KIND_SECTIONS["reference"] = (QuinticSteps, Multisine)


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
        """
        return _build(self.to_dict(), overrides, source=f"scenario '{self.name}'")

    def to_dict(self) -> dict[str, Any]:
        """The fully resolved scenario as plain nested dicts."""
        return self.model_dump()

    def to_toml(self) -> str:
        """The fully resolved scenario as TOML text (all keys)."""
        return to_toml(self.to_dict())


# ---------------------------------------------------------------------------
# loading


def builtin_names() -> list[str]:
    """Names of the scenarios shipped with the package."""
    root = resources.files("esoarm") / "scenarios"
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: TOML syntax error: {exc}") from None


def _builtin_text(name: str) -> str:
    return (resources.files("esoarm") / "scenarios" / f"{name}.toml").read_text(encoding="utf-8")


def load_scenario(
    scenario: str | Path | Scenario = "test-1",
    overrides: dict[str, Any] | list[str] | None = None,
) -> Scenario:
    """Load a scenario by built-in name or TOML path, with optional overrides.

    Parameters
    ----------
    scenario : str, Path or Scenario
        A built-in name (see :func:`builtin_names`), a path to a TOML file, or
        an existing :class:`Scenario`.
    overrides : dict or list of str, optional
        Dotted keys to change, e.g. ``{"observer.eps": 0.05}`` or
        ``["observer.eps=0.05", "observer.discretization=zoh"]``.

    Raises
    ------
    ScenarioError
        Unknown scenario, missing file, TOML syntax error, unknown key, wrong
        type, or a value out of range; the message names the key or file.

    Examples
    --------
    >>> scn = load_scenario("test-1", ["observer.eps=0.05", "controller.kind=pid"])
    >>> scn.observer.eps, scn.controller.kind, scn.n_samples
    (0.05, 'pid', 1000)
    >>> load_scenario("test-1", {"obs.eps": 0.05})
    Traceback (most recent call last):
    ...
    esoarm.scenario.ScenarioError: override: unknown key 'obs.eps'; did you mean 'observer.eps'?
    """
    if isinstance(scenario, Scenario):
        return scenario.with_overrides(overrides or {})
    text_name = str(scenario)
    path = Path(text_name)
    if text_name in builtin_names() and not path.suffix:
        source = f"built-in scenario '{text_name}'"
        data = _read_toml(_builtin_text(text_name), source)
    elif path.suffix == ".toml" or path.exists() or "/" in text_name or "\\" in text_name:
        source = f"file '{text_name}'"
        if path.is_dir():
            raise ScenarioError(f"{source}: is a directory, expected a TOML file")
        if not path.is_file():
            raise ScenarioError(f"{source}: no such file")
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ScenarioError(f"{source}: cannot read: {exc}") from None
        data = _read_toml(text, source)
        data.setdefault("name", path.stem)
    else:
        names = builtin_names()
        close = difflib.get_close_matches(text_name, names, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ScenarioError(
            f"unknown scenario '{text_name}': not a built-in ({', '.join(names)}) "
            f"nor a .toml file{hint}"
        )
    return _build(data, overrides or {}, source=source)


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
                kept = {k: v for k, v in out[key].items() if k in shared}
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


def _valid_keys() -> list[str]:
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


def _build(data: dict[str, Any], overrides: dict[str, Any] | list[str], source: str) -> Scenario:
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
    overridden = {key for key, _ in pairs}

    def origin(key: str) -> str:  # blame the override when it set the offending key
        return "override" if key.split("[")[0] in overridden else source

    try:
        scn = Scenario.model_validate(merged)
    except ValidationError as exc:
        raise ScenarioError(_format_validation_error(exc, source, origin)) from None
    _check_consistency(scn, source, origin)
    return scn


def _check_key(key: str, source: str) -> None:
    valid = _valid_keys()
    if key in valid:
        return
    if not key.strip():
        raise ScenarioError(f"{source}: empty key; give a dotted key such as 'observer.eps'")
    # a whole table given to --set is not allowed either; suggest a leaf key
    close = difflib.get_close_matches(key, valid, n=1, cutoff=0.5)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise ScenarioError(f"{source}: unknown key '{key}'{hint}")


def _format_validation_error(exc: ValidationError, source: str,
                             origin: Callable[[str], str] | None = None) -> str:
    err = exc.errors()[0]
    loc = [str(p) for p in err["loc"] if not isinstance(p, int)]
    # drop the discriminator tag pydantic inserts for tagged unions
    section = loc[0] if loc else ""
    tags = {m.model_fields["kind"].default: m for m in KIND_SECTIONS.get(section, ())}
    tag_in_loc = [p for p in loc[1:2] if p in tags]
    loc = [p for i, p in enumerate(loc) if not (i == 1 and p in tags)]
    idx = [p for p in err["loc"] if isinstance(p, int)]
    key = ".".join(loc)
    more = len(exc.errors()) - 1
    tail = f" (and {more} more error{'s' if more > 1 else ''})" if more else ""
    kind = err["type"]
    if origin is not None:
        source = origin(key if kind != "union_tag_invalid" else key + ".kind")
    if kind == "extra_forbidden":
        valid = _valid_keys()
        if key in valid and tag_in_loc:  # a key of another kind of this section
            model = tags[tag_in_loc[0]]
            return (f"{source}: key '{key}' does not apply to {section} kind "
                    f"'{tag_in_loc[0]}' (its keys: {', '.join(model.model_fields)}){tail}")
        close = difflib.get_close_matches(key, valid, n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        return f"{source}: unknown key '{key}'{hint}{tail}"
    where = f"{key}[{']['.join(map(str, idx))}]" if idx else key
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
    return f"{source}: key '{where}' = {shown}: {msg}{tail}"


def _check_consistency(scn: Scenario, source: str,
                       origin: Callable[[str], str] | None = None) -> None:
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
    samples = scn.duration * scn.sensor.rate_hz
    if not samples <= MAX_SAMPLES:  # also catches an overflow to inf
        fail("duration", f"{scn.duration:g} s at {scn.sensor.rate_hz:g} Hz is {samples:.3g} "
             f"samples; at most {MAX_SAMPLES:.0e} are allowed")
    if scn.n_samples < 1:
        fail("duration", f"{scn.duration:g} s is shorter than one sample period ({ts:g} s)")
    ref = scn.reference
    if isinstance(ref, QuinticSteps):
        end = -math.inf
        for i, move in enumerate(ref.moves):
            if len(move) != 3:
                fail(f"reference.moves[{i}]", "each move is [start s, duration s, target rad]")
            t0, dur, _ = move
            if not all(math.isfinite(v) for v in move):
                fail(f"reference.moves[{i}]", "must be finite numbers")
            if dur <= 0:
                fail(f"reference.moves[{i}]", f"duration {dur:g} s must be > 0")
            if t0 < 0:
                fail(f"reference.moves[{i}]", f"start {t0:g} s must be >= 0")
            if t0 < end - 1e-12:
                fail(
                    f"reference.moves[{i}]",
                    f"starts at {t0:g} s, before the previous move ends ({end:g} s): "
                    "moves must be in time order and not overlap",
                )
            end = t0 + dur
    else:
        n = len(ref.amplitudes)
        if len(ref.frequencies) != n:
            fail("reference.frequencies", f"needs one entry per amplitude ({n})")
        if ref.phases and len(ref.phases) != n:
            fail("reference.phases", f"needs one entry per amplitude ({n}) or none")


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
        ("observer.eps", lambda: 1.0 / np.float64(obs.eps) ** 3,
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

    A discrete observer whose error poles are unstable or poorly damped at
    this sample rate, or faster than the samples support (see
    :func:`esoarm.studies.analysis.observer_warnings`); and settings that
    silently do nothing or less than asked (:func:`timing_warnings`).
    """
    from esoarm.studies.analysis import observer_warnings

    obs = scn.observer
    eps, disc = getattr(obs, "eps", None), getattr(obs, "discretization", None)
    observer = [] if eps is None or disc is None else observer_warnings(eps, scn.sample_time, disc)
    return [*observer, *timing_warnings(scn)]


def timing_warnings(scn: Scenario) -> list[str]:
    """Settings that the run's length or sample rate makes (partly) ineffective.

    A transport delay as long as the run (no command ever acts), a reference
    move that starts after the run has ended, a multisine tone at or above
    the Nyquist frequency of the samples, and a duration that is not a whole
    number of sample periods (the run is rounded to N samples).
    """
    out: list[str] = []
    ts, n = scn.sample_time, scn.n_samples
    end = n * ts
    delay = scn.actuator.delay_samples
    if delay >= n:
        out.append(f"actuator.delay_samples = {delay} ({delay * ts:g} s) is as long as the run "
                   f"({n} samples, {end:g} s): no command ever reaches the arm")
    ref = scn.reference
    if isinstance(ref, QuinticSteps):
        late = [i for i, move in enumerate(ref.moves) if len(move) == 3 and move[0] >= end]
        if late:
            i = late[0]
            more = f" (and {len(late) - 1} later moves)" if len(late) > 1 else ""
            out.append(f"reference.moves[{i}] starts at {ref.moves[i][0]:g} s, when the run has "
                       f"ended ({end:g} s): it is never tracked{more}; raise duration")
    else:
        nyquist = math.pi / ts
        fast = [i for i, w in enumerate(ref.frequencies) if abs(w) >= nyquist]
        if fast:
            i = fast[0]
            out.append(f"reference.frequencies[{i}] = {ref.frequencies[i]:g} rad/s is at or above "
                       f"the Nyquist frequency of the samples (π·rate_hz = {nyquist:g} rad/s): "
                       "the loop sees an aliased reference")
    steps = n * scn.substeps
    if scn.substeps > 10_000 or steps > 100_000_000:
        out.append(f"rig.step = {scn.rig.step:g} s is {scn.substeps:,} RK4 steps per sample, "
                   f"{steps:,} for the run: that takes hours in esoarm simulate; a step of "
                   f"about Ts/20 = {ts / 20:g} s is usually enough")
    if abs(end - scn.duration) > 1e-9 * max(scn.duration, 1.0):
        out.append(f"duration = {scn.duration:g} s is not a whole number of sample periods "
                   f"(Ts = {ts:g} s): the run has {n} samples ({end:g} s)")
    return out


# ---------------------------------------------------------------------------
# TOML output


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        # control characters are not allowed raw in a TOML string: \uXXXX
        escaped = "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c
                          for c in escaped)
        return f'"{escaped}"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def to_toml(data: dict[str, Any], _prefix: str = "") -> str:
    """Write nested dicts of scalars and lists as TOML text (tables last)."""
    lines: list[str] = []
    tables = []
    for key, value in data.items():
        if value is None:  # an absent optional section (e.g. [motor])
            continue
        if isinstance(value, dict):
            tables.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, value in tables:
        name = f"{_prefix}{key}"
        body = to_toml(value, name + ".")
        lines.append("")
        lines.append(f"[{name}]")
        lines.append(body.rstrip("\n"))
    return "\n".join(line for line in lines).lstrip("\n") + "\n"
