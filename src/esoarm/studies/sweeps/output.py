"""Sweep output: the rows of a sweep in memory (:class:`SweepResult`) or streamed to CSV in
memory independent of the number of runs (:class:`SweepWriter`)."""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from esoarm._io import OutputError, atomic_path, describe_os_error, target_file, temp_name
from esoarm.engines.metrics import METRICS

if TYPE_CHECKING:
    from esoarm.studies.sweeps.grid import SweepGrid

__all__ = ["DIVERGED_SHOWN", "SweepResult", "SweepWriter", "write_rows_atomic"]

#: Diverged grid points named in the sweep's warning line (the first in grid order).
DIVERGED_SHOWN = 3


def _cell(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, list | tuple):
        return repr(list(value))
    return str(value)


class SweepWriter:
    """Consume a sweep chunk by chunk in memory independent of the number of runs.

    Rows are written to the CSV in grid order as soon as every run before them
    has finished (chunks from a Dask cluster may finish out of order: those
    waiting for an earlier one are held until it comes).  The summary -- runs
    finished, diverged, the best grid points by seed mean -- is updated per
    chunk and kept in O(1) memory.  Chunks hold whole grid points.

    The CSV is written to a temporary file beside ``path`` and renamed to
    ``path`` by :meth:`close`: a finished sweep's file appears complete; an
    interrupted one (``close(complete=False)``) holds the finished rows, each
    row whole, in grid order.

    Parameters
    ----------
    grid : SweepGrid
    path : path, optional
        CSV file to write (columns :meth:`SweepResult.header`).
    best : int
        How many best grid points to keep (:meth:`best`).
    by : str
        Metric that ranks the grid points (lowest seed mean first).
    """

    def __init__(self, grid: SweepGrid, path: str | Path | None = None, *, best: int = 5,
                 by: str = "rms_error") -> None:
        self.grid = grid
        self.path = Path(path) if path is not None else None
        self.n_done = 0
        self.diverged = 0
        #: grid points with at least one diverged run
        self.diverged_points = 0
        #: the first few of them in grid order: (point index, diverged runs there)
        self.first_diverged: list[tuple[int, int]] = []
        self.rows_written = 0
        self.seconds = 0.0
        self._per_point = max(len(grid.seeds), 1)
        self._keep, self._by = best, METRICS.index(by)
        self._best: list[tuple[float, int, np.ndarray]] = []
        self._next = 0  # first run not yet written
        self._pending: dict[int, np.ndarray] = {}
        self._seed_col = None if grid.seeds else grid.keys.index("sensor.seed")
        self._tmp: Path | None = None
        self._target: Path | None = None
        self._fh: Any = None
        if self.path is not None:
            self._target = target_file(self.path)  # a symbolic link: its target is written
            self._tmp = temp_name(self._target)
            try:
                self._target.parent.mkdir(parents=True, exist_ok=True)
                self._fh = self._tmp.open("w", encoding="utf-8", newline="")
                self._csv = csv.writer(self._fh, lineterminator="\n")
                self._csv.writerow([*grid.keys, "seed", *METRICS])
            except OSError as exc:
                self._fail(exc)

    def add(self, start: int, values: np.ndarray) -> None:
        """Take the metric rows of runs ``start`` … ``start + len(values) − 1``.

        Parameters
        ----------
        start : int
            Index of the chunk's first run (runs in grid order, seed fastest).
        values : ndarray, shape (runs, len(METRICS))
            The chunk's metric rows.
        """
        self.n_done += len(values)
        self.diverged += int(np.count_nonzero(values[:, -1]))
        self._note_diverged(start // self._per_point, values)
        self._rank(start // self._per_point, values)
        if self._fh is None:
            return
        self._pending[start] = values
        try:
            while self._next in self._pending:
                chunk = self._pending.pop(self._next)
                self._write(self._next, chunk)
                self._next += len(chunk)
            self._fh.flush()
        except OSError as exc:  # a full disk, a file-size limit: one clear error, no file
            self._fail(exc)

    def _fail(self, exc: OSError) -> None:
        self.discard()
        assert self.path is not None
        raise OutputError(self.path, describe_os_error(exc)) from None

    def _write(self, start: int, values: np.ndarray) -> None:
        n_float = len(METRICS) - 2  # samples, diverged are counts
        # Python floats (tolist) print exactly as the float64 values they come from
        for k, m in enumerate(values.tolist()):
            p, j = divmod(start + k, self._per_point)
            combo = self.grid.points.combo(p)
            seed = self.grid.seeds[j] if self._seed_col is None else combo[self._seed_col]
            counts = [int(v) if math.isfinite(v) else v for v in m[n_float:]]
            self._csv.writerow([*map(_cell, combo), _cell(seed), *map(repr, m[:n_float]),
                                *map(_cell, counts)])
        self.rows_written += len(values)

    def _note_diverged(self, first_point: int, values: np.ndarray) -> None:
        per_point = values[:, -1].reshape(-1, self._per_point) > 0
        counts = per_point.sum(axis=1)
        hit = [(first_point + int(k), int(counts[k])) for k in np.flatnonzero(counts)]
        self.diverged_points += len(hit)
        # chunks may finish out of order: keep the first few in grid order
        self.first_diverged = sorted(self.first_diverged + hit)[:DIVERGED_SHOWN]

    def divergence_warning(self) -> str | None:
        """One line on the runs that diverged, or None when none did.

        How many runs diverged, at which grid points (the first few), and the likely cause at
        the first of them (:func:`esoarm.engines.diagnosis.divergence_causes`).

        Returns
        -------
        str or None
        """
        if not self.diverged:
            return None
        from esoarm.engines.diagnosis import divergence_causes
        from esoarm.engines.loop import DIVERGENCE_LIMIT

        grid = self.grid
        shown = []
        for p, n in self.first_diverged:
            values = ", ".join(f"{k} = {_short(v)}" for k, v in
                               zip(grid.keys, grid.points.combo(p), strict=True))
            seeds = f" ({n} of {self._per_point} seeds)" if self._per_point > 1 else ""
            shown.append(values + seeds)
        more = self.diverged_points - len(shown)
        where = "; ".join(shown) + (f"; and {more} more" if more > 0 else "")
        causes = divergence_causes(grid.points[self.first_diverged[0][0]], DIVERGENCE_LIMIT)
        why = (f"likely cause at the first: {causes[0]}" if causes else
               "nothing in the scenario of the first stands out; check observer.eps against "
               "the sample rate, the gains and the disturbance")
        points = len(grid.points)
        return (f"{self.diverged} of {self.n_done} runs diverged, at {self.diverged_points} of "
                f"{points} grid point{'s' if points > 1 else ''} ({where}); {why} (diverged = 1 "
                "in the CSV; their metrics cover the samples up to divergence)")

    def _rank(self, first_point: int, values: np.ndarray) -> None:
        by_point = values.reshape(-1, self._per_point, len(METRICS))
        means = np.array([_finite_means(pt) for pt in by_point])
        for k, row in enumerate(means):
            if np.isfinite(row[self._by]):
                self._best.append((float(row[self._by]), first_point + k, row))
        # a point with a diverged run ranks after every point without (its metrics cover
        # only the samples before divergence)
        div = METRICS.index("diverged")
        self._best.sort(key=lambda item: (item[2][div] > 0, item[0], item[1]))
        del self._best[self._keep:]

    def best(self, n: int = 5) -> list[dict[str, Any]]:
        """The best grid points seen so far (lowest seed-mean ``by``), with their mean metrics.

        Parameters
        ----------
        n : int
            How many (at most the ``best`` given to the writer).

        Returns
        -------
        list of dict
            Per grid point, best first: the varied keys' values and the seed-mean metrics.
        """
        out = []
        for _, p, row in self._best[:n]:
            entry: dict[str, Any] = dict(zip(self.grid.keys, self.grid.points.combo(p),
                                            strict=True))
            entry.update({m: float(row[i]) for i, m in enumerate(METRICS) if m != "samples"})
            out.append(entry)
        return out

    def close(self, complete: bool = True) -> int:
        """Finish the CSV (also the rows held for an earlier unfinished chunk).

        With ``complete=False`` (interrupted, or a chunk failed) the file keeps
        every finished row in grid order, with gaps where runs did not finish.

        Parameters
        ----------
        complete : bool
            Every run finished.

        Returns
        -------
        int
            Rows written (0 without a file).
        """
        if self._fh is None:
            return 0
        try:
            for start in sorted(self._pending):
                self._write(start, self._pending.pop(start))
            self._fh.close()
            self._fh = None
            assert self._tmp is not None and self._target is not None
            os.replace(self._tmp, self._target)
        except OSError as exc:
            self._fail(exc)
        return self.rows_written

    def discard(self) -> None:
        """Remove the temporary file (nothing was written worth keeping)."""
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:  # its last data could not be flushed: removed below anyway
                pass
            self._fh = None
        if self._tmp is not None:
            try:
                self._tmp.unlink(missing_ok=True)
            except OSError:  # pragma: no cover
                pass


def _short(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _finite_means(a: np.ndarray) -> np.ndarray:
    """Per-column means over the finite entries (NaN where none)."""
    ok = np.isfinite(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok, a, 0.0).sum(axis=0) / ok.sum(axis=0)


@dataclass
class SweepResult:
    """Metrics of a (possibly partial) sweep, one row per run in grid order.

    Attributes
    ----------
    grid : SweepGrid
    values : ndarray, shape (runs, len(METRICS))
        Metric rows; rows of unfinished runs are NaN.
    done : ndarray of bool, shape (runs,)
        Which runs finished.
    seconds : float
        Wall time of the runs [s].
    """

    grid: SweepGrid
    values: np.ndarray
    done: np.ndarray
    seconds: float = 0.0

    @classmethod
    def empty(cls, grid: SweepGrid) -> SweepResult:
        """A result with no run finished yet.

        Parameters
        ----------
        grid : SweepGrid
            The sweep's grid.

        Returns
        -------
        SweepResult
            Every metric NaN, no run done.
        """
        return cls(grid, np.full((grid.n_runs, len(METRICS)), np.nan),
                   np.zeros(grid.n_runs, dtype=bool))

    def add(self, start: int, values: np.ndarray) -> None:
        """Store the rows of one finished chunk.

        Parameters
        ----------
        start : int
            Index of the chunk's first run (runs in grid order, seed fastest).
        values : ndarray, shape (runs, len(METRICS))
            The chunk's metric rows.
        """
        self.values[start : start + len(values)] = values
        self.done[start : start + len(values)] = True

    @property
    def complete(self) -> bool:
        """Every run finished."""
        return bool(self.done.all())

    @property
    def n_done(self) -> int:
        """Runs finished."""
        return int(self.done.sum())

    def header(self) -> list[str]:
        """CSV columns.

        Returns
        -------
        list of str
            The varied keys, ``seed``, then :data:`~esoarm.engines.metrics.METRICS`.
        """
        return [*self.grid.keys, "seed", *METRICS]

    def rows(self, finished_only: bool = True) -> Iterator[list[Any]]:
        """Rows in grid order: varied values, seed, metrics (counts as int).

        Parameters
        ----------
        finished_only : bool
            Leave out the runs that did not finish.

        Returns
        -------
        iterator of list
            One row per run, the columns of :meth:`header`.
        """
        n_float = len(METRICS) - 2  # samples, diverged are counts
        i = 0
        for values, seeds in zip(self.grid.point_values(), self.grid.point_seeds(), strict=True):
            for seed in seeds:
                if self.done[i] or not finished_only:
                    m = self.values[i]
                    counts = [int(v) if np.isfinite(v) else v for v in m[n_float:]]
                    yield [*values, seed, *m[:n_float], *counts]
                i += 1

    def point_metric(self, name: str) -> np.ndarray:
        """Metric ``name`` per grid point and seed (NaN where unfinished).

        Parameters
        ----------
        name : str
            A name of :data:`~esoarm.engines.metrics.METRICS`.

        Returns
        -------
        ndarray, shape (points, seeds)
            In the metric's unit.
        """
        per_point = max(len(self.grid.seeds), 1)
        return self.values[:, METRICS.index(name)].reshape(len(self.grid.points), per_point)

    def best(self, n: int = 5, by: str = "rms_error") -> list[dict[str, Any]]:
        """The ``n`` grid points with the lowest seed-mean ``by``, with their mean metrics.

        Parameters
        ----------
        n : int
            How many grid points.
        by : str
            The metric that ranks them (a name of :data:`~esoarm.engines.metrics.METRICS`);
            points with a diverged run come last.

        Returns
        -------
        list of dict
            Per grid point, best first: the varied keys' values and the seed-mean metrics.
        """
        means = {m: _nanmean_rows(self.point_metric(m)) for m in METRICS}
        order = [i for i in np.lexsort((means[by], means["diverged"] > 0))
                 if np.isfinite(means[by][i])]  # diverged points last
        out = []
        values = list(self.grid.point_values())
        for i in order[:n]:
            row: dict[str, Any] = dict(zip(self.grid.keys, values[i], strict=True))
            row.update({m: float(means[m][i]) for m in METRICS if m not in ("samples",)})
            out.append(row)
        return out

    def write_csv(self, path: str | Path) -> int:
        """Write the finished rows (atomic: the file appears only complete).

        Parameters
        ----------
        path : str or Path
            The CSV file.

        Returns
        -------
        int
            Rows written.
        """
        return write_rows_atomic(path, self.header(), self.rows())


def _nanmean_rows(a: np.ndarray) -> np.ndarray:
    out = np.full(a.shape[0], np.nan)
    ok = np.isfinite(a).any(axis=1)
    out[ok] = np.array([np.mean(r[np.isfinite(r)]) for r in a[ok]])
    return out


def write_rows_atomic(path: str | Path, header: Sequence[str], rows: Iterator[list[Any]]) -> int:
    """Write a CSV table; the file appears only once complete.

    Parameters
    ----------
    path : str or Path
        The CSV file.
    header : sequence of str
        The column names.
    rows : iterator of list
        The rows, a cell per column.

    Returns
    -------
    int
        Rows written.
    """
    count = 0
    with atomic_path(path) as tmp, tmp.open("w", encoding="utf-8", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(header)
        for row in rows:
            writer.writerow([_cell(v) for v in row])
            count += 1
    return count
