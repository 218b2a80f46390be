"""``esoarm commission``: a new rig from excitation to a measured on-board run, one report."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from esoarm.cli._common import (
    BadInput,
    Interrupted,
    RunFailure,
    bad_input_guard,
    output_dir,
    require_extra,
    resolve_scenario,
    scenario_argument,
    set_option,
)


@click.command()
@scenario_argument
@set_option
@click.option("--port", metavar="PATH", help="Serial device of the rig: an Uno with the rig "
              "firmware for the excitation; the on-board build is then written to it through "
              "its bootloader (avrdude) for the run.")
@click.option("--hil", is_flag=True, help="Commission the simulated Uno (simavr, the scenario's "
              "twin on its pins) instead of a rig: the same steps, flashing loads the simulated "
              "chip.")
@click.option("--workdir", default=None, metavar="DIR",
              help="One file per step (default: commission-SCENARIO in the current directory).")
@click.option("--resume", is_flag=True, help="Take each step from its file in --workdir when "
              "its inputs are unchanged, and go on from the first that is missing or changed.")
@click.option("--bandwidth", type=float, default=None, metavar="RAD/S",
              help="Perturbation-estimate bandwidth to design the observer for (f → ẑ3, −3 dB) "
              "[rad/s]; default: proposed, the bandwidth of the scenario's own observer.")
@click.option("--observer-kind", type=click.Choice(["linear", "cascade"]), default=None,
              help="Take this observer kind's ε for the bandwidth instead of the one chosen "
              "(the least noise-driven chatter among the kinds whose disturbance → error peak "
              "is within 1.5× of the smallest; the report compares them).")
@click.option("--amplitude", type=float, default=0.2, show_default=True, metavar="N·M",
              help="RMS torque of the excitation multisine [N·m] (saturated at "
              "actuator.torque_limit).")
@click.option("--excite-seconds", type=float, default=60.0, show_default=True, metavar="S",
              help="Length of the excitation [s].")
@click.option("--angle-limit", type=float, default=1.5, show_default=True, metavar="RAD",
              help="Stop any step when |θ| measured exceeds this [rad].")
@click.option("--baud", type=int, default=115200, show_default=True, metavar="BITS/S",
              help="Line rate of the rig firmware for the excitation [bit/s] (the on-board "
              "build runs at 1000000).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: steps, excitation, identified, design, codegen, "
              "flash, predicted, measured, agreement, report (and refused, when a step "
              "refused).")
@bad_input_guard
def commission(scenario: str, overrides: tuple[str, ...], port: str | None, hil: bool,
               workdir: str | None, resume: bool, bandwidth: float | None,
               observer_kind: str | None, amplitude: float,
               excite_seconds: float, angle_limit: float, baud: int, as_json: bool) -> None:
    """Commission a rig: excite, identify, design, generate, flash and run on board.

    The path a person follows on a new rig, in one command: an excitation within
    the torque limit and --angle-limit, the identification (a fit it does not trust
    stops here), the noise budget and the observer kind and ε recommended for a
    perturbation-estimate bandwidth (--bandwidth, or proposed), the generated C for
    the Uno, the on-board firmware flashed (on --hil: loaded into the simulated
    chip), an on-board run of the reference trajectory, and the measured RMS
    error and RMS Δu beside the predicted ones (esoarm simulate of the design on
    the identified rig). Every step writes its file in --workdir; --resume
    continues from them. Writes report.html and commission.json there. Exit
    status 1 when a step refuses (the reason and what to change on one line) or
    the measured run is more than 25 % off the prediction; 2 for bad input.
    """
    from esoarm.scenario import ScenarioError
    from esoarm.studies.commission import Commission, CommissionOptions, CommissionRefused
    from esoarm.studies.commission.report import write_report
    from esoarm.studies.commission.steps import check_options

    if hil or port is not None:
        require_extra("serial", "'esoarm commission' (the serial link to the board)")
    scn = resolve_scenario(scenario, overrides)
    folder = output_dir(workdir or f"commission-{scn.name}", "--workdir")
    opts = CommissionOptions(scenario, tuple(overrides), folder.resolve(), port, hil,
                             bandwidth, observer_kind, amplitude, excite_seconds, angle_limit,
                             baud, resume)
    check_options(opts)
    if folder.exists() and any(folder.glob("0*-*.json")) and not resume:
        raise BadInput(f"--workdir '{folder}' holds the steps of an earlier commissioning: "
                       "add --resume to continue from them, or give another --workdir")

    def say(line: str) -> None:
        click.echo(f"commission: {line}", err=True)

    job = Commission(opts, say)
    refused = None
    try:
        summary = job.run()
    except CommissionRefused as exc:
        refused = {"step": exc.step, "reason": exc.reason, "advice": exc.advice}
        summary = job.summary()
    except ScenarioError as exc:
        raise BadInput(str(exc)) from None
    except KeyboardInterrupt:
        raise Interrupted(f"the steps done are in {folder}; --resume continues") from None
    page = write_report(summary, folder / "report.html", refused)
    summary["report"] = str(page)
    if refused:
        summary["refused"] = refused
    (folder / "commission.json").write_text(json.dumps(summary, indent=1), encoding="utf-8")
    if as_json:
        click.echo(json.dumps(summary))
    else:
        _print(summary)
    if refused:
        raise RunFailure(f"{refused['step']}: {refused['reason']}; to go on: "
                         f"{refused['advice']} (report: {page})")
    agreement = summary["agreement"]
    if not (agreement["rms_error_ok"] and agreement["rms_du_ok"]):
        rel = agreement["relative"]
        raise RunFailure(
            f"the on-board run is not what was predicted: RMS error {100 * rel['rms_error']:+.1f}"
            f" %, RMS Δu {100 * (rel['rms_du'] or float('nan')):+.1f} % (limit ±25 %): the rig "
            f"differs from the identified model; see {page}")


def _print(s: dict) -> None:
    d, p, m = s.get("design") or {}, s.get("predicted") or {}, s.get("measured") or {}
    out = sys.stdout
    if d:
        print(f"design: observer.kind={d['observer_kind']} observer.eps={d['eps']:.4g} s for "
              f"{d['bandwidth']:.4g} rad/s ({d['bandwidth_source']})", file=out)
    if p and m:
        print(f"RMS error: predicted {p['rms_error']:.4g} rad, measured {m['rms_error']:.4g} rad; "
              f"RMS Δu: predicted {p['rms_du']:.4g} N·m, measured {m['rms_du']:.4g} N·m", file=out)
    print(f"report: {Path(s['workdir']) / 'report.html'}", file=out)
