"""``esoarm log``: logs from elsewhere (``esoarm log import``)."""

from __future__ import annotations

import json

import click

from esoarm.cli._common import add_verbosity_options, bad_input_guard, note, output_path


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
                   "--map t=data:1,y=data:3,u=data:5.")
@click.option("--rate", "rate_hz", type=float, default=None, metavar="HZ",
              help="Sample rate [Hz] of a FILE without time stamps (then map no t): "
                   "t = k / HZ.")
@click.option("--scale", "scale", default="", metavar="COL=FACTOR,...",
              help="Multiply a column by a number or by a scalar variable of FILE, e.g. "
                   "--scale u=gtau (a drive gain [N/V] turning the logged voltage into a "
                   "force) or --scale t=0.001 (stamps in ms).")
@click.option("--out", "out", required=True, metavar="LOG.csv",
              help="The esoarm log to write (t, y, u first, then the other mapped columns).")
@click.option("--json", "as_json", is_flag=True,
              help="Print rate, jitter, mapping and scales as one JSON object.")
@bad_input_guard
def import_(file: str, mapping: str, scale: str, rate_hz: float | None, out: str,
            as_json: bool) -> None:
    """Turn FILE (MATLAB .mat or CSV) into an esoarm log LOG.csv.

    Reports the sample rate and the time-stamp jitter (the largest deviation of
    a stamp from the uniform grid, in samples). Jitter up to a tenth of a sample
    (a clock's or single precision's rounding) is accepted and the log is written
    on the exact uniform grid; a real gap is refused, naming the worst one.
    Example (the EMPS benchmark): esoarm log import DATA_EMPS.mat --map
    t=t,y=qm,u=vir,theta_ref=qg --scale u=gtau --out estimation.csv
    """
    from esoarm.hardware.logimport import import_log, parse_pairs, write_log

    path = output_path(out, "--out", (".csv",))
    assert path is not None
    pairs = parse_pairs(mapping, "--map")
    scales = parse_pairs(scale, "--scale")
    imported = import_log(file, pairs, scales, rate_hz)
    write_log(imported, path)
    if as_json:
        click.echo(json.dumps({"file": imported.source, "out": str(path), "samples": imported.n,
                               "rate_hz": imported.rate_hz, "jitter_samples": imported.jitter,
                               "jitter_rms_samples": imported.jitter_rms,
                               "map": imported.mapping, "scale": imported.scales}, indent=2))
    else:
        note(f"{file}: {imported.summary()}")
        note(f"wrote {path}")


add_verbosity_options(import_)

__all__ = ["log"]
