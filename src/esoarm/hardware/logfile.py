"""Reading the CSV log of a run: header, chosen columns, checked numbers.

The logs of ``esoarm run``, ``esoarm emulate``, ``esoarm excite`` and
``esoarm simulate --out`` are CSV files with a header line and one row per
sample.  :func:`read_log_columns` reads the columns a consumer needs (replay,
arm replay, identification) and applies the checks they share; every problem
is a :class:`~esoarm.scenario.ScenarioError` with one line naming the file
and, where it applies, the line and the column (lines starting with ``#`` before
the header are comments: ``esoarm run --onboard`` says there what it logged):

- the file is missing or unreadable, or has no header or no data rows;
- a needed column is missing (the message says what the consumer needs), or
  named twice in the header;
- a cell of a needed column is not a number;
- a value is not finite -- except ``nan`` in a measured-angle column after
  the first row, which marks a sample lost on the link (``esoarm run`` logs
  them that way).

:func:`sample_period` checks the time column (at least two rows, uniformly
spaced and increasing) and returns the sample period [s].
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TypeAlias

import numpy as np

from esoarm.scenario import ScenarioError

__all__ = ["read_log_columns", "sample_period"]

#: Columns to read: their names, or a function of the (stripped) header giving them.
Pick: TypeAlias = Sequence[str] | Callable[[list[str]], Sequence[str]]


def read_log_columns(path: str | Path, pick: Pick, need: str,
                     lost_ok: Sequence[str] = (),
                     all_nan_why: Mapping[str, str] | None = None,
                     ) -> tuple[list[str], np.ndarray]:
    """Read the columns ``pick`` of the CSV log at ``path``; return (names, data).

    Parameters
    ----------
    path : str or Path
        The log file.
    pick : sequence of str, or callable
        The columns to read, in order, or a function of the header (a list of
        stripped column names) that chooses them -- e.g. the measured angle
        ``y`` when the file has it, else ``theta``.
    need : str
        What the consumer needs, for the missing-column message
        (``"need t [s], theta [rad], u [N·m]"``).
    lost_ok : sequence of str
        Chosen columns in which ``nan`` marks a lost sample (allowed after the
        first row); every other value of every chosen column must be finite.
    all_nan_why : mapping of str to str, optional
        For a column that is nan in every row (of two or more), why that happens and
        what to do, added to the message that says so.

    Returns
    -------
    names : list of str
        The chosen column names.
    data : ndarray (N, len(names))
        The values, N >= 1 rows, in the order of ``names`` (blank lines skipped).

    Raises
    ------
    ScenarioError
        One line naming the file (and the line and column where there is one).
    """
    src = f"log '{path}'"
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh)
            row0 = next(reader, [])
            while row0 and row0[0].lstrip().startswith("#"):  # comment lines before the header
                row0 = next(reader, [])
            header = [h.strip() for h in row0]
            if not any(header):
                raise ScenarioError(f"{src}: empty file (expected a header line, then one "
                                    "row per sample)")
            names = list(pick(header) if callable(pick) else pick)
            missing = [c for c in names if c not in header]
            if missing:
                raise ScenarioError(f"{src}: missing column(s) {', '.join(missing)}; {need}")
            twice = [c for c in dict.fromkeys(names) if header.count(c) > 1]
            if twice:
                raise ScenarioError(f"{src}: column {twice[0]} appears "
                                    f"{header.count(twice[0])} times in the header; which one "
                                    "to read is unclear (rename or remove the others)")
            idx = [header.index(c) for c in names]
            rows, lines = [], []
            for row in reader:
                if not row:
                    continue
                try:
                    rows.append([float(row[i]) for i in idx])
                except (ValueError, IndexError):
                    raise ScenarioError(f"{src}: line {reader.line_num}: expected numbers in "
                                        f"columns {', '.join(names)}") from None
                lines.append(reader.line_num)
    except FileNotFoundError:
        raise ScenarioError(f"{src}: no such file") from None
    except IsADirectoryError:
        raise ScenarioError(f"{src}: is a directory, not a file") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{src}: not a text CSV (byte 0x{exc.object[exc.start]:02x} at "
                            f"offset {exc.start} is not UTF-8): a MAT file or another program's "
                            "binary export comes in with 'esoarm log import FILE "
                            "--map t=…,y=…,u=… --out LOG.csv'") from None
    except (OSError, csv.Error) as exc:
        raise ScenarioError(f"{src}: cannot read: {exc}") from None
    if not rows:
        raise ScenarioError(f"{src}: no data rows (only the header)")
    data = np.array(rows, dtype=float)
    _check_finite(src, data, names, lines, lost_ok, all_nan_why or {})
    return names, data


def _check_finite(src: str, data: np.ndarray, names: list[str], lines: list[int],
                  lost_ok: Sequence[str], all_nan_why: Mapping[str, str]) -> None:
    """One-line error for the first non-finite value not allowed (see the module)."""
    lost_cols = [j for j, c in enumerate(names) if c in lost_ok]
    allowed = np.zeros(data.shape, dtype=bool)
    allowed[1:, lost_cols] = np.isnan(data[1:, lost_cols])
    bad = ~(np.isfinite(data) | allowed)
    if not bad.any():
        return
    k, j = (int(i) for i in np.argwhere(bad)[0])
    col, value = names[j], data[k, j]
    if j not in lost_cols and len(data) > 1 and np.isnan(data[:, j]).all():
        why = all_nan_why.get(col)
        raise ScenarioError(f"{src}: column {col} is nan in every row"
                            + (f": {why}" if why else ""))
    if j in lost_cols and np.isnan(value):  # only in the first row
        raise ScenarioError(f"{src}: line {lines[k]}: {col} must be finite in the first row "
                            "(nan marks a lost sample, allowed after the first row)")
    if lost_cols:
        allowed_text = (f"only {', '.join(names[i] for i in lost_cols)} may be nan, "
                        "for a lost sample")
    else:
        allowed_text = "every value must be a finite number"
    raise ScenarioError(f"{src}: line {lines[k]}: non-finite value {col} = {value:g} "
                        f"({allowed_text})")


def sample_period(t: np.ndarray, path: str | Path) -> float:
    """The sample period [s] of the time column ``t`` of the log at ``path``, checked.

    Raises :class:`ScenarioError` (one line naming the file) unless ``t`` has
    at least two rows and is uniformly spaced (relative tolerance 1e-6) and
    increasing.
    """
    src = f"log '{path}'"
    if len(t) < 2:
        raise ScenarioError(f"{src}: needs at least 2 rows, has {len(t)}")
    dt = np.diff(t)
    ts = float(t[1] - t[0])
    if not ts > 0 or np.max(np.abs(dt - ts)) > 1e-6 * ts + 1e-12:
        raise ScenarioError(f"{src}: column t must be uniformly spaced and increasing "
                            f"(steps from {dt.min():g} to {dt.max():g} s)")
    return ts
