"""Run metrics shared by every engine, and the reference engine run for metrics.

:data:`METRICS` names the columns every engine reports for a run and
:class:`MetricsTable` holds them for many runs.  This module imports neither
numba nor the compiled engines, so code that only handles metrics (sweep
tables, tuning objectives) and small sweeps start quickly:
:func:`reference_metrics` runs a few runs on the plain-Python reference engine,
whose numbers the compiled exact engine reproduces bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from esoarm.plants.sensor import noise_sequence
from esoarm.scenario import Scenario

__all__ = ["METRICS", "MetricsTable", "NoiseCache", "metrics_row", "reference_metrics"]

#: Metric columns of a run, in order.
#:
#: ``rms_error`` [rad], ``rms_u`` [N·m], ``max_abs_error`` [rad]: RMS and largest
#: tracking error, RMS control; ``max_abs_u`` [N·m] the largest |u_k|;
#: ``rms_f_error`` [rad/s²] the RMS error of the ESO's perturbation estimate,
#: sqrt(mean((ẑ3_k − f_k)²)); ``samples`` the number of samples logged (N, or
#: fewer for a diverged run); ``diverged`` 1.0 if the run left the finite range
#: (metrics then cover the samples logged up to and including the one that
#: diverged, exactly like the partial result of
#: :class:`~esoarm.engines.simulation.SimulationDiverged`), else 0.0.
METRICS: tuple[str, ...] = (
    "rms_error", "rms_u", "max_abs_error", "max_abs_u", "rms_f_error", "samples", "diverged",
)


@dataclass(frozen=True)
class MetricsTable:
    """Metrics of many runs: ``values[i]`` is run i, columns :data:`METRICS`.

    Attributes
    ----------
    values : ndarray, shape (R, len(METRICS))
        One row per run, in run order.
    """

    values: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """One metric for every run (see :data:`METRICS` for names and units)."""
        return self.values[:, METRICS.index(name)]

    def row(self, i: int) -> dict[str, float]:
        """Metrics of run ``i`` as a dict."""
        return {name: float(v) for name, v in zip(METRICS, self.values[i], strict=True)}

    def __len__(self) -> int:
        return int(self.values.shape[0])


class NoiseCache:
    """Standard-normal sequences, drawn once per (seed, N) (the sensor noise of a run)."""

    def __init__(self) -> None:
        self._store: dict[tuple[int, int], np.ndarray] = {}

    def get(self, seed: int, n: int, noise_deg: float) -> tuple[tuple[int, int], np.ndarray]:
        """(key, sequence) of a seed; runs without noise share one zero sequence."""
        key = (seed, n) if noise_deg > 0 else (-1, n)
        if key not in self._store:
            self._store[key] = noise_sequence(seed, n, noise_deg)
        return key, self._store[key]


def metrics_row(error: np.ndarray, u: np.ndarray, f_error: np.ndarray,
                diverged: bool) -> np.ndarray:
    """One row of :data:`METRICS` from the logged e_k, u_k and ẑ3_k − f_k.

    NumPy's pairwise sums, as the compiled engine computes them: the same bits.
    """
    return np.array([
        np.sqrt(np.mean(error**2)), np.sqrt(np.mean(u**2)), np.max(np.abs(error)),
        np.max(np.abs(u)), np.sqrt(np.mean(f_error**2)), float(len(error)),
        1.0 if diverged else 0.0,
    ])


def reference_metrics(
    points: Sequence[Scenario],
    seeds: Sequence[int] | None = None,
    *,
    progress: Callable[[int], None] | None = None,
    **_ignored: object,
) -> MetricsTable:
    """Metrics of every point (× every seed) from the plain-Python reference engine.

    Same arguments and result as :func:`esoarm.engines.batch.run_metrics`, and
    the same numbers; about 0.1 s per 20 s run, so meant for a handful of runs
    (no compiled kernel to load).
    """
    from esoarm.engines.simulation import SimulationDiverged, prepare, run_reference

    if seeds is None:
        runs = [scn for scn in points]
    else:
        runs = [scn.with_overrides({"sensor.seed": int(s)}) if s != scn.sensor.seed else scn
                for scn in points for s in seeds]
    out = np.empty((len(runs), len(METRICS)))
    for i, scn in enumerate(runs):
        diverged = False
        try:
            res = run_reference(scn, prepare(scn))
        except SimulationDiverged as exc:
            res, diverged = exc.result, True
        out[i] = metrics_row(res.error, res.u, res.z[:, 2] - res.f_true, diverged)
        if progress is not None:
            progress(1)
    return MetricsTable(out)
