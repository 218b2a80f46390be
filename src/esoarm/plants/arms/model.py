"""A serial arm from a URDF file: its rigid-body model through Pinocchio.

Pinocchio (PyPI package ``pin``, the optional extra ``esoarm[arms]``) is
imported lazily, so the lever arm needs nothing beyond the core install.  A
URDF arm is described by two Pinocchio models built from the same file:

* the **nominal** model, what the controller knows: the URDF as written,
  giving M̂(q) (CRBA) and n̂(q, q̇) = Ĉ(q, q̇) q̇ + ĝ(q) (RNEA);
* the **true** model of the digital twin: the URDF plus an optional payload
  (a point mass fixed to the last body), whose kinetic energy is scaled by
  ``inertia_scale`` (gravity is not): s·(M(q) q̈ + C(q, q̇) q̇) + g(q) = τ.

The scale is the lever arm's ``inertia_scale`` written for many joints; on
the one-joint lever URDF it is exactly I = s·I0 with G unchanged.  It is
realised without a second dynamics code path: s·(M q̈ + C q̇) + g = τ is
M q̈ + C q̇ + g/s = τ/s, one articulated-body (ABA) call on the true model
with its gravity divided by s (see :func:`esoarm.plants.arms.twin.arm_acceleration`).

Joint angles are the generalized coordinates q [rad, or m for prismatic
joints], one per joint in URDF (Pinocchio) order.  A ``continuous`` joint is
stored by Pinocchio as (cos q, sin q); :meth:`ArmModel.configuration` maps
angles to Pinocchio's configuration vector.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "ArmModel",
    "UrdfError",
    "builtin_robot",
    "import_pinocchio",
    "load_arm",
]

#: Install hint shown when Pinocchio is missing.
INSTALL_HINT = "pip install 'esoarm[arms]' (Pinocchio, PyPI package 'pin')"

#: Pinocchio joint models esoarm accepts, by the suffix of their short name.
_ONE_DOF = ("RX", "RY", "RZ", "RevoluteUnaligned", "PX", "PY", "PZ", "PrismaticUnaligned")
_UNBOUNDED = ("RUBX", "RUBY", "RUBZ", "RevoluteUnboundedUnaligned")


class UrdfError(ValueError):
    """Bad URDF input: the message is one line naming the file and the problem."""


def import_pinocchio() -> Any:
    """Import Pinocchio, or fail with one line naming the extra to install.

    Returns
    -------
    module
        The ``pinocchio`` module.

    Raises
    ------
    UrdfError
        Pinocchio is not installed.
    """
    try:
        import pinocchio
    except ImportError:
        raise UrdfError(f"plant.kind = 'urdf' needs Pinocchio: {INSTALL_HINT}") from None
    return pinocchio


def builtin_robot(name: str) -> Path:
    """Path of a URDF shipped with esoarm (``two-link``, ``lever-arm``).

    Parameters
    ----------
    name : str
        The robot's name, the file name without ``.urdf``.

    Returns
    -------
    Path
        ``esoarm/scenarios/robots/<name>.urdf`` (not checked to exist).

    Examples
    --------
    >>> builtin_robot("two-link").name
    'two-link.urdf'
    """
    path = resources.files("esoarm") / "scenarios" / "robots" / f"{name}.urdf"
    return Path(str(path))


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Capture what C++ code writes to file descriptor 2 (urdfdom prints its errors)."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # pragma: no cover - no stderr descriptor
        yield lines
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(tmp.read().decode("utf-8", "replace").splitlines())


def _urdf_problem(lines: list[str]) -> str:
    for line in lines:
        text = line.strip()
        if text.startswith("Error:"):
            return text[len("Error:"):].strip()
    return "Pinocchio could not build a model from it"


@dataclass(frozen=True)
class ArmModel:
    """Nominal and true rigid-body models of a serial arm, with their joints.

    Build one with :func:`load_arm`.

    Attributes
    ----------
    path : Path
        The URDF file.
    joint_names : tuple of str
        Actuated joints, in URDF (Pinocchio) order; one entry of q per joint.
    lower, upper : ndarray (n,)
        Position limits [rad or m]; ±inf for a continuous joint.
    continuous : ndarray of bool (n,)
        Joints without limits (Pinocchio stores them as cos q, sin q).
    nominal, true : pinocchio.Model
        The model the controller knows and the model of the twin (payload
        added, gravity divided by ``inertia_scale``).
    inertia_scale : float
        s, the factor on the true kinetic energy.
    g : float
        Gravity [m/s²] (along −z of the URDF's base frame).
    """

    path: Path
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    continuous: np.ndarray
    nominal: Any
    true: Any
    inertia_scale: float
    g: float
    has_continuous: bool = False
    _data: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_joints(self) -> int:
        """Number of actuated joints n."""
        return len(self.joint_names)

    def data(self, which: str = "nominal") -> Any:
        """Pinocchio workspace (``pinocchio.Data``) of the nominal or true model, reused.

        Parameters
        ----------
        which : {"nominal", "true"}
            The model.

        Returns
        -------
        pinocchio.Data
            Created on first use, then the same object.
        """
        if which not in self._data:
            self._data[which] = getattr(self, which).createData()
        return self._data[which]

    def workspace(self) -> np.ndarray:
        """Scratch (8, n) array of the twin's RK4 stages (reused).

        Returns
        -------
        ndarray, shape (8, n)
            The same array on every call (see :func:`esoarm.plants.arms.twin.rk4_stage`).
        """
        if "rk4" not in self._data:
            self._data["rk4"] = np.zeros((8, self.n_joints))
        return self._data["rk4"]  # type: ignore[no-any-return]

    @property
    def aba(self) -> Any:
        """``pinocchio.aba`` (Featherstone's articulated-body algorithm)."""
        return import_pinocchio().aba

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration vector of the joint angles q (cos/sin for continuous).

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint positions [rad or m].

        Returns
        -------
        ndarray
            Pinocchio's q (nq values): q itself without continuous joints, else
            (cos qi, sin qi) in place of each continuous qi.
        """
        if not self.has_continuous:
            return q
        parts: list[float] = []
        for qi, cont in zip(q, self.continuous, strict=True):
            if cont:
                parts.extend((np.cos(qi), np.sin(qi)))
            else:
                parts.append(qi)
        return np.array(parts)

    # -- nominal rigid-body terms (what the controller knows) ---------------
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Nominal joint-space inertia M̂(q) [kg·m²], symmetric (CRBA).

        The last evaluation is kept: the controller and the observers' input
        ask for M̂ at the same estimate q̂ in every sample.

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint positions [rad or m].

        Returns
        -------
        ndarray, shape (n, n)
            M̂(q) [kg·m² (revolute), kg (prismatic)], read-only.
        """
        key = np.asarray(q, dtype=float).tobytes()
        cached = self._data.get("mass")
        if cached is not None and cached[0] == key:
            return cached[1]  # type: ignore[no-any-return]
        pin = import_pinocchio()
        m = np.array(pin.crba(self.nominal, self.data(), self.configuration(q)))
        lower = self._data.get("lower")
        if lower is None:
            lower = self._data["lower"] = np.tril_indices(self.n_joints, -1)
        m[lower] = m.T[lower]  # CRBA fills the upper triangle
        m.setflags(write=False)
        self._data["mass"] = (key, m)
        return m

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Nominal n̂(q, q̇) = Ĉ(q, q̇) q̇ + ĝ(q) [N·m] (RNEA with q̈ = 0).

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint positions [rad or m].
        v : ndarray, shape (n,)
            Joint rates [rad/s or m/s].

        Returns
        -------
        ndarray, shape (n,)
            n̂ [N·m or N], the torque that holds q̈ = 0 (M̂ q̈ + n̂ = τ).
        """
        pin = import_pinocchio()
        return np.array(pin.nonLinearEffects(self.nominal, self.data(),
                                             self.configuration(q), v))

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Nominal gravity torque ĝ(q) [N·m].

        Parameters
        ----------
        q : ndarray, shape (n,)
            Joint positions [rad or m].

        Returns
        -------
        ndarray, shape (n,)
            ĝ(q) [N·m or N], the torque that holds the arm still against gravity.
        """
        pin = import_pinocchio()
        return np.array(pin.computeGeneralizedGravity(self.nominal, self.data(),
                                                      self.configuration(q)))


def _check_xml(path: Path, source: str) -> None:
    import xml.etree.ElementTree as ET  # only where a URDF is read

    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UrdfError(f"{source}: not valid XML: {exc}") from None
    if root.tag != "robot":
        raise UrdfError(f"{source}: not a URDF: the root element is <{root.tag}>, "
                        "expected <robot>")


def _body_name(model: Any, jid: int) -> str:
    """The URDF link moved by joint ``jid`` (its child link)."""
    for frame in model.frames:
        if str(frame.type).endswith("BODY") and frame.parentJoint == jid:
            return str(frame.name)
    return str(model.names[jid])  # pragma: no cover - every joint has a child link


def _check_masses(pin: Any, model: Any, names: list[str], lower: np.ndarray,
                  upper: np.ndarray, source: str) -> None:
    """Physical masses, inertias and limits: the dynamics must be defined and invertible.

    Every moved body (a link with the links fixed to it) needs a finite mass >= 0 and a
    positive semi-definite inertia tensor, an inertia only with a mass, and every joint
    something to move: the mass matrix M(q) must be invertible (a joint whose links are
    massless has a zero row; the arm's acceleration would be 0/0).  A massless link
    inside the chain, carrying links with mass, is an ideal massless rod and allowed.
    """
    for i, name in enumerate(names):
        if lower[i] > upper[i]:
            raise UrdfError(f"{source}: joint '{name}': lower limit {lower[i]:g} is above "
                            f"the upper limit {upper[i]:g}")
    for jid in range(1, model.njoints):
        body = model.inertias[jid]
        link = _body_name(model, jid)
        mass = float(body.mass)
        rot = np.asarray(body.inertia, dtype=float)
        if not (math.isfinite(mass) and np.isfinite(rot).all()
                and np.isfinite(np.asarray(body.lever)).all()):
            raise UrdfError(f"{source}: link '{link}': its mass or inertia is not finite")
        if mass < 0:
            raise UrdfError(f"{source}: link '{link}' has mass {mass:g} kg; a mass must be "
                            ">= 0")
        moments = np.linalg.eigvalsh(0.5 * (rot + rot.T))
        scale = max(float(np.abs(moments).max()), 1e-300)
        if moments.min() < -1e-9 * scale:
            raise UrdfError(f"{source}: link '{link}': its inertia tensor is not positive "
                            f"semi-definite (principal moments "
                            f"{', '.join(f'{m:.3g}' for m in moments)} kg·m²)")
        if mass == 0 and moments.max() > 0:
            raise UrdfError(f"{source}: link '{link}' has an inertia tensor but mass 0; give "
                            "it its mass (an inertia needs one)")
    m = np.array(pin.crba(model, model.createData(), pin.neutral(model)))
    m = np.triu(m) + np.triu(m, 1).T  # CRBA fills the upper triangle
    diag = np.diag(m)
    for i, name in enumerate(names):
        if not diag[i] > 1e-12 * max(float(diag.max()), 0.0):
            raise UrdfError(f"{source}: joint '{name}' moves no mass: link "
                            f"'{_body_name(model, i + 1)}' and the links it carries are "
                            "massless, so the arm's mass matrix is singular; give the link an "
                            "<inertial> with mass > 0")
    try:
        np.linalg.cholesky(m)
    except np.linalg.LinAlgError:
        raise UrdfError(f"{source}: the arm's mass matrix is singular at q = 0 (the links' "
                        "masses and inertias leave a motion without inertia)") from None


def load_arm(
    path: str | Path,
    *,
    g: float = 9.81,
    inertia_scale: float = 1.0,
    payload_mass: float = 0.0,
    payload_offset: tuple[float, float, float] | list[float] = (0.0, 0.0, 0.0),
    source: str | None = None,
) -> ArmModel:
    """Build the nominal and true models of the arm in a URDF file.

    Parameters
    ----------
    path : str or Path
        URDF file.
    g : float
        Gravity [m/s²], acting along −z of the base frame.
    inertia_scale : float
        s > 0: the twin's kinetic energy is s times the URDF's (payload included).
    payload_mass : float
        Point mass [kg] fixed to the last body of the twin (not known to the
        controller).
    payload_offset : sequence of 3 floats
        Its position [m] in the frame of the last joint.
    source : str, optional
        How to name the file in error messages (default ``file '<path>'``).

    Returns
    -------
    ArmModel
        Nominal and true models, joint names and limits.

    Raises
    ------
    UrdfError
        Missing file, malformed XML or URDF, no actuated joint, a joint
        type other than revolute, continuous or prismatic, a lower limit above
        the upper one, a mass or inertia that is not physical, or a joint that
        moves no mass (a singular mass matrix); one line.
    """
    path = Path(path)
    source = source or f"file '{path}'"
    if path.is_dir():
        raise UrdfError(f"{source}: is a directory, not a URDF file")
    if not path.is_file():
        raise UrdfError(f"{source}: no such URDF file")
    _check_xml(path, source)
    pin = import_pinocchio()
    with _captured_stderr() as errors:
        try:
            nominal = pin.buildModelFromUrdf(str(path))
        except (ValueError, RuntimeError):
            nominal = None
    if nominal is None or any(line.strip().startswith("Error:") for line in errors):
        # urdfdom reports some errors and builds the model anyway, without the part it
        # could not read (an <inertial> with mass "nan": a massless link)
        raise UrdfError(f"{source}: not a valid URDF: {_urdf_problem(errors)}")
    if nominal.njoints < 2:
        raise UrdfError(f"{source}: the URDF has no movable joint")
    names, cont = [], []
    for jid in range(1, nominal.njoints):
        kind = nominal.joints[jid].shortname().removeprefix("JointModel")
        name = nominal.names[jid]
        if kind in _UNBOUNDED:
            cont.append(True)
        elif kind in _ONE_DOF:
            cont.append(False)
        else:
            raise UrdfError(
                f"{source}: joint '{name}' is of type {kind}; esoarm controls arms of "
                "revolute, continuous and prismatic joints"
            )
        names.append(name)
    if nominal.nv != len(names):  # pragma: no cover - guarded by the joint types above
        raise UrdfError(f"{source}: unexpected number of velocity variables")
    continuous = np.array(cont, dtype=bool)
    lower = np.full(len(names), -np.inf)
    upper = np.full(len(names), np.inf)
    for i, jid in enumerate(range(1, nominal.njoints)):
        if not continuous[i]:
            idx = nominal.idx_qs[jid]
            lower[i] = nominal.lowerPositionLimit[idx]
            upper[i] = nominal.upperPositionLimit[idx]
    _check_masses(pin, nominal, names, lower, upper, source)
    nominal.gravity.linear = np.array([0.0, 0.0, -g])
    true = pin.Model(nominal)
    if payload_mass > 0.0:
        last = true.njoints - 1
        point = pin.Inertia(payload_mass, np.asarray(payload_offset, dtype=float),
                            np.zeros((3, 3)))
        true.inertias[last] = true.inertias[last] + point
    # s (M q̈ + C q̇) + g = τ  <=>  M q̈ + C q̇ + g/s = τ/s  (module docstring)
    true.gravity.linear = np.array([0.0, 0.0, -g / inertia_scale])
    for arr in (lower, upper, continuous):
        arr.setflags(write=False)
    return ArmModel(path=path, joint_names=tuple(names), lower=lower, upper=upper,
                    continuous=continuous, nominal=nominal, true=true,
                    inertia_scale=float(inertia_scale), g=float(g),
                    has_continuous=bool(continuous.any()))
