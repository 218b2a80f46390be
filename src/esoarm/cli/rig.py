"""``esoarm emulate``, ``esoarm run`` and ``esoarm replay``: the rig commands."""

from __future__ import annotations

import json
import math
import signal
import sys
from pathlib import Path

import click

from esoarm.cli._common import (
    PLOT_SUFFIXES,
    BadInput,
    Interrupted,
    RunFailure,
    bad_input_guard,
    lever_only,
    output_path,
    require_extra,
    resolve_scenario,
    scenario_argument,
    set_option,
    stderr_is_tty,
    warn_line,
)


def _say(line: str) -> None:
    print(line, flush=True)


def scope_options(func):  # type: ignore[no-untyped-def]
    """--scope, --scope-port, --scope-window (the live page).

    Parameters
    ----------
    func : callable
        A command's function.

    Returns
    -------
    callable
        ``func`` with the three options.
    """
    func = click.option("--scope-window", type=float, default=10.0, show_default=True,
                        metavar="SECONDS",
                        help="Seconds of data the scope keeps and shows [s].")(func)
    func = click.option("--scope-port", type=int, default=8765, show_default=True,
                        metavar="PORT",
                        help="TCP port of the scope on 127.0.0.1 (0: any free port).")(func)
    return click.option("--scope", "scope", is_flag=True,
                        help="Serve a live scope at http://127.0.0.1:PORT/ (local only, works "
                        "offline): the signals as they arrive and the status counters. Closing "
                        "the page never disturbs the loop.")(func)


def _check_scope(port: int, window: float) -> None:
    if not 0 <= port <= 65535:
        raise BadInput(f"--scope-port {port}: must be 0 … 65535")
    if not (math.isfinite(window) and window > 0):
        raise BadInput(f"--scope-window {window:g}: must be a finite number of seconds > 0")


def _start_scope(make, announce: bool = True):  # type: ignore[no-untyped-def]
    from esoarm.hardware.scope import ScopeError

    try:
        scope = make()
    except ScopeError as exc:
        raise BadInput(f"{exc}; choose another --scope-port (0: any free port)") from None
    if announce:
        click.echo(f"scope: {scope.url}", err=True)
    return scope


@click.command()
@scenario_argument
@set_option
@click.option("--lockstep", is_flag=True,
              help="Advance the twin exactly one sample (Ts) per command received, so a run "
              "over the link commands the same u [N·m] sequence as 'esoarm simulate', bit for "
              "bit. Default: real time, one sample every Ts = 1/sensor.rate_hz seconds.")
@click.option("--fault", "faults", multiple=True, metavar="KIND@SECONDS",
              help="Inject a fault at twin time SECONDS [s]: drop (outgoing frames lost), "
              "corrupt (outgoing frames damaged), stall (the device stops answering), "
              "disconnect (the port goes away), glitch (encoder jumps half a revolution). "
              "Repeatable.")
@click.option("--once", is_flag=True,
              help="Exit after the first stop command instead of waiting for another run.")
@scope_options
@bad_input_guard
def emulate(scenario: str, overrides: tuple[str, ...], lockstep: bool, faults: tuple[str, ...],
            once: bool, scope: bool, scope_port: int, scope_window: float) -> None:
    """Serve the digital twin of SCENARIO as a device behind a new pseudo-terminal.

    The first line printed is 'device: PATH'; pass PATH to 'esoarm run --port'.
    The twin integrates the rig exactly as the simulator does (RK4 step
    rig.step [s], actuator lag and delay), draws the encoder noise on the device
    side, reports angles as encoder counts of sensor.resolution_deg [deg] and,
    with a [motor] table, turns PWM duties into torque [N·m] through the motor
    model. On a stop command it prints a line and holds the motor off. With
    --scope, a local page plots the true and measured angle [rad], the rate
    [rad/s] and the applied torque [N·m] with the device's counters.
    """
    from esoarm.hardware.emulator import Emulator, parse_fault

    specs = [parse_fault(f) for f in faults]
    if scope:
        _check_scope(scope_port, scope_window)
    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "emulate")
    emu = Emulator(scn, lockstep=lockstep, faults=specs, once=once, echo=_say)
    live = None
    if scope:  # bound before 'device:' is printed: a busy port is an error, no dead path
        from esoarm.hardware.scope import scope_for_emulator

        try:
            live = _start_scope(lambda: scope_for_emulator(emu, scn.name, scope_window,
                                                           scope_port), announce=False)
        except BadInput:
            emu.close()
            raise
    _say(f"device: {emu.path}")
    actuator = f"PWM duty ±{emu.twin.pwm_max}" if emu.twin.motor else "ideal torque"
    _say(f"scenario '{scn.name}': {emu.twin.counts_per_rev} counts/rev, "
         f"{1e6 / emu.period_us:g} Hz, {actuator}, {'lockstep' if lockstep else 'real time'}")
    if live is not None:
        click.echo(f"scope: {live.url}", err=True)
    terminated = []

    def on_term(signum, frame) -> None:  # type: ignore[no-untyped-def]
        terminated.append(signum)

    old = signal.signal(signal.SIGTERM, on_term)
    try:
        emu.serve(until=lambda: bool(terminated))
    except KeyboardInterrupt:
        raise Interrupted("emulator stopped") from None
    finally:
        signal.signal(signal.SIGTERM, old)
        emu.close()
        if live is not None:
            live.close()
    if terminated:
        _say("terminated: port closed")


@click.command()
@scenario_argument
@click.option("--port", required=True, metavar="PATH",
              help="Serial device of the rig (e.g. /dev/ttyACM0) or the path printed by "
              "'esoarm emulate'.")
@set_option
@click.option("--log", "log", metavar="FILE.csv",
              help="Stream the log here, one flushed row per sample: t [s], theta (the "
              "measured angle: a rig's true angle is unknown), theta_ref, error [rad], u [N·m], "
              "z1 [rad], z2 [rad/s], z3 [rad/s²], then k, t_device, t_host, latency [s], late "
              "(0/1), duty [counts], y (measured angle [rad]). See docs/semantics.md.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the metrics as one JSON object: rms_error [rad, measured angle], "
              "rms_u [N·m], rms_du [N·m: RMS of u_k − u_k−1], deadline_misses, "
              "jitter_p50_us/jitter_p99_us [µs], ..., wall_clock_s [s] (the run's wall-clock "
              "time, beside samples / rate_hz: a device not paced in real time differs)")
@click.option("--angle-limit", type=float, default=math.pi, show_default=True,
              metavar="RAD", help="Stop when |measured angle| exceeds this [rad].")
@click.option("--max-jump", type=float, default=0.5, show_default=True, metavar="RAD",
              help="Stop when the measured angle changes more than this in one sample [rad].")
@click.option("--watchdog", type=float, default=0.25, show_default=True, metavar="SECONDS",
              help="Stop when no sample arrives for this long [s].")
@click.option("--max-error", type=float, default=0.5, show_default=True, metavar="RAD",
              help="Stop when the measured following error |θ − θd| exceeds this [rad] (a "
              "driver or encoder fault leaves the arm behind its reference).")
@click.option("--baud", type=int, default=115200, show_default=True, metavar="BITS/S",
              help="Serial line rate [bit/s]; must match the firmware (ignored by USB CDC "
              "boards and pseudo-terminals). 1 kHz sampling needs about 500000 or more.")
@click.option("--onboard", is_flag=True,
              help="The chip runs SCENARIO's generated controller itself (firmware built with "
              "make -C firmware ONBOARD=DIR, or 'esoarm hil SCENARIO --onboard'): this host's "
              "control law is off; it checks the chip's controller comes from the same scenario, "
              "starts and stops it, feeds its watchdog, keeps the safety limits and logs the "
              "chip's samples (y, u, z1..z3, duty) -- every sample where the link carries them, "
              "else every n-th, said on screen and in the log's first line.")
@click.option("--switch-at", "switch_at", type=float, default=None, metavar="SECONDS",
              help="Run a PID (the scenario's gains if its controller is one) until SECONDS, "
              "then the ESO + FLC, without a bump in u (controller.kind = \"switch\", "
              "docs/adrc.md); with --set controller.switch_back=T back to the PID at T.")
@scope_options
@bad_input_guard
def run(scenario: str, port: str, overrides: tuple[str, ...], log: str | None, as_json: bool,
        angle_limit: float, max_jump: float, watchdog: float, max_error: float,
        baud: int, onboard: bool, switch_at: float | None, scope: bool, scope_port: int,
        scope_window: float) -> None:
    """Drive the rig on PORT through SCENARIO at its rate for its duration.

    The ESO + FLC of the scenario runs on this host, one sample at a time; the
    device sends encoder counts and receives torques [N·m] (ideal torque source)
    or PWM duties (with a [motor] table). Safety: torque limit, angle limit,
    encoder-jump check, following-error limit, watchdog on incoming samples,
    NaN guard. A fault sends stop, keeps the log and exits 1; Ctrl-C does the
    same and exits 130. With --scope, a local page plots θ, θd, u and the
    estimates as they arrive, with the status counters (the address is
    printed on stderr).
    """
    from esoarm.hardware.link import LinkError, SerialLink
    from esoarm.hardware.realtime import RigFault, RigInterrupted, SafetyLimits, run_rig

    log_path = output_path(log, "--log", (".csv",))
    for name, value in (("--angle-limit", angle_limit), ("--max-jump", max_jump),
                        ("--watchdog", watchdog), ("--max-error", max_error)):
        if not (math.isfinite(value) and value > 0):
            raise BadInput(f"{name} {value:g}: must be a finite number > 0")
    if baud <= 0:
        raise BadInput(f"--baud {baud}: must be > 0")
    if scope:
        _check_scope(scope_port, scope_window)
    if switch_at is not None:
        if not (math.isfinite(switch_at) and switch_at >= 0):
            raise BadInput(f"--switch-at {switch_at:g}: must be a finite time >= 0 [s]")
        overrides = ("controller.kind=switch", f"controller.switch_at={switch_at!r}",
                     *overrides)
    require_extra("serial", "'esoarm run' (the serial link)")
    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "run")
    limits = SafetyLimits(angle_limit=angle_limit, max_jump=max_jump, watchdog=watchdog,
                          max_error=max_error)
    try:
        link = SerialLink(port, baudrate=baud)
    except LinkError as exc:
        raise RunFailure(str(exc)) from None
    live = _status_display() if stderr_is_tty() and not as_json else None
    page = None
    if scope:
        from esoarm.hardware.scope import scope_for_run

        try:
            page = _start_scope(lambda: scope_for_run(scn.name, scn.sensor.rate_hz, scope_window,
                                                      scope_port))
        except BadInput:
            link.close()
            raise
    status = live.update if live else None
    if page is not None:
        status = _tee_status(page, status)
    import time

    started = time.monotonic()
    try:
        summary = run_rig(scn, link, log_path, limits, status=status,
                          monitor=page.push if page is not None else None, onboard=onboard,
                          notice=_stream_notice)
    except RigFault as exc:
        if as_json:  # one JSON object on stdout, as a run that ended well prints
            click.echo(json.dumps({"scenario": scn.name, **exc.summary.to_dict(),
                                   "wall_clock_s": round(time.monotonic() - started, 3),
                                   "fault": str(exc)}))
        raise RunFailure(str(exc)) from None
    except RigInterrupted as exc:
        if as_json:
            click.echo(json.dumps({"scenario": scn.name, **exc.summary.to_dict(),
                                   "wall_clock_s": round(time.monotonic() - started, 3),
                                   "interrupted": str(exc)}))
        raise Interrupted(str(exc)) from None
    except LinkError as exc:
        raise RunFailure(str(exc)) from None
    except KeyboardInterrupt:  # before the run loop took over Ctrl-C (handshake)
        link.stop()
        raise Interrupted("before the run started: stop sent, nothing logged") from None
    finally:
        if live:
            live.close()
        if page is not None:
            page.close()
        link.close()
    wall = time.monotonic() - started
    pace = _pace(summary, wall, 1.0 / scn.sensor.rate_hz)
    if pace is not None:
        warn_line(pace)
    if as_json:
        click.echo(json.dumps(_json_summary(scn.name, summary, wall, 1.0 / scn.sensor.rate_hz)))
        return
    _print_summary(scn, summary, wall, 1.0 / scn.sensor.rate_hz)


def _json_summary(name: str, s, wall: float, ts: float) -> dict:  # type: ignore[no-untyped-def, type-arg]
    """``run --json``: the summary, its "mode" what was measured (as the table's title)."""
    out = {"scenario": name, **s.to_dict(), "wall_clock_s": round(wall, 3)}
    pace = _pace(s, wall, ts)
    if pace is not None:  # asked for real time, delivered otherwise: say what was measured
        out["mode_requested"] = out.get("mode", s.mode)
        out["mode"] = "not real time"
        out["pace_warning"] = pace
    return out


def _stream_notice(line: str) -> None:
    """On board: what the chip streams (a warning when it is not every sample)."""
    if "DECIMATED" in line:
        warn_line(line)
    else:
        click.echo(line, err=True)


#: A run whose wall-clock time differs from its samples' time by more than this share
#: (plus :data:`PACE_SLACK_S`) was not paced by a real-time device.
PACE_TOLERANCE = 0.1
#: ... plus this much [s] for the handshake and the stop.
PACE_SLACK_S = 1.0


def _pace(s, wall: float, ts: float) -> str | None:  # type: ignore[no-untyped-def]
    """A warning when a 'real time' device delivered its samples faster or slower than Ts."""
    sampled = s.samples * s.stream_every * ts
    if s.mode == "lockstep" or abs(wall - sampled) <= PACE_TOLERANCE * sampled + PACE_SLACK_S:
        return None
    if s.onboard:
        return (f"the chip's samples span {sampled:.1f} s but took {wall:.1f} s of wall clock: "
                "the device is not real time (a simulator such as 'esoarm hil'); the chip's "
                "own timing (its clock, t_device) is what the run measured")
    return (f"the device delivered {sampled:.1f} s of samples in {wall:.1f} s of wall clock: it "
            "is not paced in real time (a simulator paced by the host?), so the deadline misses "
            "and jitter describe that device, not a real-time rig")


def _mode_title(s, wall: float, ts: float) -> str:  # type: ignore[no-untyped-def]
    """What was measured: the device's mode and the time its samples took on the wall clock."""
    sampled = s.samples * s.stream_every * ts
    if s.mode == "lockstep":
        return f"lockstep: {sampled:.1f} s of samples in {wall:.1f} s"
    board = "on board, " if s.onboard else ""
    if _pace(s, wall, ts) is not None:
        return f"{board}not real time: {sampled:.1f} s of samples in {wall:.1f} s"
    return f"{board}real time: {sampled:.1f} s of samples in {wall:.1f} s"


def _tee_status(page, other):  # type: ignore[no-untyped-def]
    def update(s: dict) -> None:
        page.set_status(s)
        if other is not None:
            other(s)
    return update


class _status_display:  # noqa: N801 - used like a function
    """A live status line on stderr (rich)."""

    def __init__(self) -> None:
        from rich.console import Console
        from rich.live import Live

        self._live = Live("", console=Console(stderr=True), auto_refresh=False, transient=False)
        self._live.start()

    def update(self, s: dict) -> None:
        self._live.update(
            f"t = {s['t']:7.2f} s  θ = {s['theta']:+.4f} rad  e = {s['error']:+.4f} rad  "
            f"u = {s['u']:+.3f} N·m  misses = {s['deadline_misses']}  "
            f"[{s['k'] + 1}/{s['n']}]", refresh=True)

    def close(self) -> None:
        self._live.stop()


def _print_summary(scn, s, wall: float, ts: float) -> None:  # type: ignore[no-untyped-def]
    from rich.console import Console
    from rich.table import Table

    from esoarm.kinds import units

    u = units(scn)
    table = Table(title=f"{scn.name} on the rig ({_mode_title(s, wall, ts)})")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")

    def fmt(v: float, spec: str) -> str:
        return format(v, spec) if math.isfinite(v) else "—"

    table.add_row("RMS tracking error (measured θ)", fmt(s.rms_error, ".5f"), u.position)
    table.add_row("RMS control", fmt(s.rms_u, ".5f"), u.force)
    table.add_row("RMS control step |u_k − u_k−1|", fmt(s.rms_du, ".5f"), u.force)
    table.add_row("max |error|", fmt(s.max_abs_error, ".5f"), u.position)
    if s.onboard:
        table.add_row("controller", f"on the chip (float32, {s.observer_sums} sums)", "")
        table.add_row("samples streamed", "every one" if s.stream_every == 1
                      else f"every {s.stream_every}th (DECIMATED)", "")
    table.add_row("samples logged", str(s.samples), "")
    table.add_row("lost samples", str(s.lost_samples), "")
    table.add_row("chip samples > Ts late" if s.onboard else "deadline misses",
                  str(s.deadline_misses), "")
    table.add_row("period jitter p50 / p99",
                  f"{fmt(s.jitter_p50_us, '.0f')} / {fmt(s.jitter_p99_us, '.0f')}", "µs")
    table.add_row("host latency p50 / p99",
                  f"{fmt(s.latency_p50_us, '.0f')} / {fmt(s.latency_p99_us, '.0f')}", "µs")
    table.add_row("bad frames", str(s.bad_frames), "")
    Console().print(table)
    if s.log:
        click.echo(f"log: {s.log}")


@click.command()
@click.argument("log_file", metavar="LOG.csv")
@click.option("--scenario", "scenario", default="test-1", show_default=True,
              metavar="NAME|PATH", help="Scenario whose observer (observer.eps [s], "
              "observer.discretization, plant.inertia [kg·m²] or an axis's plant.mass [kg]) "
              "is replayed.")
@set_option
@click.option("--out", "out", metavar="FILE.csv",
              help="Write t [s], theta [rad], u [N·m], z1 [rad], z2 [rad/s], z3 [rad/s²] "
              "(m, N, m/s, m/s² on a prismatic axis; default: CSV on stdout).")
@click.option("--plot", "plot", metavar="FILE.png",
              help="Draw the measured angle with the estimates (.png, .pdf or .svg).")
@bad_input_guard
def replay(log_file: str, scenario: str, overrides: tuple[str, ...], out: str | None,
           plot: str | None) -> None:
    """Run the ESO offline over LOG.csv to recover velocity and perturbation estimates.

    LOG.csv needs columns t [s, uniform], the measured angle [rad] as y (used
    when present: a simulated series' theta is the true angle) or theta, and u
    [N·m, applied from that row on] (on a prismatic axis: position [m],
    force [N]); logs from 'esoarm run' replay directly.
    Row k of the output holds the estimate the controller would use at t_k
    (docs/semantics.md, the sampled-data loop); the sample period comes from
    the log.
    """
    import numpy as np

    from esoarm.hardware import replay as rp
    from esoarm.kinds import hook, kinds_of
    from esoarm.scenario import ScenarioError

    out_path = output_path(out, "--out", (".csv",))
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    scn = resolve_scenario(scenario, overrides)
    plant = kinds_of(scn).plant
    names_of = hook(plant, "joint_names")  # an arm's joints: theta_i, u_i columns
    names = tuple(names_of(scn)) if names_of is not None else ()
    if names:
        t, theta2, u2, ts = rp.read_arm_log(log_file, len(names))
    else:
        t, theta, u, ts = rp.read_log(log_file)
        theta2, u2 = theta.reshape(-1, 1), u.reshape(-1, 1)
    if any(o.split("=", 1)[0].strip() == "sensor.rate_hz" for o in overrides):
        rate = 1.0 / ts  # replay runs at the log's rate: a rate set here must be the log's
        if abs(scn.sensor.rate_hz - rate) > 1e-6 * rate:
            raise ScenarioError(
                f"sensor.rate_hz = {scn.sensor.rate_hz:g} Hz, but '{log_file}' is sampled at "
                f"{rate:.6g} Hz (its t column); replay runs the observer at the log's rate: "
                "drop --set sensor.rate_hz or resample the log")
    rp.check_units(scn, theta2, u2, ts, log_file)
    lost = int(np.isnan(theta2).any(axis=1).sum())  # NaN: a sample lost on the link
    if lost:
        warn_line(f"{lost} of {len(t)} rows of '{log_file}' have no measured angle (theta = nan, "
                  "lost samples): bridged by the observer's prediction with zero innovation")
    failure = None
    try:
        z = rp.estimates(scn, theta2, u2, ts)
    except rp.ReplayDiverged as exc:
        z, failure = exc.estimates, str(exc)
    rows = len(z)
    result: rp.ReplayResult | rp.ArmReplay
    if names:
        result = rp.ArmReplay(t[:rows], theta2[:rows], u2[:rows], z, ts)
        columns = result.columns()
    else:
        result = rp.ReplayResult(t[:rows], theta2[:rows, 0], u2[:rows, 0], z[:, 0, :], ts, scn)
        columns = list(rp.REPLAY_COLUMNS)
    if out_path is None:
        sys.stdout.write(",".join(columns) + "\n")
        np.savetxt(sys.stdout, result.table(), delimiter=",", fmt="%.17g")
    else:
        result.to_csv(out_path)
    if plot_path is not None and failure is None:
        if isinstance(result, rp.ArmReplay):
            from esoarm.plotting.arms import figure_arm_replay

            figure_arm_replay(result, names, plot_path)
        else:
            rp.plot_replay(result, plot_path)
    joints = f", {len(names)} joints" if names else ""
    for label, path in (("estimates", out_path), ("figure", plot_path)):
        if path is not None and (failure is None or label == "estimates"):
            click.echo(f"{label}: {Path(path)} ({rows} rows{joints}, Ts = {ts:g} s)")
    if failure is not None:
        kept = f"; {rows} rows kept in {out_path}" if out_path is not None else ""
        raise RunFailure(f"{failure}{kept}")
