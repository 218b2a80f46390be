"""Offline observer over a logged run (``esoarm replay``), for the lever arm and for arms.

Given a log with ``t`` [s, uniform], the measured angle and the torque applied from that
row on -- ``theta`` (or ``y``) and ``u`` for one joint, ``theta_i`` (or ``y_i``) and
``u_i`` per joint i = 1 … n of an arm (m and N on a prismatic axis) -- the scenario's
observer kind (its settings, b0 from the plant) is designed for the log's sample period
and stepped sample by sample by :class:`esoarm.engines.stepper.Stepper`, exactly as in
the loop (the sampled-data loop, step 5): row k holds ẑ_k, the estimate the controller
would use at t_k, then the observer is updated with (y_k, v_k), v_k the plant kind's
observer input for u_k (u_k itself for the lever arm, M̂(q̂)⁻¹(u_k − c·n̂) for a URDF
arm).  A row with a NaN angle (a sample lost on the link, as ``esoarm run`` logs it) is
bridged with the observer kind's ``predict`` (the measurement it expects: zero
innovation).  A log of ``esoarm run`` therefore replays to its own z1, z2, z3 columns.

An observer that leaves the finite range (|ẑ1| beyond
:data:`esoarm.engines.sample.DIVERGENCE_LIMIT`, or a non-finite estimate) stops the
replay as diverged (:class:`ReplayDiverged`, with the rows before it), as ``simulate``
does; :func:`check_units` refuses a log whose drive-to-acceleration gain is far from the
scenario's b0 (angles in degrees, a rotary log replayed on a prismatic axis).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from esoarm.engines.sample import DIVERGENCE_LIMIT
from esoarm.engines.stepper import Stepper
from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.result import write_csv_atomic
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["REPLAY_COLUMNS", "ArmReplay", "ReplayDiverged", "ReplayResult", "check_units",
           "estimates", "read_arm_log", "read_log", "replay", "replay_arm"]

REPLAY_COLUMNS = ("t", "theta", "u", "z1", "z2", "z3")


@dataclass(frozen=True)
class ReplayResult:
    """Estimates recovered from a log.

    Attributes
    ----------
    t, theta, u : ndarray (N,)
        From the log [s, rad, N·m] (m and N on a prismatic axis).
    z : ndarray (N, 3)
        ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²] (m, m/s, m/s²).
    ts : float
        Sample period taken from the log [s].
    scenario : Scenario or None
        The scenario replayed (its plant names the units: :func:`esoarm.kinds.units`).
    """

    t: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    z: np.ndarray
    ts: float
    scenario: Scenario | None = field(default=None, compare=False)

    def table(self) -> np.ndarray:
        """The estimates as a table.

        Returns
        -------
        ndarray (N, 6)
            :data:`REPLAY_COLUMNS` in order.
        """
        return np.column_stack([self.t, self.theta, self.u, self.z])

    def to_csv(self, path: str | Path) -> None:
        """Write :data:`REPLAY_COLUMNS` (atomic).

        Parameters
        ----------
        path : str or Path
            The CSV file.
        """
        write_csv_atomic(path, REPLAY_COLUMNS, self.table())


def read_log(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Read t, theta, u from a CSV log and check them; return (t, theta, u, Ts).

    The measured angle is the column ``y`` where the file has it (a simulated
    series' ``theta`` is the true angle), else ``theta`` (a rig log's theta is
    the measured angle); nan in it marks a lost sample.  Raises
    :class:`ScenarioError` (one line naming the file) for a missing file,
    missing columns, bad numbers or a non-uniform time column
    (:mod:`esoarm.hardware.logfile`).

    Parameters
    ----------
    path : str or Path
        The CSV log.

    Returns
    -------
    t, theta, u : ndarray (N,)
        Times [s], measured angle [rad] (NaN: lost), torque [N·m].
    ts : float
        Sample period [s].
    """
    def pick(header: list[str]) -> list[str]:
        return ["t", "y" if "y" in header else "theta", "u"]

    _, data = read_log_columns(path, pick, "need t [s], theta or y [rad or m, measured], "
                               "u [N·m or N]",
                               lost_ok=("theta", "y"))
    t, theta, u = data[:, 0], data[:, 1], data[:, 2]
    return t, theta, u, sample_period(t, path)


@dataclass(frozen=True)
class ArmReplay:
    """Estimates recovered from an arm's log; arrays (N, n) unless noted.

    Attributes
    ----------
    t : ndarray (N,)
        Sample times [s].
    theta, u : ndarray (N, n)
        From the log [rad, N·m].
    z : ndarray (N, n, 3)
        ẑ_k per joint: angle [rad], rate [rad/s], total perturbation [rad/s²].
    ts : float
        Sample period [s].
    """

    t: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    z: np.ndarray
    ts: float

    def columns(self) -> list[str]:
        """The column names.

        Returns
        -------
        list of str
            ``t`` then ``theta_i, u_i, z1_i, z2_i, z3_i`` per joint i = 1 … n.
        """
        n = self.theta.shape[1]
        return ["t", *(f"{c}_{i}" for i in range(1, n + 1)
                       for c in ("theta", "u", "z1", "z2", "z3"))]

    def table(self) -> np.ndarray:
        """The estimates as a table.

        Returns
        -------
        ndarray (N, 1 + 5n)
            :meth:`columns` in order.
        """
        blocks = [self.t[:, None]]
        for j in range(self.theta.shape[1]):
            blocks.append(np.column_stack([self.theta[:, j], self.u[:, j], self.z[:, j]]))
        return np.column_stack(blocks)

    def to_csv(self, path: str | Path) -> None:
        """Write :meth:`columns` (atomic).

        Parameters
        ----------
        path : str or Path
            The CSV file.
        """
        write_csv_atomic(path, self.columns(), self.table())


def read_arm_log(path: str | Path, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Read t, theta_i, u_i of n joints from a CSV log; return (t, theta, u, Ts).

    The measured angles are the columns ``y_i`` when the log has all of them
    (a CSV of ``esoarm simulate``), else ``theta_i``; a one-joint arm may use
    unsuffixed ``theta`` (or ``y``) and ``u``.  Raises :class:`ScenarioError`
    (one line naming the file) for a missing file, missing columns, bad
    numbers or a non-uniform time column (:mod:`esoarm.hardware.logfile`).

    Parameters
    ----------
    path : str or Path
        The CSV log.
    n : int
        Number of joints.

    Returns
    -------
    t : ndarray (N,)
        Times [s].
    theta, u : ndarray (N, n)
        Measured angles [rad] (NaN: lost) and torques [N·m].
    ts : float
        Sample period [s].
    """
    joints = range(1, n + 1)

    def pick(header: list[str]) -> list[str]:
        suffixed = all(f"theta_{i}" in header for i in joints)
        thetas, us = ([f"theta_{i}" for i in joints], [f"u_{i}" for i in joints])
        if n == 1 and not suffixed:
            thetas, us = ["theta"], ["u"]
        ys = [c.replace("theta", "y") for c in thetas]
        return ["t", *(ys if all(c in header for c in ys) else thetas), *us]

    _, data = read_log_columns(
        path, pick, f"an arm of {n} joints needs t, theta_1 … theta_{n}, u_1 … u_{n}",
        lost_ok=[f"{c}{j}" for c in ("theta", "y") for j in ("", *(f"_{i}" for i in joints))])
    t, theta, u = data[:, 0], data[:, 1:1 + n], data[:, 1 + n:]
    return t, theta, u, sample_period(t, path)



class ReplayDiverged(RuntimeError):
    """The observer left the finite range at row ``row``; ``estimates`` holds rows 0 … row."""

    def __init__(self, message: str, row: int, estimates: np.ndarray) -> None:
        super().__init__(message)
        self.row = row
        self.estimates = estimates


def estimates(scn: Scenario, theta: np.ndarray, u: np.ndarray, ts: float) -> np.ndarray:
    """ẑ_k of the scenario's observer kind over a log: the one observer loop of ``replay``.

    Parameters
    ----------
    scn : Scenario
        The scenario (its observer and plant kinds and settings).
    theta : ndarray (N, n)
        Measured angles per joint [rad] (NaN: a lost sample).
    u : ndarray (N, n)
        Torque applied from each row on [N·m].
    ts : float
        Sample period [s].

    Returns
    -------
    ndarray (N, n, 3)
        ẑ_k per joint: angle [rad], rate [rad/s], total perturbation [rad/s²].

    Raises
    ------
    ReplayDiverged
        The estimate left the finite range (its rows up to that one kept).
    ScenarioError
        The first row has no measured angle (nothing to start the observer from).
    """
    n_rows, nj = theta.shape
    st = Stepper.observer_of(scn, ts)
    if st.n_joints != nj:
        raise ScenarioError(f"the log has {nj} joint(s), the scenario's plant {st.n_joints}")
    if n_rows and not np.all(np.isfinite(theta[0])):
        raise ScenarioError("the log's first row has no measured angle: the observer has "
                            "nothing to start from")
    out = np.full((n_rows, nj, 3), math.nan)
    with np.errstate(all="ignore"):  # a diverging observer is reported below, not by NumPy
        for k in range(n_rows):
            zhat = st.estimate(theta[k])
            out[k] = zhat.reshape(nj, 3)
            z1 = zhat[0::3]
            if not (np.all(np.isfinite(zhat)) and np.all(np.abs(z1) < DIVERGENCE_LIMIT)):
                raise ReplayDiverged(
                    f"the observer diverged at row {k} (t = {k * ts:.4g} s): ẑ left the "
                    f"finite range ({_observer_words(scn, ts)})", k, out[:k + 1])
            st.observe(u[k])
    return out


def _observer_words(scn: Scenario, ts: float) -> str:
    from esoarm.kinds import observer_summary, observer_warnings

    warn = [w for w in observer_warnings(scn) if "unstable" in w]
    return warn[0] if warn else f"{observer_summary(scn)} at Ts = {ts:g} s"


def check_units(scn: Scenario, theta: np.ndarray, u: np.ndarray, ts: float,
                path: str | Path) -> None:
    """Refuse a log whose drive-to-acceleration gain is far from the scenario's b0.

    The log's own gain b̂ comes from least squares on filtered derivatives (as
    identification's inverse dynamic model): the measured angle of joint 0 and the torque,
    both low-passed by the same zero-phase filter, θ̈ on (u, 1, θ̇, a smooth sign(θ̇),
    cos θ, sin θ, and the scenario's disturbance frequency's sine and cosine); it is
    decisive only when its 95 % interval is narrower than half of it.  A correct log
    comes out within a few times b0 (the closed loop and the unmodelled friction leave
    some bias: 0.25-0.5× on ``esoarm simulate``'s test-1 logs); an angle logged in degrees
    makes it 15-30× and a rotary log replayed on a prismatic axis (or the reverse) off by
    orders of magnitude.  A ratio outside [:data:`UNIT_RATIO_LOW`, :data:`UNIT_RATIO`] is
    bad input.

    Parameters
    ----------
    scn : Scenario
        The scenario replayed (its plant's b0).
    theta, u : ndarray (N, n)
        Measured angles and torques.
    ts : float
        Sample period [s].
    path : str or Path
        The log (for the message).

    Raises
    ------
    ScenarioError
        One line naming the log, the ratio and what would explain it.
    """
    from scipy.signal import butter, filtfilt

    from esoarm.kinds import kinds_of, units

    y, uu = theta[:, 0], u[:, 0]
    n = len(y)
    if n < 200 or not np.all(np.isfinite(y)) or not np.std(uu) > 0:
        return  # too short to tell, or lost samples (not interpolated here)
    t = np.arange(n) * ts
    with np.errstate(all="ignore"):
        b, a = butter(4, 0.1)
        yf, uf = filtfilt(b, a, y), filtfilt(b, a, uu)
        vel = np.gradient(yf, ts)
        acc = np.gradient(vel, ts)
        scale = max(float(np.std(vel)), 1e-12)
        cols = [uf, np.ones(n), vel, np.tanh(vel / (0.05 * scale)), np.cos(yf), np.sin(yf)]
        w = float(getattr(getattr(getattr(scn, "rig", None), "disturbance", None),
                          "frequency", 0.0) or 0.0)
        if w > 0:
            cols += [np.sin(w * t), np.cos(w * t)]
        keep = slice(20, n - 20)  # the filter's edges
        x, target = np.column_stack(cols)[keep], acc[keep]
        coef, *_ = np.linalg.lstsq(x, target, rcond=None)
        r = target - x @ coef
        cov = np.linalg.pinv(x.T @ x) * float(r @ r) / max(len(r) - x.shape[1], 1)
    gain, half = float(coef[0]), 1.96 * math.sqrt(max(float(cov[0, 0]), 0.0))
    b0 = float(kinds_of(scn).plant.design(scn).b0[0])
    if not (math.isfinite(gain) and gain > 0 and half < 0.5 * gain and b0 > 0):
        return
    ratio = gain / b0
    if UNIT_RATIO_LOW <= ratio <= UNIT_RATIO:
        return
    un = units(scn)
    deg = 180.0 / math.pi
    hint = (f"an angle logged in degrees gives about {deg:.3g}× less the loop's bias "
            "(convert: esoarm log import --scale y=0.017453292519943295)"
            if 0.2 * deg <= ratio <= 5.0 * deg else
            f"is it a log of this plant? (a rotary log on a prismatic axis, or the reverse, "
            f"is off by orders of magnitude; plant.kind = {scn.plant.kind!r} has b0 = "
            f"{b0:.4g} per {un.inertia})")
    raise ScenarioError(
        f"log '{path}': the units look wrong: the log's acceleration per unit drive is "
        f"{gain:.4g} ± {half:.2g}, {ratio:.3g}× the scenario's b0 = {b0:.4g}; {hint}")


#: Largest ratio of the log's drive-to-acceleration gain to the scenario's b0.
UNIT_RATIO = 8.0
#: Smallest ratio (a log of a far heavier plant, e.g. a prismatic axis on a rotary scenario).
UNIT_RATIO_LOW = 0.02


def replay(scn: Scenario, t: np.ndarray, theta: np.ndarray, u: np.ndarray,
           ts: float) -> ReplayResult:
    """Run the scenario's observer kind over (theta, u) of one joint, sampled every ``ts`` [s].

    Parameters
    ----------
    scn : Scenario
        The scenario (observer and plant).
    t, theta, u : ndarray (N,)
        Times [s], measured angle [rad] (NaN: lost), torque [N·m].
    ts : float
        Sample period [s].

    Returns
    -------
    ReplayResult
        The estimates.
    """
    z = estimates(scn, theta.reshape(-1, 1), u.reshape(-1, 1), ts)
    return ReplayResult(t, theta, u, z[:, 0, :], ts, scn)


def replay_arm(scn: Scenario, t: np.ndarray, theta: np.ndarray, u: np.ndarray,
               ts: float) -> ArmReplay:
    """Run the scenario's observer kind over (theta, u) of every joint, sampled every ``ts`` [s].

    Parameters
    ----------
    scn : Scenario
        The scenario (observer and plant).
    t : ndarray (N,)
        Times [s].
    theta, u : ndarray (N, n)
        Measured angles [rad] (NaN: lost) and torques [N·m] per joint.
    ts : float
        Sample period [s].

    Returns
    -------
    ArmReplay
        The estimates per joint.
    """
    return ArmReplay(t, theta, u, estimates(scn, theta, u, ts), ts)


def plot_replay(result: ReplayResult, path: str | Path) -> None:
    """Draw the replay; see :func:`esoarm.plotting.run.figure_replay`.

    Parameters
    ----------
    result : ReplayResult
        The estimates.
    path : str or Path
        The figure (.png, .pdf or .svg).
    """
    from esoarm.plotting.run import figure_replay

    figure_replay(result, path)
