"""``esoarm log``: logs from elsewhere (``esoarm log import``)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from esoarm.cli._common import (
    BadInput,
    add_verbosity_options,
    bad_input_guard,
    note,
    output_path,
)


@click.group()
def log() -> None:
    """Bring logs recorded elsewhere into esoarm's CSV format."""


@log.command("import")
@click.argument("file", metavar="FILE")
@click.option("--map", "mapping", required=True, metavar="t=VAR,y=VAR,u=VAR",
              help="Which variable of FILE is each esoarm column: t time [s], y measured "
                   "position [rad or m], u applied torque or force [N·m or N]; optional "
                   "theta_ref (reference), theta, duty. E.g. --map t=t,y=qm,u=vir,theta_ref=qg. "
                   "A column of a .mat matrix: NAME:J (J from 1, MATLAB's NAME(:, J)), e.g. "
                   "--map t=data:1,y=data:3,u=data:5. A field of a .mat struct: NAME.FIELD.")
@click.option("--rate", "rate_hz", type=float, default=None, metavar="HZ",
              help="Sample rate [Hz] of a FILE without time stamps (then map no t): "
                   "t = k / HZ (1e-3 to 1e6 Hz).")
@click.option("--resample", "resample_hz", type=float, default=None, metavar="HZ",
              help="Interpolate every column linearly onto a uniform grid of HZ [Hz] (stamps "
                   "that are not evenly spaced); says how far the stamps were apart. A step "
                   "longer than 10 new samples is refused (split the log there).")
@click.option("--scale", "scale", default="", metavar="COL=FACTOR,...",
              help="Multiply a column by a number or by a scalar variable of FILE, e.g. "
                   "--scale u=gtau (a drive gain [N/V] turning the logged voltage into a "
                   "force) or --scale t=0.001 (stamps in ms).")
@click.option("--offset", "offset", default="", metavar="COL=VALUE,...",
              help="Add a number or a scalar variable of FILE to a column after the scale "
                   "(value = sign · scale · raw + offset), e.g. --offset y=-1.5708.")
@click.option("--sign", "sign", default="", metavar="COL=±1,...",
              help="Flip a column (an encoder or a drive counting the other way), e.g. "
                   "--sign y=-1,u=-1.")
@click.option("--out", "out", required=True, metavar="LOG.csv",
              help="The esoarm log to write (t, y, u first, then the other mapped columns).")
@click.option("--json", "as_json", is_flag=True,
              help="Print rate, jitter, mapping and scales as one JSON object.")
@bad_input_guard
def import_(file: str, mapping: str, scale: str, rate_hz: float | None,
            resample_hz: float | None, offset: str, sign: str, out: str,
            as_json: bool) -> None:
    """Turn FILE (MATLAB .mat, CSV or JSON) into an esoarm log LOG.csv.

    Reports the sample rate and the time-stamp jitter (the largest deviation of
    a stamp from the uniform grid, in samples). Jitter up to a tenth of a sample
    (a clock's or single precision's rounding) is accepted and the log is written
    on the exact uniform grid; a real gap is refused, naming the worst one.
    JSON: a list of records [{"t": 0, "y": 0.1, "u": 0}, ...] or an object of
    columns {"t": [...], "y": [...], "u": [...]}.
    Example (the EMPS benchmark): esoarm log import DATA_EMPS.mat --map
    t=t,y=qm,u=vir,theta_ref=qg --scale u=gtau --out estimation.csv
    """
    from esoarm.hardware.logimport import import_log, parse_pairs, write_log

    path = output_path(out, "--out", (".csv",))
    assert path is not None
    _not_the_input(Path(file), path)
    pairs = parse_pairs(mapping, "--map")
    scales = parse_pairs(scale, "--scale")
    offsets = parse_pairs(offset, "--offset")
    signs = parse_pairs(sign, "--sign")
    imported = import_log(file, pairs, scales, rate_hz, offsets, signs, resample_hz)
    write_log(imported, path)
    if as_json:
        click.echo(json.dumps({"file": imported.source, "out": str(path), "samples": imported.n,
                               "rate_hz": imported.rate_hz, "jitter_samples": imported.jitter,
                               "jitter_rms_samples": imported.jitter_rms,
                               "map": imported.mapping, "scale": imported.scales,
                               "offset": imported.offsets, "sign": imported.signs,
                               "resampled": imported.resampled, "notes": imported.notes},
                              indent=2))
    else:
        note(f"{file}: {imported.summary()}")
        note(f"wrote {path}")


def _not_the_input(source: Path, out: Path) -> None:
    """Refuse an --out that is FILE itself (it would replace the source by a few columns)."""
    same = False
    try:
        same = source.exists() and out.exists() and source.samefile(out)
    except OSError:
        same = False
    if same or source.resolve() == out.resolve():
        raise BadInput(f"--out {out}: is FILE itself; the import writes only the mapped columns, "
                       "so the source would be lost: give another path")


add_verbosity_options(import_)

__all__ = ["log"]
