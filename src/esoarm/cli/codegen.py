"""``esoarm codegen``: C99 source of SCENARIO's observer and controller for a target."""

from __future__ import annotations

from pathlib import Path

import click

from esoarm.cli._common import (
    BadInput,
    bad_input_guard,
    note,
    output_dir,
    resolve_scenario,
    scenario_argument,
    set_option,
    warn_line,
)


@click.command()
@scenario_argument
@set_option
@click.option("--target", type=click.Choice(["avr", "cortex-m4", "host"]), default=None,
              help="avr: ATmega328P (avr-gcc, double is 32 bits); cortex-m4: with FPU "
              "(arm-none-eabi-gcc); host: the machine's gcc.")
@click.option("--out", "out", required=True, metavar="DIR",
              help="Folder for esoarm_controller.h and esoarm_controller.c (created).")
@click.option("--precision", type=click.Choice(["float32", "float64"]), default=None,
              help="Type of every real in the generated code [default: float32; float64 "
              "is not available on avr].")
@click.option("--plain-sums", is_flag=True,
              help="float32: sum the observer's increments plainly instead of carrying "
              "their rounding error (compensated, the default; docs/on-the-chip.md).")
@click.option("--no-check", is_flag=True,
              help="Skip the float32 check (the generated code built for the host and run "
              "against the float64 Python reference over the twin run).")
@click.option("--project", type=click.Choice(["stm32"]), default=None,
              help="Write a whole firmware project into --out instead: stm32 is a Makefile "
              "project for an STM32F401RE (Nucleo-F401RE: startup, linker script, register-"
              "level TIM2 encoder, TIM3 PWM, TIM4 sample clock, USART2 link for 'esoarm run "
              "--onboard'), float32 for its FPU; build it with make (arm-none-eabi-gcc).")
@bad_input_guard
def codegen(scenario: str, overrides: tuple[str, ...], target: str | None, out: str,
            precision: str | None, plain_sums: bool, no_check: bool,
            project: str | None) -> None:
    """Generate self-contained C99 for SCENARIO's observer and controller on a target.

    The code is the scenario as designed: the observer and controller kinds'
    C (each kind provides it beside its Python step), their gains and
    discretization, the reference trajectory, the saturation and (with a
    [motor] table) the torque-to-duty map. It has a state struct,
    esoarm_init() and esoarm_step(state, y) -> u; no heap. The header names
    the scenario and a SHA-256 of it. With float32 the generated code is built
    for the host and run against the float64 Python reference over the twin
    run; a warning says when it does not agree to 1e-4 of the torque limit.
    """
    from esoarm.codegen import AGREEMENT, CodegenError, generate, write_sources

    if project is not None:
        from esoarm.cli.codegen_project import write_project

        write_project(scenario, overrides, project, out, target, precision, plain_sums)
        return
    if target is None:
        raise BadInput("--target is required (avr, cortex-m4 or host), or --project stm32")
    precision = precision or "float32"
    folder = output_dir(out, "--out")
    scn = resolve_scenario(scenario, overrides)
    compensated = None if precision == "float32" and not plain_sums else False
    try:
        gen = generate(scn, target, precision, compensated)
    except CodegenError as exc:
        raise BadInput(str(exc)) from None
    paths = write_sources(gen, Path(folder))
    note(f"wrote {paths[0]} and {paths[1].name}: scenario '{scn.name}' (sha256 {gen.digest}), "
         f"{target}, {precision}" + (", compensated observer sums" if gen.compensated else ""))
    if precision != "float32" or no_check:
        return
    from esoarm.codegen.generate import generate as gen_host
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep
    from esoarm.hardware.hil.build import ToolchainMissing

    try:
        run = lockstep(scn, HostChip(gen_host(scn, "host", precision, gen.compensated)))
    except ToolchainMissing as exc:
        warn_line(f"float32 not checked ({exc})")
        return
    text = (f"float32 check on the host: max |Δu| = {run.max_abs_du:.3g} N·m "
            f"({run.max_rel_du:.2g} of the torque limit) against the float64 Python "
            f"reference over {run.steps} samples")
    if run.max_rel_du > AGREEMENT:
        warn_line(f"{text}: float32 does not hold here (> {AGREEMENT:g}); use --precision "
                  "float64 (cortex-m4, host)" + ("" if gen.compensated else
                                                    " or drop --plain-sums"))
    else:
        note(text)
