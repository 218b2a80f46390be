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
column (``rate_hz``, at most :data:`MAX_RATE_HZ`): t_k = k/rate.

Irregular stamps (a logger that writes when it can: 0.8 ms, then 1.3 ms, ...)
are refused unless ``resample_hz`` is given: then every mapped column is
interpolated linearly onto t_0 + k/resample_hz up to the last stamp, and the
import says how far the stamps were apart (median, smallest and largest step,
the row of the largest).  A step longer than :data:`MAX_RESAMPLE_GAP` new
samples is refused (linear interpolation across it would invent the motion).

Calibration
-----------
Each mapped column may be corrected: value = sign · scale · raw + offset
(``signs``, ``scales``, ``offsets``; a scale or offset is a number or the name
of a scalar variable of the file).

Source variables
----------------
A CSV column by its header name (a trailing empty field on every line, as
MATLAB's ``writematrix`` of a table leaves, is dropped; a file whose header
has semicolons and no commas -- a spreadsheet's regional CSV -- is read with
``;`` between fields and a decimal comma allowed).  A column that holds text
(a clock time such as ``12:00:01.5``) is kept aside and named if mapped.  A
``.mat`` variable by its name; a column of a 2-D matrix (a Simulink ``data``
array) as ``NAME:J``, J counted from 1 as in MATLAB's ``data(:, J)``; a field
of a 1×1 struct as ``NAME.FIELD``.  A variable that is text, complex, empty, a
cell array or an array of more than 2 dimensions is named as such when mapped.
A JSON file holds either a list of records (``[{"t": 0, "y": 0.1, ...}, ...]``)
or columns (``{"t": [...], "y": [...], "gain": 35.15}``; a number is a scalar).

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

__all__ = ["ImportedLog", "MAX_JITTER", "MAX_RATE_HZ", "REQUIRED", "import_log", "parse_pairs",
           "read_source", "write_log"]

#: Largest deviation of a stamp from the uniform grid, in samples, still read as jitter.
MAX_JITTER = 0.1
#: Highest sample rate accepted [Hz] (``rate_hz``, ``resample_hz``): no electromechanical log
#: is sampled faster; a larger number is usually a period or a count mistaken for a rate.
MAX_RATE_HZ = 1e6
#: Lowest sample rate accepted [Hz].
MIN_RATE_HZ = 1e-3
#: Longest step between two stamps that ``resample_hz`` interpolates across, in new samples.
MAX_RESAMPLE_GAP = 10.0
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
    offsets : dict of str to float
        esoarm column -> offset added after the scale.
    signs : dict of str to float
        esoarm column -> ±1 applied.
    notes : list of str
        What the import did besides mapping (resampling and how far the
        stamps were apart, the field separator read).
    resampled : bool
        The columns were interpolated onto the grid (``resample_hz``); the
        jitter fields are then 0.
    """

    columns: dict[str, np.ndarray]
    rate_hz: float
    jitter: float
    jitter_rms: float
    source: str
    mapping: dict[str, str]
    scales: dict[str, float]
    constants: dict[str, float] = field(default_factory=dict)
    offsets: dict[str, float] = field(default_factory=dict)
    signs: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    resampled: bool = False

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.columns["t"])

    def summary(self) -> str:
        """One line: samples, rate, duration and jitter."""
        dur = self.n / self.rate_hz
        text = f"{self.n} samples at {self.rate_hz:.6g} Hz ({dur:.4g} s)"
        if not self.resampled:
            text += (f"; time-stamp jitter {self.jitter:.2g} of a sample at most, "
                     f"{self.jitter_rms:.2g} RMS (written on the uniform grid)")
        return "; ".join([text, *self.notes])


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


@dataclass
class _Source:
    """What a file holds: vectors and scalars by name, the rest described, notes."""

    vectors: dict[str, np.ndarray]
    scalars: dict[str, float]
    others: dict[str, str] = field(default_factory=dict)  # name -> what it is (not a column)
    notes: list[str] = field(default_factory=list)


def read_source(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """The variables of a ``.mat``, CSV or JSON file: (vectors by name, scalars by name).

    A ``.mat`` file (MATLAB 5 to 7.2, read with :func:`scipy.io.loadmat`): every
    numeric variable with one non-singleton dimension is a vector, every 1×1
    numeric variable a scalar, each column of a matrix a vector ``NAME:J``,
    each field of a 1×1 struct ``NAME.FIELD``.  A CSV file: a header line of
    names, then numbers (a UTF-8 byte-order mark is skipped; see the module
    docstring for semicolons and text columns).  A JSON file: a list of records
    or an object of columns.
    """
    src = _read(path)
    return src.vectors, src.scalars


def _read(path: str | Path) -> _Source:
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
    if suffix == ".json":
        return _read_json(p, src)
    raise ScenarioError(f"{src}: unknown format '{p.suffix}' (a MATLAB .mat, a .csv or a "
                        ".json file)")


def _describe(value: np.ndarray) -> str | None:
    """What a .mat value is when it is not a numeric vector, scalar or matrix (else None)."""
    kind = value.dtype.kind
    if kind in "US":
        text = str(value.ravel()[0]) if value.size else ""
        return f"text ('{text[:20]}'), not numbers"
    if kind == "c":
        return "complex numbers (map its real part, saved as a variable of its own)"
    if value.dtype.names:
        return None  # a struct: its fields are flattened by the caller
    if kind == "O":
        return "a cell array, not a numeric array (save its contents as numeric variables)"
    if kind == "b":
        return None
    if value.size == 0:
        return "empty (0 values)"
    if value.ndim > 2 and sum(d > 1 for d in value.shape) > 2:
        return f"an array of {value.ndim} dimensions {value.shape}, not a vector or matrix"
    return None


def _add_mat_value(name: str, value: np.ndarray, out: _Source) -> None:
    what = _describe(value)
    if what is not None:
        out.others[name] = what
        return
    if value.dtype.names:  # a struct (scipy: a structured array)
        if value.size != 1:
            out.others[name] = (f"a {'×'.join(map(str, value.shape))} struct array, not "
                                "numbers (save each field as a numeric variable)")
            return
        fields = list(value.dtype.names)
        out.others[name] = (f"a struct with fields {', '.join(fields)}: name one as "
                            f"{name}.{fields[0]}")
        for f in fields:
            inner = value[f].ravel()[0]
            if isinstance(inner, np.ndarray):
                _add_mat_value(f"{name}.{f}", inner, out)
        return
    if value.size == 1:
        out.scalars[name] = float(value.ravel()[0])
    elif sum(d > 1 for d in value.shape) == 1:
        out.vectors[name] = value.astype(float).ravel()
    elif value.ndim == 2:  # a matrix: its columns as NAME:1 … NAME:n (MATLAB's data(:, j))
        for j in range(value.shape[1]):
            out.vectors[f"{name}:{j + 1}"] = value[:, j].astype(float)


def _read_mat(p: Path, src: str) -> _Source:
    import scipy.io
    from scipy.io.matlab import MatReadError

    try:
        raw = scipy.io.loadmat(p)
    except NotImplementedError:
        raise ScenarioError(f"{src}: a MATLAB 7.3 (HDF5) file; save it with "
                            "save(..., '-v7') in MATLAB, then import it") from None
    except MatReadError as exc:
        raise ScenarioError(f"{src}: not a MATLAB .mat file ({exc}); give a file saved by "
                            "MATLAB's save (v4 to v7.2), or a .csv or .json file") from None
    except (ValueError, OSError, TypeError, EOFError, KeyError, IndexError) as exc:
        raise ScenarioError(f"{src}: cannot read as a MATLAB .mat file: {exc}") from None
    out = _Source({}, {})
    for name, value in raw.items():
        if name.startswith("__") or not isinstance(value, np.ndarray):
            continue
        _add_mat_value(name, value, out)
    return out


def _number(text: str, decimal_comma: bool) -> float:
    text = text.strip()
    if decimal_comma:
        text = text.replace(",", ".")
    return float(text)


def _read_csv(p: Path, src: str) -> _Source:
    notes: list[str] = []
    try:
        with open(p, encoding="utf-8-sig", newline="") as fh:
            first = fh.readline()
            delimiter = ","
            if ";" in first and "," not in first:
                delimiter = ";"
                notes.append("fields separated by ';' (decimal commas read as points)")
            fh.seek(0)
            if fh.read(1) != "\ufeff":
                fh.seek(0)
            reader = csv.reader(fh, delimiter=delimiter)
            header = [h.strip() for h in next(reader, [])]
            if not any(header):
                raise ScenarioError(f"{src}: empty file (expected a header line of names)")
            trailing = len(header) > 1 and header[-1] == ""  # "V1","V2", (a trailing comma)
            if trailing:
                header = header[:-1]
            if all(_is_number(h, delimiter == ";") for h in header):
                raise ScenarioError(f"{src}: the first line holds numbers ({', '.join(header[:3])}"
                                    f"{', …' if len(header) > 3 else ''}), not column names: add "
                                    "a header line naming the columns (e.g. t,y,u) and map them "
                                    "with --map")
            if len(header) == 1 and ("\t" in header[0] or " " in header[0].strip()):
                raise ScenarioError(f"{src}: one column named '{header[0][:40]}': the fields "
                                    "are not separated by commas or semicolons (tabs or "
                                    "spaces?); save the file as CSV with commas")
            rows: list[list[str]] = []
            for row in reader:
                if not row or not any(v.strip() for v in row):
                    continue
                if trailing and len(row) == len(header) + 1 and not row[-1].strip():
                    row = row[:-1]
                if len(row) != len(header):
                    raise ScenarioError(f"{src}: line {reader.line_num}: {len(row)} values, "
                                        f"the header names {len(header)}")
                rows.append(row)
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{src}: not a text file (byte 0x{exc.object[exc.start]:02x} at "
                            f"position {exc.start} is not UTF-8); a CSV is text: export it as "
                            "CSV (UTF-8), or give the .mat or .json file it came from") from None
    except (OSError, csv.Error) as exc:
        raise ScenarioError(f"{src}: cannot read: {exc}") from None
    if not rows:
        raise ScenarioError(f"{src}: no data rows (only the header)")
    out = _Source({}, {}, notes=notes)
    for j, name in enumerate(header):
        values = np.empty(len(rows))
        for i, row in enumerate(rows):
            try:
                values[i] = _number(row[j], delimiter == ";")
            except ValueError:
                out.others[name] = (f"text ('{row[j].strip()[:24]}' on data row {i + 1}), not "
                                    "numbers")
                break
        else:
            out.vectors[name] = values
    return out


def _is_number(text: str, decimal_comma: bool) -> bool:
    try:
        _number(text, decimal_comma)
    except ValueError:
        return False
    return bool(text.strip())


def _read_json(p: Path, src: str) -> _Source:
    import json

    try:
        with open(p, encoding="utf-8-sig") as fh:
            data = json.load(fh)
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{src}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise ScenarioError(f"{src}: not JSON: {exc.msg} at line {exc.lineno} column "
                            f"{exc.colno}") from None
    out = _Source({}, {})
    if isinstance(data, list):  # records
        if not data:
            raise ScenarioError(f"{src}: an empty list (expected records such as "
                                '[{"t": 0.0, "y": 0.1, "u": 0.0}, ...])')
        if not all(isinstance(r, dict) for r in data):
            i = next(i for i, r in enumerate(data) if not isinstance(r, dict))
            raise ScenarioError(f"{src}: record {i + 1} is {type(data[i]).__name__}, not an "
                                'object of named values ({"t": 0.0, "y": 0.1, ...})')
        names = list(dict.fromkeys(k for r in data for k in r))
        for name in names:
            missing = next((i for i, r in enumerate(data) if name not in r), None)
            if missing is not None:
                out.others[name] = f"missing from record {missing + 1} of {len(data)}"
                continue
            _json_column(name, [r[name] for r in data], out)
        return out
    if isinstance(data, dict):  # columns
        for name, value in data.items():
            if isinstance(value, list):
                _json_column(name, value, out)
            elif isinstance(value, (int, float)) and not isinstance(value, bool):
                out.scalars[name] = float(value)
            else:
                out.others[name] = f"{type(value).__name__}, not a list of numbers or a number"
        return out
    raise ScenarioError(f"{src}: holds a {type(data).__name__}; expected a list of records "
                        '([{"t": 0.0, "y": 0.1, "u": 0.0}, ...]) or an object of columns '
                        '({"t": [...], "y": [...], "u": [...]})')


def _json_column(name: str, values: list, out: _Source) -> None:
    bad = next((i for i, v in enumerate(values) if isinstance(v, bool)
                or not isinstance(v, (int, float)) and v is not None), None)
    if bad is not None:
        out.others[name] = (f"{type(values[bad]).__name__} ({str(values[bad])[:24]!r}) at "
                            f"position {bad + 1}, not numbers")
    elif not values:
        out.others[name] = "empty (0 values)"
    else:  # null is a missing value: nan, refused below like any non-finite value
        out.vectors[name] = np.array([math.nan if v is None else v for v in values], dtype=float)


def check_rate(rate: float, option: str) -> float:
    """``rate`` [Hz] if it is a plausible sample rate, else a one-line error naming ``option``."""
    if not (math.isfinite(rate) and MIN_RATE_HZ <= rate <= MAX_RATE_HZ):
        raise ScenarioError(f"{option} {rate:g}: must be a sample rate > 0 (from "
                            f"{MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz; is it a period? the rate "
                            "is 1/period)")
    return float(rate)


def import_log(path: str | Path, mapping: Mapping[str, str],
               scales: Mapping[str, str | float] | None = None,
               rate_hz: float | None = None,
               offsets: Mapping[str, str | float] | None = None,
               signs: Mapping[str, str | float] | None = None,
               resample_hz: float | None = None) -> ImportedLog:
    """Read ``path`` and map, scale and check it into an esoarm log.

    Parameters
    ----------
    path : str or Path
        A MATLAB ``.mat``, a CSV or a JSON file.
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
    offsets : mapping of str to (float or str), optional
        esoarm column -> offset added after the scale [the column's unit]
        (e.g. ``y=-1.5708`` to move a zero that the source put at the bottom).
    signs : mapping of str to (float or str), optional
        esoarm column -> +1 or -1 (an encoder counting the other way).
    resample_hz : float, optional
        Interpolate every column linearly onto a uniform grid of this rate
        [Hz] (irregular stamps); the import notes how far the stamps were apart.

    Returns
    -------
    ImportedLog
        On the uniform grid (see the module docstring): value = sign · scale ·
        raw + offset.

    Raises
    ------
    ScenarioError
        One line naming the file and the variable: unknown or missing
        variable (or one that is text, complex, empty, a struct), columns of
        different lengths, a non-finite value, a gap in the time stamps (the
        worst one named), a non-increasing time column.
    """
    src = f"file '{path}'"
    for col in mapping:
        if col not in REQUIRED + OPTIONAL:
            raise ScenarioError(f"map {col}: not an esoarm log column (one of "
                                f"{', '.join(REQUIRED + OPTIONAL)})")
    if rate_hz is not None:
        check_rate(rate_hz, "rate")
        if "t" in mapping:
            raise ScenarioError(f"map t={mapping['t']} and a rate of {rate_hz:g} Hz: give one "
                                "(the time stamps, or the rate of a file without them)")
    if resample_hz is not None:
        check_rate(resample_hz, "resample")
        if rate_hz is not None:
            raise ScenarioError(f"resample {resample_hz:g} Hz and a rate of {rate_hz:g} Hz: "
                                "a file without stamps is already on its grid; give one")
    missing = [c for c in REQUIRED if c not in mapping and not (c == "t" and rate_hz)]
    if missing:
        hint = (" (or --rate HZ for a file without time stamps)" if missing == ["t"] else "")
        raise ScenarioError(f"map: give {', '.join(missing)} (t = time [s], y = measured "
                            "position, u = applied force or torque), e.g. --map t=t,y=qm,u=vir"
                            + hint)
    source = _read(path)
    vectors, scalars = source.vectors, source.scalars
    for col, value in (signs or {}).items():
        if str(value).strip() not in ("1", "+1", "-1", "1.0", "+1.0", "-1.0"):
            raise ScenarioError(f"sign {col}={value}: must be +1 or -1 (use --scale for a "
                                "factor)")
    factors = _per_column(scales, "scale", mapping, scalars, src, nonzero=True)
    shifts = _per_column(offsets, "offset", mapping, scalars, src, nonzero=False)
    flips = _per_column(signs, "sign", mapping, {}, src, nonzero=True)
    columns: dict[str, np.ndarray] = {}
    for col, var in mapping.items():
        if var not in vectors:
            _missing_variable(source, var, col, src, rate_hz)
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is named below
            values = vectors[var] * (flips.get(col, 1.0) * factors.get(col, 1.0)) \
                + shifts.get(col, 0.0)
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
    notes = list(source.notes)
    resampled = False
    if rate_hz is not None:
        n = len(columns["y"])
        columns = {"t": np.arange(n) / rate_hz, **columns}
        if n < 2:
            raise ScenarioError(f"{src}: needs at least 2 samples, has {n}")
        rate, jitter, jitter_rms = float(rate_hz), 0.0, 0.0
        grid = columns["t"]
    elif resample_hz is not None:
        rate, jitter, jitter_rms = float(resample_hz), 0.0, 0.0
        grid, columns, note = _resample(columns, rate, f"{src}: {mapping['t']} (for t)")
        notes.append(note)
        resampled = True
    else:
        t = columns["t"]
        ts, jitter, jitter_rms = check_time(t, f"{src}: {mapping['t']} (for t)")
        rate = _round_rate(t, ts)
        grid = t[0] + np.arange(len(t)) / rate
    order = [*REQUIRED, *(c for c in columns if c not in REQUIRED)]
    ordered = {c: grid if c == "t" else columns[c] for c in order}
    return ImportedLog(ordered, rate, jitter, jitter_rms, str(path), dict(mapping),
                       factors, scalars, shifts, flips, notes, resampled)


def _missing_variable(source: _Source, var: str, col: str, src: str,
                      rate_hz: float | None) -> None:
    """Raise the one-line error for a mapped variable that is not a column of the file."""
    vectors = source.vectors
    matrix = sorted(int(k.rsplit(":", 1)[1]) for k in vectors
                    if k.rsplit(":", 1)[0] == var and ":" in k)
    if matrix:
        raise ScenarioError(f"{src}: {var} (for {col}) is a matrix of {len(matrix)} "
                            f"columns: name one as {var}:1 … {var}:{matrix[-1]} "
                            f"(MATLAB's {var}(:, j))")
    if var in source.others:
        what = source.others[var]
        if col == "t" and what.startswith("text"):
            what += ("; stamps must be seconds as numbers: convert them, or map no t and give "
                     "--rate HZ")
        raise ScenarioError(f"{src}: {var} (for {col}) is {what}")
    names = sorted({k.rsplit(":", 1)[0] + (":j" if ":" in k else "") for k in vectors})
    what = "a scalar, not a column" if var in source.scalars else "no such variable"
    hint = ""
    if col == "t" and rate_hz is None:
        hint = ("; map t to the column of time stamps [s], or, for a file without stamps, map "
                "no t and give --rate HZ")
    raise ScenarioError(f"{src}: {var} (for {col}): {what}; the file has "
                        f"{', '.join(names) or 'no numeric columns'}{hint}")


def _per_column(values: Mapping[str, str | float] | None, option: str,
                mapping: Mapping[str, str], scalars: Mapping[str, float], src: str,
                nonzero: bool) -> dict[str, float]:
    out: dict[str, float] = {}
    for col, value in (values or {}).items():
        if col not in mapping:
            raise ScenarioError(f"{option} {col}: not a mapped column (mapped: "
                                f"{', '.join(mapping)})")
        out[col] = _factor(value, scalars, src, col, option, nonzero)
    return out


def _resample(columns: dict[str, np.ndarray], rate: float,
              what: str) -> tuple[np.ndarray, dict[str, np.ndarray], str]:
    """Columns interpolated linearly onto t_0 + k/rate; a note on how far the stamps were apart."""
    t = columns["t"]
    n = len(t)
    if n < 2:
        raise ScenarioError(f"{what}: needs at least 2 samples, has {n}")
    dt = np.diff(t)
    if not np.all(dt > 0):
        i = int(np.argmin(dt))
        raise ScenarioError(f"{what}: time must increase; row {i + 2} (t = {t[i + 1]:.9g} s) "
                            f"is not after row {i + 1} (t = {t[i]:.9g} s)")
    worst = int(np.argmax(dt))
    if dt[worst] * rate > MAX_RESAMPLE_GAP:
        raise ScenarioError(
            f"{what}: a gap of {dt[worst]:.6g} s between row {worst + 1} (t = {t[worst]:.9g} s) "
            f"and row {worst + 2}, {dt[worst] * rate:.3g} samples at {rate:g} Hz: interpolating "
            f"across more than {MAX_RESAMPLE_GAP:g} would invent the motion; split the log there")
    grid = t[0] + np.arange(int(math.floor((t[-1] - t[0]) * rate * (1 + 1e-12))) + 1) / rate
    grid = grid[grid <= t[-1]]
    if len(grid) < 2:
        raise ScenarioError(f"{what}: spans {t[-1] - t[0]:.6g} s, less than two samples at "
                            f"{rate:g} Hz")
    out = {c: np.interp(grid, t, v) for c, v in columns.items() if c != "t"}
    med = float(np.median(dt))
    note = (f"resampled linearly from {n} stamps {med * 1e3:.4g} ms apart (median; from "
            f"{float(dt.min()) * 1e3:.4g} to {float(dt[worst]) * 1e3:.4g} ms, the longest "
            f"between rows {worst + 1} and {worst + 2})")
    return grid, out, note


def _factor(value: str | float, scalars: Mapping[str, float], src: str, col: str,
            option: str = "scale", nonzero: bool = True) -> float:
    if isinstance(value, (int, float)):
        f = float(value)
    else:
        try:
            f = float(value)
        except ValueError:
            if value not in scalars:
                raise ScenarioError(f"{option} {col}={value}: neither a number nor a scalar of "
                                    f"{src} (its scalars: "
                                    f"{', '.join(sorted(scalars)) or 'none'})") from None
            f = scalars[value]
    if not math.isfinite(f) or (nonzero and f == 0.0):
        what = "non-zero factor" if nonzero else "number"
        raise ScenarioError(f"{option} {col}={value}: must be a finite{', ' if nonzero else ' '}"
                            f"{what}")
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
            "the gap, or resample irregular stamps (--resample HZ)")
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
                                "resample the log (--resample HZ)")
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
