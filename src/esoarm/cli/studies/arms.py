"""``esoarm arm-study``: the paper's Fig. 7 comparison and ε trade-off on a URDF arm."""

from __future__ import annotations

import contextlib

import click

from esoarm.cli._common import (
    BadInput,
    bad_input_guard,
    note,
    output_dir,
    resolve_scenario,
    scenario_argument,
    set_option,
    stderr_is_tty,
)


def _eps_list(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise BadInput(f"--eps '{text}': expected comma-separated numbers [s], "
                       "e.g. 0.01,0.02,0.04") from None
    if not values or not all(v > 0 and v == v and v != float("inf") for v in values):
        raise BadInput(f"--eps '{text}': every ε must be a finite number > 0 [s]")
    return values


@click.command("arm-study")
@scenario_argument
@set_option
@click.option("--out", "out_dir", default="esoarm-arm-study", show_default=True, metavar="DIR",
              help="Directory for report.html, summary.json, runs/*.csv and the figures.")
@click.option("--eps", "eps", metavar="E1,E2,...",
              help="ε values [s] to sweep, applied to every joint (default: nine from ε/4 to "
              "4ε, geometric).")
@click.option("--workers", type=click.IntRange(min=1), metavar="N",
              help="Worker processes (default: all cores).")
@click.option("--format", "fmt", type=click.Choice(["png", "pdf", "svg"]), default="png",
              show_default=True, help="File format of the figures (report.html embeds PNG).")
@bad_input_guard
def arm_study(scenario: str, overrides: tuple[str, ...], out_dir: str, eps: str | None,
              workers: int | None, fmt: str) -> None:
    """Compare controllers and sweep ε on the arm SCENARIO (plant.kind = "urdf").

    Runs the ESO-based computed torque τ = M̂(α − ẑ3), the same with the nominal
    n̂ fed forward, and computed torque without estimation τ = M̂α + n̂ (the
    paper's Fig. 7 baseline), prints the RMS tracking error [rad] per joint and
    its ratio, then sweeps ε [s] (the paper's Table II trade-off) and writes
    DIR/report.html (self-contained), summary.json, runs/*.csv and figures with
    one panel per joint (all at the end: if a file cannot be written, DIR is
    left as it was).  Runs go to worker processes (Pinocchio cannot be called
    from the compiled engine).
    """
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from esoarm._io import staged_dir
    from esoarm.studies.arms import VARIANTS, run_arm_study, write_arm_study

    out = output_dir(out_dir, "--out")  # before the runs: an unwritable DIR is bad input
    grid = _eps_list(eps)
    scn = resolve_scenario(scenario, overrides)
    from esoarm.kinds import hook, kinds_of

    if hook(kinds_of(scn).plant, "joint_names") is None:  # an arm declares its joints
        raise BadInput(f"scenario '{scn.name}': arm-study needs plant.kind = 'urdf' "
                       f"(got '{scn.plant.kind}'); for the lever arm use 'esoarm reproduce'")
    if "eps" not in type(scn.observer).model_fields:  # what the observer kind declares
        raise BadInput(f"observer.kind: arm-study sweeps observer.eps, which observer kind "
                       f"'{scn.observer.kind}' does not have; simulate, sweep and tune run it")
    what = (f"simulating {len(VARIANTS)} controllers and the ε sweep "
            f"({len(grid) if grid else 9} values), in worker processes")
    if stderr_is_tty():  # a spinner; in a log one line says what the wait is for
        status: contextlib.AbstractContextManager[object] = Console(stderr=True).status(what)
    else:
        note(f"arm-study: {what}")
        status = contextlib.nullcontext()
    with status:
        study = run_arm_study(scn, grid, workers)
        # written into a temporary directory, moved into DIR once all is complete: a
        # failure halfway (a full disk, Ctrl-C) leaves DIR as it was
        with staged_dir(out) as staging:
            write_arm_study(study, staging, fmt)
    table = Table(title=f"{scn.name}: RMS tracking error per joint [rad]")
    table.add_column("controller")
    for name in study.names:
        table.add_column(escape(name), justify="right")
    table.add_column("RMS torque [N·m]", justify="right")
    for label, res in study.runs.items():
        table.add_row(escape(label), *(f"{p.rms_error:.4f}" for p in res.per_joint),
                      f"{res.rms_u:.4f}")
    table.add_row("ratio: no estimation / ESO", *(f"{r:.2f}×" for r in study.ratios), "")
    Console().print(table)
    click.echo(f"lowest overall RMS error at ε = {study.best_eps:.4g} s over "
               f"{len(study.eps)} values; report: {out / 'report.html'}")
