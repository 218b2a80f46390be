"""The result of one closed-loop run: time series as arrays plus metrics."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm._io import atomic_path

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CSV_COLUMNS", "SimResult", "compute_metrics", "write_csv_atomic"]

#: Time-series CSV columns (docs/semantics.md, output files and columns), SI units.
CSV_COLUMNS = ("t", "theta", "theta_ref", "error", "u", "z1", "z2", "z3", "f_true")


def compute_metrics(error: np.ndarray, u: np.ndarray) -> dict[str, float]:
    """RMS tracking error [rad], RMS control [N·m], max |error| [rad] (the sampled-data loop)."""
    if len(error) == 0:
        return {"rms_error": float("nan"), "rms_u": float("nan"), "max_abs_error": float("nan")}
    return {
        "rms_error": float(np.sqrt(np.mean(error**2))),
        "rms_u": float(np.sqrt(np.mean(u**2))),
        "max_abs_error": float(np.max(np.abs(error))),
    }


def write_csv_atomic(
    path: str | Path, header: list[str] | tuple[str, ...], data: np.ndarray
) -> None:
    """Write a numeric table as CSV; the file appears only once complete."""
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
    metrics: dict[str, float] = field(default_factory=dict)

    @classmethod
    def from_log(cls, scenario: Scenario, t: np.ndarray, log: np.ndarray,
                 omega: np.ndarray) -> SimResult:
        """Build from the engine log (columns θ, θd, e, u, z1, z2, z3, f_true)."""
        log = np.asarray(log, dtype=float)
        return cls(
            scenario=scenario,
            t=np.asarray(t, dtype=float),
            theta=log[:, 0],
            theta_ref=log[:, 1],
            error=log[:, 2],
            u=log[:, 3],
            z=log[:, 4:7],
            f_true=log[:, 7],
            omega=np.asarray(omega, dtype=float),
            metrics=compute_metrics(log[:, 2], log[:, 3]),
        )

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
        """The time series as an (N, 9) array in :data:`CSV_COLUMNS` order."""
        return np.column_stack(
            [self.t, self.theta, self.theta_ref, self.error, self.u, self.z, self.f_true]
        )

    def to_csv(self, path: str | Path) -> Path:
        """Write the time series (output columns, SI units); atomic."""
        write_csv_atomic(path, CSV_COLUMNS, self.table())
        return Path(path)

    def summary(self) -> dict[str, Any]:
        """Metrics plus the identifying settings, JSON-ready."""
        scn = self.scenario
        return {
            "scenario": scn.name,
            "eps": scn.observer.eps,
            "discretization": scn.observer.discretization,
            "compensation": scn.controller.compensation,
            "samples": int(len(self.t)),
            **self.metrics,
        }

    def plot(self, path: str | Path | None = None, **kwargs: Any):  # type: ignore[no-untyped-def]
        """Plot angle, error, control and estimates; see :func:`esoarm.plotting.plot_run`."""
        from esoarm.plotting import plot_run

        return plot_run(self, path=path, **kwargs)
