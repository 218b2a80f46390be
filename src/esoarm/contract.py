"""What every plant, observer and controller kind hands to the engines.

A *kind* is one module (``esoarm.plants.lever_arm``, ``esoarm.observers.linear``,
``esoarm.controllers.flc``, ...) registered in :mod:`esoarm.kinds`.  It provides

* ``KIND`` (the tag written in the scenario), ``CODE`` (a small integer, unique
  within its component, stored in element 0 of its parameter vector) and
  ``JIT`` (whether its step functions compile with numba);
* ``Params``: its validated scenario table, a :class:`esoarm._schema.Section`
  with a ``kind`` literal;
* ``design(scn, ...)``: the scenario turned into what its step functions need,
  one of the frozen records below (a read-only float vector plus sizes);
* plain step functions on array-valued state, called as Python by the
  reference engine and compiled by the batch engine (see docs/contract.md for
  their signatures);
* optionally ``C_SOURCE``: the name of a ``.c`` file beside the module with the
  same step in C99 for the generated controller (:mod:`esoarm.codegen`); a kind
  without it is refused by ``esoarm codegen``.

Array conventions (n joints): the plant state ``x`` holds the angles in
``x[:n]`` and the rates in ``x[n:2n]`` (further states after them); the
observer's estimate ``zhat`` holds (angle, rate, total perturbation) of joint
j in ``zhat[3j:3j+3]``; measurements ``y`` and commands ``u`` have length n.

The required names of each component are :class:`PlantKind`, :class:`ObserverKind` and
:class:`ControllerKind` (typing protocols: mypy checks the registered modules against
them) and, for the check the registry runs when a kind is registered, :data:`REQUIRED`.
The optional names and their defaults are :data:`OPTIONAL`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, TypeAlias

import numpy as np

if TYPE_CHECKING:
    from esoarm._schema import Section
    from esoarm.scenario import Scenario

__all__ = ["COMPONENTS", "OPTIONAL", "PRISMATIC_UNITS", "REQUIRED", "REQUIRED_IF_JIT",
           "ROTARY_UNITS", "ComponentDesign", "ControllerKind", "Kind", "ObserverKind",
           "ObserverLinearization", "PlantDesign", "PlantKind", "Units", "Vector", "read_only"]

#: A parameter vector as the step functions take it: a NumPy array, or a tuple of
#: floats (the compiled engine hands vectors over as tuples, which live in registers).
Vector: TypeAlias = np.ndarray | tuple[float, ...]


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` as float64, flagged read-only (designs are immutable).

    Parameters
    ----------
    array : ndarray or array_like
        Values to freeze (copied; the argument itself is left writable).

    Returns
    -------
    ndarray
        A float64 copy with ``flags.writeable`` False.

    Examples
    --------
    >>> v = read_only([1, 2])
    >>> v.dtype.name, v.flags.writeable
    ('float64', False)
    """
    out = np.array(array, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class PlantDesign:
    """What a plant kind's ``design`` returns.

    Attributes
    ----------
    vector : ndarray
        Parameters of the plant's step functions; ``vector[0]`` is the kind's CODE.
    x0 : ndarray
        Initial state (angles, then rates, then any further states).
    n_joints : int
        Number of joints n (inputs and measured angles).
    b0 : ndarray, shape (n,)
        Nominal input gain per joint [1/(kg·m²)], the b0 of the observer model
        and of the logged total perturbation f = θ̈ − b0 u.
    """

    vector: np.ndarray
    x0: np.ndarray
    n_joints: int
    b0: np.ndarray


@dataclass(frozen=True)
class ComponentDesign:
    """What an observer or controller kind's ``design`` returns.

    Attributes
    ----------
    vector : ndarray
        Parameters of the step functions; ``vector[0]`` is the kind's CODE.
    n_state : int
        Length of the component's own state array (≥ 1; unused entries are fine).
    """

    vector: np.ndarray
    n_state: int


@dataclass(frozen=True)
class ObserverLinearization:
    """An observer kind's linear model for the frequency-domain analysis (``analyze``).

    One joint, sampled at Ts, state z (n), inputs the measured angle y [rad] and
    the observer input u, output the estimate ẑ (angle, rate, perturbation):

        z⁺ = P z + Q y + Γ u,    ẑ = Hz z + Hy y

    (an ESO of 3 states: Hz = I − M C, Hy = M with C = (1, 0, 0)).

    Attributes
    ----------
    p, q, gamma, hz, hy : ndarray
        P (n, n), Q (n, 1), Γ (n, 1), Hz (3, n), Hy (3, 1).
    pole : float
        The observer's slowest discrete error pole (z-plane); its frequency
        −ln|pole|/Ts [rad/s] is reported.
    eps : float
        The observer's time constant ε [s] (reported, and the key ``analyze
        --vary`` sweeps).
    discretization : str
        The name of the discretization this model is of (reported).
    label : str
        What the observer is, for titles ("linear ESO").
    """

    p: np.ndarray
    q: np.ndarray
    gamma: np.ndarray
    hz: np.ndarray
    hy: np.ndarray
    pole: float
    eps: float
    discretization: str
    label: str


# ---------------------------------------------------------------------------
# the contract itself: what a kind module provides (checked by mypy against the registry,
# and by esoarm.kinds when a kind is registered)


class Kind(Protocol):
    """The names every kind module provides, whatever its component."""

    @property
    def __name__(self) -> str:
        """The module's dotted name (``esoarm.observers.linear``)."""

    @property
    def KIND(self) -> str:  # noqa: N802 - module constants
        """The tag written in the scenario (``"linear"``)."""

    @property
    def CODE(self) -> int:  # noqa: N802
        """Small integer, unique within the component; element 0 of the parameter vector."""

    @property
    def JIT(self) -> bool:  # noqa: N802
        """The step functions compile with numba (:func:`esoarm._jit.jitable`)."""

    @property
    def Params(self) -> type[Section]:  # noqa: N802
        """The kind's validated scenario table, with a ``kind`` literal equal to KIND."""


class PlantKind(Kind, Protocol):
    """A plant kind (the true system). ``advance_block`` too when JIT is true."""

    def design(self, scn: Scenario, /) -> PlantDesign:
        """The scenario turned into the plant's vector, initial state, sizes and b0.

        Parameters
        ----------
        scn : Scenario
            A validated scenario.

        Returns
        -------
        PlantDesign
            Vector (p[0] = CODE), x0, n_joints and b0 [1/(kg·m²) per joint].
        """

    def advance(self, x: np.ndarray, u: np.ndarray, t0: float, h: float, nsub: int,
                p: np.ndarray, /) -> None:
        """Integrate x over one sample [t0, t0 + nsub·h], input u held (in place).

        Parameters
        ----------
        x : ndarray
            Plant state: angles [rad] in ``x[:n]``, rates [rad/s] in ``x[n:2n]`` ([m], [m/s]
            on a prismatic axis), further states after them; updated in place.
        u : ndarray, shape (n,)
            Applied drive per joint [N·m] (force [N] on a prismatic axis), held over the
            sample (positive along increasing θ).
        t0 : float
            Start of the sample [s].
        h : float
            Integration step [s] (RK4 for the built-in kinds).
        nsub : int
            Number of steps; nsub·h is the sample time Ts [s].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        """

    def acceleration(self, x: np.ndarray, u: np.ndarray, t: float, p: np.ndarray,
                     out: np.ndarray, /) -> None:
        """The true angular acceleration per joint [rad/s²] into ``out``.

        Parameters
        ----------
        x : ndarray
            Plant state (layout as in :meth:`advance`).
        u : ndarray, shape (n,)
            Applied drive per joint [N·m] (force [N] on a prismatic axis), from t on.
        t : float
            Time [s].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        out : ndarray, shape (n,)
            Output: θ̈ per joint [rad/s²], written in place.
        """

    def observer_input(self, zhat: np.ndarray, u: np.ndarray, p: np.ndarray,
                       v: np.ndarray, /) -> None:
        """What the observers take as input for the command u, per joint, into ``v``.

        Parameters
        ----------
        zhat : ndarray, shape (3n,)
            The observer estimate ẑ_k (angle [rad], rate [rad/s], perturbation [rad/s²]
            of joint j in ``zhat[3j:3j+3]``).
        u : ndarray, shape (n,)
            The command as applied [N·m].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        v : ndarray, shape (n,)
            Output: the observer input per joint (b0·v enters the ESO's rate equation).
        """


class ObserverKind(Kind, Protocol):
    """An observer kind: ẑ_k from the measurements and the observer input."""

    def design(self, scn: Scenario, plant: PlantDesign, ts: float, /) -> ComponentDesign:
        """The observer's vector and state size for the plant at sample period ts [s].

        Parameters
        ----------
        scn : Scenario
            A validated scenario.
        plant : PlantDesign
            The plant's design (joints, b0).
        ts : float
            Sample period Ts [s].

        Returns
        -------
        ComponentDesign
            Vector (``vector[0]`` = CODE) and the size of the component's state.
        """

    def initialize(self, z: np.ndarray, y: np.ndarray, p: np.ndarray, /) -> None:
        """Its state z_0 from the first measurement y_0 (in place).

        Parameters
        ----------
        z : ndarray
            Observer state, set in place to z_0.
        y : ndarray, shape (n,)
            First measured angle(s) y_0 [rad].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        """

    def estimate(self, z: np.ndarray, y: np.ndarray, p: np.ndarray,
                 zhat: np.ndarray, /) -> None:
        """The estimate ẑ_k the controller uses at t_k into ``zhat``.

        Parameters
        ----------
        z : ndarray
            Observer state z_k (not changed).
        y : ndarray, shape (n,)
            Measured angle(s) y_k [rad].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        zhat : ndarray, shape (3n,)
            Output: the estimate ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²] of
            joint j in ``zhat[3j:3j+3]``.
        """

    def predict(self, z: np.ndarray, zhat: np.ndarray, p: Vector, y: np.ndarray,
                /) -> None:
        """A lost sample: the measurement the observer expects at t_k into ``y``.

        The stepper (:class:`esoarm.engines.stepper.Stepper`) bridges a sample that never
        arrived with it: estimate and update then see zero innovation.  The kind says
        which of its states (or what function of them) is the angle; no consumer assumes
        it is ``z[0]``.

        Parameters
        ----------
        z : ndarray
            Observer state z_k (not changed).
        zhat : ndarray, shape (3n,)
            The previous estimate ẑ_{k−1} (angle, rate, perturbation per joint), for a
            kind whose state does not hold the angle.
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        y : ndarray, shape (n,)
            Output: the predicted angle(s) [rad].
        """

    def state_size(self, params: Any, /) -> int:
        """The observer's states per joint for these settings (its design has n times as many).

        Parameters
        ----------
        params : Params
            The kind's validated table.

        Returns
        -------
        int
            States per joint (≥ 1); the engines size z from the design, the registry checks
            the design against this.
        """

    def advance(self, z: np.ndarray, zhat: np.ndarray, y: np.ndarray, u: np.ndarray,
                p: np.ndarray, /) -> None:
        """z_{k+1} in place from z_k, ẑ_k, y_k and the observer input u_k.

        Parameters
        ----------
        z : ndarray
            Observer state z_k, updated in place to z_{k+1}.
        zhat : ndarray, shape (3n,)
            The estimate ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²] of
            joint j in ``zhat[3j:3j+3]``.
        y : ndarray, shape (n,)
            Measured angle(s) y_k [rad].
        u : ndarray, shape (n,)
            The observer input u_k (from the plant's ``observer_input``).
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        """


class ControllerKind(Kind, Protocol):
    """A controller kind: the raw command from the estimate and the references."""

    def design(self, scn: Scenario, plant: PlantDesign, ts: float, /) -> ComponentDesign:
        """The controller's vector and state size for the plant at sample period ts [s].

        Parameters
        ----------
        scn : Scenario
            A validated scenario.
        plant : PlantDesign
            The plant's design (joints, b0).
        ts : float
            Sample period Ts [s].

        Returns
        -------
        ComponentDesign
            Vector (``vector[0]`` = CODE) and the size of the component's state.
        """

    def initialize(self, c: np.ndarray, y: np.ndarray, p: np.ndarray, /) -> None:
        """Its own state from the first measurement (in place).

        Parameters
        ----------
        c : ndarray
            Controller state, set in place.
        y : ndarray, shape (n,)
            First measured angle(s) y_0 [rad].
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        """

    def control(self, c: np.ndarray, zhat: np.ndarray, y: np.ndarray, refs: np.ndarray,
                k: int, p: np.ndarray, u: np.ndarray, /) -> None:
        """The raw command of sample k per joint into ``u`` (the actuator saturates).

        Parameters
        ----------
        c : ndarray
            Controller state (updated in place by kinds that have one).
        zhat : ndarray, shape (3n,)
            The estimate ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²] of
            joint j in ``zhat[3j:3j+3]``.
        y : ndarray, shape (n,)
            Measured angle(s) y_k [rad].
        refs : ndarray, shape (3n, N)
            θd [rad], θ̇d [rad/s], θ̈d [rad/s²] of joint j in rows 3j … 3j+2, one column
            per sample.
        k : int
            Sample index (column of ``refs``).
        p : ndarray
            The design vector, ``p[0]`` the kind's CODE.
        u : ndarray, shape (n,)
            Output: the raw command u_k per joint [N·m], positive along increasing θ.
        """


#: The three components, as named in the scenario's tables.
COMPONENTS: tuple[str, ...] = ("plant", "observer", "controller")

_COMMON = ("KIND", "CODE", "JIT", "Params", "design")

#: Names a kind module must define, per component (the protocols above, for the
#: check :mod:`esoarm.kinds` runs when a kind is registered).
REQUIRED: dict[str, tuple[str, ...]] = {
    "plant": (*_COMMON, "advance", "acceleration", "observer_input"),
    "observer": (*_COMMON, "initialize", "estimate", "advance", "predict", "state_size"),
    "controller": (*_COMMON, "initialize", "control"),
}

#: Further names a kind with ``JIT = True`` must define.
REQUIRED_IF_JIT: dict[str, tuple[str, ...]] = {
    "plant": ("advance_block",),
    "observer": (),
    "controller": (),
}

@dataclass(frozen=True)
class Units:
    """The SI units (and the words) a command prints for a plant's joint quantities.

    Every table, JSON ``"units"`` field, plot label and report line that names the unit of
    a position, a rate or a drive reads it from here (:func:`esoarm.kinds.units`), so a
    prismatic axis says m, m/s and N where a rotary joint says rad, rad/s and N·m.
    """

    #: joint position q (an angle θ on a rotary joint)
    position: str
    #: its rate q̇
    velocity: str
    #: its acceleration q̈, also the unit of the total perturbation f and of ẑ3
    acceleration: str
    #: the drive u: a torque or a force
    force: str
    #: the inertia seen by the drive: a moment of inertia or a mass
    inertia: str
    #: viscous friction, a rate gain (drive per velocity)
    damping: str
    #: a position gain (drive per position), e.g. noise → control
    stiffness: str
    #: a compliance (position per drive), e.g. disturbance → error; also the weight's unit
    compliance: str
    #: what the position is called in prose ("angle" or "position")
    position_word: str
    #: what the drive is called in prose ("torque" or "force")
    force_word: str
    #: format of a metric in a table: fixed decimals for radians (the paper's tables), four
    #: significant digits for metres, whose errors are micrometres
    number_format: str = ".5f"


#: A rotary joint (the lever arm, a revolute URDF joint, a rotary axis): the default.
ROTARY_UNITS = Units(position="rad", velocity="rad/s", acceleration="rad/s²", force="N·m",
                     inertia="kg·m²", damping="N·m·s/rad", stiffness="N·m/rad",
                     compliance="rad/(N·m)", position_word="angle", force_word="torque")

#: A prismatic axis (plant kind ``"axis"`` with ``motion = "prismatic"``).
PRISMATIC_UNITS = Units(position="m", velocity="m/s", acceleration="m/s²", force="N",
                        inertia="kg", damping="N·s/m", stiffness="N/m", compliance="m/N",
                        position_word="position", force_word="force", number_format=".4g")


#: Names a kind may define, with their meaning when it does not (its default):
#:
#: ``MOTOR`` (plants; default False)
#:     driven by the actuator's motor when the scenario has a ``[motor]`` table (else the
#:     table is refused);
#: ``RIG`` (plants; default False)
#:     the one-joint rig of the serial protocol: ``run``, ``emulate``, ``excite`` and
#:     ``identify`` drive it, and the frequency-domain analysis (``analyze``) models it;
#: ``AXIS_FIT`` (plants; default False)
#:     ``identify`` fits it as one axis in SI units (IDIM-LS with an output-error fit
#:     beside it, :mod:`esoarm.studies.identification.axis`) instead of the rig's model;
#: ``NOISE_BUDGET`` (observers; default False)
#:     its ``linearization`` holds for sensor noise (a linear observer), so the noise
#:     budget predicts its chatter: ``analyze --bandwidth`` recommends among these kinds;
#: ``BASELINE`` (observers; default False)
#:     the reference observer the bandwidth criterion is stated against (``analyze
#:     --bandwidth W --tracking`` matches the others to its tracking); one kind at most;
#: ``FLC_LAW`` (controllers; default False)
#:     its law is the feedback linearization of eq. 14-16 with the gains ``k1``, ``k2``
#:     and ``compensation`` of its table: the frequency-domain analysis and κ (eq. 17)
#:     model it (a controller without it is refused there in one line);
#: ``flc_equivalent(params) -> dict[str, object]`` (controllers without ``FLC_LAW``;
#:     default: none) the scenario overrides under which the FLC (``compensation = "eso"``)
#:     with the linear ESO closes the same feedback loop y → u as this kind (the reference
#:     path may differ): the frequency-domain analysis models the kind through them;
#: ``FAST`` (default False)
#:     the opt-in fast engine (:mod:`esoarm.engines.fast`, a C kernel) models it;
#: ``C_SOURCE`` (default None)
#:     the name of a ``.c`` file beside the module with the same step in C99 for the
#:     generated on-chip controller (:mod:`esoarm.codegen`; None: ``codegen`` refuses it);
#: ``check(scn) -> str | None`` (default: no check)
#:     a scenario-level check run at validation (a message naming the key is bad input);
#: ``label(params) -> str`` (default ``"<KIND> observer"`` / ``"<KIND> controller"``)
#:     a short description for titles (``result.kind_labels``);
#: ``summary(params) -> str`` (observers; default ``"observer kind '<KIND>'"``)
#:     one line on its settings for the command line ("ε = 0.09 s (euler)");
#: ``warnings(params, ts) -> list[str]`` (observers; default: none)
#:     what is doubtful about the settings at sample period ts [s] (shown by
#:     ``simulate``, used to explain a run that diverged; an "unstable" in a message
#:     marks an observer that cannot work);
#: ``linearization(params, ts, b0) -> ObserverLinearization`` (observers; default: not
#:     modelled, ``analyze`` refuses the kind in one line);
#: ``units_of(params) -> Units`` (plants; default :data:`ROTARY_UNITS`)
#:     the units every command prints for the plant's position, rate and drive (read
#:     through :func:`esoarm.kinds.units`);
#: ``joint_names(scn) -> tuple[str, ...]`` (plants; default: none, one unnamed joint)
#:     the names of an arm's joints: logs and replays then have one column per joint
#:     (``theta_1``, ``u_1``, ...), the report names them;
#: ``joint_limits(scn) -> (lower, upper)`` (plants; default: none)
#:     per-joint position limits [rad or m]; the references are checked against them and
#:     clipped to them (:func:`esoarm.reference.reference_rows`).
OPTIONAL: dict[str, Any] = {
    "FAST": False,
    "MOTOR": False,
    "RIG": False,
    "FLC_LAW": False,
    "AXIS_FIT": False,
    "NOISE_BUDGET": False,
    "BASELINE": False,
    "C_SOURCE": None,
    "check": None,
    "label": None,
    "summary": None,
    "warnings": None,
    "linearization": None,
    "flc_equivalent": None,
    "units_of": None,
    "joint_names": None,
    "joint_limits": None,
}
