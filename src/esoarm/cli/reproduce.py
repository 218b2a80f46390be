"""``esoarm reproduce``: the paper's experiment set on the built-in twin."""

from __future__ import annotations

import contextlib
from pathlib import Path

import click

from esoarm.cli._common import (
    Interrupted,
    RunFailure,
    bad_input_guard,
    detail,
    output_dir,
    progress,
    stderr_is_tty,
)


@click.command()
@click.option("--out", "out_dir", default="esoarm-results", show_default=True, metavar="DIR",
              help="Directory for tables (CSV, JSON), one time-series CSV per run, figures and "
              "report.html.")
@click.option("--format", "fmt", type=click.Choice(["png", "pdf", "svg"]), default="png",
              show_default=True, help="File format of the figures (report.html embeds PNG).")
@click.option("--twin", "twin", type=click.Choice(["nominal", "paper"]), default="nominal",
              show_default=True, help="The rig to run on: the built-in scenarios' twin "
              "(nominal) or the twin calibrated to the paper's hardware tables (paper). "
              "report.html shows both.")
@bad_input_guard
def reproduce(out_dir: str, fmt: str, twin: str) -> None:
    """Run the paper's experiments on the digital twin and compare with its tables.

    Runs test-1 and test-2 at ε = 0.05, 0.09, 0.2 s (Tables II and III) and the
    Fig. 7 ablation (test-2, ε = 0.09 s, with and without perturbation
    estimation); prints the paper's RMS tracking error [rad] and RMS control
    [N·m] beside the twin's, checks each qualitative claim, and writes the
    tables, time series and Fig. 4-7 into DIR (all at the end: if a file cannot
    be written, DIR is left as it was).  Also repeats the set with the
    three ESO discretizations (euler, zoh, current), sweeps ε on test-1, checks
    Theorem 1 and 2, and writes everything into one self-contained
    DIR/report.html (open it in a browser; no network needed). --twin paper runs
    everything on the twin whose rig, encoder and drive keys were calibrated to
    the paper's twelve RMS values within physically plausible ranges; the report
    (and DIR/twins.csv, DIR/twins.md) shows both twins' tables, ln(twin/paper)
    per value, claims, and which of the paper's numbers no plausible twin reaches.
    """
    from esoarm.kinds import compile_only, kinds_of
    from esoarm.studies.reproduction.paper_twin import twin_overrides
    from esoarm.studies.reproduction.run import plan_runs
    from esoarm.studies.reproduction.twins import EVIDENCE_NAMES, NOISE_SCAN

    out = output_dir(out_dir, "--out")
    overrides = twin_overrides(twin)
    planned = plan_runs(overrides)
    n_runs = len(planned) + ((1 + len(EVIDENCE_NAMES) + len(NOISE_SCAN))
                             * len(plan_runs(compare=False)))
    # the compiled kernels with only the kinds the paper's experiments use (lever arm,
    # linear ESO, FLC, PID): a first reproduce after installation compiles less
    compile_only([kinds_of(scn) for scn in planned.values()])
    done = [0]
    try:
        _reproduce(out, fmt, twin, overrides, n_runs, done)
    except KeyboardInterrupt:
        raise Interrupted(f"after {done[0]} of about {n_runs} simulated runs; nothing written "
                          f"to {out} (its files are moved there only once all are complete)"
                          ) from None
    finally:
        compile_only(None)


def _reproduce(out: Path, fmt: str, twin: str, overrides: list[str], n_runs: int,
               simulated: list[int]) -> None:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from esoarm._io import staged_dir
    from esoarm.engines.simulation import SimulationDiverged
    from esoarm.studies.reproduction.run import figure_specs, run_reproduction, write_outputs
    from esoarm.studies.reproduction.twins import compared_twins, twins_section, write_twin_tables

    console = Console(stderr=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True,
                  disable=not stderr_is_tty()) as bar, \
            (progress(n_runs, "reproduce", "simulated runs (all twins)")
             if not stderr_is_tty()  # logs, pipes
             else contextlib.nullcontext(lambda n: None)) as lines:
        task = bar.add_task("simulating", total=n_runs)

        def step(what: str) -> None:
            bar.update(task, advance=1, description=what)
            simulated[0] += what.startswith("simulated")
            if bar.disable:  # without a terminal: a line every 10 s, each step with --verbose
                detail(what)
                if what.startswith("simulated"):
                    lines(1)

        try:
            rep = run_reproduction(overrides, progress=lambda key: step(f"simulated {key}"))
            reps = compared_twins({twin: rep}, progress=lambda key: step(f"simulated {key}"))
        except SimulationDiverged as exc:  # nothing written yet: no half-complete results
            raise RunFailure(str(exc)) from None
        rep.n_simulated_all = simulated[0]  # the report counts what the progress counted
        bar.update(task, total=n_runs + len(figure_specs(rep)) + 4)
        section = ("twins", "Two twins: nominal and calibrated to the paper",
                   twins_section(reps))
        # written into a temporary directory, moved into DIR once all is complete: a
        # failure halfway (a full disk) leaves DIR as it was, not looking complete
        with staged_dir(out) as staging:
            write_outputs(rep, staging, fmt=fmt, progress=lambda what: step(f"wrote {what}"),
                          extra_sections=[section])
            for path in write_twin_tables(reps, staging):
                step(f"wrote {path.name}")
    _print(rep, out, fmt, twin)


def _print(rep, out: Path, fmt: str, twin: str) -> None:  # type: ignore[no-untyped-def]
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from esoarm.studies.reproduction.run import EPS_SET, PAPER_TABLES, TABLE_NAMES

    console = Console()
    for test, table_name in TABLE_NAMES.items():
        table = Table(title=f"{table_name} — {test}: RMS over the run (paper: hardware; "
                      f"esoarm: the {twin} digital twin)")
        for name in ("ε [s]", "error, paper [rad]", "error, esoarm [rad]",
                     "control, paper [N·m]", "control, esoarm [N·m]"):
            table.add_column(escape(name), justify="right")
        for eps in EPS_SET:
            p_err, p_u = PAPER_TABLES[test][eps]
            table.add_row(f"{eps:g}", f"{p_err:.4f}", f"{rep.metric(test, eps, 'rms_error'):.4f}",
                          f"{p_u:.4f}", f"{rep.metric(test, eps, 'rms_u'):.4f}")
        console.print(table)
    claims = Table(title=f"The paper's qualitative claims, checked on the {twin} twin",
                   show_lines=True)
    claims.add_column("on the twin")
    claims.add_column("paper")
    claims.add_column("claim")
    claims.add_column("numbers behind it")
    for claim in rep.claims:
        mark = "[green]reproduced[/green]" if claim.reproduced else "[red]not reproduced[/red]"
        claims.add_row(mark, escape(claim.source), escape(claim.statement),
                       escape(claim.evidence))
    console.print(claims)
    n_ok = sum(c.reproduced for c in rep.claims)
    console.print(f"{n_ok} of {len(rep.claims)} claims reproduced. Results in {out}/ "
                  "(tables.csv, tables.json; twins.csv and twins.md: both twins against the "
                  f"paper; runs/*.csv, fig4-7.{fmt}); the full report: "
                  f"{out / 'report.html'}", highlight=False)
