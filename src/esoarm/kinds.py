"""The registry of plant, observer and controller kinds: the one place a kind is added.

Each kind is a module following :mod:`esoarm.contract` (``KIND``, ``CODE``,
``JIT``, ``Params``, ``design`` and its step functions).  This module lists
them per component; from the lists come the scenario's tagged unions
(``plant.kind``, ``observer.kind``, ``controller.kind``), the lookup of a
scenario's kinds (:func:`kinds_of`) and, for the compiled engine, one
dispatch function per step that calls the kind whose CODE is in element 0
of the parameter vector.  A kind with ``JIT = False`` (e.g. one that calls a
library numba cannot compile) runs only in the reference engine; the batch
engine runs its points in worker processes instead.

To add a kind: write its module, append it to the component's tuple below,
and -- if it compiles -- add one branch to that component's dispatch
functions.  Nothing in the engines, the CLI or the report changes.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING, Annotated, Any, NamedTuple

import numpy as np
from pydantic import Field

from esoarm._jit import jitable
from esoarm.controllers import computed_torque, flc, pid
from esoarm.observers import cascade, linear, nonlinear
from esoarm.plants import axis, lever_arm, urdf

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CONTROLLERS", "OBSERVERS", "PLANTS", "Kinds", "kind_labels", "kinds_of", "tagged_union"]

#: Registered kinds per component; the first is the default.
PLANTS: tuple[ModuleType, ...] = (lever_arm, urdf, axis)
OBSERVERS: tuple[ModuleType, ...] = (linear, nonlinear, cascade)
CONTROLLERS: tuple[ModuleType, ...] = (flc, pid, computed_torque)


def _check(component: str, kinds: tuple[ModuleType, ...]) -> None:
    for attr in ("KIND", "CODE"):
        values = [getattr(m, attr) for m in kinds]
        if len(set(values)) != len(values):  # pragma: no cover - guards a registration
            raise ImportError(f"esoarm.kinds: two {component} kinds share a {attr}: {values}")


_check("plant", PLANTS)
_check("observer", OBSERVERS)
_check("controller", CONTROLLERS)


def tagged_union(kinds: tuple[ModuleType, ...]) -> Any:
    """The pydantic tagged union of the kinds' ``Params`` (discriminator ``kind``)."""
    models = tuple(m.Params for m in kinds)
    union = models[0]
    for model in models[1:]:
        union = union | model
    return Annotated[union, Field(discriminator="kind")]


def by_name(kinds: tuple[ModuleType, ...], name: str) -> ModuleType:
    """The kind module registered as ``name``."""
    for module in kinds:
        if module.KIND == name:
            return module
    raise KeyError(name)  # pragma: no cover - the scenario validated the name


class Kinds(NamedTuple):
    """The kind modules of one scenario: plant, observer, controller."""

    plant: ModuleType
    observer: ModuleType
    controller: ModuleType

    @property
    def jit(self) -> bool:
        """All three compile with numba (the batch engine can run them)."""
        return bool(self.plant.JIT and self.observer.JIT and self.controller.JIT)


def kinds_of(scn: Scenario) -> Kinds:
    """The kind modules a scenario selects.

    Examples
    --------
    >>> from esoarm.scenario import load_scenario
    >>> k = kinds_of(load_scenario("test-1", {"observer.kind": "nonlinear"}))
    >>> k.plant.KIND, k.observer.KIND, k.controller.KIND, k.jit
    ('lever-arm', 'nonlinear', 'flc', True)
    """
    return Kinds(by_name(PLANTS, scn.plant.kind), by_name(OBSERVERS, scn.observer.kind),
                 by_name(CONTROLLERS, scn.controller.kind))


def kind_labels(scn: Scenario) -> tuple[str, str]:
    """Short descriptions of the observer and the controller of ``scn`` for titles.

    ("euler", "eso compensation") for the paper's linear ESO and FLC; the kind
    is named for the others ("euler nonlinear ESO", "pid controller").
    """
    obs, ctl = scn.observer, scn.controller
    disc = getattr(obs, "discretization", None)
    obs_text = (str(disc) if obs.kind == "linear" else f"{disc} {obs.kind} ESO") if disc \
        else f"{obs.kind} observer"
    comp = getattr(ctl, "compensation", None)
    ctl_text = f"{comp} compensation" if comp is not None else f"{ctl.kind} controller"
    return obs_text, ctl_text


# ---------------------------------------------------------------------------
# dispatch for the compiled engine: element 0 of each vector is the kind's CODE


@jitable
def plant_advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
                  p: np.ndarray) -> None:
    """``advance`` of the plant kind whose CODE is p[0]."""
    if p[0] == axis.CODE:
        axis.advance(x, u, t0, h, nsub, p)
    elif p[0] == urdf.CODE:
        urdf.advance(x, u, t0, h, nsub, p)
    else:
        lever_arm.advance(x, u, t0, h, nsub, p)


@jitable
def plant_advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                        nsub: int, p: np.ndarray) -> None:
    """``advance_block`` of the plant kind whose CODE is p[0] (a block of runs, same p)."""
    if p[0] == axis.CODE:
        axis.advance_block(xs, us, live, t0, h, nsub, p)
    elif p[0] == urdf.CODE:
        urdf.advance_block(xs, us, live, t0, h, nsub, p)
    else:
        lever_arm.advance_block(xs, us, live, t0, h, nsub, p)


@jitable
def plant_acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                       out: np.ndarray) -> None:
    """``acceleration`` of the plant kind whose CODE is p[0]."""
    if p[0] == axis.CODE:
        axis.acceleration(x, u, t, p, out)
    elif p[0] == urdf.CODE:
        urdf.acceleration(x, u, t, p, out)
    else:
        lever_arm.acceleration(x, u, t, p, out)


@jitable
def plant_observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """``observer_input`` of the plant kind whose CODE is p[0]."""
    if p[0] == axis.CODE:
        axis.observer_input(zhat, u, p, v)
    elif p[0] == urdf.CODE:
        urdf.observer_input(zhat, u, p, v)
    else:
        lever_arm.observer_input(zhat, u, p, v)


@jitable
def observer_initialize(z: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """``initialize`` of the observer kind whose CODE is p[0]."""
    if p[0] == nonlinear.CODE:
        nonlinear.initialize(z, y, p)
    elif p[0] == cascade.CODE:
        cascade.initialize(z, y, p)
    else:
        linear.initialize(z, y, p)


@jitable
def observer_estimate(z: np.ndarray, y: np.ndarray, p: np.ndarray, zhat: np.ndarray) -> None:
    """``estimate`` of the observer kind whose CODE is p[0]."""
    if p[0] == nonlinear.CODE:
        nonlinear.estimate(z, y, p, zhat)
    elif p[0] == cascade.CODE:
        cascade.estimate(z, y, p, zhat)
    else:
        linear.estimate(z, y, p, zhat)


@jitable
def observer_advance(z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray,
                     p: np.ndarray) -> None:
    """``advance`` of the observer kind whose CODE is p[0]."""
    if p[0] == nonlinear.CODE:
        nonlinear.advance(z, zhat, y, u, p)
    elif p[0] == cascade.CODE:
        cascade.advance(z, zhat, y, u, p)
    else:
        linear.advance(z, zhat, y, u, p)


@jitable
def controller_initialize(c: np.ndarray, y: np.ndarray, p: np.ndarray) -> None:
    """``initialize`` of the controller kind whose CODE is p[0]."""
    if p[0] == pid.CODE:
        pid.initialize(c, y, p)
    elif p[0] == computed_torque.CODE:
        computed_torque.initialize(c, y, p)
    else:
        flc.initialize(c, y, p)


@jitable
def controller_control(c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray, k: int,
                       p: np.ndarray, u: np.ndarray) -> None:
    """``control`` of the controller kind whose CODE is p[0]."""
    if p[0] == pid.CODE:
        pid.control(c, zhat, y, refs, k, p, u)
    elif p[0] == computed_torque.CODE:
        computed_torque.control(c, zhat, y, refs, k, p, u)
    else:
        flc.control(c, zhat, y, refs, k, p, u)
