"""Offline ESO over a logged run (``esoarm replay``).

Given a log with ``t`` [s, uniform], ``theta`` [rad, measured] and ``u``
[N·m, applied from that row on] (m and N on a prismatic axis), the observer of the scenario (ε,
discretization, b0 = 1/I0) is run sample by sample exactly as in the loop
(the sampled-data loop, step 5): row k holds ẑ_k, the estimate the controller would use at
t_k, then the observer is updated with (y_k, u_k).  A row with ``theta = nan``
(a sample lost on the link, as ``esoarm run`` logs it) is bridged with zero
innovation, as the loop does.  A log of ``esoarm run`` therefore replays to
its own z1, z2, z3 columns.  The sample period is taken from the log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.kinds import kinds_of
from esoarm.result import write_csv_atomic
from esoarm.scenario import Scenario

__all__ = ["REPLAY_COLUMNS", "ReplayResult", "read_log", "replay"]

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
        """(N, 6) array in :data:`REPLAY_COLUMNS` order."""
        return np.column_stack([self.t, self.theta, self.u, self.z])

    def to_csv(self, path: str | Path) -> None:
        """Write :data:`REPLAY_COLUMNS` (atomic)."""
        write_csv_atomic(path, REPLAY_COLUMNS, self.table())


def read_log(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Read t, theta, u from a CSV log and check them; return (t, theta, u, Ts).

    The measured angle is the column ``y`` where the file has it (a simulated
    series' ``theta`` is the true angle), else ``theta`` (a rig log's theta is
    the measured angle); nan in it marks a lost sample.  Raises
    :class:`ScenarioError` (one line naming the file) for a missing file,
    missing columns, bad numbers or a non-uniform time column
    (:mod:`esoarm.hardware.logfile`).
    """
    def pick(header: list[str]) -> list[str]:
        return ["t", "y" if "y" in header else "theta", "u"]

    _, data = read_log_columns(path, pick, "need t [s], theta or y [rad or m, measured], "
                               "u [N·m or N]",
                               lost_ok=("theta", "y"))
    t, theta, u = data[:, 0], data[:, 1], data[:, 2]
    return t, theta, u, sample_period(t, path)


def replay(scn: Scenario, t: np.ndarray, theta: np.ndarray, u: np.ndarray,
           ts: float) -> ReplayResult:
    """Run the scenario's observer kind over (theta, u) sampled every ``ts`` [s].

    The observer is designed for the log's sample period (its other settings
    and b0 from the scenario) and stepped with the functions every engine uses.
    """
    kinds = kinds_of(scn)
    design = kinds.observer.design(scn, kinds.plant.design(scn), ts)
    obs, p = kinds.observer, design.vector
    z = np.zeros(max(design.n_state, 1))
    zhat = np.zeros_like(z)
    y, uk = np.zeros(1), np.zeros(1)
    out = np.empty((len(theta), 3))
    y[0] = theta[0]
    obs.initialize(z, y, p)
    for k in range(len(theta)):
        y[0] = z[0] if math.isnan(theta[k]) else theta[k]  # a lost sample: no innovation
        obs.estimate(z, y, p, zhat)
        out[k] = zhat[:3]
        uk[0] = u[k]
        obs.advance(z, zhat, y, uk, p)
    return ReplayResult(t, theta, u, out, ts, scn)


def plot_replay(result: ReplayResult, path: str | Path) -> None:
    """Draw the replay; see :func:`esoarm.plotting.run.figure_replay`."""
    from esoarm.plotting.run import figure_replay

    figure_replay(result, path)
