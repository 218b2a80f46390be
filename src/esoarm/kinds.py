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
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Annotated, Any, NamedTuple, cast

import numpy as np
from pydantic import Field

from esoarm import _jit
from esoarm.contract import (
    COMPONENTS,
    OPTIONAL,
    REQUIRED,
    REQUIRED_IF_JIT,
    ROTARY_UNITS,
    ControllerKind,
    ObserverKind,
    PlantKind,
    Units,
)
from esoarm.controllers import computed_torque, flc, pid
from esoarm.observers import cascade, linear, nonlinear
from esoarm.plants import axis, lever_arm
from esoarm.plants.arms import urdf

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CONTROLLERS", "OBSERVERS", "PLANTS", "Kinds", "by_name", "check_kind",
           "compile_only", "compiled_selection", "covers", "hook",
           "kind_labels", "kinds_of", "observer_summary", "on_dispatch_change",
           "observer_warnings", "on_change", "register", "registry_stamp",
           "tagged_union", "units", "unregister"]

#: Registered kinds per component; the first is the default.  (mypy checks each module
#: against its component's protocol, :class:`esoarm.contract.PlantKind` etc.)
PLANTS: tuple[PlantKind, ...] = (lever_arm, urdf, axis)
OBSERVERS: tuple[ObserverKind, ...] = (linear, nonlinear, cascade)
CONTROLLERS: tuple[ControllerKind, ...] = (flc, pid, computed_torque)

#: What was registered at import: the kinds of the package itself.
_BUILTIN: dict[str, tuple[Any, ...]] = {
    "plant": PLANTS, "observer": OBSERVERS, "controller": CONTROLLERS}
_listeners: list[Callable[[], None]] = []


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
    for flag in ("JIT", "FAST", "MOTOR"):
        if not isinstance(getattr(module, flag, False), bool):
            raise ImportError(f"esoarm.kinds: {who}: {flag} must be True or False")
    steps = tuple(n for n in required if n not in ("KIND", "CODE", "JIT", "Params", "design"))
    source = getattr(module, "C_SOURCE", None)
    if source is not None and not (isinstance(source, str) and hasattr(module, "__file__")
                                   and (Path(module.__file__).parent / source).is_file()):
        raise ImportError(f"esoarm.kinds: {who}: C_SOURCE = {source!r} is not a file beside "
                          "the module")
    for fn in steps + tuple(n for n, d in OPTIONAL.items()
                            if d is None and n != "C_SOURCE" and hasattr(module, n)):
        if not callable(getattr(module, fn)):
            raise ImportError(f"esoarm.kinds: {who}: {fn} must be a function")
    if not callable(module.design):
        raise ImportError(f"esoarm.kinds: {who}: design must be a function")
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
        The module is not a complete kind, or its KIND or CODE is taken.
    """
    kinds = _registered(component) if component in COMPONENTS else ()
    check_kind(component, module, kinds)
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
