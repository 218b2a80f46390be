"""Offline ESOs over a logged run of an arm (``esoarm replay`` with a URDF scenario).

The arm's counterpart of :mod:`esoarm.hardware.replay`: the log gives ``t``
[s, uniform] and, per joint i = 1 … n in URDF order, the measured angle
``theta_i`` [rad] and the torque ``u_i`` [N·m] applied from that row on (a
one-joint arm may use ``theta`` and ``u``).  A CSV of ``esoarm simulate`` on an
arm replays directly: its measured angles ``y_i`` are used when present, and
the replay gives back its ``z1_i``, ``z2_i``, ``z3_i``.  Each joint's observer
runs exactly as in the loop, through the scenario's kinds: row k holds ẑ_k,
the estimate the controller would use at t_k, then every observer is updated
with the observers' input of the plant (v = M̂(q̂)⁻¹(u − c n̂),
:func:`esoarm.plants.arms.urdf.observer_input`).  A NaN angle (a lost sample) is
bridged with zero innovation.  The sample period comes from the log.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.result import write_csv_atomic
from esoarm.scenario import Scenario

__all__ = ["ArmReplay", "read_arm_log", "replay_arm"]


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
        """``t`` then ``theta_i, u_i, z1_i, z2_i, z3_i`` per joint i = 1 … n."""
        n = self.theta.shape[1]
        return ["t", *(f"{c}_{i}" for i in range(1, n + 1)
                       for c in ("theta", "u", "z1", "z2", "z3"))]

    def table(self) -> np.ndarray:
        """The estimates in :meth:`columns` order."""
        blocks = [self.t[:, None]]
        for j in range(self.theta.shape[1]):
            blocks.append(np.column_stack([self.theta[:, j], self.u[:, j], self.z[:, j]]))
        return np.column_stack(blocks)

    def to_csv(self, path: str | Path) -> None:
        """Write :meth:`columns` (atomic)."""
        write_csv_atomic(path, self.columns(), self.table())


def read_arm_log(path: str | Path, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Read t, theta_i, u_i of n joints from a CSV log; return (t, theta, u, Ts).

    The measured angles are the columns ``y_i`` when the log has all of them
    (a CSV of ``esoarm simulate``), else ``theta_i``; a one-joint arm may use
    unsuffixed ``theta`` (or ``y``) and ``u``.  Raises :class:`ScenarioError`
    (one line naming the file) for a missing file, missing columns, bad
    numbers or a non-uniform time column (:mod:`esoarm.hardware.logfile`).
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


def replay_arm(scn: Scenario, t: np.ndarray, theta: np.ndarray, u: np.ndarray,
               ts: float) -> ArmReplay:
    """Run the scenario's observers over (theta, u) of every joint, sampled every ``ts`` [s]."""
    from esoarm.kinds import kinds_of

    kinds = kinds_of(scn)
    plant = kinds.plant.design(scn)
    obs = kinds.observer.design(scn, plant, ts)
    n = plant.n_joints
    z = np.zeros(max(obs.n_state, 1))
    zhat = np.zeros_like(z)
    v = np.empty(n)
    kinds.observer.initialize(z, theta[0].copy(), obs.vector)
    out = np.empty((len(t), n, 3))
    for k in range(len(t)):
        y = theta[k].copy()
        lost = np.isnan(y)
        y[lost] = z[0:3 * n:3][lost]  # a lost sample: zero innovation
        kinds.observer.estimate(z, y, obs.vector, zhat)
        out[k] = zhat[:3 * n].reshape(n, 3)
        kinds.plant.observer_input(zhat, u[k], plant.vector, v)
        kinds.observer.advance(z, zhat, y, v, obs.vector)
    return ArmReplay(t, theta, u, out, ts)
