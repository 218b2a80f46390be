"""``esoarm learn-map``: ẑ3 of a logged run binned over the angle into a feedforward table."""

from __future__ import annotations

import click

from esoarm.cli._common import (
    BadInput,
    bad_input_guard,
    output_path,
    resolve_scenario,
    scenario_argument,
    set_option,
)


@click.command("learn-map")
@click.argument("log", metavar="LOG.csv", type=click.Path(dir_okay=False))
@scenario_argument
@set_option
@click.option("--bins", type=click.IntRange(2, 4096), default=72, show_default=True,
              help="N nodes over [0, 2π) (θ_i = 2π i/N); resolve the shortest period, "
                   "e.g. at least 6 per cogging period.")
@click.option("--skip", type=click.FloatRange(0.0), default=1.0, show_default=True,
              help="Seconds at the start of the log left out (the observer's transient).")
@click.option("--out", "out", required=True, metavar="FILE.toml",
              help="The scenario with controller.feedforward_map set (fully resolved TOML).")
@bad_input_guard
def learn_map(log: str, scenario: str, overrides: tuple[str, ...], bins: int, skip: float,
              out: str) -> None:
    """Learn a position-periodic perturbation from LOG.csv into SCENARIO's feedforward table.

    LOG.csv is a run of SCENARIO (``esoarm simulate --out`` or ``esoarm run``) with the
    estimated angle z1 [rad] and perturbation z3 [rad/s²]; z3 is averaged in --bins bins
    over z1 modulo 2π and written as controller.feedforward_map (added to the table
    SCENARIO already has: the run's z3 was the residual it left).  The next run adds
    −I0·map(ẑ1) to the drive; its ESO estimates only what the table misses.
    """
    from esoarm._io import atomic_path
    from esoarm.hardware.logfile import read_log_columns
    from esoarm.studies.adrc.learn_map import learn_map as learn

    path = output_path(out, "--out", (".toml",))
    assert path is not None
    scn = resolve_scenario(scenario, overrides)
    if "feedforward_map" not in type(scn.controller).model_fields:
        raise BadInput(f"SCENARIO: controller.kind = '{scn.controller.kind}' takes no "
                       "feedforward table (controller kinds that do: 'flc')")
    _, data = read_log_columns(log, ["t", "z1", "z3"], "need t [s], z1 [rad], z3 [rad/s²]")
    t, z1, z3 = data[:, 0], data[:, 1], data[:, 2]
    first = int((t < t[0] + skip).sum())
    if len(t) - first < 2 * bins:
        raise BadInput(f"LOG.csv '{log}': {len(t) - first} samples after --skip {skip:g} s, "
                       f"fewer than 2 per bin ({bins} bins); log a longer run or use fewer bins")
    previous = list(scn.controller.feedforward_map) or None
    try:
        learned = learn(z1, z3, bins, skip=first, previous=previous)
    except ValueError as exc:
        raise BadInput(f"LOG.csv '{log}': {exc}") from None
    new = scn.with_overrides({"controller.feedforward_map": [float(v) for v in learned.table]})
    with atomic_path(path) as tmp:
        tmp.write_text(new.to_toml(), encoding="utf-8")
    lo = float(learned.table[learned.counts > 0].min())
    hi = float(learned.table[learned.counts > 0].max())
    click.echo(f"{path}: controller.feedforward_map, {bins} bins, {learned.visited} visited "
               f"by the run ({len(t) - first} samples), map {lo:.4g} … {hi:.4g} rad/s²")
    if learned.visited < bins:
        click.echo(f"note: {bins - learned.visited} bins the run never visited are "
                   f"{'kept from the previous table' if previous else '0'}; the map holds "
                   "only over the angles the run covered", err=True)
