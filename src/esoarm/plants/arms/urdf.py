"""Plant kind ``"urdf"``: any serial arm from a URDF file, its dynamics from Pinocchio.

``[plant]`` names the URDF file (relative to the scenario file) and what the
twin carries beyond it; the nominal model known to the controller is the URDF
as written (:mod:`esoarm.plants.arms.model`).  The twin is the lever arm's rig
joint by joint (:mod:`esoarm.plants.arms.twin`): the ``[rig]`` friction,
disturbance, inertia scale and RK4 step, the ``[actuator]`` lag, applied to
every joint.

As a kind (see :mod:`esoarm.contract`): :func:`design` gives the state
x = (q, q̇, τ) of n joints and b0 = 1 per joint, because the observers'
input is already an acceleration: :func:`observer_input` maps the command to
v = M̂(q̂)⁻¹ (u − c·n̂(q̂, q̂̇)) -- the joint's component of M̂⁻¹τ, c = 1 when
the controller feeds the nominal n̂ forward.  In the reference engine
:func:`advance`, :func:`acceleration` and :func:`observer_input` call
Pinocchio; numba cannot, so the compiled engine runs
:mod:`esoarm.plants.arms.compiled` in their place (``JIT = True``): the same
twin on the rigid-body dynamics of :mod:`esoarm.plants.arms.rigid_body`, the same
numbers to rounding.

The parameter vector holds (CODE, handle, c, n, twin parameters, nominal
model, true model), the models packed for the compiled engine.  The handle
names the loaded Pinocchio models in this process (:func:`arm_of`), so a
design is valid for the reference engine in the process that made it -- the
engines design each run where they run it; the compiled engine needs only the
vector.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field

from esoarm._jit import jitable_as
from esoarm._schema import PER_JOINT_KEYS, Section, unit
from esoarm.contract import PlantDesign, read_only
from esoarm.plants.actuator import motor_refused
from esoarm.plants.arms import compiled
from esoarm.plants.arms.model import ArmModel, UrdfError, load_arm
from esoarm.plants.arms.twin import TwinParams, pack_params, twin_acceleration, twin_advance

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CODE", "JIT", "KIND", "MOTOR", "Params", "acceleration", "advance", "advance_block",
           "arm_of", "check", "design", "joint_limits", "joint_names", "observer_input",
           "packed_models", "scenario_arm"]

KIND = "urdf"
CODE = 1
JIT = True
#: The compiled step functions agree with the reference (Pinocchio) to rounding, not
#: bit for bit (:data:`esoarm.plants.arms.compiled.ENGINE_TOLERANCE`).
COMPILED_EXACT = False
#: No motor: one ``[motor]`` table cannot describe the drive of each joint, so a scenario
#: with one is refused (:func:`check`, :func:`esoarm.plants.actuator.motor_refused`).
MOTOR = False

HANDLE, _FEEDFORWARD = 1, 2
_NJ, _TWIN = compiled.NJ, compiled.TWIN

class Params(Section):
    """``[plant]`` of kind "urdf": a serial arm from a URDF file (Pinocchio)."""

    kind: Literal["urdf"] = Field(
        "urdf", description='plant kind: "urdf" (a serial arm from a URDF file)')
    file: str = Field(
        "", description="URDF file, relative to the scenario file (required)")
    g: float = Field(9.81, ge=0, description="gravity along −z of the URDF base frame",
                     json_schema_extra=unit("m/s²"))
    payload_mass: float = Field(
        0.0, ge=0, description="point mass the twin carries on the last link, unknown to the "
        "controller", json_schema_extra=unit("kg"))
    payload_offset: list[float] = Field(
        default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3,
        description="its position in the last joint's frame", json_schema_extra=unit("m"))
    q0: list[float] = Field(
        default_factory=list,
        description="initial angle of each joint (empty: rig.theta0 for every joint)",
        json_schema_extra=unit("rad"))


# ---------------------------------------------------------------------------
# loaded models, by handle (process-local)

_LOADED: OrderedDict[tuple[Any, ...], int] = OrderedDict()
_ARMS: dict[int, ArmModel] = {}
_MAX_LOADED = 64


def scenario_arm(scn: Scenario) -> ArmModel:
    """The nominal and true models of a urdf scenario (loaded once per process, cached).

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "urdf".

    Returns
    -------
    ArmModel
        The arm of ``plant.file`` with the scenario's gravity, inertia scale and payload.
    """
    return _ARMS[_handle(scn)]


def _handle(scn: Scenario) -> int:
    plant = scn.plant
    path = Path(plant.file)
    try:
        stamp = os.stat(path).st_mtime_ns
    except OSError:
        stamp = None
    key = (str(path), stamp, plant.g, scn.rig.inertia_scale, plant.payload_mass,
           tuple(plant.payload_offset))
    if key in _LOADED:
        _LOADED.move_to_end(key)
        return _LOADED[key]
    arm = load_arm(path, g=plant.g, inertia_scale=scn.rig.inertia_scale,
                   payload_mass=plant.payload_mass, payload_offset=plant.payload_offset,
                   source=f"key 'plant.file': URDF '{plant.file}'")
    handle = max(_ARMS, default=0) + 1
    _ARMS[handle] = arm
    _LOADED[key] = handle
    while len(_LOADED) > _MAX_LOADED:
        _, old = _LOADED.popitem(last=False)
        _ARMS.pop(old, None)
    return handle


def arm_of(p: np.ndarray) -> ArmModel:
    """The models named by a design vector's handle.

    Parameters
    ----------
    p : ndarray
        The design vector of :func:`design` (p[1] is the handle).

    Returns
    -------
    ArmModel
        The arm loaded in this process under that handle.
    """
    return _ARMS[int(p[HANDLE])]


def feeds_forward(scn: Scenario) -> bool:
    """Whether the controller adds the nominal n̂ (so the observers must not estimate it).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    bool
        True for ``controller.feedforward`` with ``compensation = "eso"``.
    """
    ctl = scn.controller
    return bool(getattr(ctl, "feedforward", False)) and getattr(ctl, "compensation", "") == "eso"


# ---------------------------------------------------------------------------
# validation at load time


def _joint_list(arm: ArmModel) -> str:
    names = ", ".join(arm.joint_names)
    return f"{arm.n_joints} joint{'s' if arm.n_joints > 1 else ''} ({names})"


def check(scn: Scenario) -> str | None:
    """One line naming the key if ``scn`` does not fit its URDF arm, else None.

    Refuses a ``[motor]`` table (the kind declares ``MOTOR = False``), loads the URDF
    (Pinocchio must be installed), checks the per-joint keys against the number of joints
    and the reference against the joint limits.

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "urdf".

    Returns
    -------
    str or None
        A one-line message naming the key, or None when the scenario fits.
    """
    refused = motor_refused(scn, KIND)
    if refused is not None:
        return refused
    if not scn.plant.file:
        return ("key 'plant.file': required for plant.kind = 'urdf' (the arm's URDF file, "
                "relative to the scenario file)")
    try:
        arm = scenario_arm(scn)
    except UrdfError as exc:
        return str(exc)
    n = arm.n_joints
    if scn.controller.kind != "computed-torque":
        return (f"key 'controller.kind': '{scn.controller.kind}' is the lever arm's; a URDF arm "
                "uses 'computed-torque'")
    # (whether the observer kind takes n joints is asked of the registry by
    # esoarm.scenario.checks, which sits above the kinds)
    if scn.rig.stiction != 0.0:
        return ("key 'rig.stiction': the URDF twin's friction is Coulomb and viscous per joint "
                "(no Stribeck term); leave it 0")
    for section in ("observer", "controller"):
        values = getattr(scn, section).model_dump()
        for key in PER_JOINT_KEYS:
            value = values.get(key)
            if isinstance(value, list) and len(value) != n:
                return (f"key '{section}.{key}': {len(value)} entries, but "
                        f"'{Path(scn.plant.file).name}' has {_joint_list(arm)}")
    q0 = scn.plant.q0
    if q0 and len(q0) != n:
        return (f"key 'plant.q0': {len(q0)} entries, but '{Path(scn.plant.file).name}' has "
                f"{_joint_list(arm)}")
    from esoarm.reference import joint_count, needs_limits

    count = joint_count(scn.reference)
    if count is not None and count != n:
        return (f"key 'reference.joints': {count} entries, but "
                f"'{Path(scn.plant.file).name}' has {_joint_list(arm)}")
    for i in needs_limits(scn.reference, n):
        if arm.continuous[i]:
            return (f"key 'reference': joint '{arm.joint_names[i]}' is continuous (no limits) "
                    f"but reference kind '{scn.reference.kind}' moves through the limits")
    return None


# ---------------------------------------------------------------------------
# design and step functions


def design(scn: Scenario) -> PlantDesign:
    """Initial state x0 = (q0, 0, 0) per joint, b0 = 1, vector (CODE, handle, c, n, twin, models).

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "urdf".

    Returns
    -------
    PlantDesign
        vector = (CODE, handle, c = 1 if the controller feeds n̂ forward else 0, n,
        :func:`esoarm.plants.arms.twin.pack_params`, nominal and true models of
        :func:`packed_models`); x0 = (q0 [rad], q̇ = 0, τ = 0);
        b0 = 1 per joint (the observers' input is already an acceleration, see
        :func:`observer_input`).
    """
    handle = _handle(scn)
    arm = _ARMS[handle]
    n = arm.n_joints
    rig = scn.rig
    lag = scn.actuator.lag

    def each(value: float) -> np.ndarray:
        return np.full(n, float(value))

    twin = TwinParams(each(rig.coulomb_friction), each(rig.friction_velocity),
                      each(rig.viscous_friction), each(rig.disturbance.amplitude),
                      each(rig.disturbance.frequency), lag)
    nominal, true = packed_models(arm)
    vector = np.concatenate([[float(CODE), float(handle), float(feeds_forward(scn)), float(n)],
                             pack_params(twin, arm.inertia_scale), nominal, true])
    q0 = np.array(scn.plant.q0, dtype=float) if scn.plant.q0 else each(rig.theta0)
    x0 = np.concatenate([q0, np.zeros(2 * n)])
    return PlantDesign(vector=read_only(vector), x0=read_only(x0), n_joints=n,
                       b0=read_only(np.ones(n)))


def joint_names(scn: Scenario) -> tuple[str, ...]:
    """The arm's actuated joints, in URDF (Pinocchio) order.

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "urdf".

    Returns
    -------
    tuple of str
        The joint names, n entries.
    """
    return scenario_arm(scn).joint_names


def joint_limits(scn: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper position limits of every joint [rad or m] (±inf: continuous).

    Parameters
    ----------
    scn : Scenario
        A scenario whose ``[plant]`` is of kind "urdf".

    Returns
    -------
    (lower, upper) : (ndarray, ndarray)
        Shape (n,) each, read-only [rad or m].
    """
    arm = scenario_arm(scn)
    return arm.lower, arm.upper


def packed_models(arm: ArmModel) -> tuple[np.ndarray, np.ndarray]:
    """The nominal and true models packed for the compiled engine (once per loaded arm).

    Parameters
    ----------
    arm : ArmModel
        A loaded arm; the packed pair is cached in it.

    Returns
    -------
    (nominal, true) : (ndarray, ndarray)
        :func:`esoarm.plants.arms.rigid_body.pack_model` of ``arm.nominal`` and ``arm.true``.
    """
    from esoarm.plants.arms.rigid_body import pack_model

    cached = arm._data.get("packed")
    if cached is None:
        cached = arm._data["packed"] = (pack_model(arm.nominal), pack_model(arm.true))
    return cached


def _twin(p: np.ndarray) -> np.ndarray:
    n = int(p[_NJ])
    return p[_TWIN:_TWIN + 5 * n + 2]


@jitable_as(compiled.advance, array_arg=5)
def advance(x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
            p: np.ndarray) -> None:
    """Integrate x = (q, q̇, τ) in place over one sample: ``nsub`` RK4 steps of h [s], u held.

    Parameters
    ----------
    x : ndarray, shape (3n,)
        State: q [rad] in x[:n], q̇ [rad/s] in x[n:2n], lag τ [N·m] in x[2n:3n]; updated in
        place.
    u : ndarray, shape (n,)
        Applied torque per joint [N·m], held over [t0, t0 + nsub·h).
    t0 : float
        Start of the sample [s] (d(t) depends on it).
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps (nsub·h = Ts).
    p : ndarray
        The design vector, p[0] = CODE (see :func:`design`).
    """
    twin_advance(arm_of(p), x, u, t0, h, nsub, _twin(p))


@jitable_as(compiled.advance_block, array_arg=6)
def advance_block(xs: np.ndarray, us: np.ndarray, live: np.ndarray, t0: float, h: float,
                  nsub: int, p: np.ndarray) -> None:
    """:func:`advance` for each live run i of a block (``xs[i]``, ``us[i]``).

    Parameters
    ----------
    xs : ndarray, shape (runs, 3n)
        States of the runs (as ``x`` of :func:`advance`), live ones updated in place.
    us : ndarray, shape (runs, n)
        Applied torque of each run [N·m].
    live : ndarray of bool, shape (runs,)
        Which runs to advance.
    t0 : float
        Start of the sample [s].
    h : float
        RK4 step [s].
    nsub : int
        Number of RK4 steps per sample.
    p : ndarray
        The design vector shared by the block, p[0] = CODE.
    """
    for i in range(xs.shape[0]):
        if live[i]:
            advance(xs[i], us[i], t0, h, nsub, p)


@jitable_as(compiled.acceleration, array_arg=3)
def acceleration(x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                 out: np.ndarray) -> None:
    """True q̈ [rad/s²] at state x, time t, input u applied from t on, into ``out``.

    Parameters
    ----------
    x : ndarray, shape (3n,)
        State (q [rad], q̇ [rad/s], τ [N·m]).
    u : ndarray, shape (n,)
        Applied torque [N·m] (acts directly when T = 0).
    t : float
        Time [s].
    p : ndarray
        The design vector, p[0] = CODE.
    out : ndarray, shape (n,)
        Output: q̈ [rad/s²].
    """
    twin_acceleration(arm_of(p), x, u, t, _twin(p), out)


@jitable_as(compiled.observer_input, array_arg=2)
def observer_input(zhat: np.ndarray, u: np.ndarray, p: np.ndarray, v: np.ndarray) -> None:
    """The observers' input v = M̂(q̂)⁻¹ (u − c·n̂(q̂, q̂̇)) [rad/s²] into ``v``.

    q̂, q̂̇ are the estimates ẑ1, ẑ2 of every joint; c = 1 when the controller
    feeds n̂ forward.  Then ẑ3 of joint i estimates q̈_i − v_i: gravity,
    Coriolis (unless fed forward), coupling, friction, model error, disturbance.

    Parameters
    ----------
    zhat : ndarray, shape (3n,)
        Estimate (q̂ [rad], q̂̇ [rad/s], f̂ [rad/s²]) of joint j in zhat[3j:3j+3].
    u : ndarray, shape (n,)
        Command as applied [N·m].
    p : ndarray
        The design vector (handle, feed-forward flag).
    v : ndarray, shape (n,)
        Output: v [rad/s²].
    """
    arm = arm_of(p)
    n = len(u)
    q_hat = zhat[0:3 * n:3]  # the estimate's first 3n values (an observer's state may be longer)
    drive = u
    if p[_FEEDFORWARD] != 0.0:
        drive = u - arm.bias(q_hat, zhat[1:3 * n:3])
    v[:] = np.linalg.solve(arm.mass_matrix(q_hat), drive)
