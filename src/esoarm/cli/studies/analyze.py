"""``esoarm analyze``: the loop in the frequency domain (margins, sensitivities, bandwidths)."""

from __future__ import annotations

import json
import math
from typing import Any

import click

from esoarm._limits import MAX_ANALYZE_POINTS
from esoarm.cli._common import (
    PLOT_SUFFIXES,
    BadInput,
    Interrupted,
    bad_input_guard,
    note,
    output_path,
    progress,
    resolve_scenario,
    scenario_argument,
    set_option,
)

#: Largest operating angle --theta0 accepts [rad]: one turn either way (gravity repeats
#: every turn; beyond, cos and sin of a huge float are round-off noise).
THETA0_LIMIT = 2 * math.pi


@click.command()
@scenario_argument
@set_option
@click.option("--vary", "varies", metavar="KEY=SPEC", multiple=True,
              help="Analyze the loop for each value of one key: a list (observer.eps=0.05,0.09,0.2"
              ") or lin:START:STOP:NUM / geom:START:STOP:NUM (observer.eps=geom:0.03:0.3:12). "
              "The figure then shows the margins against the key. Once (a grid of keys: "
              "'esoarm sweep').")
@click.option("--max-points", "max_points", type=int, default=MAX_ANALYZE_POINTS,
              show_default=True, metavar="N",
              help="Refuse a --vary of more values than this, before any work (each point "
              "takes about 0.1-0.3 s).")
@click.option("--theta0", type=float, default=None, metavar="RAD",
              help="Operating angle of the linearization [rad], within ±2π (default: "
              "rig.theta0). The worst margins over the reference's range are reported beside "
              "it.")
@click.option("--friction", type=click.Choice(["viscous", "slope", "none"]), default="viscous",
              show_default=True,
              help="Friction in the linear plant: viscous b only (Coulomb friction as a "
              "disturbance, the least damped model), slope (b + (Fc + Fst)/vs, the friction "
              "slope at rest), or none.")
@click.option("--plot", "plot", metavar="FILE.png",
              help="Bode diagram of the loop with its margins, |S| and |T|, and the disturbance "
              "transfer; with --vary, the margins against the key (.png, .pdf or .svg).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: gain_margin [ratio], phase_margin [deg], "
              "delay_margin [s], ms, mt, bandwidths [rad/s], ..., noise_budget {rms_u, rms_du "
              "[N·m], "
              "rms_error [rad]: noise-driven, from the scenario's noise model: "
              "sensor.noise_deg, coloured with sensor.noise_ar / sensor.vibration_deg} (with "
              "--vary: 'points', one object per value).")
@click.option("--bandwidth", "target_bw", type=float, default=None, metavar="RAD/S",
              help="Recommend an observer kind and ε for this disturbance-rejection bandwidth "
              "(−3 dB of the perturbation estimate f → ẑ3) [rad/s]: the ε of each kind "
              "(linear, cascade) that reaches it, ranked by the noise budget's RMS Δu.")
@click.option("--tracking", is_flag=True,
              help="With --bandwidth: match the tracking instead: each kind at the largest ε "
              "whose measured RMS error (the twin, seeds 0-3) is at most the linear ESO's at "
              "bandwidth W, ranked by the noise budget's RMS Δu (what a sweep optimizes; "
              "runs about 50 simulations).")
@bad_input_guard
def analyze(scenario: str, overrides: tuple[str, ...], varies: tuple[str, ...],
            max_points: int, theta0: float | None, friction: str, plot: str | None,
            as_json: bool, target_bw: float | None, tracking: bool) -> None:
    """Frequency-domain analysis of SCENARIO's loop, linearized and sampled at Ts.

    The rig is linearized at the operating angle θ0 (gravity becomes a spring,
    friction per --friction) and sampled with the zero-order hold, the
    actuator lag and the transport delay; the ESO (of observer.discretization)
    and the FLC form one discrete controller. Reported: gain margin [ratio],
    phase margin [deg] and delay margin [s] at the plant input, the peak
    sensitivity Ms and complementary sensitivity Mt, the closed-loop and
    observer bandwidths [rad/s] against the Nyquist frequency π/Ts, and the
    gain from a torque disturbance at the plant input to the tracking error
    [rad/(N·m)]. Saturation, quantization and noise are left out (linear).
    With a [motor] table its back-EMF damping and the host's back-EMF
    compensation are in the loop; its deadband, PWM quantization and supply
    saturation are left out (a note line says so). Models the lever arm with
    the FLC and either ESO kind (the nonlinear one in fal's linear zone,
    innovations within ±δ).
    """
    from esoarm.studies.frequency.linearization import check_supported

    if len(varies) > 1:  # click would keep the last one without a word
        raise BadInput(f"--vary given {len(varies)} times: analyze varies one key (for a grid "
                       "of keys use 'esoarm sweep')")
    vary = varies[0] if varies else None
    plot_path = output_path(plot, "--plot", PLOT_SUFFIXES)
    if theta0 is not None and not (math.isfinite(theta0) and abs(theta0) <= THETA0_LIMIT):
        raise BadInput(f"--theta0 {theta0:g}: must be an angle within ±2π rad (±6.283; gravity "
                       "repeats every turn)")
    if target_bw is not None and not (math.isfinite(target_bw) and target_bw > 0):
        raise BadInput(f"--bandwidth {target_bw:g}: must be a positive frequency [rad/s]")
    if tracking and target_bw is None:
        raise BadInput("--tracking: needs --bandwidth W (the linear ESO's bandwidth whose "
                       "tracking is matched)")
    if vary is not None and target_bw is not None:
        raise BadInput("--bandwidth with --vary: the recommendation is made for one scenario, "
                       "not for each value of the key; drop --vary (or --bandwidth)")
    if max_points < 1:
        raise BadInput(f"--max-points {max_points}: must be a whole number >= 1")
    if vary is not None:
        _check_count(vary, max_points)
    scn = resolve_scenario(scenario, overrides)
    check_supported(scn)
    if vary is None:
        scn = _as_its_loop(scn, target_bw)
        try:
            _analyze_one(scn, theta0, friction, plot_path, as_json, target_bw, tracking)
        except KeyboardInterrupt:
            raise Interrupted("nothing written (analyze prints and draws only at the end)"
                              ) from None
        return
    _as_its_loop(scn, None)  # the note (each point is mapped on its own: the key may be the form's)
    _analyze_vary(scn, vary, max_points, theta0, friction, plot_path, as_json)


def _as_its_loop(scn: Any, target_bw: float | None) -> Any:
    """``scn``, or the FLC + linear ESO with the same loop y → u for a linear ADRC form (a
    note says so); ``--bandwidth`` is refused there (it recommends the FLC's observer)."""
    from esoarm.studies.frequency.linearization import loop_scenario

    loop = loop_scenario(scn)
    if loop is scn:
        return scn
    if target_bw is not None:
        raise BadInput(f"--bandwidth: recommends the settings of the FLC's observer "
                       f"(observer.*); controller.kind = '{scn.controller.kind}' runs its own "
                       "ESO (controller.eps, controller.discretization, controller.tuning): "
                       "compare them with 'esoarm compare' or 'esoarm sweep'")
    note(f"controller.kind = '{scn.controller.kind}': analyzed as the loop it closes, the FLC "
         f"(compensation 'eso') with the linear ESO of its own keys (controller.eps = "
         f"{scn.controller.eps:g} s, {scn.controller.discretization}, "
         f"{scn.controller.tuning}): the same feedback y → u (its reference path is not "
         "part of these margins)")
    return loop


def _analyze_one(scn: Any, theta0: float | None, friction: str, plot_path: Any, as_json: bool,
                 target_bw: float | None, tracking: bool) -> None:
    from esoarm.studies.frequency.margins import analyze as run_analysis

    res = run_analysis(scn, theta0=theta0, friction=friction)
    budget = _noise_budget(scn, theta0, friction)
    if tracking:
        note("--tracking: measuring the tracking of each observer kind on the twin (about 50 "
             "runs)")
    recs, why = (_recommend_tracking(scn, target_bw) if tracking
                 else _recommend(scn, target_bw))
    if plot_path is not None:  # last: Ctrl-C before it leaves nothing written
        from esoarm.studies.frequency.plots import figure_frequency

        figure_frequency(res, plot_path)
    from esoarm.studies.frequency.margins import left_out_notes

    left_out = left_out_notes(scn)
    if as_json:
        extra: dict[str, Any] = {} if recs is None else {"recommendation": recs}
        if why:
            extra["recommendation_note"] = why
        if left_out:
            extra["left_out"] = left_out
        click.echo(json.dumps({**res.to_dict(), "noise_budget": budget, **extra}))
    else:
        _print_one(res)
        for line in left_out:
            click.echo(line)
        _print_budget(budget)
        if tracking:
            _print_tracking(target_bw, recs, why)
        else:
            _print_recommendation(target_bw, recs, why)
        if plot_path is not None:
            click.echo(f"figure: {plot_path}")


def _analyze_vary(scn: Any, vary: str, max_points: int, theta0: float | None, friction: str,
                  plot_path: Any, as_json: bool) -> None:
    from esoarm.scenario import ScenarioError
    from esoarm.studies.frequency.linearization import check_supported, loop_scenario
    from esoarm.studies.frequency.margins import analyze as run_analysis
    from esoarm.studies.sweeps.sweep import parse_vary

    spec = parse_vary(vary, scn, max_values=max_points)
    if len(spec.values) > max_points:  # a list of values
        raise BadInput(_too_many(vary, len(spec.values), max_points))
    scenarios = []
    for value in spec.values:  # validate every point before any work
        try:
            point = loop_scenario(scn.with_overrides({spec.key: value}))
            check_supported(point)
            scenarios.append(point)
        except ScenarioError as exc:
            raise BadInput(f"--vary {spec.key}={value!r}: {exc}") from None
    points = []
    try:
        with progress(len(scenarios), "analyzing", "points") as advance:
            for point in scenarios:
                points.append(run_analysis(point, theta0=theta0, friction=friction))
                advance(1)
    except KeyboardInterrupt:
        raise Interrupted(f"after {len(points)} of {len(scenarios)} points of --vary "
                          f"{spec.key}; nothing written (analyze prints and draws only at the "
                          "end: use fewer values)") from None
    if plot_path is not None:
        from esoarm.studies.frequency.plots import figure_vary

        figure_vary(spec.key, spec.values, points, plot_path)
    if as_json:
        click.echo(json.dumps({"key": spec.key, "points": [
            {"value": v, **p.to_dict()} for v, p in zip(spec.values, points, strict=True)]}))
        return
    _print_vary(spec.key, spec.values, points)
    from esoarm.studies.frequency.margins import left_out_notes

    for line in sorted({line for p in scenarios for line in left_out_notes(p)}):
        click.echo(line)
    if plot_path is not None:
        click.echo(f"figure: {plot_path}")


def _too_many(vary: str, n: int, max_points: int) -> str:
    return (f"--vary {vary}: {n:,} points, more than --max-points {max_points:,} (at 0.1-0.3 s "
            f"a point: {_duration(n * 0.1)} to {_duration(n * 0.3)}); use fewer points or raise "
            "--max-points")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _check_count(vary: str, max_points: int) -> None:
    """A lin/geom NUM above --max-points: refused before any value is made."""
    _key, _, spec = vary.partition("=")
    parts = spec.strip().split(":")
    if len(parts) == 4 and parts[0] in ("lin", "geom"):
        try:
            num = int(parts[3])
        except ValueError:
            return  # parse_vary names the problem
        if num > max_points:
            raise BadInput(_too_many(vary, num, max_points))


def _f(v: float, spec: str) -> str:
    return format(v, spec) if math.isfinite(v) else "∞" if v == math.inf else "—"


def _print_one(a: Any) -> None:
    from rich.console import Console
    from rich.table import Table

    from esoarm.studies.frequency.margins import eso_label, motor_note

    table = Table(title=f"{a.scenario}  (ε = {a.eps:g} s, {a.discretization} {eso_label(a)}; "
                  f"linearized at θ0 = {a.theta0:g} rad, friction '{a.friction}', Ts = {a.ts:g} s)")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_column("unit")
    table.add_column("at ω [rad/s]", justify="right")
    rows = [
        ("closed loop stable (spectral radius)",
         f"{'yes' if a.stable else 'NO'} ({a.closed_loop_radius:.4f})", "", ""),
        ("gain margin", f"{_f(a.gain_margin, '.3f')} ({_f(20 * math.log10(a.gain_margin), '.1f')}"
         " dB)" if math.isfinite(a.gain_margin) else "∞", "ratio", _f(a.phase_crossover, ".3g")),
        ("phase margin", _f(a.phase_margin, ".2f"), "deg", _f(a.gain_crossover, ".3g")),
        ("delay margin", _f(a.delay_margin * 1e3, ".2f"), "ms", _f(a.gain_crossover, ".3g")),
        ("peak sensitivity Ms", _f(a.ms, ".3f"), "", _f(a.ms_frequency, ".3g")),
        ("peak complementary sensitivity Mt", _f(a.mt, ".3f"), "", _f(a.mt_frequency, ".3g")),
        ("closed-loop bandwidth (|T| = −3 dB)", _f(a.closed_loop_bandwidth, ".3g"), "rad/s", ""),
        ("observer bandwidth (f → ẑ3, −3 dB)", _f(a.observer_bandwidth, ".3g"), "rad/s", ""),
        ("observer pole frequency", _f(a.observer_pole_frequency, ".3g"), "rad/s", ""),
        ("Nyquist frequency π/Ts", _f(a.nyquist, ".4g"), "rad/s", ""),
        ("measurement noise → control, peak |K S|", _f(a.noise_to_control_peak, ".4g"),
         "N·m/rad", _f(a.noise_to_control_frequency, ".3g")),
        ("disturbance → error, peak", _f(a.disturbance_peak, ".4g"), "rad/(N·m)",
         _f(a.disturbance_peak_frequency, ".3g")),
        ("disturbance → error, DC", _f(a.disturbance_dc, ".3g"), "rad/(N·m)", "0"),
        ("scenario's disturbance → error amplitude", _f(a.scenario_disturbance_error, ".3g"),
         "rad", ""),
    ]
    for row in rows:
        table.add_row(*row)
    Console(width=max(Console().width, 110)).print(table)
    if not a.stable:
        click.echo(f"the closed loop is UNSTABLE (spectral radius {a.closed_loop_radius:.4g} >= 1):"
                   " the margins above describe a loop that does not settle")
    r = a.range
    if r and len(r.get("angles", [])) > 1:
        click.echo(f"over the reference's range θ0 ∈ [{r['theta_min']:g}, {r['theta_max']:g}] rad: "
                   f"gain margin ≥ {_f(r['gain_margin_min'], '.3f')}, phase margin ≥ "
                   f"{_f(r['phase_margin_min'], '.2f')} deg, delay margin ≥ "
                   f"{_f(r['delay_margin_min'] * 1e3, '.2f')} ms")
    if a.motor:
        click.echo(motor_note(a))


def _print_vary(key: str, values: Any, points: Any) -> None:
    from rich.console import Console
    from rich.table import Table

    from esoarm.studies.frequency.margins import motor_note

    a = points[0]
    table = Table(title=f"{a.scenario}: margins against {key} (linearized at θ0 = {a.theta0:g} "
                  f"rad, friction '{a.friction}', Nyquist {a.nyquist:.4g} rad/s)")
    for name in (key.rsplit(".", 1)[-1], "stable", "GM", "PM°", "DM ms", "Ms", "Mt",
                 "bw CL", "bw ESO", "w→e pk", "n→u pk"):
        table.add_column(name, justify="right")
    for v, p in zip(values, points, strict=True):
        table.add_row(f"{v:.4g}" if isinstance(v, float) else str(v), "yes" if p.stable else "NO",
                      _f(p.gain_margin, ".3g"), _f(p.phase_margin, ".3g"),
                      _f(p.delay_margin * 1e3, ".3g"), _f(p.ms, ".3g"), _f(p.mt, ".3g"),
                      _f(p.closed_loop_bandwidth, ".3g"), _f(p.observer_bandwidth, ".3g"),
                      _f(p.disturbance_peak, ".3g"), _f(p.noise_to_control_peak, ".3g"))
    Console(width=max(Console().width, 110)).print(table)
    click.echo("GM gain margin [ratio], PM phase margin [deg], DM delay margin [ms], bw "
               "bandwidths [rad/s], w→e pk peak torque-disturbance-to-error gain [rad/(N·m)], "
               "n→u pk peak noise-to-control gain [N·m/rad]")
    notes = {motor_note(p) for p in points} - {""}
    if notes:  # one line: with values when every point has the same motor
        click.echo(notes.pop() if len(notes) == 1 else motor_note(
            next(p for p in points if p.motor), values=False))


def _noise_budget(scn: Any, theta0: float | None, friction: str) -> dict[str, Any]:
    """The noise budget as JSON (or {"not_modelled": why})."""
    from esoarm.studies.frequency.noise import noise_budget

    try:
        return noise_budget(scn, theta0=theta0, friction=friction).to_dict()
    except ValueError as exc:
        return {"not_modelled": str(exc)}


def _print_budget(b: dict[str, Any]) -> None:
    if "not_modelled" in b:
        click.echo(f"noise budget: not modelled: {b['not_modelled']}")
        return
    if not b["stable"]:
        click.echo("noise budget: the loop is unstable, no stationary budget")
        return
    click.echo(f"noise budget (white encoder noise σ = {math.degrees(b['noise_rms']):.3g}°, "
               f"linear loop): noise-driven RMS u {b['rms_u']:.4g} N·m, RMS Δu (u_k − u_k−1) "
               f"{b['rms_du']:.4g} N·m, RMS error {b['rms_error']:.3g} rad")


def _not_modelled(scn: Any) -> str | None:
    """Why the recommendation cannot be made for this scenario, or None."""
    from esoarm.kinds import can

    if not can(scn, "RIG"):  # what the plant kind declares
        return (f"the recommendation models the lever arm only (plant.kind = "
                f"'{scn.plant.kind}')")
    if getattr(scn, "motor", None) is not None:
        return ("the recommendation does not model a [motor] table (its back-EMF and the host's "
                "compensation change the observer's input); ask it of the same scenario without "
                "[motor] (a TOML file without the table), whose torque loop it describes")
    return None


Recs = tuple[list[dict[str, Any]] | None, str | None]


def _recommend(scn: Any, target_bw: float | None) -> Recs:
    if target_bw is None:
        return None, None
    from esoarm.studies.frequency.noise import recommend_eps

    blocked = _not_modelled(scn)
    if blocked:
        return [], blocked
    why: list[str] = []
    recs = [{"kind": r.kind, "eps": r.eps, "bandwidth": r.bandwidth,
             "disturbance_peak": r.disturbance_peak, **r.budget.to_dict()}
            for r in recommend_eps(scn, target_bw, why=why)]
    return recs, "; ".join(why) or None


def _recommend_tracking(scn: Any, target_bw: float | None) -> Recs:
    if target_bw is None:
        return None, None
    from esoarm.studies.frequency.sweep_check import match_tracking

    blocked = _not_modelled(scn)
    if blocked:
        return [], blocked
    try:
        bound, matches = match_tracking(scn, target_bw)
    except ValueError as exc:
        return [], str(exc)
    return [{"kind": m.kind, "eps": m.eps, "rms_error_bound": bound,
             "rms_error": m.measured.rms_error, "rms_du_measured": m.measured.rms_du,
             "rms_du": m.budget_du} for m in matches], None


def _print_tracking(target_bw: float | None, recs: list[dict[str, Any]] | None,
                    why: str | None = None) -> None:
    if not recs:
        _print_recommendation(target_bw, recs, why)
        return
    best = recs[0]
    click.echo(f"at the tracking of the linear ESO at bandwidth {target_bw:g} rad/s (RMS error "
               f"{best['rms_error_bound']:.3g} rad, measured, seeds 0-3): "
               f"observer.kind={best['kind']} observer.eps={best['eps']:.4g} has the least "
               f"chatter (budget RMS Δu {best['rms_du']:.3g} N·m, measured "
               f"{best['rms_du_measured']:.3g} N·m; RMS error {best['rms_error']:.3g} rad)")
    for r in recs[1:]:
        click.echo(f"  else observer.kind={r['kind']} observer.eps={r['eps']:.4g}: budget RMS Δu "
                   f"{r['rms_du']:.3g} N·m, RMS error {r['rms_error']:.3g} rad")


def _print_recommendation(target_bw: float | None, recs: list[dict[str, Any]] | None,
                          why: str | None = None) -> None:
    if recs is None:
        return
    if not recs:
        why = why or "no observer kind reaches it with a stable loop"
        click.echo(f"--bandwidth {target_bw:g} rad/s: no recommendation: {why}")
        return
    best = recs[0]
    click.echo(f"for a perturbation-estimate bandwidth of {target_bw:g} rad/s: "
               f"observer.kind={best['kind']} observer.eps={best['eps']:.4g} "
               f"has the least chatter (noise-driven RMS Δu {best['rms_du']:.3g} N·m, RMS u "
               f"{best['rms_u']:.3g} N·m; disturbance → error peak "
               f"{best['disturbance_peak']:.3g} rad/(N·m))")
    for r in recs[1:]:
        click.echo(f"  else observer.kind={r['kind']} observer.eps={r['eps']:.4g}: RMS Δu "
                   f"{r['rms_du']:.3g} N·m, RMS u {r['rms_u']:.3g} N·m, disturbance → error peak "
                   f"{r['disturbance_peak']:.3g} rad/(N·m)")
    if len({r["kind"] for r in recs}) > 1:
        click.echo("  equal f → ẑ3 bandwidths are not equal rejection: check the disturbance "
                   "peaks, and the tracking error with 'esoarm sweep'")
