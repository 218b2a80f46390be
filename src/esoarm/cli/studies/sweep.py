"""``esoarm sweep`` and ``esoarm tune``: many runs on the compiled batch engine."""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from esoarm._limits import MAX_RUNS
from esoarm.cli import _common
from esoarm.cli._common import (
    NORMAL,
    PLOT_SUFFIXES,
    VERBOSE,
    BadInput,
    RunFailure,
    bad_input_guard,
    output_path,
    scenario_argument,
    set_option,
    stderr_is_tty,
    verbosity,
    warn_line,
)

INTERRUPTED = 130


def _positive(value: int | None, option: str) -> None:
    if value is not None and value < 1:
        raise BadInput(f"{option} {value}: must be a whole number >= 1")


def _warn_grid(messages: list[str]) -> None:
    if not messages:
        return
    more = len(messages) - 1
    tail = f" (and {more} more grid point{'s' if more > 1 else ''} with risky settings)" \
        if more else ""
    warn_line(f"{messages[0]}{tail}")


@contextmanager
def _progress(total: int, label: str, unit: str) -> Iterator[Callable[[int], None]]:
    """Progress on stderr: a live bar on a terminal; lines elsewhere.

    Without a terminal: with --verbose a line a second at most (and the first and the
    last); otherwise a line every PROGRESS_LINE_S (10 s) once the work has run that
    long, so that a long sweep in a log shows it is alive. Nothing with --quiet.
    """
    if not stderr_is_tty():
        if verbosity() < NORMAL:
            yield lambda n: None
            return
        if verbosity() >= VERBOSE:
            yield _progress_lines(total, label, unit)
        else:
            yield _progress_lines(total, label, unit, every=_common.PROGRESS_LINE_S,
                                  eager=False)
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class Rate(ProgressColumn):
        """Runs (generations) per second so far."""

        def render(self, task: Any) -> Text:
            speed = task.finished_speed or task.speed
            return Text(f"{speed:,.0f} {unit}/s" if speed else f"- {unit}/s")

    with Progress(TextColumn(f"{label}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn(unit), Rate(), TimeElapsedColumn(), TextColumn("ETA"),
                  TimeRemainingColumn(),
                  console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(label, total=total)
        yield lambda n: bar.advance(task, n)


def _progress_lines(total: int, label: str, unit: str, every: float = 1.0,
                    eager: bool = True) -> Callable[[int], None]:
    """One line per ``every`` seconds at most, for logs and pipes.

    ``eager``: also the first and the last; otherwise lines only once ``every``
    seconds have passed (then the last one too).
    """
    import time

    start = time.monotonic()
    state = {"done": 0, "last": -math.inf if eager else start, "start": start,
             "shown": eager}

    def advance(n: int) -> None:
        state["done"] += n
        now = time.monotonic()
        if now - state["last"] >= every or (state["shown"] and state["done"] >= total):
            state["shown"] = True
            state["last"] = now
            rate = state["done"] / max(now - state["start"], 1e-9)
            click.echo(f"esoarm: {label}: {int(state['done'])} of {total} {unit} "
                       f"({rate:.0f} {unit}/s)", err=True)

    return advance


def _check_engine(engine: str, scn: Any) -> None:
    """--engine fast on a scenario it does not model is bad input (one line)."""
    if engine != "fast":
        return
    from esoarm.engines.fast import unsupported

    why = unsupported(scn)
    if why is not None:
        raise BadInput(f"--engine fast: scenario '{scn.name}' has {why}, which the fast engine "
                       "does not model; use --engine exact")


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.5g}"
    return str(value)


# ---------------------------------------------------------------------------
# sweep


@click.command()
@scenario_argument
@click.option("--vary", "vary", multiple=True, metavar="KEY=SPEC",
              help="Vary a dotted scenario key (in its own unit, e.g. observer.eps in s). "
              "SPEC: a comma list 0.05,0.09,0.2 (strings allowed: euler,zoh,current; an "
              "arm's per-joint lists: [0.02,0.03],[0.04,0.06]), "
              "lin:START:STOP:NUM or geom:START:STOP:NUM. Repeatable: the grid is the cross "
              "product, first --vary slowest.")
@set_option
@click.option("--seeds", "seeds", type=int, default=1, show_default=True, metavar="K",
              help="Run every grid point with sensor.seed = 0 … K−1 (noise seeds).")
@click.option("--out", "out", metavar="FILE.csv",
              help="Write one row per run: the varied keys, seed, rms_error [rad], rms_u [N·m], "
              "max_abs_error [rad], max_abs_u [N·m], rms_f_error [rad/s²], rms_rate_error "
              "[rad/s], rms_du [N·m], saturated_fraction, samples, diverged (on a prismatic "
              "axis m, N, m/s², m/s).")
@click.option("--plot", "plot", metavar="FILE.png",
              help="Draw RMS error [rad or m] and RMS control [N·m or N] against the varied key "
              "with the "
              "spread over seeds, or heat maps for two varied keys (.png, .pdf or .svg). "
              "Keeps every row in memory.")
@click.option("--json", "as_json", is_flag=True,
              help="Print a JSON summary: runs, seconds, best grid points (seed means), "
              "\"units\" of their metrics.")
@click.option("--engine", "engine", type=click.Choice(["exact", "fast"]), default="exact",
              show_default=True,
              help="exact: bit-identical to `esoarm simulate`. fast: vectorized C kernel built on "
              "first use with the system C compiler, agrees to relative 1e-9 (see the "
              "benchmarks page); falls back to exact with a warning where no compiler works.")
@click.option("--workers", "workers", type=int, default=None, metavar="N",
              help="Threads (cores) in this process [default: all] (for a URDF arm: worker "
              "processes); with --scheduler, numba threads per Dask task [default: 1].")
@click.option("--scheduler", "scheduler", metavar="ADDRESS",
              help="Run the chunks on an existing Dask distributed cluster, e.g. "
              "tcp://127.0.0.1:8786 (needs the 'cluster' extra here and esoarm installed on the "
              "workers; start workers with --nthreads 1, one process per core). Same results "
              "as in-process.")
@click.option("--chunk", "chunk", type=int, default=None, metavar="RUNS",
              help="Runs per chunk (whole grid points) [default: 1024 in-process, 256 on Dask]. "
              "Does not change the results.")
@click.option("--max-runs", "max_runs", type=int, default=MAX_RUNS, show_default=True,
              metavar="N", help="Refuse sweeps of more runs (grid points × seeds) than this, "
              "before any work; each run keeps about 80 bytes of results.")
@bad_input_guard
def sweep(scenario: str, vary: tuple[str, ...], overrides: tuple[str, ...], seeds: int,
          out: str | None, plot: str | None, as_json: bool, engine: str, workers: int | None,
          scheduler: str | None, chunk: int | None, max_runs: int) -> None:
    """Sweep SCENARIO over a grid of parameters × noise seeds (compiled engine).

    Every run follows the sampled-data closed loop (docs/semantics.md) exactly
    (same numbers as `esoarm simulate`; --engine fast: to round-off; a URDF
    arm: its compiled rigid body, to round-off of Pinocchio's); only metrics
    are kept. Rows reach --out as chunks finish, so memory does not
    grow with the number of runs (except with --plot). Ctrl-C (or SIGTERM)
    stops the sweep and keeps
    the finished rows in --out. Example:

    \b
      esoarm sweep test-1 --vary observer.eps=geom:0.03:0.3:100 --seeds 20 --out eps.csv
    """
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps import sweep as sweep_mod
    from esoarm.studies.sweeps.sweep import (
        ClusterError,
        SweepResult,
        SweepWriter,
        build_grid,
        parse_scheduler,
    )

    if scheduler is not None:
        parse_scheduler(scheduler)
    out_path = output_path(out, "--out", (".csv",))
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    _positive(workers, "--workers")
    _positive(chunk, "--chunk")
    if seeds < 1:
        raise BadInput(f"--seeds {seeds}: must be a whole number >= 1")
    _positive(max_runs, "--max-runs")
    base = load_scenario(scenario, list(overrides))
    with _progress(_grid_points(base, vary, max_runs), "checking grid", "points") as advance:
        grid = build_grid(base, list(vary), seeds, max_runs=max_runs, progress=advance)
    if plot_path is not None and len(grid.vary) > 2:
        raise BadInput(f"--plot draws one or two varied keys; this sweep varies {len(grid.vary)}")
    _warn_grid(grid.warnings())
    _check_engine(engine, grid.points[0] if len(grid.points) else base)

    # rows go to --out as chunks finish, so memory does not grow with the runs
    # (only --plot keeps every row: it draws them all)
    writer = SweepWriter(grid, out_path)
    kept = SweepResult.empty(grid) if plot_path is not None else None
    start = time.perf_counter()
    try:
        with _progress(grid.n_runs, "sweep", "runs") as advance, _sigterm_as_interrupt():
            for first, values in sweep_mod.iter_sweep(grid, workers=workers,
                                                      scheduler=scheduler, chunk=chunk,
                                                      engine=engine):
                writer.add(first, values)
                if kept is not None:
                    kept.add(first, values)
                advance(len(values))
    except KeyboardInterrupt:
        click.echo(f"esoarm: interrupted: {writer.n_done} of {grid.n_runs} runs finished"
                   f"{_keep_partial(writer, out_path)}", err=True)
        raise click.exceptions.Exit(INTERRUPTED) from None
    except ClusterError as exc:
        raise RunFailure(f"{exc}{_keep_partial(writer, out_path)}") from None
    except ValueError as exc:  # e.g. a grid point the fast engine does not model
        writer.discard()
        raise BadInput(str(exc)) from None
    except BaseException:
        writer.discard()
        raise
    writer.seconds = time.perf_counter() - start
    writer.close()
    if plot_path is not None and kept is not None:
        from esoarm.studies.sweeps.plots import figure_sweep

        figure_sweep(kept, plot_path)
    divergence = writer.divergence_warning()
    if divergence is not None:
        warn_line(divergence)
    if as_json:
        import json

        click.echo(json.dumps(_summary(writer, out_path, plot_path, writer.diverged)))
        return
    _print_sweep(writer, writer.diverged)
    for label, path in (("table", out_path), ("figure", plot_path)):
        if path is not None:
            click.echo(f"{label}: {path}")


def _grid_points(base: Any, vary: tuple[str, ...], max_runs: int) -> int:
    """Number of grid points (for the checking bar); 0 when the grid is invalid."""
    from esoarm.scenario import ScenarioError
    from esoarm.studies.sweeps.sweep import parse_vary

    try:
        return math.prod(len(parse_vary(v, base, max_values=max_runs).values) for v in vary)
    except ScenarioError:
        return 0  # build_grid says why, in one line


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (kill, a batch scheduler's time limit) stops a sweep like Ctrl-C does."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    saved = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, saved)


def _keep_partial(writer: Any, out_path: Path | None) -> str:
    if out_path is None:
        return " (no --out given, nothing kept)"
    rows = writer.close(complete=False)
    return f"; the {rows} finished rows are in {out_path}"


def _summary(result: Any, out_path: Path | None, plot_path: Path | None,
             diverged: int) -> dict[str, Any]:
    from esoarm.engines.metrics import metric_units
    from esoarm.kinds import units

    grid = result.grid
    return {
        "scenario": grid.base.name,
        "vary": {v.key: list(v.values) for v in grid.vary},
        "seeds": len(grid.seeds) or 1,
        "points": len(grid.points),
        "runs": grid.n_runs,
        "finished": result.n_done,
        "diverged": diverged,
        "seconds": round(result.seconds, 4),
        "runs_per_second": round(grid.n_runs / result.seconds, 1) if result.seconds else None,
        "best": [_json_safe(row) for row in result.best(5)],
        "units": metric_units(units(grid.base)),
        "out": str(out_path) if out_path else None,
        "plot": str(plot_path) if plot_path else None,
    }


def _json_safe(row: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in row.items()}


def _print_sweep(result: Any, diverged: int) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    grid = result.grid
    rate = grid.n_runs / result.seconds if result.seconds else float("inf")
    n_seeds = len(grid.seeds) or 1
    table = Table(title=f"{grid.base.name}: {grid.n_runs} runs in {result.seconds:.2f} s "
                  f"({rate:.0f} runs/s); best grid points, mean over {n_seeds} "
                  f"seed{'s' if n_seeds > 1 else ''}")
    for key in grid.keys:
        table.add_column(key)
    from esoarm.kinds import units

    u = units(grid.base)
    for label in (f"RMS error [{u.position}]", f"RMS u [{u.force}]",
                  f"max |error| [{u.position}]"):
        table.add_column(escape(label), justify="right")  # "[rad]" is not rich markup
    for row in result.best(5):
        mark = " (diverged)" if row["diverged"] > 0 else ""
        table.add_row(*(_fmt(row[k]) for k in grid.keys),
                      *(f"{row[m]:{u.number_format}}{mark}"
                        for m in ("rms_error", "rms_u", "max_abs_error")))
    Console(emoji=False).print(table)  # no :emoji: codes here; rich's emoji table stays unloaded


# ---------------------------------------------------------------------------
# tune


@click.command()
@scenario_argument
@click.option("--vary", "vary", multiple=True, metavar="KEY=LOW:HIGH",
              help="A key to tune within bounds, in its own unit (observer.eps [s], "
              "controller.k1 [1/s], controller.k2 [1/s²], ...). Repeatable. Bounds both > 0 "
              "and a decade apart are searched on a log scale.")
@set_option
@click.option("--objective", "objective", default=None, metavar="EXPR",
              help="Expression to minimize over rms_error [rad], rms_u [N·m], max_abs_error "
              "[rad], max_abs_u [N·m], rms_f_error [rad/s²], rms_rate_error [rad/s], rms_du "
              "[N·m] (m, N, m/s², m/s on a prismatic axis), saturated_fraction and w, "
              "evaluated on the means over "
              "seeds and robust samples [default: rms_error + w*rms_u]. A candidate with a "
              "diverged run, or at which EXPR is inf or nan, scores 1e6 (a warning counts the "
              "latter); an EXPR that is finite nowhere (1/0, log(-rms_error)) is bad input.")
@click.option("--weight", "weight", type=float, default=None, metavar="W",
              help="w in the objective [rad/(N·m)]: the price of 1 N·m of RMS control in "
              "radians of RMS error (on a prismatic axis [m/N]: of 1 N in metres) "
              "[default: 1.0].")
@click.option("--seeds", "seeds", type=int, default=3, show_default=True, metavar="K",
              help="Noise seeds 0 … K−1 every candidate is run with.")
@click.option("--robust", "robust", multiple=True, metavar="KEY=LOW:HIGH",
              help="Average over rig uncertainty: sample KEY uniformly in [LOW, HIGH] "
              "(Latin hypercube, --samples values, seeded), e.g. rig.inertia_scale=0.8:1.2, "
              "rig.coulomb_friction=0:0.1 [N·m], plant.mass=90:100 [kg] (prismatic axis). "
              "Repeatable.")
@click.option("--samples", "samples", type=int, default=8, show_default=True, metavar="M",
              help="Robust samples (rig variants) per candidate.")
@click.option("--seed", "seed", type=int, default=0, show_default=True,
              help="Seed of the optimizer and of the robust sampling.")
@click.option("--maxiter", "maxiter", type=int, default=30, show_default=True,
              help="Differential-evolution generations at most.")
@click.option("--popsize", "popsize", type=int, default=10, show_default=True,
              help="Population per tuned key.")
@click.option("--engine", "engine", type=click.Choice(["exact", "fast"]), default="exact",
              show_default=True,
              help="exact: bit-identical to `esoarm simulate`. fast: vectorized C kernel built on "
              "first use with the system C compiler, agrees to relative 1e-9 (see the "
              "benchmarks page); falls back to exact with a warning where no compiler works.")
@click.option("--workers", "workers", type=int, default=None, metavar="N",
              help="Threads (cores) [default: all].")
@click.option("--out", "out", metavar="FILE.csv",
              help="Write every candidate scored: its values, mean metrics, objective.")
@click.option("--plot", "plot", default=None, metavar="FILE.png",
              help="Write the trade-off figure: RMS error [rad or m] against RMS control [N·m "
              "or N] of every candidate, the Pareto front, the optimum (.png, .pdf or .svg). "
              "Without it no figure is written.")
@click.option("--no-plot", "no_plot", is_flag=True,
              help="No figure (the default; kept for scripts that pass it).")
@click.option("--json", "as_json", is_flag=True,
              help="Print a JSON object: best values, their metrics, the baseline, runs, seconds.")
@bad_input_guard
def tune(scenario: str, vary: tuple[str, ...], overrides: tuple[str, ...],
         objective: str | None, weight: float | None, seeds: int, robust: tuple[str, ...],
         samples: int, seed: int, maxiter: int, popsize: int, engine: str, workers: int | None,
         out: str | None, plot: str | None, no_plot: bool, as_json: bool) -> None:
    """Tune keys of SCENARIO to minimize an objective (SciPy differential evolution).

    Each candidate is scored on K noise seeds (and M sampled rig variants with
    --robust) on the compiled engine; prints the
    best values with their metrics next to the scenario's own values, and draws
    the Pareto front of tracking error against control effort. Example:

    \b
      esoarm tune test-1 --vary observer.eps=0.02:0.3 --robust rig.inertia_scale=0.8:1.2
    """
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.tune import (
        DEFAULT_OBJECTIVE,
        DEFAULT_WEIGHT,
        Objective,
        describe_baseline,
        describe_nonfinite,
        parse_bound,
    )
    from esoarm.studies.sweeps.tune import tune as run_tune

    out_path = output_path(out, "--out", (".csv",))
    if no_plot and plot is not None:
        raise BadInput(f"--plot {plot} with --no-plot: give one (--plot FILE writes the figure, "
                       "without it none is written)")
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    for value, option in ((seeds, "--seeds"), (samples, "--samples"), (maxiter, "--maxiter"),
                          (popsize, "--popsize")):
        _positive(value, option)
    _positive(workers, "--workers")
    if seed < 0:
        raise BadInput(f"--seed {seed}: must be >= 0")
    w = DEFAULT_WEIGHT if weight is None else weight
    if not (math.isfinite(w) and w >= 0):
        raise BadInput(f"--weight {weight}: must be a finite number >= 0 [rad/(N·m), m/N on a "
                       "prismatic axis] (the price of control effort; a negative one rewards it)")
    obj = Objective(objective or DEFAULT_OBJECTIVE, w)
    base = load_scenario(scenario, list(overrides))
    bounds = [parse_bound(item, base, "--vary") for item in vary]
    rob = [parse_bound(item, base, "--robust") for item in robust]
    given = click.get_current_context().get_parameter_source("samples")
    if not rob and given is click.core.ParameterSource.COMMANDLINE:
        raise BadInput(f"--samples {samples}: counts the rig variants of --robust KEY=LOW:HIGH, "
                       "which is not given (without it each candidate runs the scenario's rig "
                       "once per seed: give --robust, or drop --samples)")
    if not bounds:
        raise BadInput("--vary: give at least one KEY=LOW:HIGH to tune, "
                       "e.g. --vary observer.eps=0.02:0.3")
    _check_engine(engine, base)
    try:
        with _progress(maxiter, "tune", "generations") as advance:
            res = run_tune(base, bounds, objective=obj, seeds=seeds, robust=rob,
                           samples=samples, seed=seed, maxiter=maxiter, popsize=popsize,
                           workers=workers, progress=advance, engine=engine)
    except KeyboardInterrupt:
        click.echo("esoarm: interrupted: tuning stopped, nothing written", err=True)
        raise click.exceptions.Exit(INTERRUPTED) from None

    for line in (describe_nonfinite(res, obj), describe_baseline(res)):
        if line is not None:
            warn_line(line)
    if out_path is not None:
        from esoarm.studies.sweeps.output import write_rows_atomic

        header = list(res.evaluations[0]) if res.evaluations else list(res.keys)
        write_rows_atomic(out_path, header, iter([list(r.values()) for r in res.evaluations]))
    from esoarm.engines.metrics import metric_units
    from esoarm.kinds import units

    u = units(base)
    if plot_path is not None:
        _plot_tune(res, base.name, obj.text, w, plot_path, u)
    if as_json:
        import json

        click.echo(json.dumps(_json_safe({
            "scenario": base.name,
            "objective": obj.text,
            "w": w,
            "best": res.best,
            "metrics": res.best_metrics,
            "baseline": res.baseline,
            "units": {**metric_units(u), "w": u.compliance},
            "seeds": seeds,
            "robust_samples": len(res.robust_samples),
            "generations": res.generations,
            "runs": res.runs,
            "seconds": round(res.seconds, 3),
            "optimizer": res.message,
            "out": str(out_path) if out_path else None,
            "plot": str(plot_path) if plot_path else None,
        })))
        return
    _print_tune(res, base.name, obj.text, w, u)
    for label, path in (("candidates", out_path), ("figure", plot_path)):
        if path is not None:
            click.echo(f"{label}: {path}")


def _plot_tune(res: Any, name: str, objective: str, w: float, path: Path, u: Any) -> None:
    from esoarm.studies.sweeps.plots import figure_pareto

    ev = [r for r in res.evaluations if r["diverged_runs"] == 0]
    first = res.keys[0]
    own = ", ".join(f"{k} = {_fmt(res.baseline[k])}" for k in res.keys)
    figure_pareto(
        [r["rms_u"] for r in ev], [r["rms_error"] for r in ev],
        best=(res.best_metrics["rms_u"], res.best_metrics["rms_error"]),
        marks={f"scenario as given ({own})": (res.baseline["rms_u"],
                                               res.baseline["rms_error"])},
        color=[r[first] for r in ev], color_label=first,
        title=f"{name}: minimize {objective} (w = {w:g} {u.compliance})",
        path=path, units=u,
    )


def _print_tune(res: Any, name: str, objective: str, w: float, u: Any) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=f"{name}: minimize {objective} (w = {w:g} {u.compliance}); "
                  f"{res.runs} runs, "
                  f"{res.generations} generations, {res.seconds:.1f} s")
    table.add_column("")
    table.add_column("best found", justify="right")
    table.add_column("scenario as given", justify="right")
    for key in res.keys:
        table.add_row(key, _fmt(res.best[key]), _fmt(res.baseline[key]))
    for metric, label in (("rms_error", f"RMS error [{u.position}]"),
                          ("rms_u", f"RMS control [{u.force}]"),
                          ("max_abs_error", f"max |error| [{u.position}]"),
                          ("objective", "objective")):
        table.add_row(escape(label), f"{res.best_metrics[metric]:{u.number_format}}",
                      f"{res.baseline[metric]:{u.number_format}}")
    Console().print(table)
    if res.robust_samples:
        click.echo(f"averaged over {len(res.robust_samples)} rig variants × seeds")
    if res.best_metrics.get("diverged_runs"):
        warn_line("some runs at the best point diverged")
    sys.stdout.flush()
