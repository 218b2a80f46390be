"""The registry of plant, observer and controller kinds: the one place a kind is added.

Each kind is a module following :mod:`esoarm.contract` (``KIND``, ``CODE``,
``JIT``, ``Params``, ``design`` and its step functions; optional ``FAST``,
``C_SOURCE``, ``check``, ``label``, ``summary``, ``warnings``, ``linearization``).
This module lists them per component and checks each when it is registered
(a missing name, a ``Params`` without the ``kind`` literal, a CODE or KIND
used twice: an ImportError naming the kind and what is missing).  From the
lists come the scenario's tagged unions (``plant.kind``, ``observer.kind``,
``controller.kind``), the lookup of a scenario's kinds (:func:`kinds_of`)
and, for the compiled engine, one dispatch function per step, *generated*
from the registered kinds with ``JIT = True``: it calls the kind whose CODE
is in element 0 of the parameter vector, and a CODE no compiled kind has is
an error (never another kind's step).  A kind with ``JIT = False`` (e.g. one
that calls a library numba cannot compile) runs only in the reference
engine; the batch engine runs its points in worker processes instead.

To add a kind: write its module and add it to the component's tuple below
(or, outside the package, e.g. in a test: ``register("observer", module)``).
Nothing in the engines, the CLI or the report changes.
"""

from __future__ import annotations

import inspect
import linecache
import math
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Annotated, Any, NamedTuple, cast

import numpy as np
from pydantic import Field

from esoarm import _jit
from esoarm._schema import Actuator
from esoarm.contract import (
    COMPONENTS,
    OPTIONAL,
    REQUIRED,
    REQUIRED_IF_JIT,
    ROTARY_UNITS,
    ControllerKind,
    ObserverKind,
    PlantDesign,
    PlantKind,
    Units,
    read_only,
)
from esoarm.controllers import adrc_error, adrc_tf, computed_torque, flc, pid, switch
from esoarm.observers import cascade, linear, nonlinear
from esoarm.plants import axis, dc_motor, lever_arm
from esoarm.plants.arms import urdf

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CONTROLLERS", "OBSERVERS", "PLANTS", "Kinds", "baseline_observer", "by_name", "can",
           "check_kind", "having",
           "check_steps",
           "compile_only", "compiled_selection", "covers", "hook",
           "kind_labels", "kinds_of", "observer_summary", "on_dispatch_change",
           "observer_warnings", "observers_for", "on_change", "register", "registry_stamp",
           "tagged_union", "units", "unregister"]

#: Registered kinds per component; the first is the default.  (mypy checks each module
#: against its component's protocol, :class:`esoarm.contract.PlantKind` etc.)
PLANTS: tuple[PlantKind, ...] = (lever_arm, urdf, axis, dc_motor)
OBSERVERS: tuple[ObserverKind, ...] = (linear, nonlinear, cascade)
CONTROLLERS: tuple[ControllerKind, ...] = (flc, pid, computed_torque, adrc_error, adrc_tf,
                                            switch)

#: What was registered at import: the kinds of the package itself.
_BUILTIN: dict[str, tuple[Any, ...]] = {
    "plant": PLANTS, "observer": OBSERVERS, "controller": CONTROLLERS}
_listeners: list[Callable[[], None]] = []


#: The capability flags (bool names of :data:`esoarm.contract.OPTIONAL`) and the component
#: whose kind carries each (``FAST``: all three).
_FLAGS: dict[str, str] = {"FAST": "all", "MOTOR": "plant", "RIG": "plant",
                          "AXIS_FIT": "plant", "NOISE_BUDGET": "observer",
                          "BASELINE": "observer", "FLC_LAW": "controller"}


def _registered(component: str) -> tuple[Any, ...]:
    return {"plant": PLANTS, "observer": OBSERVERS, "controller": CONTROLLERS}[component]


def check_kind(component: str, module: Any, others: tuple[Any, ...] = ()) -> None:
    """Check that ``module`` is a complete kind of ``component`` (the contract).

    Parameters
    ----------
    component : {"plant", "observer", "controller"}
        Its component.
    module : module
        The kind module.
    others : tuple of modules
        The kinds already registered for the component (KIND and CODE must differ).

    Raises
    ------
    ImportError
        One line naming the kind and what is missing or wrong.
    """
    if component not in COMPONENTS:
        raise ImportError(f"esoarm.kinds: no component {component!r}; the components are "
                          f"{', '.join(COMPONENTS)}")
    name = getattr(module, "__name__", repr(module))
    kind = getattr(module, "KIND", None)
    who = f"{component} kind {kind!r} ({name})" if isinstance(kind, str) else \
        f"{component} kind module {name}"
    jit = getattr(module, "JIT", None)
    required = REQUIRED[component] + (REQUIRED_IF_JIT[component] if jit else ())
    missing = [n for n in required if not hasattr(module, n)]
    if missing:
        raise ImportError(f"esoarm.kinds: {who} does not define {', '.join(missing)} "
                          "(see esoarm.contract and docs/contract.md)")
    code = module.CODE
    if not isinstance(kind, str) or not kind:
        raise ImportError(f"esoarm.kinds: {who}: KIND must be a non-empty str")
    if isinstance(code, bool) or not isinstance(code, int) or code < 0:
        raise ImportError(f"esoarm.kinds: {who}: CODE must be an int >= 0, got {code!r}")
    for flag in ("JIT", *_FLAGS):
        if not isinstance(getattr(module, flag, False), bool):
            raise ImportError(f"esoarm.kinds: {who}: {flag} must be True or False")
    steps = tuple(n for n in required
                  if n not in ("KIND", "CODE", "JIT", "Params", "design", "state_size"))
    source = getattr(module, "C_SOURCE", None)
    if source is not None and not (isinstance(source, str) and hasattr(module, "__file__")
                                   and (Path(module.__file__).parent / source).is_file()):
        raise ImportError(f"esoarm.kinds: {who}: C_SOURCE = {source!r} is not a file beside "
                          "the module")
    for fn in steps + tuple(n for n, d in OPTIONAL.items()
                            if d is None and n != "C_SOURCE" and hasattr(module, n)):
        if not callable(getattr(module, fn)):
            raise ImportError(f"esoarm.kinds: {who}: {fn} must be a function")
    for fn in ("design", "state_size"):
        if fn in required and not callable(getattr(module, fn)):
            raise ImportError(f"esoarm.kinds: {who}: {fn} must be a function")
    if jit:
        plain = [fn for fn in steps if not _jit.is_jitable(getattr(module, fn))]
        if plain:
            raise ImportError(f"esoarm.kinds: {who} has JIT = True but {', '.join(plain)} "
                              "not decorated with esoarm._jit.jitable")
    params = module.Params
    fields = getattr(params, "model_fields", None)
    if not isinstance(params, type) or fields is None:
        raise ImportError(f"esoarm.kinds: {who}: Params must be an esoarm._schema.Section")
    if "kind" not in fields:
        raise ImportError(f"esoarm.kinds: {who}: Params has no field 'kind' "
                          f"(kind: Literal[{kind!r}] = {kind!r})")
    if fields["kind"].default != kind:
        raise ImportError(f"esoarm.kinds: {who}: Params.kind defaults to "
                          f"{fields['kind'].default!r}, not KIND = {kind!r}")
    for other in others:
        if other is module:
            raise ImportError(f"esoarm.kinds: {who} is registered already")
        if hook(module, "BASELINE") and hook(other, "BASELINE"):
            raise ImportError(f"esoarm.kinds: {who}: BASELINE = True is {other.__name__}'s "
                              "already (one reference observer)")
        for attr in ("KIND", "CODE"):
            if getattr(other, attr) == getattr(module, attr):
                raise ImportError(f"esoarm.kinds: {who}: {attr} = {getattr(module, attr)!r} "
                                  f"is {other.__name__}'s already")


def _check_all() -> None:
    for component in COMPONENTS:
        kinds = _registered(component)
        for i, module in enumerate(kinds):
            check_kind(component, module, kinds[:i])


def tagged_union(kinds: tuple[Any, ...]) -> Any:
    """The pydantic tagged union of the kinds' ``Params`` (discriminator ``kind``).

    Parameters
    ----------
    kinds : tuple of modules
        The registered kinds of one component (at least one), e.g. :data:`PLANTS`.

    Returns
    -------
    typing.Annotated
        ``Params₁ | Params₂ | …`` annotated with ``Field(discriminator="kind")``, the type
        of the component's table in the scenario schema.
    """
    models = tuple(m.Params for m in kinds)
    union = models[0]
    for model in models[1:]:
        union = union | model
    return Annotated[union, Field(discriminator="kind")]


def by_name(kinds: tuple[Any, ...], name: str) -> Any:
    """The kind module registered as ``name``.

    Parameters
    ----------
    kinds : tuple of modules
        The registered kinds of one component.
    name : str
        A KIND tag, as written in the scenario (``"lever-arm"``).

    Returns
    -------
    module
        The kind whose KIND is ``name``.

    Raises
    ------
    KeyError
        No kind has that tag (the scenario schema refuses such a name first).

    Examples
    --------
    >>> by_name(PLANTS, "axis").CODE
    2
    """
    for module in kinds:
        if module.KIND == name:
            return module
    raise KeyError(name)  # pragma: no cover - the scenario validated the name


def hook(module: Any, name: str) -> Any:
    """The optional name ``name`` of a kind module, or its default (:data:`OPTIONAL`).

    Parameters
    ----------
    module : module
        A kind module.
    name : str
        One of the keys of :data:`esoarm.contract.OPTIONAL` (``"FAST"``, ``"check"``, ...).

    Returns
    -------
    object
        The module's attribute, or the default when it does not define it.

    Examples
    --------
    >>> hook(by_name(PLANTS, "lever-arm"), "MOTOR"), hook(by_name(OBSERVERS, "linear"), "MOTOR")
    (True, False)
    """
    return getattr(module, name, OPTIONAL[name])


class Kinds(NamedTuple):
    """The kind modules of one scenario: plant, observer, controller."""

    plant: PlantKind
    observer: ObserverKind
    controller: ControllerKind

    @property
    def jit(self) -> bool:
        """All three compile with numba (the batch engine can run them)."""
        return bool(self.plant.JIT and self.observer.JIT and self.controller.JIT)

    @property
    def fast(self) -> bool:
        """The fast engine models all three (each declares ``FAST = True``)."""
        return all(bool(hook(m, "FAST")) for m in self)


def can(scn: Scenario, capability: str) -> bool:
    """Whether the scenario's kinds declare ``capability`` (a flag of :data:`OPTIONAL`).

    The way a consumer asks what a kind can do, never by its name: ``"RIG"``,
    ``"MOTOR"`` and ``"AXIS_FIT"`` of the plant, ``"NOISE_BUDGET"`` and ``"BASELINE"``
    of the observer, ``"FLC_LAW"`` of the controller, ``"FAST"`` of all three.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.
    capability : str
        The flag's name.

    Returns
    -------
    bool
        True when the component that carries the flag declares it.

    Raises
    ------
    KeyError
        ``capability`` is not a capability flag.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> can(load_scenario("test-1"), "RIG"), can(load_scenario("emps"), "RIG")
    (True, False)
    >>> can(load_scenario("test-1", {"controller.kind": "pid"}), "FLC_LAW")
    False
    >>> can(load_scenario("emps"), "AXIS_FIT"), can(load_scenario("test-1"), "AXIS_FIT")
    (True, False)
    """
    k = kinds_of(scn)
    carrier = _FLAGS[capability]
    if carrier == "all":
        return k.fast
    return bool(hook(getattr(k, carrier), capability))


def having(component: str, capability: str) -> tuple[str, ...]:
    """The KINDs of the registered ``component`` kinds that declare ``capability``.

    In registration order; a kind registered at run time with the flag is among them,
    so a consumer that compares kinds (``analyze --bandwidth``) needs no list of names.

    Parameters
    ----------
    component : {"plant", "observer", "controller"}
        The component.
    capability : str
        A capability flag carried by that component (``"NOISE_BUDGET"``, ...).

    Returns
    -------
    tuple of str
        The KIND tags, possibly empty.

    Examples
    --------
    >>> having("observer", "NOISE_BUDGET")
    ('linear', 'cascade')
    """
    if _FLAGS.get(capability) not in (component, "all"):
        raise KeyError(f"{capability!r} is not a capability flag of {component} kinds")
    return tuple(m.KIND for m in _registered(component) if hook(m, capability))


def observers_for(joints: int) -> tuple[str, ...]:
    """The KINDs of the registered observer kinds whose design takes ``joints`` joints.

    Asked of each kind, not listed by name: its ``design`` is tried on the registration
    case (:func:`check_steps`, its ``Params`` defaults) of a plant with ``joints`` joints,
    and a kind that refuses the shape in its own words (ValueError, e.g. "one joint
    only") is left out.  A kind registered at run time is asked too.

    Parameters
    ----------
    joints : int
        The plant's number of joints (≥ 1).

    Returns
    -------
    tuple of str
        The KIND tags, in registration order.

    Examples
    --------
    >>> observers_for(2)
    ('linear', 'nonlinear', 'cascade')
    """
    out = []
    for module in _registered("observer"):
        who = f"observer kind {module.KIND!r}"
        params = _params(who, module)
        case = _Case(plant=PLANTS[0].Params(), observer=params,
                     controller=CONTROLLERS[0].Params(), actuator=Actuator())
        with np.errstate(all="ignore"):
            if _designed(who, module, case, joints) is not None:
                out.append(module.KIND)
    return tuple(out)


def baseline_observer() -> str:
    """The KIND of the reference observer (``BASELINE = True``) criteria are stated against.

    Returns
    -------
    str
        Its KIND.

    Raises
    ------
    LookupError
        No registered observer kind declares ``BASELINE``.

    Examples
    --------
    >>> baseline_observer()
    'linear'
    """
    base = having("observer", "BASELINE")
    if not base:
        raise LookupError("no registered observer kind declares BASELINE = True")
    return base[0]


def kinds_of(scn: Scenario) -> Kinds:
    """The kind modules a scenario selects.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    Kinds
        The plant, observer and controller modules named by its ``kind`` keys.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> k = kinds_of(load_scenario("test-1", {"observer.kind": "nonlinear"}))
    >>> k.plant.KIND, k.observer.KIND, k.controller.KIND, k.jit
    ('lever-arm', 'nonlinear', 'flc', True)
    """
    return Kinds(by_name(PLANTS, scn.plant.kind), by_name(OBSERVERS, scn.observer.kind),
                 by_name(CONTROLLERS, scn.controller.kind))


def units(scn: Scenario | None) -> Units:
    """The units every command prints for the plant of ``scn`` (its kind's ``units_of``).

    The one place a table, a JSON ``"units"`` field, a plot label or a report line gets
    the unit of a position, a rate or a drive: m, m/s, N on a prismatic axis; rad, rad/s,
    N·m on every rotary joint (a kind without ``units_of``, and ``scn`` None).

    Parameters
    ----------
    scn : Scenario or None
        A validated scenario (None: the rotary units).

    Returns
    -------
    Units
        Its units (:class:`esoarm.contract.Units`).

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> units(load_scenario("emps")).position, units(load_scenario("test-1")).position
    ('m', 'rad')
    """
    if scn is None:
        return ROTARY_UNITS
    fn = hook(by_name(PLANTS, scn.plant.kind), "units_of")
    return ROTARY_UNITS if fn is None else cast(Units, fn(scn.plant))


def kind_labels(scn: Scenario) -> tuple[str, str]:
    """Short descriptions of the observer and the controller of ``scn`` for titles.

    Each kind's ``label(params)``: ("euler", "eso compensation") for the paper's
    linear ESO and FLC, "euler nonlinear ESO"; a kind without ``label`` is named
    ("luenberger observer", "pid controller").

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    (observer, controller) : (str, str)
        The two labels.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> kind_labels(load_scenario("test-1", {"controller.kind": "pid"}))
    ('euler', 'pid controller')
    """
    k = kinds_of(scn)
    obs_label, ctl_label = hook(k.observer, "label"), hook(k.controller, "label")
    obs_text = obs_label(scn.observer) if obs_label else f"{k.observer.KIND} observer"
    ctl_text = ctl_label(scn.controller) if ctl_label else f"{k.controller.KIND} controller"
    return str(obs_text), str(ctl_text)


def observer_summary(scn: Scenario) -> str:
    """One line on the observer's settings (the kind's ``summary``), e.g. ``ε = 0.09 s (euler)``.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    str
        The kind's summary, or ``observer kind '<KIND>'`` for a kind without one.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> observer_summary(load_scenario("test-1"))
    'ε = 0.09 s (euler)'
    """
    k = kinds_of(scn).observer
    summary = hook(k, "summary")
    return str(summary(scn.observer)) if summary else f"observer kind '{k.KIND}'"


def observer_warnings(scn: Scenario) -> list[str]:
    """What the observer kind finds doubtful in its settings at the scenario's Ts (``warnings``).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    list of str
        One message each (empty: nothing doubtful, or the kind has no ``warnings``); a
        message containing "unstable" marks an observer that cannot work.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> observer_warnings(load_scenario("test-1", {"observer.eps": 0.004}))[0][:60]
    "observer.eps = 0.004 s with discretization 'euler' at Ts = 0"
    """
    warn = hook(kinds_of(scn).observer, "warnings")
    return list(warn(scn.observer, scn.sample_time)) if warn else []


# ---------------------------------------------------------------------------
# the passive check: every step run once on exactly sized arrays (as Gymnasium's env checker)

#: Sample period [s] and nominal input gain [1/(kg·m²)] of the registration cases.
_CASE_TS = 0.02
_CASE_B0 = 20.0


class _Case(NamedTuple):
    """The tables a kind's ``design`` reads, for the registration cases (defaults)."""

    plant: Any
    observer: Any
    controller: Any
    actuator: Any


def _params(who: str, module: Any) -> Any:
    try:
        return module.Params()
    except Exception as exc:  # noqa: BLE001 - any failure is the kind's to fix
        raise ImportError(f"esoarm.kinds: {who}: Params() must build from its defaults (the "
                          f"registration check designs a case with them): "
                          f"{str(exc).splitlines()[0]}") from None


def _run_step(who: str, step: str, nj: int, sizes: str, func: Callable[..., object],
              *args: object) -> None:
    try:
        func(*args)
    except (IndexError, ValueError, TypeError, ZeroDivisionError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ImportError(f"esoarm.kinds: {who}: {step} on the {nj}-joint case: {first} "
                          f"({sizes})") from None


def _finite(who: str, step: str, nj: int, name: str, array: np.ndarray, sizes: str) -> None:
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        raise ImportError(f"esoarm.kinds: {who}: {step} on the {nj}-joint case left {name}"
                          f"[{int(bad[0])}] of shape {array.shape} unwritten or not finite "
                          f"({sizes})")


def _designed(who: str, module: Any, case: _Case, nj: int) -> Any:
    """The kind's design for an ``nj``-joint plant, or None where it refuses the shape."""
    plant = PlantDesign(vector=read_only(np.array([math.nan])), x0=np.zeros(2 * nj), n_joints=nj,
                        b0=read_only(np.full(nj, _CASE_B0)))
    try:
        d = module.design(case, plant, _CASE_TS)
    except ValueError:  # the kind refuses this plant in its own words (e.g. one joint only)
        return None
    except Exception as exc:  # noqa: BLE001
        raise ImportError(f"esoarm.kinds: {who}: design on the {nj}-joint case: "
                          f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                          ) from None
    vector = np.asarray(getattr(d, "vector", None), dtype=float)
    n_state = getattr(d, "n_state", None)
    if vector.ndim != 1 or vector.size < 1 or vector[0] != module.CODE:
        raise ImportError(f"esoarm.kinds: {who}: design on the {nj}-joint case: vector of "
                          f"shape {vector.shape} must be 1-D with vector[0] = CODE {module.CODE}")
    if isinstance(n_state, bool) or not isinstance(n_state, int) or n_state < 1:
        raise ImportError(f"esoarm.kinds: {who}: design on the {nj}-joint case: n_state "
                          f"{n_state!r} must be an int >= 1")
    return d


def _check_observer(who: str, module: Any, case: _Case) -> None:
    params = case.observer
    per = module.state_size(params)
    if isinstance(per, bool) or not isinstance(per, int) or per < 1:
        raise ImportError(f"esoarm.kinds: {who}: state_size(params) = {per!r}: must be an "
                          "int >= 1 (states per joint)")
    for nj in (1, 2):
        d = _designed(who, module, case, nj)
        if d is None:
            continue
        if d.n_state != per * nj:
            raise ImportError(f"esoarm.kinds: {who}: design on the {nj}-joint case has n_state "
                              f"{d.n_state}, state_size declares {per} per joint ({per * nj})")
        p = d.vector
        sizes = f"z of shape ({d.n_state},) = state_size {per} × {nj}, ẑ ({3 * nj},), " \
                f"y and u ({nj},)"
        z = np.zeros(d.n_state)
        y = np.array([0.1, -0.2][:nj])
        u = np.array([0.3, -0.1][:nj])
        zhat = np.full(3 * nj, math.nan)
        _run_step(who, "initialize", nj, sizes, module.initialize, z, y, p)
        _finite(who, "initialize", nj, "z", z, sizes)
        _run_step(who, "estimate", nj, sizes, module.estimate, z, y, p, zhat)
        _finite(who, "estimate", nj, "zhat", zhat, sizes)
        _run_step(who, "advance", nj, sizes, module.advance, z, zhat, y, u, p)
        _finite(who, "advance", nj, "z", z, sizes)
        guess = np.full(nj, math.nan)
        _run_step(who, "predict", nj, sizes, module.predict, z, zhat, p, guess)
        _finite(who, "predict", nj, "y", guess, sizes)
    lin = hook(module, "linearization")
    if lin is not None:
        model = lin(params, _CASE_TS, _CASE_B0)
        n = np.shape(model.p)[0] if np.ndim(model.p) == 2 else -1
        want = {"p": (n, n), "q": (n, 1), "gamma": (n, 1), "hz": (3, n), "hy": (3, 1)}
        for name, shape in want.items():
            got = np.shape(getattr(model, name))
            if got != shape or n != per or not np.all(np.isfinite(getattr(model, name))):
                raise ImportError(f"esoarm.kinds: {who}: linearization's {name} has shape "
                                  f"{got}, must be {(per, per) if name == 'p' else shape} "
                                  f"and finite (state_size {per})")


def _check_controller(who: str, module: Any, case: _Case) -> None:
    for nj in (1, 2):
        d = _designed(who, module, case, nj)
        if d is None:
            continue
        p = d.vector
        sizes = f"c of shape ({d.n_state},), ẑ ({3 * nj},), y and u ({nj},), refs ({3 * nj}, 2)"
        c = np.zeros(d.n_state)
        y = np.array([0.1, -0.2][:nj])
        zhat = np.array([0.1, 0.5, -1.0, -0.2, 0.2, 0.5][:3 * nj])
        refs = np.tile(np.array([[0.2], [0.1], [0.0], [-0.1], [0.0], [0.3]][:3 * nj]), (1, 2))
        u = np.full(nj, math.nan)
        _run_step(who, "initialize", nj, sizes, module.initialize, c, y, p)
        _finite(who, "initialize", nj, "c", c, sizes)
        for k in (0, 1):
            _run_step(who, "control", nj, sizes,
                      module.control, c, zhat, y, refs, k, p, u)
            _finite(who, "control", nj, "u", u, sizes)
            _finite(who, "control", nj, "c", c, sizes)


def check_steps(component: str, module: Any) -> None:
    """Run each step of an observer or controller kind once on exactly sized arrays.

    The passive check of registration (as Gymnasium's environment checker): the kind
    designs a one-joint and a two-joint case (its ``Params`` defaults, Ts = 0.02 s,
    b0 = 20 per joint; a case its ``design`` refuses with ValueError, e.g. "one joint
    only", is left out), then every step runs once on arrays of exactly the declared
    size -- z of ``state_size(params)`` per joint, ẑ of 3 per joint, y and u of one per
    joint -- which NumPy bounds-checks.  Each output must be written and finite, the
    design's ``n_state`` must be the declared size, and ``linearization``'s matrices must
    have the shapes of :class:`esoarm.contract.ObserverLinearization`.  Plant kinds are
    held to the engines by the tests instead.

    Parameters
    ----------
    component : {"plant", "observer", "controller"}
        The kind's component (plants pass unchecked).
    module : module
        The kind module (its names checked by :func:`check_kind` first).

    Raises
    ------
    ImportError
        One line naming the kind, the step, the case and the shapes.
    """
    if component == "plant":
        return
    name = getattr(module, "__name__", repr(module))
    who = f"{component} kind {module.KIND!r} ({name})"
    params = _params(who, module)
    case = _Case(plant=PLANTS[0].Params(),
                 observer=params if component == "observer" else OBSERVERS[0].Params(),
                 controller=params if component == "controller" else CONTROLLERS[0].Params(),
                 actuator=Actuator())
    with np.errstate(all="ignore"):
        if component == "observer":
            _check_observer(who, module, case)
        else:
            _check_controller(who, module, case)



# ---------------------------------------------------------------------------
# registering kinds at run time (a kind outside the package, a test's kind)


def on_change(callback: Callable[[], None]) -> None:
    """Call ``callback()`` after each :func:`register` / :func:`unregister`.

    The scenario schema rebuilds its tagged unions, the compiled engine drops
    kernels compiled with the former dispatch functions.

    Parameters
    ----------
    callback : callable
        Called without arguments; its return value is ignored.
    """
    _listeners.append(callback)


def _set(component: str, kinds: tuple[Any, ...]) -> None:
    global PLANTS, OBSERVERS, CONTROLLERS
    if component == "plant":
        PLANTS = kinds
    elif component == "observer":
        OBSERVERS = kinds
    else:
        CONTROLLERS = kinds
    if _selection is not None:  # a kind removed from the registry leaves the selection
        _selection.update({c: tuple(m for m in _selection[c] if m in _registered(c))
                           for c in COMPONENTS})
    _generate_dispatch()
    for callback in _listeners:
        callback()
    for callback in _dispatch_listeners:
        callback()


def register(component: str, module: ModuleType) -> None:
    """Add the kind ``module`` to ``component`` ("plant", "observer" or "controller").

    The kind is checked first (:func:`check_kind`); after this call scenarios accept
    ``<component>.kind = module.KIND`` and every engine runs it.

    Parameters
    ----------
    component : {"plant", "observer", "controller"}
        The component the kind belongs to.
    module : module
        The kind module (see :mod:`esoarm.contract`).

    Raises
    ------
    ImportError
        The module is not a complete kind, or its KIND or CODE is taken, or one of its
        steps writes past an array or leaves an output unwritten or not finite
        (:func:`check_steps`, one line naming the step and the shape).
    """
    kinds = _registered(component) if component in COMPONENTS else ()
    check_kind(component, module, kinds)
    check_steps(component, module)
    _set(component, (*kinds, module))


def unregister(component: str, module: ModuleType) -> None:
    """Remove a kind added by :func:`register` (the package's own kinds stay).

    Parameters
    ----------
    component : {"plant", "observer", "controller"}
        The component it was registered to.
    module : module
        The kind module; a module not registered there is ignored.

    Raises
    ------
    ValueError
        ``module`` is one of the package's own kinds.
    """
    if module in _BUILTIN.get(component, ()):
        raise ValueError(f"{component} kind {module.KIND!r} belongs to esoarm; it stays")
    _set(component, tuple(m for m in _registered(component) if m is not module))


def _builtin_root() -> Path:
    return Path(__file__).resolve().parent


def registry_stamp() -> str:
    """'' for the package's own kinds, else a hash of every kind added at run time.

    The compiled engine keys its on-disk cache on it (kernels compiled with other
    dispatch functions are kept apart): the added modules' sources, their
    components and the generated dispatch.

    Returns
    -------
    str
        ``""`` or 16 hexadecimal digits of a SHA-256.

    Examples
    --------
    >>> registry_stamp()
    ''
    """
    extra = [(c, m) for c in COMPONENTS for m in _registered(c) if m not in _BUILTIN[c]]
    if not extra and all(_registered(c) == _BUILTIN[c] for c in COMPONENTS):
        return ""
    import hashlib  # only for a registry with kinds of one's own (~5 ms to import)

    digest = hashlib.sha256(_DISPATCH_SOURCE.encode())
    for component, module in extra:
        digest.update(component.encode())
        try:
            digest.update(Path(inspect.getfile(module)).read_bytes())
        except (OSError, TypeError):  # pragma: no cover - a module without a file
            digest.update(repr(module).encode())
    return digest.hexdigest()[:16]


# ---------------------------------------------------------------------------
# dispatch for the compiled engine: element 0 of each vector is the kind's CODE

#: The dispatched steps: component -> step -> its arguments (``p`` the kind's vector).
STEPS: dict[str, dict[str, str]] = {
    "plant": {"advance": "x, u, t0, h, nsub, p",
              "advance_block": "xs, us, live, t0, h, nsub, p",
              "acceleration": "x, u, t, p, out",
              "observer_input": "zhat, u, p, v"},
    "observer": {"initialize": "z, y, p",
                 "estimate": "z, y, p, zhat",
                 "advance": "z, zhat, y, u, p"},
    "controller": {"initialize": "c, y, p",
                   "control": "c, zhat, y, refs, k, p, u"},
}

#: Each argument of :data:`STEPS`: (type, description), for the generated docstrings.
STEP_ARGS: dict[str, tuple[str, str]] = {
    "x": ("ndarray", "Plant state: angles [rad] in x[:n], rates [rad/s] in x[n:2n], then "
          "further states."),
    "xs": ("ndarray", "Plant states of a block of runs, one row per run."),
    "u": ("ndarray", "Drive [N·m] per joint (plant), observer input (observer) or output "
          "command [N·m] (controller)."),
    "us": ("ndarray", "Drive [N·m] per run and joint."),
    "live": ("ndarray", "Which runs of the block to advance (bool)."),
    "t0": ("float", "Start of the sample [s]."),
    "t": ("float", "Time [s]."),
    "h": ("float", "Integration step [s]."),
    "nsub": ("int", "Steps per sample (nsub·h = Ts)."),
    "p": ("ndarray", "The kind's design vector; p[0] is its CODE."),
    "out": ("ndarray", "Output: true acceleration per joint [rad/s²]."),
    "zhat": ("ndarray", "Estimate: angle [rad], rate [rad/s], perturbation [rad/s²] of "
             "joint j in zhat[3j:3j+3]."),
    "v": ("ndarray", "Output: the observer input per joint."),
    "z": ("ndarray", "Observer state."),
    "y": ("ndarray", "Measured angle(s) [rad]."),
    "c": ("ndarray", "Controller state."),
    "refs": ("ndarray", "References θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows "
             "3j..3j+2, one column per sample."),
    "k": ("int", "Sample index (column of refs)."),
}

# The generated functions (typed here for mypy; bodies made by _generate_dispatch).
plant_advance: Callable[[np.ndarray, np.ndarray, float, float, int, np.ndarray], None]
plant_advance_block: Callable[[np.ndarray, np.ndarray, np.ndarray, float, float, int,
                               np.ndarray], None]
plant_acceleration: Callable[[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray], None]
plant_observer_input: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]
observer_initialize: Callable[[np.ndarray, np.ndarray, np.ndarray], None]
observer_estimate: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]
observer_advance: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]
controller_initialize: Callable[[np.ndarray, np.ndarray, np.ndarray], None]
controller_control: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int,
                              np.ndarray, np.ndarray], None]

_DISPATCH_SOURCE = ""
_generation = 0
#: The compiled kinds the dispatch calls, per component (None: every registered one);
#: see :func:`compile_only`.
_selection: dict[str, tuple[Any, ...]] | None = None
_dispatch_listeners: list[Callable[[], None]] = []


def on_dispatch_change(callback: Callable[[], None]) -> None:
    """Call ``callback()`` after the dispatch functions are generated again.

    After :func:`register`, :func:`unregister` and :func:`compile_only` (which
    changes no scenario, only what the compiled kernels contain).

    Parameters
    ----------
    callback : callable
        Called without arguments; its return value is ignored.
    """
    _dispatch_listeners.append(callback)


def compiled_selection() -> str:
    """'' when the dispatch calls every compiled kind, else the KINDs it calls.

    Returns
    -------
    str
        E.g. ``"lever-arm.linear.flc+pid"``: the plant, observer and controller kinds
        (``+`` between kinds of a component), for the name of a kernel cache.

    Examples
    --------
    >>> compiled_selection()
    ''
    """
    if _selection is None:
        return ""
    return ".".join("+".join(m.KIND for m in _selection[c]) for c in COMPONENTS)


def covers(kinds: Kinds) -> bool:
    """The dispatch functions call each of ``kinds`` (see :func:`compile_only`).

    Parameters
    ----------
    kinds : Kinds
        A scenario's kinds (:func:`kinds_of`).

    Returns
    -------
    bool
        False also for a kind that does not compile (``JIT = False``).
    """
    return all(m.JIT and (_selection is None or m in _selection[c])
               for c, m in zip(COMPONENTS, kinds, strict=True))


def compile_only(used: list[Kinds] | None) -> bool:
    """Let the compiled dispatch call only the kinds in ``used`` (None: every kind).

    numba compiles every kind a dispatch function can call into each kernel; a
    kernel for the paper's lever arm, linear ESO, FLC and PID compiles in about
    two thirds of the time of one for every kind.  The kernels are cached apart
    per selection (:func:`compiled_selection`).  A point of another kind needs
    another selection: the compiled engine widens it (:func:`covers`).  The
    numbers do not depend on the selection: each kind's functions are the same.

    Parameters
    ----------
    used : list of Kinds or None
        The kinds of the scenarios to be run (kinds with ``JIT = False`` are left
        out), or None for every registered kind.

    Returns
    -------
    bool
        Whether the dispatch changed (the compiled kernels must be loaded again).
    """
    global _selection
    if used is None:
        selection = None
    else:
        chosen = {c: {m for k in used for cc, m in zip(COMPONENTS, k, strict=True)
                      if cc == c and m.JIT} for c in COMPONENTS}
        selection = {c: tuple(m for m in _registered(c) if m in chosen[c])
                     for c in COMPONENTS}
        if all(len(selection[c]) == len([m for m in _registered(c) if m.JIT])
               for c in COMPONENTS):
            selection = None  # every compiled kind: the usual kernels
    if selection == _selection:
        return False
    _selection = selection
    _generate_dispatch()
    for callback in _dispatch_listeners:
        callback()
    return True


def dispatch_source() -> str:
    """The Python source of the dispatch functions generated from the registry.

    Returns
    -------
    str
        A module's source: one function ``<component>_<step>(<args>)`` per entry of
        :data:`STEPS`, each with a numpydoc docstring (:data:`STEP_ARGS`).
    """
    lines = ['"""Generated by esoarm.kinds from the registered kinds (do not edit)."""', ""]
    for component in COMPONENTS:
        compiled = [(i, m) for i, m in enumerate(_registered(component)) if m.JIT
                    and (_selection is None or m in _selection[component])]
        known = ", ".join(f"{m.KIND}={m.CODE}" for _, m in compiled) or "none"
        for step, args in STEPS[component].items():
            lines += ["", f"def {component}_{step}({args}):",
                      f'    """``{step}`` of the compiled {component} kind whose CODE is p[0].',
                      "", "    Parameters", "    ----------"]
            for arg in args.split(", "):
                kind_of, text = STEP_ARGS[arg]
                lines += [f"    {arg} : {kind_of}", f"        {text}"]
            lines += ['    """', "    code = p[0]"]
            for n, (i, m) in enumerate(compiled):
                lines += [f"    {'if' if n == 0 else 'elif'} code == {float(m.CODE)!r}:",
                          f"        _{component}_{i}.{step}({args})"]
            fail = (f"    raise ValueError('esoarm: no compiled {component} kind has this CODE "
                    f"(compiled: {known})')")
            lines += ["    else:", "    " + fail] if compiled else [fail]
            lines += ["    return None"] if not compiled else []
    return "\n".join(lines) + "\n"


def _generate_dispatch() -> None:
    """(Re)build the dispatch functions from the registry, marked for numba."""
    global _DISPATCH_SOURCE, _generation
    source = dispatch_source()
    _generation += 1
    filename = f"<esoarm.kinds dispatch {_generation}>"
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    namespace: dict[str, Any] = {f"_{c}_{i}": m for c in COMPONENTS
                                 for i, m in enumerate(_registered(c))}
    exec(compile(source, filename, "exec"), namespace)  # noqa: S102 - our own generated code
    for component in COMPONENTS:
        for step in STEPS[component]:
            func = namespace[f"{component}_{step}"]
            func.__module__ = __name__
            globals()[f"{component}_{step}"] = _jit.jitable(cast(Callable[..., None], func))
    _DISPATCH_SOURCE = source


_check_all()
_generate_dispatch()
