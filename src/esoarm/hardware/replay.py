"""Offline ESO over a logged run (``esoarm replay``).

Given a log with ``t`` [s, uniform], ``theta`` [rad, measured] and ``u``
[N·m, applied from that row on], the observer of the scenario (ε,
discretization, b0 = 1/I0) is run sample by sample exactly as in the loop
(the sampled-data loop, step 5): row k holds ẑ_k, the estimate the controller would use at
t_k, then the observer is updated with (y_k, u_k).  A row with ``theta = nan``
(a sample lost on the link, as ``esoarm run`` logs it) is bridged with zero
innovation, as the loop does.  A log of ``esoarm run`` therefore replays to
its own z1, z2, z3 columns.  The sample period is taken from the log.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from esoarm.kinds import kinds_of
from esoarm.result import write_csv_atomic
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["REPLAY_COLUMNS", "ReplayResult", "read_log", "replay"]

REPLAY_COLUMNS = ("t", "theta", "u", "z1", "z2", "z3")


@dataclass(frozen=True)
class ReplayResult:
    """Estimates recovered from a log.

    Attributes
    ----------
    t, theta, u : ndarray (N,)
        From the log [s, rad, N·m].
    z : ndarray (N, 3)
        ẑ_k: angle [rad], rate [rad/s], total perturbation [rad/s²].
    ts : float
        Sample period taken from the log [s].
    """

    t: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    z: np.ndarray
    ts: float

    def table(self) -> np.ndarray:
        """(N, 6) array in :data:`REPLAY_COLUMNS` order."""
        return np.column_stack([self.t, self.theta, self.u, self.z])

    def to_csv(self, path: str | Path) -> None:
        """Write :data:`REPLAY_COLUMNS` (atomic)."""
        write_csv_atomic(path, REPLAY_COLUMNS, self.table())


def read_log(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Read t, theta, u from a CSV log and check them; return (t, theta, u, Ts).

    Raises :class:`ScenarioError` (one line naming the file) for a missing
    file, missing columns, bad numbers or a non-uniform time column.
    """
    path = Path(path)
    src = f"log '{path}'"
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None:
                raise ScenarioError(f"{src}: empty file")
            header = [h.strip() for h in header]
            # the measured angle: `y` where the file has it (a simulated series' `theta` is
            # the true angle), else `theta` (a rig log's theta is the measured angle)
            angle = "y" if "y" in header else "theta"
            missing = [c for c in ("t", angle, "u") if c not in header]
            if missing:
                raise ScenarioError(f"{src}: missing column(s) {', '.join(missing)}; "
                                    "need t [s], theta or y [rad, measured], u [N·m]")
            idx = [header.index(c) for c in ("t", angle, "u")]
            rows = []
            for line_no, row in enumerate(reader, start=2):
                if not row:
                    continue
                try:
                    rows.append([float(row[i]) for i in idx])
                except (ValueError, IndexError):
                    raise ScenarioError(f"{src}: line {line_no}: expected numbers in columns "
                                        f"t, {angle}, u") from None
    except FileNotFoundError:
        raise ScenarioError(f"{src}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{src}: cannot read: {exc}") from None
    data = np.array(rows, dtype=float).reshape(-1, 3)
    t, theta, u = data[:, 0], data[:, 1], data[:, 2]
    if len(t) < 2:
        raise ScenarioError(f"{src}: needs at least 2 rows, has {len(t)}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
        raise ScenarioError(f"{src}: columns t and u must be finite numbers")
    if np.isnan(theta[0]) or np.any(np.isinf(theta)):
        raise ScenarioError(f"{src}: theta must be finite (nan allowed for lost samples, "
                            "not in the first row)")
    dt = np.diff(t)
    ts = float(t[1] - t[0])
    if not ts > 0 or np.max(np.abs(dt - ts)) > 1e-6 * ts + 1e-12:
        raise ScenarioError(f"{src}: column t must be uniformly spaced and increasing "
                            f"(steps from {dt.min():g} to {dt.max():g} s)")
    return t, theta, u, ts


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
    return ReplayResult(t, theta, u, out, ts)


def plot_replay(result: ReplayResult, path: str | Path) -> None:
    """Draw the replay; see :func:`esoarm.plotting.figure_replay`."""
    from esoarm.plotting import figure_replay

    figure_replay(result, path)
