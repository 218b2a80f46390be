"""``esoarm excite`` and ``esoarm identify``: record an identification experiment, fit the rig."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import click

from esoarm.cli._common import (
    PLOT_SUFFIXES,
    BadInput,
    RunFailure,
    bad_input_guard,
    lever_only,
    output_path,
    require_extra,
    resolve_scenario,
    scenario_argument,
    set_option,
    status_lines,
    stderr_is_tty,
)


@click.command()
@scenario_argument
@set_option
@click.option("--port", metavar="PATH", help="Serial device of the rig (or the path printed "
              "by 'esoarm emulate').")
@click.option("--twin", is_flag=True, help="Run the experiment on the scenario's digital twin "
              "(seeded: sensor.seed for the noise, --seed for the tone phases).")
@click.option("--log", "log", metavar="FILE.csv", help="Stream the log here, one flushed row "
              "per sample: the columns of 'esoarm run' (theta measured [rad], u applied [N·m], "
              "duty [counts]); on the twin also theta_true [rad].")
@click.option("--plan", "plan_only", is_flag=True, help="Print the signal and its spectrum "
              "(and what it does on the twin) and exit; nothing moves.")
@click.option("--duration", type=float, default=60.0, show_default=True, metavar="S",
              help="Length of the experiment [s].")
@click.option("--amplitude", type=float, default=0.2, show_default=True, metavar="N·M",
              help="RMS of the multisine torque [N·m].")
@click.option("--f-min", "f_min", type=float, default=0.1, show_default=True, metavar="HZ",
              help="Lowest tone [Hz] (slow reversals: Coulomb and viscous friction).")
@click.option("--f-max", "f_max", type=float, default=5.0, show_default=True, metavar="HZ",
              help="Highest tone [Hz] (inertia, lag, delay); below half the sample rate.")
@click.option("--tones", type=int, default=24, show_default=True, metavar="N",
              help="Number of log-spaced tones.")
@click.option("--sweep", type=float, default=0.6, show_default=True, metavar="RAD",
              help="Amplitude of the slow setpoint sweep [rad] (gravity: cos θ must vary).")
@click.option("--sweep-period", type=float, default=20.0, show_default=True, metavar="S",
              help="Period of the setpoint sweep [s].")
@click.option("--kp", type=float, default=1.0, show_default=True, metavar="N·M/RAD",
              help="Guard-loop proportional gain [N·m/rad] (keeps the arm near the setpoint).")
@click.option("--kd", type=float, default=0.05, show_default=True, metavar="N·M·S/RAD",
              help="Guard-loop rate gain [N·m·s/rad] (rate from the scenario's ESO).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the tone phases.")
@click.option("--probe", "probe", type=float, default=6.0, show_default=True, metavar="S",
              help="Breakaway probe before the multisine [s] (half each direction; 0: none): "
                   "a rising torque finds the breakaway torque, and the multisine's RMS is "
                   "raised to twice it, its peak within actuator.torque_limit.")
@click.option("--angle-limit", type=float, default=math.pi, show_default=True, metavar="RAD",
              help="Stop when |measured angle| exceeds this [rad].")
@click.option("--max-jump", type=float, default=0.5, show_default=True, metavar="RAD",
              help="Stop when the measured angle changes more than this in one sample [rad].")
@click.option("--watchdog", type=float, default=0.25, show_default=True, metavar="SECONDS",
              help="Stop when no sample arrives for this long [s] (rig only).")
@click.option("--baud", type=int, default=115200, show_default=True, metavar="BITS/S",
              help="Serial line rate [bit/s] (rig only).")
@bad_input_guard
def excite(scenario: str, overrides: tuple[str, ...], port: str | None, twin: bool,
           log: str | None, plan_only: bool, duration: float, amplitude: float, f_min: float,
           f_max: float, tones: int, sweep: float, sweep_period: float, kp: float, kd: float,
           seed: int, probe: float, angle_limit: float, max_jump: float, watchdog: float,
           baud: int) -> None:
    """Record an identification experiment on the rig at PORT or on the twin of SCENARIO.

    The torque is a multisine (RMS --amplitude [N·m], tones from --f-min to
    --f-max [Hz]) added to a weak guard loop u = e(t) − kp (y − θc) − kd ẑ2
    that keeps the nearly neutrally stable arm near a slow setpoint sweep θc.
    On a rig it runs through the safety layer of 'esoarm run' (torque limit
    actuator.torque_limit [N·m], angle limit, encoder-jump check, watchdog,
    stop on any fault, every row logged and flushed). First a --probe phase
    measures the breakaway torque and the multisine is scaled to overcome it;
    during the multisine the share of time the arm is stuck and the velocity
    reversals are counted. Both are printed and written as the log's first
    line ('# esoarm excite: key=value ...'). Feed the log to 'esoarm identify'.
    """
    from esoarm.hardware.realtime import SafetyLimits
    from esoarm.studies.identification.experiment.excitation import ExcitationPlan, plan_text

    plan = ExcitationPlan(duration=duration, amplitude=amplitude, f_min=f_min, f_max=f_max,
                          n_tones=tones, sweep=sweep, sweep_period=sweep_period, kp=kp, kd=kd,
                          seed=seed)
    for name, value in (("--angle-limit", angle_limit), ("--max-jump", max_jump),
                        ("--watchdog", watchdog)):
        if not (math.isfinite(value) and value > 0):
            raise BadInput(f"{name} {value:g}: must be a finite number > 0")
    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "excite")
    plan.check(scn.sample_time)
    from esoarm.studies.identification.experiment.probe import ProbingExcitation, probe_text

    limits = SafetyLimits(angle_limit=angle_limit, max_jump=max_jump, watchdog=watchdog)
    ctl = ProbingExcitation(scn, plan, probe)
    if plan_only:
        from esoarm.cli._common import Interrupted
        from esoarm.hardware.excite import ExcitationFault, ExcitationInterrupted, excite_twin

        try:
            _summary, preview = excite_twin(scn, plan, None, limits, controller=ctl)
        except ExcitationInterrupted:
            raise Interrupted("the plan's preview on the twin; nothing written") from None
        except ExcitationFault as exc:
            preview = None
            click.echo(f"on the twin: stops early: {exc}")
        shown = plan if ctl.amplitude == plan.amplitude else dataclasses.replace(
            plan, amplitude=ctl.amplitude)
        click.echo(plan_text(shown, scn, preview))
        click.echo("on the twin, probe and motion:")
        click.echo(probe_text(ctl.finish()))
        return
    if twin == (port is not None):
        raise BadInput("give exactly one of --port PATH (a rig) or --twin (the digital twin), "
                       "or --plan to only print the experiment")
    log_path = output_path(log, "--log", (".csv",))
    if log_path is None:
        raise BadInput("--log FILE.csv is required (the experiment is only useful logged)")
    if port is not None:
        require_extra("serial", "'esoarm excite --port' (the serial link)")
    if twin:
        _excite_twin(scn, ctl, log_path, limits)
    else:
        _excite_rig(scn, ctl, port, log_path, limits, baud)  # type: ignore[arg-type]
    click.echo(probe_text(ctl.finish()))


def _excite_twin(scn, ctl, log_path: Path, limits) -> None:  # type: ignore[no-untyped-def]
    from esoarm.cli._common import Interrupted
    from esoarm.hardware.excite import ExcitationFault, ExcitationInterrupted, excite_twin

    try:
        summary, preview = excite_twin(scn, None, log_path, limits, controller=ctl)
    except ExcitationInterrupted as exc:
        raise Interrupted(str(exc)) from None
    except ExcitationFault as exc:
        raise RunFailure(str(exc)) from None
    click.echo(f"twin of '{scn.name}': {summary.samples} samples, RMS u {preview['rms_u']:.4g} "
               f"N·m, |θ| up to {preview['max_abs_theta']:.3g} rad")
    click.echo(f"log: {log_path}")


def _excite_rig(scn, ctl, port: str, log_path: Path, limits, baud: int) -> None:  # type: ignore[no-untyped-def]
    from esoarm.cli._common import Interrupted
    from esoarm.hardware.excite import finish_log
    from esoarm.hardware.link import LinkError, SerialLink
    from esoarm.hardware.realtime import RigFault, RigInterrupted, run_rig

    try:
        link = SerialLink(port, baudrate=baud)
    except LinkError as exc:
        raise RunFailure(str(exc)) from None
    try:
        summary = run_rig(scn, link, log_path, limits, controller=ctl)
    except RigFault as exc:
        finish_log(ctl, log_path)
        raise RunFailure(str(exc)) from None
    except RigInterrupted as exc:
        finish_log(ctl, log_path)
        raise Interrupted(str(exc)) from None
    except LinkError as exc:
        finish_log(ctl, log_path)
        raise RunFailure(str(exc)) from None
    except KeyboardInterrupt:
        link.stop()
        raise Interrupted("before the experiment started: stop sent, nothing logged") from None
    finally:
        link.close()
    finish_log(ctl, log_path)
    click.echo(f"rig ({summary.mode}): {summary.samples} samples, RMS u {summary.rms_u:.4g} N·m, "
               f"{summary.lost_samples} lost, {summary.deadline_misses} deadline misses")
    click.echo(f"log: {log_path}")


@click.command()
@click.argument("logs", nargs=-1, required=True, metavar="LOG.csv [LOG2.csv ...]")
@click.option("--scenario", "scenario", default="test-1", show_default=True,
              metavar="NAME|PATH", help="Scenario with the nominal values (the starting point "
              "and the parameters held) and the optional [motor] table.")
@set_option
@click.option("--validate", "validate", multiple=True, metavar="LOG.csv",
              help="A log used only for validation (repeatable). Default: the last of several "
              "logs, or the last --validate-fraction of a single one.")
@click.option("--validate-fraction", type=float, default=0.25, show_default=True,
              metavar="FRACTION", help="Share of a single log kept for validation (0 to 0.5).")
@click.option("--segment", type=float, default=2.0, show_default=True, metavar="S",
              help="Simulation horizon of one segment [s]; each segment's initial angle and "
              "rate are estimated.")
@click.option("--max-delay", type=int, default=2, show_default=True, metavar="SAMPLES",
              help="Largest transport delay tried [samples]; while the best delay is the "
              "longest tried, the search goes on, up to 3 samples more.")
@click.option("--fix", "fix", multiple=True, metavar="KEY",
              help="Hold a parameter at the scenario's value (repeatable), e.g. --fix "
              "actuator.lag --fix plant.m2.")
@click.option("--out", "out", metavar="FILE.toml", help="Write a scenario with the fitted rig "
              "as the twin and the plant (the controller's model) updated to the fit.")
@click.option("--plot", "plot", metavar="FILE.png", help="Draw measured against fitted angle, "
              "residual and its autocorrelation (.png, .pdf or .svg).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object: parameters "
              "{scenario key: {value, ci95}}, fit and validation quality.")
@click.option("--cutoff", type=float, default=None, metavar="HZ",
              help="Cut-off of the IDIM-LS derivative filter [Hz] (default: from the band of "
              "the logged input, so the estimate does not depend on the sample rate).")
@click.option("--input-unit", "input_unit", default="", metavar="UNIT",
              help="Unit of the logged u when it is not a force/torque (e.g. V for a drive "
              "voltage): the axis fit's units follow (V·s²/rad instead of kg·m²).")
@bad_input_guard
def identify(logs: tuple[str, ...], scenario: str, overrides: tuple[str, ...],
             validate: tuple[str, ...], validate_fraction: float, segment: float,
             max_delay: int, fix: tuple[str, ...], out: str | None, plot: str | None,
             as_json: bool, cutoff: float | None, input_unit: str) -> None:
    """Fit the rig model to logs of 'esoarm excite' or 'esoarm run' (grey-box, output error).

    Fits the true inertia (rig.inertia_scale), gravity (plant.m2), Coulomb and
    viscous friction [N·m, N·m·s/rad], actuator lag [s], transport delay
    [samples] and encoder noise [deg] (and motor.torque_constant [N·m/A] with a
    [motor] table), each with a 95 % interval, flags what the log does not
    determine, and validates on data not used for fitting (fit %, residual
    whiteness). The residual's spectrum is fitted as an AR model (with 95 %
    intervals); it is written as sensor.noise_ar and sensor.noise_deg only when
    it is sensor noise (its innovation white and uncorrelated with the past
    input), never when it is model error. Closed-loop logs work: the fit uses
    the torque actually logged.
    The inverse-dynamic-model least squares (IDIM-LS) estimate is computed
    beside it; logs whose angles cannot be in rad are refused.

    With plant.kind = "axis" (a rotary or prismatic axis in SI units, e.g.
    --scenario emps): IDIM-LS gives mass or inertia, viscous and Coulomb
    friction and offset with Newey-West 95 % intervals, checked between the
    halves of the data, beside an output-error fit over --segment pieces, and
    validated on the force (cross-test) and the simulated position. --json
    has "physical": {name: {value, ci95, unit}} in SI names for every plant.
    """
    out_path = output_path(out, "--out", (".toml",))
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    if not (0.0 <= validate_fraction <= 0.5):
        raise BadInput(f"--validate-fraction {validate_fraction:g}: must be in [0, 0.5]")
    if not (math.isfinite(segment) and segment > 0):
        raise BadInput(f"--segment {segment:g}: must be a finite number of seconds > 0")
    if not 0 <= max_delay <= 20:
        raise BadInput(f"--max-delay {max_delay}: must be in 0 … 20 samples")
    if cutoff is not None and not (math.isfinite(cutoff) and cutoff > 0):
        raise BadInput(f"--cutoff {cutoff:g}: must be a finite frequency > 0 [Hz]")
    _check_log_paths(logs, validate)
    scn = resolve_scenario(scenario, overrides)
    _check_rotary_log(scn, logs)
    with _numpy_quiet():
        _identify(scn, logs, validate, validate_fraction, segment, max_delay, fix, out_path,
                  plot, plot_path, as_json, cutoff, input_unit)


def _identify(scn, logs, validate, validate_fraction, segment, max_delay, fix, out_path,  # type: ignore[no-untyped-def]
              plot, plot_path, as_json, cutoff, input_unit) -> None:
    from esoarm.kinds import can
    from esoarm.plants.actuator import motor_of
    from esoarm.studies.identification.data import read_ident_log
    from esoarm.studies.identification.identify import FitFailed
    from esoarm.studies.identification.identify import identify as run_fit

    if can(scn, "AXIS_FIT"):  # the plant declares the axis fit (SI units)
        if plot_path is not None:
            raise BadInput(f"--plot {plot}: the axis fit (plant.kind = \"axis\") draws no "
                           "figure; its residual and validation are in --json")
        _identify_axis(scn, logs, validate, validate_fraction, segment, fix, out_path, as_json,
                       cutoff, input_unit)
        return
    lever_only(scn, "identify")
    if input_unit:
        raise BadInput(f"--input-unit {input_unit}: the lever arm's u is a torque [N·m] (the "
                       "twin's model); --input-unit is for plant.kind = \"axis\"")
    limit = scn.actuator.torque_limit
    motor = motor_of(scn)
    fit_logs = [read_ident_log(p, limit, motor) for p in logs]
    val_logs = [read_ident_log(p, limit, motor, validation=True) for p in validate]
    from esoarm.studies.identification.identify import rate_mismatch

    for lg in (*fit_logs, *val_logs):  # before the segment's check: it counts in samples
        if abs(lg.ts - scn.sample_time) > 1e-9 * scn.sample_time:
            raise BadInput(rate_mismatch(lg.path, lg.ts, scn.sensor.rate_hz))
    _check_segment(segment, fit_logs, val_logs, validate_fraction)
    say: Any = _progress_for(as_json)
    try:
        res = run_fit(scn, fit_logs, validation=val_logs or None,
                      validate_fraction=validate_fraction, segment=segment, max_delay=max_delay,
                      fix=fix, progress=say, cutoff=cutoff)
    except FitFailed as exc:
        raise RunFailure(str(exc)) from None
    finally:
        if say is not None:
            say.close()
    fitted = res.fitted_scenario()
    if plot_path is not None:
        from esoarm.studies.identification.plots import figure_identification

        figure_identification(res, plot_path)
    if out_path is not None:
        from esoarm._io import atomic_path
        from esoarm.studies.identification.report import scenario_toml

        with atomic_path(out_path) as tmp:
            tmp.write_text(scenario_toml(res, fitted), encoding="utf-8")
    if as_json:
        click.echo(json.dumps(res.to_json()))
        return
    from esoarm.studies.identification.report import result_text

    click.echo(result_text(res))
    for label, path in (("scenario", out_path), ("figure", plot_path)):
        if path is not None:
            click.echo(f"{label}: {path}")


#: At most this many segments: each adds two initial states to the fit, whose normal
#: equations grow with their square (a 60 s log in 0.1 s segments took 216 s).
MAX_SEGMENTS = 200
#: A segment has at least this many samples.
MIN_SEGMENT_SAMPLES = 5


def _check_segment(segment: float, fit_logs, val_logs, fraction: float) -> None:  # type: ignore[no-untyped-def]
    """Refuse a --segment shorter than :data:`MIN_SEGMENT_SAMPLES` samples, or one that cuts
    the fitting data into more than :data:`MAX_SEGMENTS` pieces (bad input, exit 2)."""
    ts = fit_logs[0].ts
    if segment < MIN_SEGMENT_SAMPLES * ts * (1 - 1e-9):
        raise BadInput(f"--segment {segment:g}: shorter than {MIN_SEGMENT_SAMPLES} samples "
                       f"({MIN_SEGMENT_SAMPLES * ts:g} s at {1 / ts:g} Hz); give at least "
                       f"{MIN_SEGMENT_SAMPLES * ts:g} s")
    n = sum(lg.n for lg in fit_logs)
    if not val_logs and len(fit_logs) == 1:
        n = int(round(n * (1.0 - fraction)))
    elif not val_logs:
        n -= fit_logs[-1].n
    count = n * ts / segment
    if count > MAX_SEGMENTS:
        shortest = n * ts / MAX_SEGMENTS
        raise BadInput(f"--segment {segment:g}: cuts the {n * ts:.3g} s of fitting data into "
                       f"{count:.0f} segments (at most {MAX_SEGMENTS}: each adds two initial "
                       f"states and the fit's time grows with their square); give --segment "
                       f"{shortest:.2g} or more")


def _check_log_paths(logs: tuple[str, ...], validate: tuple[str, ...]) -> None:
    """Refuse a validation log that is also fitted, and a MATLAB file (bad input)."""
    for p in (*logs, *validate):
        path = Path(p)
        head = b""
        if path.is_file():
            with open(path, "rb") as fh:
                head = fh.read(128)
        if path.suffix.lower() == ".mat" or head.startswith(b"MATLAB"):
            raise BadInput(f"log '{p}': a MATLAB file; identify reads CSV logs: convert it "
                           f"with 'esoarm log import {p} --map t=…,y=…,u=… --out LOG.csv'")
    def key(p: str) -> str:
        return str(Path(p).resolve())

    fitted = [key(p) for p in logs]
    for p in validate:
        if key(p) in fitted:
            raise BadInput(f"--validate {p}: also given to fit; validation needs a log not "
                           "used for fitting (or leave --validate out: the last "
                           "--validate-fraction of the log is kept apart)")
    if not validate and len(logs) > 1 and key(logs[-1]) in fitted[:-1]:
        raise BadInput(f"log '{logs[-1]}' is given twice: the last log is the validation log "
                       "and must not be fitted as well; give it once")
    if len(set(fitted)) < len(fitted):
        dup = next(p for p in logs if fitted.count(key(p)) > 1)
        raise BadInput(f"log '{dup}' is given twice; give each log once")


def _check_rotary_log(scn, logs: tuple[str, ...]) -> None:  # type: ignore[no-untyped-def]
    """Refuse a lever-arm log (the columns of 'esoarm run'/'excite': theta [rad], the ESO's
    z1 … z3) fitted as a prismatic axis (bad input)."""
    from esoarm.kinds import can

    if not can(scn, "AXIS_FIT") or getattr(scn.plant, "motion", "") != "prismatic":
        return
    for p in logs:
        try:
            with open(p, encoding="utf-8") as fh:
                header = next((ln for ln in fh if not ln.startswith("#")), "")
        except (OSError, UnicodeDecodeError):
            return
        cols = {c.strip() for c in header.split(",")}
        if {"theta", "z1", "z2"} <= cols:
            raise BadInput(f"log '{p}': a log of the lever arm (the columns of 'esoarm run' or "
                           f"'esoarm excite': theta [rad], z1, z2): a rotary arm, but "
                           f"scenario '{scn.name}' is a prismatic axis (plant.motion = "
                           "\"prismatic\"); identify it with its own scenario (--scenario "
                           "test-1, or plant.motion=rotary)")


class _numpy_quiet:  # noqa: N801 - a context manager
    """No numpy RuntimeWarning reaches the user: overflow and invalid values are caught by
    the checks and refusals themselves (a log with u scaled by 1e200 is refused)."""

    def __enter__(self) -> None:
        import warnings

        import numpy as np

        self._err = np.seterr(all="ignore")
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc: Any) -> None:
        import numpy as np

        self._w.__exit__(*exc)
        np.seterr(**self._err)


def _identify_axis(scn, logs, validate, validate_fraction, segment, fix, out_path,  # type: ignore[no-untyped-def]
                   as_json, cutoff=None, input_unit="") -> None:
    """``identify`` for plant.kind = "axis": IDIM-LS, output error beside it (SI units)."""
    from esoarm.scenario import ScenarioError
    from esoarm.studies.identification.axis.identify import (
        AxisFitRefused,
        identify_axis,
        physical_names,
    )
    from esoarm.studies.identification.data import read_ident_log

    if fix:
        raise BadInput("--fix: an axis is fitted by IDIM-LS, every parameter at once; hold "
                       "nothing (set the scenario's values with --set)")
    limit = scn.actuator.torque_limit
    fit_logs = [read_ident_log(p, limit) for p in logs]
    val_logs = [read_ident_log(p, limit, validation=True) for p in validate]
    flat = constant_force_half(fit_logs, bool(val_logs), validate_fraction)
    if flat is not None:
        raise RunFailure(flat)
    try:
        res = identify_axis(scn, fit_logs, val_logs, segment, validate_fraction, cutoff)
    except AxisFitRefused as exc:
        raise RunFailure(_in_input_units(str(exc), scn.plant.motion, input_unit)) from None
    if input_unit:  # u in volts (or counts): every printed unit follows
        from esoarm.studies.identification.axis.identify import unit_of as _unit

        for name, e in res.physical.items():
            e["unit"] = _unit(scn.plant.motion, name, input_unit)
            for key in ("note", "withheld"):
                if isinstance(e.get(key), str):
                    e[key] = _in_input_units(e[key], scn.plant.motion, input_unit)
        if res.asymmetry:
            res.asymmetry["unit"] = _unit(scn.plant.motion, "viscous_friction", input_unit)
        res.oe_warning = _in_input_units(res.oe_warning, scn.plant.motion, input_unit)
        for key, text in list(res.validation.items()):
            if isinstance(text, str):
                res.validation[key] = _in_input_units(text, scn.plant.motion, input_unit)
    try:  # the estimate must make a valid axis (friction ≥ 0 each way, mass > 0)
        fitted = res.fitted_scenario()
    except ScenarioError as exc:  # not bad input: the fit's result is not a physical axis
        raise RunFailure(f"the estimate is not a physical axis: {exc} (fitted from "
                         f"{', '.join(res.fit_logs)}); nothing written") from None
    sim_fit = res.validation.get("simulated_fit_percent")
    if sim_fit is not None and not sim_fit > 0.0:  # also nan
        raise RunFailure(
            f"validation failed (the IDIM-LS axis simulated): over the validation log it fits "
            f"{sim_fit:.4g} % of its motion (0 % is its mean: the model predicts nothing; "
            f"relative force error {res.validation['estimation_force_error_percent']:.3g} % "
            "on the fitting data); nothing written")
    if out_path is not None:
        from esoarm._io import atomic_path

        head = [f"# Fitted by esoarm identify (IDIM-LS) from: {', '.join(res.fit_logs)}",
                "# 95 % intervals (HAC):"]
        head += [f"#   {name} = {e['value']:.6g} "
                 + (f"(interval withheld: {e['withheld']})" if e.get("ci95") is None else
                    f"[{e['ci95'][0]:.6g}, {e['ci95'][1]:.6g}]") + f" {e['unit']}"
                 for name, e in res.physical.items()]
        with atomic_path(out_path) as tmp:
            tmp.write_text("\n".join(head) + "\n\n" + fitted.to_toml(),
                           encoding="utf-8")
    if as_json:
        data = res.to_json()
        if input_unit and data.get("output_error"):  # the output error's units follow u too
            from esoarm.studies.identification.axis.identify import unit_of as _unit_of

            for name, e in data["output_error"]["parameters"].items():
                e["unit"] = _unit_of(scn.plant.motion, name, input_unit)
            if "warning" in data["output_error"]:
                data["output_error"]["warning"] = _in_input_units(
                    data["output_error"]["warning"], scn.plant.motion, input_unit)
        click.echo(json.dumps(data))
        return
    from esoarm.studies.identification.axis.identify import unit_of

    motion = scn.plant.motion
    lines = [f"axis '{scn.name}' ({motion}), IDIM-LS on {', '.join(res.fit_logs)}:"]
    oe = res.oe
    oe_by_name = ({} if oe is None else
                  {n: i for i, n in enumerate(physical_names(motion, oe.names))})
    for name, e in res.physical.items():
        line = (f"  {name:21s} {e['value']:12.6g} {unit_of(motion, name, input_unit):10s} 95 % "
                + ("withheld" if e.get("ci95") is None else
                   f"[{e['ci95'][0]:.6g}, {e['ci95'][1]:.6g}]"))
        if oe is not None and name in oe_by_name:
            i = oe_by_name[name]
            line += (f"   output error {oe.values[i]:.6g}" if res.oe_warning else
                     f"   output error {oe.values[i]:.6g} ± {oe.ci95_half[i]:.3g}")
        lines.append(line)
    for name, e in res.physical.items():
        if e.get("note"):
            lines.append(f"  note: {name}: {e['note']}")
    a = res.asymmetry
    if a:
        verdict = "kept" if a["kept"] else "not significant: symmetric model kept"
        lines.append(f"  viscous friction asymmetry Fv+ − Fv− = {a['difference']:.4g} "
                     f"{a['unit']} (z = {a['z']:.3g} against {a['threshold_z']:.3g}, {verdict})")
    if res.oe_warning:
        lines.append(f"  warning: {res.oe_warning}")
    v = res.validation
    lines.append(f"  relative force error {v['estimation_force_error_percent']:.3g} % "
                 "(estimation)" + (f", {v['cross_test_force_error_percent']:.3g} % (cross-test)"
                                   if "cross_test_force_error_percent" in v else ""))
    if "not_validated" in v:
        lines.append(f"  not validated: {v['not_validated']}")
    if "simulated_fit_percent" in v:
        lines.append(f"  simulated validation: fit {v['simulated_fit_percent']:.4g} % over "
                     f"{v['simulated_segment_s']:g} s segments")
    lines.append("  noise: not written (the residual is model error)")
    click.echo("\n".join(lines))
    if out_path is not None:
        click.echo(f"scenario: {out_path}")


def _in_input_units(text: str, motion: str, input_unit: str) -> str:
    """``text`` with every SI unit of an axis parameter (kg·m², N·m·s/rad, N, ...) replaced
    by the unit that follows from the logged u's ``input_unit`` (V·s²/rad, V·s/rad, V)."""
    if not input_unit or not text:
        return text
    import re

    from esoarm.plants.axis import units
    from esoarm.studies.identification.axis.identify import unit_of

    si = units(motion)
    pairs = {si[k]: unit_of(motion, k, input_unit)
             for k in ("mass", "inertia", "viscous_friction", "coulomb_friction") if k in si}
    for old in sorted(pairs, key=len, reverse=True):
        new = pairs[old].replace("\\", "\\\\")
        text = re.sub(rf"([\d\]] ?){re.escape(old)}(?=[\s,;:.)\]]|$)", rf"\g<1>{new}", text)
    return text


def constant_force_half(logs: list[Any], validation_given: bool,
                        validate_fraction: float) -> str | None:
    """Why an axis cannot be identified from ``logs``: a half with one force per direction.

    IDIM-LS is checked between the two halves of the fitting data.  Where, over a half,
    the force takes one value while the axis moves forward and one while it moves back
    (a torque step held for the whole half, as a bare motor's step-response log has),
    Coulomb friction and the offset reproduce it exactly, with no inertia and no viscous
    friction: the motion under a constant force satisfies M q̈ + Fv q̇ = const for every
    (M, Fv) on a line, so the half determines neither.  The fit would compare two
    arbitrary points of that line; this names the cause instead.

    Parameters
    ----------
    logs : list of IdentLog
        The logs given to fit, before the validation part is taken (as identify does:
        the last of several logs, or the last ``validate_fraction`` of a single one,
        unless ``validation_given``).
    validation_given : bool
        Validation logs were given (--validate): every log is fitted.
    validate_fraction : float
        Share of a single log kept for validation.

    Returns
    -------
    str or None
        A one-line message naming the log, the half and the force levels, or None.
    """
    import numpy as np

    fit = logs
    if not validation_given and validate_fraction > 0:
        if len(logs) > 1:
            fit = logs[:-1]
        else:
            fit = [logs[0].part(0, int(round(logs[0].n * (1.0 - validate_fraction))))]
    for half in ("first", "second"):
        levels: dict[float, set[float]] = {1.0: set(), -1.0: set()}
        for lg in fit:
            mid = lg.n // 2
            part = slice(0, mid) if half == "first" else slice(mid, lg.n)
            y, u = lg.y[part], lg.u[part]
            if len(y) < 3:
                return None
            direction = np.sign(np.gradient(y))
            for sign in (1.0, -1.0):
                levels[sign].update(np.unique(u[direction == sign]).tolist())
        if any(len(v) > 1 for v in levels.values()):
            continue
        shown = ", ".join(f"{next(iter(v)):.6g} moving {'forward' if s > 0 else 'back'}"
                          for s, v in levels.items() if v)
        return (f"the {half} half of the fitting data has one force per direction of motion "
                f"({shown}): inertia and viscous friction are not determined there (under a "
                "constant force any inertia fits with a matching friction); log a force "
                "that varies within each half (steps, a multisine: esoarm excite)")
    return None


def _progress_for(as_json: bool) -> Any:
    """What the fit reports its stages to: a live status line on a terminal (rich, on
    stderr), lines every 10 s in a log or pipe (every stage with --verbose); nothing under
    --json or --quiet unless --verbose asks for it."""
    from esoarm.cli._common import VERBOSE, verbosity

    if as_json and verbosity() < VERBOSE:
        return None
    if stderr_is_tty() and not as_json:
        return _progress()
    return status_lines("identify")


class _progress:  # noqa: N801 - used like a function
    """One transient status line on stderr: the stage and the time since the start."""

    def __init__(self) -> None:
        import time

        from rich.console import Console

        self._t0 = time.monotonic()
        self._status = Console(stderr=True).status("identify: reading the logs")
        self._status.start()

    def __call__(self, message: str) -> None:
        import time

        self._status.update(f"identify: {message} [{time.monotonic() - self._t0:.0f} s]")

    def close(self) -> None:
        self._status.stop()
