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
    series_metrics,
)

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["CSV_COLUMNS", "SimResult", "kind_labels", "write_csv_atomic"]

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


#: Time-series CSV columns, SI units (see :data:`esoarm.engines.metrics.SERIES_COLUMNS`).
CSV_COLUMNS = SERIES_COLUMNS


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
    y : ndarray
        Measured angle y_k [rad] (noise and quantization).
    saturated : ndarray
        1.0 where the command hit ±torque_limit, else 0.0.
    diverged : bool
        The run left the finite range (the series end at that sample).
    metrics : dict
        :data:`esoarm.engines.metrics.METRICS` of the run.
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

    @classmethod
    def from_log(cls, scenario: Scenario, t: np.ndarray, log: np.ndarray,
                 diverged: bool = False) -> SimResult:
        """Build from an engine log (rows :data:`esoarm.engines.metrics.LOG_ROWS`, columns samples).

        A one-joint run; the rows are copied out of ``log``.
        """
        log = np.asarray(log, dtype=float)
        if log.shape[0] != NROW:
            raise ValueError(f"a one-joint log has {NROW} rows, got {log.shape[0]}")
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
            **rows,
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
        """The time series as an (N, 11) array in :data:`CSV_COLUMNS` order."""
        return np.column_stack(
            [self.t, self.theta, self.theta_ref, self.error, self.u, self.z, self.f_true, self.y,
             self.saturated]
        )

    def to_csv(self, path: str | Path) -> Path:
        """Write the time series (output columns, SI units); atomic."""
        write_csv_atomic(path, CSV_COLUMNS, self.table())
        return Path(path)

    def summary(self) -> dict[str, Any]:
        """Metrics plus the identifying settings, JSON-ready."""
        scn = self.scenario
        settings = {"scenario": scn.name, "plant": scn.plant.kind, "observer": scn.observer.kind,
                    "controller": scn.controller.kind}
        for section in (scn.observer, scn.controller):
            settings.update({k: v for k, v in section.model_dump().items()
                             if k != "kind" and isinstance(v, str | int | float)})
        return {**settings, **self.metrics, "samples": int(len(self.t))}

    def plot(self, path: str | Path | None = None, **kwargs: Any):  # type: ignore[no-untyped-def]
        """Plot angle, error, control and estimates; see :func:`esoarm.plotting.plot_run`."""
        from esoarm.plotting import plot_run

        return plot_run(self, path=path, **kwargs)
