"""The result of one closed-loop run: time series as arrays plus metrics."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm._io import atomic_path
from esoarm.engines.metrics import (
    ERR,
    NROW,
    OM,
    REF,
    SAT,
    SERIES_COLUMNS,
    TH,
    Z1,
    Z3,
    F,
    U,
    Y,
    combine_joints,
    series_metrics,
)

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CSV_COLUMNS", "SimResult", "write_csv_atomic"]

#: Time-series CSV columns, SI units (see :data:`esoarm.engines.metrics.SERIES_COLUMNS`).
CSV_COLUMNS = SERIES_COLUMNS


#: The metrics a summary gives for each joint of an arm.
JOINT_KEYS = ("rms_error", "rms_u", "rms_du", "max_abs_error", "max_abs_u", "rms_f_error")


def run_settings(scn: Scenario) -> dict[str, Any]:
    """The identifying settings of a run's summary: scenario, kinds, observer and controller keys.

    Parameters
    ----------
    scn : Scenario
        The scenario run.

    Returns
    -------
    dict
        JSON-ready names and values.
    """
    settings = {"scenario": scn.name, "plant": scn.plant.kind, "observer": scn.observer.kind,
                "controller": scn.controller.kind}
    for section in (scn.observer, scn.controller):
        settings.update({k: v for k, v in section.model_dump().items()
                         if k != "kind" and isinstance(v, str | int | float | list)})
    return settings


def _joint_names(scenario: Scenario, n_joints: int) -> tuple[str, ...]:
    from esoarm.kinds import kinds_of

    plant = kinds_of(scenario).plant
    if hasattr(plant, "joint_names"):
        return tuple(plant.joint_names(scenario))
    return tuple(f"joint {j + 1}" for j in range(n_joints)) if n_joints > 1 else ()


def write_csv_atomic(
    path: str | Path, header: list[str] | tuple[str, ...], data: np.ndarray
) -> None:
    """Write a numeric table as CSV; the file appears only once complete.

    Parameters
    ----------
    path : str or Path
        The CSV file; written beside it, then renamed (no half-written file on failure).
    header : sequence of str
        Column names, one per column of ``data``.
    data : ndarray, shape (N, len(header))
        The numbers, written with ``repr`` precision (they read back bit for bit).

    Raises
    ------
    esoarm._io.OutputError
        The path cannot be written (a one-line message naming it).
    """
    with atomic_path(path) as tmp, tmp.open("w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.17g")


@dataclass(frozen=True)
class SimResult:
    """Time series of one run (row k at t_k = k·Ts) and its metrics.

    Attributes
    ----------
    scenario : Scenario
        The fully resolved scenario that produced the run.
    t : ndarray
        Sample times [s].
    theta : ndarray
        True angle θ(t_k) [rad].
    theta_ref : ndarray
        Reference θd(t_k) [rad].
    error : ndarray
        e_k = θ(t_k) − θd(t_k) [rad] (true, not measured).
    u : ndarray
        Commanded torque u_k after saturation [N·m].
    z : ndarray, shape (N, 3)
        Estimate ẑ_k used by the controller: angle [rad], rate [rad/s],
        total perturbation [rad/s²].
    f_true : ndarray
        True total perturbation θ̈(t_k) − b0 u_k [rad/s²].
    omega : ndarray
        True rate θ̇(t_k) [rad/s].
    y : ndarray
        Measured angle y_k [rad] (noise and quantization).
    saturated : ndarray
        1.0 where the command hit ±torque_limit, else 0.0.
    diverged : bool
        The run left the finite range (the series end at that sample).
    metrics : dict
        :data:`esoarm.engines.metrics.METRICS` of the run (an arm: over every joint and sample).
    joints : tuple of SimResult
        An arm's joints, one one-joint result each in URDF order (empty for one
        joint); the series above then hold the first joint's.
    joint_names : tuple of str
        Names of the joints (an arm's URDF joint names; empty for the lever arm).
    """

    scenario: Scenario
    t: np.ndarray
    theta: np.ndarray
    theta_ref: np.ndarray
    error: np.ndarray
    u: np.ndarray
    z: np.ndarray
    f_true: np.ndarray
    omega: np.ndarray
    y: np.ndarray
    saturated: np.ndarray
    diverged: bool = False
    metrics: dict[str, float] = field(default_factory=dict)
    joints: tuple[SimResult, ...] = ()
    joint_names: tuple[str, ...] = ()

    @classmethod
    def from_log(cls, scenario: Scenario, t: np.ndarray, log: np.ndarray,
                 diverged: bool = False) -> SimResult:
        """Build from an engine log: :data:`esoarm.engines.metrics.LOG_ROWS` per joint, one
        column per sample (the rows are copied out of ``log``).

        Parameters
        ----------
        scenario : Scenario
            The scenario that was run.
        t : ndarray, shape (N,)
            Sample times t_k = k·Ts [s].
        log : ndarray, shape (n·NROW, N)
            The engine's log, :data:`~esoarm.engines.metrics.LOG_ROWS` rows per joint.
        diverged : bool
            True when the run stopped early because the state left the finite range.

        Returns
        -------
        SimResult
            The series as attributes (θ, θ̇, u, ẑ, f, ...) and :attr:`metrics` computed from them.
        """
        log = np.asarray(log, dtype=float)
        if log.shape[0] % NROW or not log.shape[0]:
            raise ValueError(f"an engine log has {NROW} rows per joint, got {log.shape[0]}")
        n_joints = log.shape[0] // NROW
        names = _joint_names(scenario, n_joints)
        parts = [cls._one_joint(scenario, t, log[j * NROW:(j + 1) * NROW], diverged, names)
                 for j in range(n_joints)]
        if n_joints == 1:
            return parts[0]
        first = parts[0]
        return cls(scenario=scenario, t=first.t, theta=first.theta, theta_ref=first.theta_ref,
                   error=first.error, u=first.u, z=first.z, f_true=first.f_true,
                   omega=first.omega, y=first.y, saturated=first.saturated, diverged=diverged,
                   joints=tuple(parts), joint_names=names,
                   metrics=combine_joints([p.metrics for p in parts]))

    @classmethod
    def _one_joint(cls, scenario: Scenario, t: np.ndarray, log: np.ndarray, diverged: bool,
                   names: tuple[str, ...]) -> SimResult:
        rows = {name: np.array(log[i]) for name, i in
                (("theta", TH), ("theta_ref", REF), ("error", ERR), ("u", U), ("f_true", F),
                 ("omega", OM), ("y", Y), ("saturated", SAT))}
        z = np.array(log[Z1 : Z3 + 1].T)
        return cls(
            scenario=scenario,
            t=np.asarray(t, dtype=float),
            z=z,
            diverged=diverged,
            metrics=series_metrics(rows["error"], rows["u"], z=z, f_true=rows["f_true"],
                                   omega=rows["omega"], saturated=rows["saturated"],
                                   diverged=diverged),
            joint_names=names if len(names) == 1 else (),
            theta=rows["theta"], theta_ref=rows["theta_ref"], error=rows["error"], u=rows["u"],
            f_true=rows["f_true"], omega=rows["omega"], y=rows["y"], saturated=rows["saturated"],
        )

    @property
    def per_joint(self) -> tuple[SimResult, ...]:
        """One one-joint result per joint (the result itself for one joint)."""
        return self.joints or (self,)

    @property
    def rms_error(self) -> float:
        """RMS tracking error [rad]."""
        return self.metrics["rms_error"]

    @property
    def rms_u(self) -> float:
        """RMS control torque [N·m]."""
        return self.metrics["rms_u"]

    @property
    def max_abs_error(self) -> float:
        """Largest |e_k| [rad]."""
        return self.metrics["max_abs_error"]

    def table(self) -> np.ndarray:
        """The time series in :meth:`columns` order: (N, 11), more for an arm.

        Returns
        -------
        ndarray, shape (N, len(columns))
            One row per sample, SI units.
        """
        blocks = [self.t[:, None]]
        for part in (self, *self.joints):
            blocks.append(np.column_stack(
                [part.theta, part.theta_ref, part.error, part.u, part.z, part.f_true, part.y,
                 part.saturated]))
        return np.column_stack(blocks)

    def columns(self) -> tuple[str, ...]:
        """CSV header: :data:`CSV_COLUMNS`, then for an arm every joint's columns suffixed
        ``_1`` … ``_n`` in URDF order (the unsuffixed columns are joint 1's).

        Returns
        -------
        tuple of str
            Column names, as written by :meth:`to_csv`.
        """
        extra = tuple(f"{name}_{j}" for j in range(1, len(self.joints) + 1)
                      for name in CSV_COLUMNS[1:])
        return tuple(CSV_COLUMNS) + extra

    def to_csv(self, path: str | Path) -> Path:
        """Write the time series (:meth:`columns`, SI units); atomic.

        Parameters
        ----------
        path : str or Path
            The CSV file to write.

        Returns
        -------
        Path
            ``path``, complete.
        """
        write_csv_atomic(path, self.columns(), self.table())
        return Path(path)

    def summary(self) -> dict[str, Any]:
        """Metrics plus the identifying settings, JSON-ready.

        Returns
        -------
        dict
            The scenario's name and kinds, the observer's and controller's settings, every metric
            of :data:`~esoarm.engines.metrics.METRICS` and the number of samples (an arm adds one
            entry per joint under ``"joints"``).
        """
        out = {**run_settings(self.scenario), **self.metrics, "samples": int(len(self.t))}
        if self.joint_names:  # an arm: the metrics of each joint, in URDF order
            out["joints"] = [{"name": name, **{k: p.metrics[k] for k in JOINT_KEYS}}
                             for name, p in zip(self.joint_names, self.per_joint, strict=True)]
        return out

    def plot(self, path: str | Path | None = None, **kwargs: Any):  # type: ignore[no-untyped-def]
        """Plot angle, error, control and estimates; see :func:`esoarm.plotting.run.plot_run`.

        Parameters
        ----------
        path : str or Path, optional
            Save the figure there (.png, .pdf or .svg); None only returns it.
        **kwargs
            Passed on to :func:`esoarm.plotting.run.plot_run`.

        Returns
        -------
        matplotlib.figure.Figure
            The figure (needs matplotlib; numerics never import it).
        """
        from esoarm.plotting.run import plot_run

        return plot_run(self, path=path, **kwargs)
