"""``esoarm pil``: the generated controller on an emulated chip, processor in the loop."""

from __future__ import annotations

import json

import click

from esoarm.cli._common import (
    BadInput,
    RunFailure,
    bad_input_guard,
    resolve_scenario,
    scenario_argument,
    set_option,
)


@click.command()
@scenario_argument
@set_option
@click.option("--target", type=click.Choice(["avr", "cortex-m0plus", "cortex-m4"]),
              required=True,
              help="avr: ATmega328P at 16 MHz in simavr (cycles counted); cortex-m0plus: "
              "soft-float build on QEMU's microbit (an nRF51 Cortex-M0 at 16 MHz, same "
              "ARMv6-M instructions); cortex-m4: mps2-an386 in QEMU (QEMU targets: an "
              "instruction-count proxy, QEMU has no cycle counter).")
@click.option("--precision", type=click.Choice(["float32", "float64"]), default="float32",
              show_default=True, help="Type of every real in the generated code (avr: float32 "
              "only).")
@click.option("--plain-sums", is_flag=True,
              help="Sum the observer's increments plainly (the default carries their rounding "
              "error; docs/on-the-chip.md).")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Run only the first STEPS samples [default: the whole run].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@bad_input_guard
def pil(scenario: str, overrides: tuple[str, ...], target: str, precision: str,
        plain_sums: bool, steps: int | None, as_json: bool) -> None:
    """Run SCENARIO's generated controller on an emulated chip in lockstep with the twin.

    Each sample the twin's measurement goes to the chip, the chip's command
    drives the twin, and the Python reference in float64 steps on the same
    measurement. Reported: max |u_chip − u_ref| [N·m] and relative to the
    torque limit, per-step cycles (min, median, max) against one sample
    period at the chip's clock, and the PIL image's flash and static RAM.
    Exit status 1 when the agreement is worse than 1e-4 of the torque limit,
    the worst step does not fit in the sample period, or the run ended before
    the arm was asked to move (an agreement at rest checks nothing).
    """
    from esoarm.codegen import AGREEMENT, CodegenError
    from esoarm.codegen.pil import run_pil
    from esoarm.hardware.hil.build import ToolchainMissing

    if plain_sums and precision != "float32":
        raise BadInput("--plain-sums applies to float32: float64 already sums the observer's "
                       "increments plainly")
    scn = resolve_scenario(scenario, overrides)
    if steps is not None and steps > scn.n_samples:
        raise BadInput(f"--steps {steps}: the scenario has {scn.n_samples} samples "
                       f"({scn.duration:g} s at {scn.sensor.rate_hz:g} Hz); for a longer run "
                       "raise duration (--set duration=...)")
    try:
        report = run_pil(scn, target, precision, False if plain_sums else None, steps)
    except CodegenError as exc:
        raise BadInput(str(exc)) from None
    except ToolchainMissing as exc:
        raise RunFailure(str(exc)) from None
    except RuntimeError as exc:
        raise RunFailure(f"{target}: {exc}") from None
    data = report.as_dict()
    if as_json:
        click.echo(json.dumps(data))
    else:
        c = data["cycles"]
        click.echo(f"scenario '{scn.name}' (sha256 {report.gen.digest}) on {target}, "
                   f"{precision}, {data['steps']} steps")
        click.echo(f"agreement: max |Δu| = {data['max_abs_du']:.3g} N·m, "
                   f"{data['max_rel_du']:.3g} of the torque limit (limit {AGREEMENT:g})"
                   + (f"; {data['duty_ties']} duty rounding ties followed"
                      if data["duty_ties"] else ""))
        click.echo(f"per step: {c['min']} / {c['median']} / {c['max']} (min / median / max) "
                   f"{report.timing}; budget {data['budget_cycles']} at "
                   f"{report.clock_hz / 1e6:g} MHz ({100 * data['budget_used']:.1f} % used)")
        click.echo(f"image: {data['flash_bytes']} bytes flash, {data['ram_bytes']} bytes "
                   "static RAM")
    if not report.covers_motion:
        move = report.run.first_move
        where = (f"the reference's first move starts at sample {move}" if move is not None
                 else "the reference does not move within them")
        hint = (f"; run at least --steps {min(scn.n_samples, 4 * move + 100)}"
                if move is not None else "")
        raise RunFailure(f"the check covered only the arm at rest: {data['steps']} samples, "
                         f"{where}, so max |Δu| = {data['max_abs_du']:.3g} N·m says nothing "
                         f"about the code while the arm moves{hint}")
    if not report.agrees:
        raise RunFailure(f"the chip does not agree with the float64 reference: max |Δu| / "
                         f"torque_limit = {data['max_rel_du']:.3g} > {AGREEMENT:g}")
    if not report.fits:
        raise RunFailure(f"the worst step took {data['cycles']['max']} of a budget of "
                         f"{data['budget_cycles']} per sample")
