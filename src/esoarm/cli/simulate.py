"""``esoarm simulate``, ``esoarm scenarios`` and ``esoarm show``."""

from __future__ import annotations

import json

import click

from esoarm.cli._common import (
    PLOT_SUFFIXES,
    Interrupted,
    RunFailure,
    bad_input_guard,
    note,
    output_path,
    progress,
    resolve_scenario,
    scenario_argument,
    set_option,
    warn_line,
)


@click.command()
@scenario_argument
@set_option
@click.option("--out", "out", metavar="FILE.csv",
              help="Write the time series: t [s], theta (true angle or position), theta_ref, "
              "error [rad], u [N·m], z1 [rad], z2 [rad/s], z3, f_true [rad/s²], then y "
              "(measured angle [rad]) and saturated (0/1); on a prismatic axis m, N, m/s, "
              "m/s². See docs/semantics.md.")
@click.option("--plot", "plot", metavar="FILE.png",
              help="Draw angle, error, control and estimates (.png, .pdf or .svg).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object with rms_error [rad], rms_u [N·m], rms_du [N·m: RMS of "
              "u_k − u_k−1], max_abs_error [rad], saturated_fraction and the other metrics, "
              "and \"units\": {metric: unit} (m and N on a prismatic axis).")
@bad_input_guard
def simulate(scenario: str, overrides: tuple[str, ...], out: str | None, plot: str | None,
             as_json: bool) -> None:
    """Simulate SCENARIO (a built-in name or a TOML file) on the digital twin.

    Follows the sampled-data semantics (docs/semantics.md) with the reference engine
    and prints the metrics: RMS tracking error [rad], RMS control [N·m] and
    max |error| [rad] (m and N on a prismatic axis).
    A long run shows its progress on stderr; Ctrl-C stops it
    and writes the rows logged so far to --out.  A run of more than 500,000 samples
    goes block by block in constant memory (compiled where the scenario allows it):
    its rows are streamed to --out, its metrics accumulated as it goes, and --plot
    draws about 100,000 evenly spaced samples.
    """
    from esoarm.engines.simulation import SimulationDiverged, SimulationInterrupted
    from esoarm.engines.simulation import simulate as run

    out_path = output_path(out, "--out", (".csv",))
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    scn = resolve_scenario(scenario, overrides)
    from esoarm.engines import stream

    if scn.n_samples > stream.STREAM_SAMPLES:
        _simulate_streamed(scn, out_path, plot_path, as_json)
        return
    try:
        with progress(scn.n_samples, "simulating", "samples") as advance:
            result = run(scn, warn=False, progress=advance)
    except SimulationInterrupted as exc:
        k = len(exc.result.t)
        done = f"at t = {exc.result.t[-1]:.4g} s of {scn.duration:g} s ({k:,} samples)" \
            if k else "before the first sample"
        if out_path is not None and k:
            exc.result.to_csv(out_path)
            raise Interrupted(f"{done}; the {k:,} rows logged are in {out_path}") from None
        raise Interrupted(f"{done}; nothing written (give --out FILE.csv to keep the rows "
                          "logged)") from None
    except SimulationDiverged as exc:
        kept = ""
        if out_path is not None:
            exc.result.to_csv(out_path)
            kept = f"; the {len(exc.result.t)} rows logged are in {out_path}"
        raise RunFailure(f"{exc}{kept}") from None
    from esoarm.engines.diagnosis import saturation_warning
    from esoarm.kinds import units

    saturated = saturation_warning(result.metrics.get("saturated_fraction", float("nan")),
                                   scn.actuator.torque_limit, units(scn))
    if saturated:
        warn_line(saturated)
    _undriven_warning(scn, result.metrics)
    if out_path is not None:
        result.to_csv(out_path)
    if plot_path is not None:
        result.plot(plot_path)
    if as_json:
        from esoarm.engines.metrics import metric_units
        from esoarm.kinds import units

        summary = result.summary()
        summary["units"] = {k: u for k, u in metric_units(units(scn)).items() if k in summary}
        click.echo(json.dumps(summary))
        return
    _print_metrics(result)
    for label, path in (("time series", out_path), ("figure", plot_path)):
        if path is not None:
            click.echo(f"{label}: {path}")


def _undriven_warning(scn, metrics: dict) -> None:  # type: ignore[no-untyped-def, type-arg]
    """A run whose every command was rounded to zero torque (a too coarse PWM): say so."""
    bits = scn.actuator.pwm_bits
    if bits > 0 and scn.motor is None and metrics.get("max_abs_u") == 0.0:
        step = scn.actuator.torque_limit / (2**bits - 1)
        warn_line(f"every command was rounded to 0 N·m: actuator.pwm_bits = {bits} steps the "
                  f"torque by {step:.3g} N·m and the controller never asked for half a step; "
                  "the arm was not driven (raise actuator.pwm_bits, e.g. 8)")


#: Samples kept for the figure of a streamed run (evenly spaced).
FIGURE_ROWS = 100_000


def _simulate_streamed(scn, out_path, plot_path, as_json: bool) -> None:  # type: ignore[no-untyped-def]
    """``simulate`` of a long run: blocks of samples streamed to --out, metrics accumulated.

    Memory stays flat whatever the run's length; the blocks run compiled where the
    scenario's kinds allow it.
    """
    import contextlib
    import threading

    from esoarm._io import atomic_path
    from esoarm.engines.simulation import SimulationDiverged
    from esoarm.engines.stream import StreamInterrupted, stream, worth_compiling

    note(f"{scn.n_samples:,} samples: run block by block (memory stays flat), the "
         "metrics accumulated as it goes" + (f", the rows streamed to {out_path}"
                                             if out_path is not None else ""))
    from esoarm.kinds import kinds_of

    compiled = worth_compiling(scn) is None and kinds_of(scn).jit
    state = {"rows": 0, "started": not compiled}
    slow = threading.Timer(3.0, lambda: None if state["started"] else note(
        "preparing the compiled engine for long runs (the first time only, about a "
        "minute; cached for the next runs)"))
    slow.daemon = True
    failure: BaseException | None = None
    with contextlib.ExitStack() as stack:
        fh = None
        if out_path is not None:
            tmp = stack.enter_context(atomic_path(out_path))
            fh = stack.enter_context(tmp.open("w", encoding="utf-8", newline=""))

        def sink(part) -> None:  # type: ignore[no-untyped-def]
            import numpy as np

            assert fh is not None
            if state["rows"] == 0:
                fh.write(",".join(part.columns()) + "\n")
            # straight to the file (Ctrl-C waits for the end of the block): formatting the
            # block into a StringIO first grew the process ~180 bytes a sample (measured)
            np.savetxt(fh, part.table(), delimiter=",", fmt="%.17g")
            state["rows"] += len(part.t)

        with progress(scn.n_samples, "simulating", "samples") as advance:
            def step(m: int) -> None:
                state["started"] = True
                advance(m)

            slow.start()
            try:
                run = stream(scn, sink=sink if fh is not None else None, progress=step,
                             figure_rows=FIGURE_ROWS if plot_path is not None else 0,
                             compiled=worth_compiling(scn))
            except (StreamInterrupted, SimulationDiverged) as exc:
                failure = exc
                if isinstance(exc, SimulationDiverged) and fh is not None:
                    sink(exc.result)
            except KeyboardInterrupt:  # a second Ctrl-C, within a block: --out is dropped
                raise Interrupted("stopped at once (a second Ctrl-C); nothing written (one "
                                  "Ctrl-C stops at the end of a block and keeps the rows "
                                  "run)") from None
            finally:
                slow.cancel()
    if isinstance(failure, StreamInterrupted):
        done = (f"at t = {failure.t_end:.4g} s of {scn.duration:g} s ({failure.samples:,} "
                "samples)")
        if out_path is not None and state["rows"]:
            raise Interrupted(f"{done}; the {state['rows']:,} rows run are in {out_path}")
        raise Interrupted(f"{done}; nothing written (give --out FILE.csv to keep the rows "
                          "run)")
    if isinstance(failure, SimulationDiverged):
        kept = f"; the {state['rows']:,} rows logged are in {out_path}" if out_path else ""
        raise RunFailure(f"{failure}{kept}")
    from esoarm.engines.diagnosis import saturation_warning
    from esoarm.kinds import units

    saturated = saturation_warning(run.metrics.get("saturated_fraction", float("nan")),
                                   scn.actuator.torque_limit, units(scn))
    if saturated:
        warn_line(saturated)
    _undriven_warning(scn, run.metrics)
    if plot_path is not None and run.series is not None:
        run.series.plot(plot_path)
    if as_json:
        from esoarm.engines.metrics import metric_units

        summary = run.summary()
        summary["units"] = {k: u for k, u in metric_units(units(scn)).items() if k in summary}
        click.echo(json.dumps(summary))
        return
    _print_metrics(run)
    if out_path is not None:
        click.echo(f"time series: {out_path}")
    if plot_path is not None:
        click.echo(f"figure: {plot_path} (every {run.stride:,}th sample)" if run.stride > 1
                   else f"figure: {plot_path}")


def _print_metrics(result) -> None:  # type: ignore[no-untyped-def]
    from rich.console import Console
    from rich.table import Table

    from esoarm.kinds import kind_labels, units

    s = result.summary()
    u = units(result.scenario)
    obs_text, ctl_text = kind_labels(result.scenario)
    eps = "" if "eps" not in s else (f"ε = {s['eps']} s, " if isinstance(s["eps"], list)
                                     else f"ε = {s['eps']:g} s, ")
    table = Table(title=f"{s['scenario']}  ({eps}{obs_text}, {ctl_text})")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    fmt = u.number_format
    table.add_row("RMS tracking error", format(s["rms_error"], fmt), u.position)
    table.add_row("RMS control", format(s["rms_u"], fmt), u.force)
    table.add_row("RMS control step u_k − u_k−1", format(s["rms_du"], fmt), u.force)
    table.add_row("max |error|", format(s["max_abs_error"], fmt), u.position)
    table.add_row("samples", str(s["samples"]), "")
    for joint in s.get("joints", []) if len(s.get("joints", [])) > 1 else []:
        table.add_row(f"  {joint['name']}: RMS error", format(joint["rms_error"], fmt),
                      u.position)
        table.add_row(f"  {joint['name']}: RMS control", format(joint["rms_u"], fmt), u.force)
    Console().print(table)


@click.command()
def scenarios() -> None:
    """List the built-in scenarios."""
    from importlib import resources

    from esoarm.scenario import builtin_names

    names = builtin_names()
    width = max(map(len, names), default=0)
    for name in names:
        text = (resources.files("esoarm") / "scenarios" / f"{name}.toml").read_text("utf-8")
        first = next((ln[1:].strip() for ln in text.splitlines() if ln.startswith("#")), "")
        click.echo(f"{name:{width}s}  {first}")


@click.command()
@scenario_argument
@set_option
@bad_input_guard
def show(scenario: str, overrides: tuple[str, ...]) -> None:
    """Print the fully resolved SCENARIO as TOML (every key, defaults filled in)."""
    scn = resolve_scenario(scenario, overrides)
    click.echo(scn.to_toml(), nl=False)
