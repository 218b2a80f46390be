"""Logs from elsewhere: a MATLAB ``.mat`` or CSV file turned into an esoarm log.

A log recorded by other software names its columns its own way (EMPS: ``t``,
``qm``, ``vir``), stores the input in its own unit (a drive voltage, to be
multiplied by a gain to give a force) and stamps time with the jitter of its
clock or of single precision.  :func:`import_log` maps the source's
variables onto esoarm's columns, scales them, checks the time stamps and
returns a :class:`ImportedLog` that :func:`write_log` writes as the CSV every
esoarm command reads (``t`` [s], ``y`` measured position, ``u`` applied
force/torque, optional ``theta_ref`` and any other mapped column).

Time stamps
-----------
The rate is 1/Ts with Ts the least-squares slope of t_k against k (once the
steps, compared with their median, show no gap).  The *jitter* is the largest
deviation of a stamp from that uniform grid, t_k − (t_0 + k·Ts), relative to
Ts.  A jitter up to :data:`MAX_JITTER` (a tenth of a sample) is the clock's or
the storage's rounding on a uniform grid (EMPS: 2e-5 of a sample): the log is
accepted and written on the exact grid t_0 + k/rate (the rate rounded to six
digits when that moves no stamp further), and the jitter is reported.  A step
between two stamps larger than (1 + :data:`MAX_JITTER`)·Ts, or smaller than
(1 − MAX_JITTER)·Ts, is a real gap (or a repeated sample): refused, naming the
worst one (its row and its time).

A file without time stamps (the Silverbox benchmark's CSV has only its input
and output voltages) is imported with its sample rate given instead of a ``t``
column (``rate_hz``): t_k = k/rate.

Source variables
----------------
A CSV column by its header name (a trailing empty field on every line, as
MATLAB's ``writematrix`` of a table leaves, is dropped).  A ``.mat`` variable
by its name; a column of a 2-D matrix (a Simulink ``data`` array) as
``NAME:J``, J counted from 1 as in MATLAB's ``data(:, J)``.

Every problem is a :class:`~esoarm.scenario.ScenarioError`: one line naming
the file and the variable.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from esoarm.scenario import ScenarioError

__all__ = ["ImportedLog", "MAX_JITTER", "REQUIRED", "import_log", "parse_pairs", "read_source",
           "write_log"]

#: Largest deviation of a stamp from the uniform grid, in samples, still read as jitter.
MAX_JITTER = 0.1
#: Columns every imported log has (time [s], measured position, applied force/torque).
REQUIRED = ("t", "y", "u")
#: Further columns an import may map (what esoarm's commands read besides t, y, u).
OPTIONAL = ("theta_ref", "theta", "duty")


@dataclass(frozen=True)
class ImportedLog:
    """An imported log on the uniform grid.

    Attributes
    ----------
    columns : dict of str to ndarray
        esoarm column name -> values (``t`` first) [s for t; the source's
        units times the scale for the others].
    rate_hz : float
        Sample rate 1/Ts [Hz].
    jitter : float
        Largest |t_k − (t_0 + k·Ts)| / Ts of the source's stamps [1].
    jitter_rms : float
        RMS of the same deviations / Ts [1].
    source : str
        The file it came from.
    mapping : dict of str to str
        esoarm column -> source variable.
    scales : dict of str to float
        esoarm column -> factor applied.
    constants : dict of str to float
        The source's scalar variables (a .mat file's gains, e.g. ``gtau``).
    """

    columns: dict[str, np.ndarray]
    rate_hz: float
    jitter: float
    jitter_rms: float
    source: str
    mapping: dict[str, str]
    scales: dict[str, float]
    constants: dict[str, float] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.columns["t"])

    def summary(self) -> str:
        """One line: samples, rate, duration and jitter."""
        dur = self.n / self.rate_hz
        return (f"{self.n} samples at {self.rate_hz:.6g} Hz ({dur:.4g} s); time-stamp jitter "
                f"{self.jitter:.2g} of a sample at most, {self.jitter_rms:.2g} RMS (written on "
                "the uniform grid)")


def parse_pairs(text: str, option: str, numbers: bool = False) -> dict[str, str]:
    """``"t=time,u=vir"`` -> {"t": "time", "u": "vir"}; one-line error naming ``option``."""
    out: dict[str, str] = {}
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        key, sep, value = part.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key or not value:
            raise ScenarioError(f"{option} '{text}': expected NAME=VALUE pairs separated by "
                                "commas, e.g. t=time,y=qm,u=vir")
        if key in out:
            raise ScenarioError(f"{option} '{text}': {key} given twice")
        out[key] = value
    return out


def read_source(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """The variables of a ``.mat`` or CSV file: (vectors by name, scalars by name).

    A ``.mat`` file (MATLAB 5 to 7.2, read with :func:`scipy.io.loadmat`): every
    numeric variable with one non-singleton dimension is a vector, every 1×1
    numeric variable a scalar.  A CSV file: a header line of names, then
    numbers (a UTF-8 byte-order mark is skipped).
    """
    src = f"file '{path}'"
    p = Path(path)
    if not p.exists():
        raise ScenarioError(f"{src}: no such file")
    if p.is_dir():
        raise ScenarioError(f"{src}: is a directory, not a file")
    suffix = p.suffix.lower()
    if suffix == ".mat":
        return _read_mat(p, src)
    if suffix in (".csv", ".txt"):
        return _read_csv(p, src)
    raise ScenarioError(f"{src}: unknown format '{p.suffix}' (a MATLAB .mat or a .csv file)")


def _read_mat(p: Path, src: str) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    import scipy.io

    try:
        raw = scipy.io.loadmat(p)
    except NotImplementedError:
        raise ScenarioError(f"{src}: a MATLAB 7.3 (HDF5) file; save it with "
                            "save(..., '-v7') in MATLAB, then import it") from None
    except (ValueError, OSError, TypeError) as exc:
        raise ScenarioError(f"{src}: cannot read as a MATLAB .mat file: {exc}") from None
    vectors: dict[str, np.ndarray] = {}
    scalars: dict[str, float] = {}
    for name, value in raw.items():
        if name.startswith("__") or not isinstance(value, np.ndarray):
            continue
        if value.dtype.kind not in "biuf" or value.size == 0:
            continue
        if value.size == 1:
            scalars[name] = float(value.ravel()[0])
        elif sum(d > 1 for d in value.shape) == 1:
            vectors[name] = value.astype(float).ravel()
        elif value.ndim == 2:  # a matrix: its columns as NAME:1 … NAME:n (MATLAB's data(:, j))
            for j in range(value.shape[1]):
                vectors[f"{name}:{j + 1}"] = value[:, j].astype(float)
    return vectors, scalars


def _read_csv(p: Path, src: str) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader, [])]
            if not any(header):
                raise ScenarioError(f"{src}: empty file (expected a header line of names)")
            trailing = len(header) > 1 and header[-1] == ""  # "V1","V2", (a trailing comma)
            if trailing:
                header = header[:-1]
            rows = []
            for row in reader:
                if not row:
                    continue
                if trailing and len(row) == len(header) + 1 and not row[-1].strip():
                    row = row[:-1]
                try:
                    rows.append([float(v) for v in row])
                except ValueError:
                    raise ScenarioError(f"{src}: line {reader.line_num}: expected numbers") \
                        from None
                if len(row) != len(header):
                    raise ScenarioError(f"{src}: line {reader.line_num}: {len(row)} values, "
                                        f"the header names {len(header)}")
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ScenarioError(f"{src}: cannot read: {exc}") from None
    if not rows:
        raise ScenarioError(f"{src}: no data rows (only the header)")
    data = np.array(rows, dtype=float)
    return {name: data[:, j] for j, name in enumerate(header)}, {}


def import_log(path: str | Path, mapping: Mapping[str, str],
               scales: Mapping[str, str | float] | None = None,
               rate_hz: float | None = None) -> ImportedLog:
    """Read ``path`` and map, scale and check it into an esoarm log.

    Parameters
    ----------
    path : str or Path
        A MATLAB ``.mat`` or a CSV file.
    mapping : mapping of str to str
        esoarm column -> source variable; ``t``, ``y`` and ``u`` are required,
        ``theta_ref``, ``theta`` and ``duty`` may be added.
    scales : mapping of str to (float or str), optional
        esoarm column -> factor, a number or the name of a scalar variable of
        the file (EMPS: ``u=gtau``, the drive gain 35.15 N/V that turns the
        logged voltage into a force).  ``t`` may be scaled too (stamps in ms:
        ``t=0.001``).
    rate_hz : float, optional
        The sample rate [Hz] of a file without time stamps: then ``t`` is not
        mapped and t_k = k/rate_hz (jitter 0).

    Returns
    -------
    ImportedLog
        On the uniform grid (see the module docstring).

    Raises
    ------
    ScenarioError
        One line naming the file and the variable: unknown or missing
        variable, columns of different lengths, a non-finite value, a gap in
        the time stamps (the worst one named), a non-increasing time column.
    """
    src = f"file '{path}'"
    for col in mapping:
        if col not in REQUIRED + OPTIONAL:
            raise ScenarioError(f"map {col}: not an esoarm log column (one of "
                                f"{', '.join(REQUIRED + OPTIONAL)})")
    if rate_hz is not None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ScenarioError(f"rate {rate_hz:g}: must be a sample rate > 0 [Hz]")
        if "t" in mapping:
            raise ScenarioError(f"map t={mapping['t']} and a rate of {rate_hz:g} Hz: give one "
                                "(the time stamps, or the rate of a file without them)")
    missing = [c for c in REQUIRED if c not in mapping and not (c == "t" and rate_hz)]
    if missing:
        raise ScenarioError(f"map: give {', '.join(missing)} (t = time [s], y = measured "
                            "position, u = applied force or torque), e.g. --map t=t,y=qm,u=vir")
    vectors, scalars = read_source(path)
    factors: dict[str, float] = {}
    for col, value in (scales or {}).items():
        if col not in mapping:
            raise ScenarioError(f"scale {col}: not a mapped column (mapped: "
                                f"{', '.join(mapping)})")
        factors[col] = _factor(value, scalars, src, col)
    columns: dict[str, np.ndarray] = {}
    for col, var in mapping.items():
        if var not in vectors:
            matrix = sorted(int(k.rsplit(":", 1)[1]) for k in vectors
                            if k.rsplit(":", 1)[0] == var and ":" in k)
            if matrix:
                raise ScenarioError(f"{src}: {var} (for {col}) is a matrix of {len(matrix)} "
                                    f"columns: name one as {var}:1 … {var}:{matrix[-1]} "
                                    f"(MATLAB's {var}(:, j))")
            what = "a scalar, not a column" if var in scalars else "no such variable"
            names = sorted({k.rsplit(":", 1)[0] + (":j" if ":" in k else "") for k in vectors})
            raise ScenarioError(f"{src}: {var} (for {col}): {what}; the file has "
                                f"{', '.join(names) or 'no columns'}")
        values = vectors[var] * factors.get(col, 1.0)
        bad = ~np.isfinite(values)
        if bad.any():
            k = int(np.argmax(bad))
            raise ScenarioError(f"{src}: {var} (for {col}) is {values[k]:g} at row {k + 1} "
                                "(every value must be a finite number)")
        columns[col] = values
    lengths = {col: len(v) for col, v in columns.items()}
    if len(set(lengths.values())) > 1:
        raise ScenarioError(f"{src}: the mapped variables differ in length ("
                            + ", ".join(f"{mapping[c]} {n}" for c, n in lengths.items()) + ")")
    if rate_hz is not None:
        n = len(columns["y"])
        columns = {"t": np.arange(n) / rate_hz, **columns}
        if n < 2:
            raise ScenarioError(f"{src}: needs at least 2 samples, has {n}")
        rate, jitter, jitter_rms = float(rate_hz), 0.0, 0.0
        grid = columns["t"]
    else:
        t = columns["t"]
        ts, jitter, jitter_rms = check_time(t, f"{src}: {mapping['t']} (for t)")
        rate = _round_rate(t, ts)
        grid = t[0] + np.arange(len(t)) / rate
    order = [*REQUIRED, *(c for c in columns if c not in REQUIRED)]
    ordered = {c: grid if c == "t" else columns[c] for c in order}
    return ImportedLog(ordered, rate, jitter, jitter_rms, str(path), dict(mapping),
                       factors, scalars)


def _factor(value: str | float, scalars: Mapping[str, float], src: str, col: str) -> float:
    if isinstance(value, (int, float)):
        f = float(value)
    else:
        try:
            f = float(value)
        except ValueError:
            if value not in scalars:
                raise ScenarioError(f"scale {col}={value}: neither a number nor a scalar of "
                                    f"{src} (its scalars: "
                                    f"{', '.join(sorted(scalars)) or 'none'})") from None
            f = scalars[value]
    if not (math.isfinite(f) and f != 0.0):
        raise ScenarioError(f"scale {col}={value}: must be a finite, non-zero factor")
    return f


def _round_rate(t: np.ndarray, ts: float) -> float:
    """The rate 1/``ts`` [Hz] rounded to 6 significant digits, if the stamps allow it.

    (1000.0000000096 Hz is 1 kHz written by a clock with jitter: the grid is written with
    the round rate when that moves no stamp by more than a hundredth of a sample more.)
    """
    rate = float(f"{1.0 / ts:.6g}")
    k = np.arange(len(t), dtype=float)
    fitted = np.max(np.abs(t - (t[0] + ts * k)))
    rounded = np.max(np.abs(t - (t[0] + k / rate)))
    return rate if rounded <= fitted + 0.01 * ts else 1.0 / ts


def check_time(t: np.ndarray, what: str) -> tuple[float, float, float]:
    """(Ts [s], largest jitter [samples], RMS jitter [samples]) of the stamps ``t`` [s].

    Raises :class:`ScenarioError` (``what`` names the column) for fewer than
    two stamps, a non-increasing column or a gap (see the module docstring).
    """
    n = len(t)
    if n < 2:
        raise ScenarioError(f"{what}: needs at least 2 samples, has {n}")
    k = np.arange(n, dtype=float)
    dt = np.diff(t)
    ts = float(np.median(dt))  # robust to gaps; refined below once there are none
    if not ts > 0 or not np.all(dt > 0):
        i = int(np.argmin(dt))
        raise ScenarioError(f"{what}: time must increase; row {i + 2} (t = {t[i + 1]:.9g} s) "
                            f"is not after row {i + 1} (t = {t[i]:.9g} s)")
    steps = dt / ts
    worst = int(np.argmax(np.abs(steps - 1.0)))
    if abs(steps[worst] - 1.0) > MAX_JITTER:
        kind = "a gap" if steps[worst] > 1.0 else "a short step"
        raise ScenarioError(
            f"{what}: not a uniform grid: {kind} of {dt[worst]:.6g} s (≈ {steps[worst]:.3g} "
            f"samples of {ts:.6g} s) between row {worst + 1} (t = {t[worst]:.9g} s) and row "
            f"{worst + 2}; the worst of {int(np.sum(np.abs(steps - 1.0) > MAX_JITTER))} such "
            f"step(s); jitter up to {MAX_JITTER:g} of a sample is accepted; split the log at "
            "the gap or resample it")
    slope, intercept = np.polyfit(k, t, 1)
    ts = float(slope)
    # the grid through the first stamp with the fitted period (the written time column)
    dev = (t - (t[0] + ts * k)) / ts
    dev_fit = (t - (intercept + ts * k)) / ts
    jitter = float(np.max(np.abs(dev_fit)))
    if float(np.max(np.abs(dev))) > MAX_JITTER:  # a drift of the first stamp off the grid
        jitter = float(np.max(np.abs(dev)))
        if jitter > 0.5:
            raise ScenarioError(f"{what}: the stamps drift off a uniform grid by {jitter:.3g} "
                                "samples (a clock that runs at another rate part of the time); "
                                "resample the log")
    return ts, jitter, float(np.sqrt(np.mean(dev_fit**2)))


def write_log(log: ImportedLog, path: str | Path) -> None:
    """Write ``log`` as an esoarm CSV log at ``path`` (atomically; full precision).

    Columns: ``t`` [s], ``y``, ``u``, then the other mapped columns, each value
    written as the shortest decimal that reads back as the same double.
    """
    from esoarm._io import atomic_path

    names = list(log.columns)
    data = np.column_stack([log.columns[c] for c in names])
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(names) + "\n")
        fh.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())
