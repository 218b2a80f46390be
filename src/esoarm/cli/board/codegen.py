"""``esoarm codegen``: C99 source of SCENARIO's observer and controller for a target."""

from __future__ import annotations

import time
from pathlib import Path

import click

from esoarm.cli._common import (
    BadInput,
    Interrupted,
    RunFailure,
    bad_input_guard,
    note,
    output_dir,
    resolve_scenario,
    scenario_argument,
    set_option,
    warn_line,
)
from esoarm.cli.board.stream import stream_given, stream_options
from esoarm.codegen.generate import DEFAULT_PREFIX, TARGETS


@click.command()
@scenario_argument
@set_option
@click.option("--target", type=click.Choice(list(TARGETS)), default=None,
              help="avr: ATmega328P (avr-gcc, double is 32 bits); cortex-m0plus: no FPU "
              "(RP2040 class, soft float); cortex-m4, cortex-m7: with FPU "
              "(arm-none-eabi-gcc); host: the machine's gcc. [required unless "
              "--arduino-library, which is avr]")
@click.option("--out", "out", default=None, metavar="DIR",
              help="Folder for PREFIX_controller.{h,c} (the library) and "
              "PREFIX_reference.{h,c} (the scenario's moves as a trajectory generator).")
@click.option("--arduino-library", "library", default=None, metavar="DIR",
              help="Write an Arduino library instead (library.properties, src/, and "
              "examples/OnBoard/ with a complete sketch and a Makefile for arduino-mk: "
              "'make' there builds the .hex); the folder's name is the library's.")
@stream_options("With --arduino-library")
@click.option("--prefix", default=DEFAULT_PREFIX, show_default=True,
              help="Of every public name and file (two designs link into one program with "
              "two prefixes).")
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
def codegen(scenario: str, overrides: tuple[str, ...], target: str | None, out: str | None,
            library: str | None, every: int | None, baud: int | None, polled: bool,
            prefix: str, precision: str | None, plain_sums: bool, no_check: bool,
            project: str | None) -> None:
    """Generate self-contained C99 for SCENARIO's observer and controller on a target.

    The code is the scenario as designed: the observer and controller kinds'
    C (each kind provides it beside its Python step), their gains and
    discretization, the saturation and (with a [motor] table) the
    torque-to-duty map. One PREFIX_state per axis; PREFIX_init(),
    PREFIX_step(state, y, theta_d, omega_d, accel_d) -> u, PREFIX_reset(),
    PREFIX_set_params() for epsilon, b0, k1, k2 at run time; no heap, no
    globals. The scenario's moves are a separate trajectory generator
    (PREFIX_reference.h). The header names the scenario, a SHA-256 of it and
    the esoarm version. With float32 the generated code is built for the host
    and run against the float64 Python reference over the twin run; exit
    status 1 when it does not agree to 1e-4 of the torque limit (the files are
    kept), as 'esoarm pil' does.
    """
    from esoarm.codegen import CodegenError, generate, write_sources

    stream = stream_given(every, baud, polled)
    if stream and library is None:
        raise BadInput(f"{stream[0]} sets the Arduino example's stream: it applies with "
                       "--arduino-library DIR")
    if project is not None:
        from esoarm.cli.board.codegen_project import write_project

        if out is None or library is not None:
            raise BadInput("--project stm32 writes into --out DIR (not --arduino-library)")
        write_project(scenario, overrides, project, out, target, precision, plain_sums)
        return
    if library is not None:
        if out is not None:
            raise BadInput("--arduino-library DIR and --out DIR: give one")
        if target not in (None, "avr") or precision not in (None, "float32"):
            raise BadInput("--arduino-library builds for the Uno: --target avr, float32 "
                           "(drop --target/--precision)")
        target = "avr"
    elif out is None:
        raise BadInput("give --out DIR (the C files, or --project stm32) or "
                       "--arduino-library DIR")
    elif target is None:
        raise BadInput(f"--target is required (one of {', '.join(TARGETS)}), or --project "
                       "stm32, or --arduino-library DIR")
    precision = precision or "float32"
    if plain_sums and precision != "float32":
        raise BadInput("--plain-sums applies to float32: float64 already sums the observer's "
                       "increments plainly (as the Python reference does)")
    target_dir = library if library is not None else out
    assert target_dir is not None
    folder = output_dir(target_dir, "--arduino-library" if library else "--out")
    scn = resolve_scenario(scenario, overrides)
    compensated = None if precision == "float32" and not plain_sums else False
    try:
        if library is not None:
            from esoarm.codegen.arduino import EXAMPLE, arduino_library

            gen, paths = arduino_library(scn, Path(folder), prefix, compensated,
                                         **({} if baud is None else {"baud": baud}),
                                         every=every, polled=polled)
            note(f"wrote the Arduino library {folder} ({len(paths)} files): scenario "
                 f"'{scn.name}' (sha256 {gen.digest}), float32"
                 + (", compensated observer sums" if gen.compensated else ", plain sums")
                 + f"; build the example with: make -C {Path(folder) / 'examples' / EXAMPLE}")
        else:
            gen = generate(scn, target, precision, compensated, prefix)
            paths = write_sources(gen, Path(folder))
            note(f"wrote {', '.join(p.name for p in paths)} in {folder}: scenario "
                 f"'{scn.name}' (sha256 {gen.digest}), {target}, {precision}"
                 + (", compensated observer sums" if gen.compensated else ""))
    except CodegenError as exc:
        raise BadInput(str(exc)) from None
    if precision != "float32" or no_check:
        return
    _check(scn, gen.compensated, folder)


def _check(scn, compensated: bool, folder: str | Path) -> None:  # type: ignore[no-untyped-def]
    """The float32 check on the host: exit 1 when it does not hold."""
    from esoarm.codegen import AGREEMENT
    from esoarm.codegen.generate import generate as gen_host
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep
    from esoarm.hardware.hil.build import ToolchainMissing

    n = scn.n_samples
    note(f"checking float32 on the host against the float64 Python reference over {n} "
         "samples of the twin run (--no-check skips it)")
    start = time.monotonic()
    last = [start]

    def progress(k: int) -> None:
        now = time.monotonic()
        if now - last[0] >= 5.0:
            last[0] = now
            note(f"  float32 check: {k} of {n} samples ({now - start:.0f} s)")

    try:
        run = lockstep(scn, HostChip(gen_host(scn, "host", "float32", compensated)),
                       progress=progress)
    except ToolchainMissing as exc:
        warn_line(f"float32 not checked ({exc})")
        return
    except KeyboardInterrupt:
        raise Interrupted(f"float32 check stopped; the generated files are kept in {folder} "
                          "(unchecked)") from None
    if not run.ref_finite:
        raise RunFailure(
            f"the float64 Python reference itself diverges (its command is not finite at "
            f"sample {run.ref_diverged_at}): the design is unstable at this observer.eps and "
            f"rate, not a float32 matter; the files are kept in {folder}. "
            + _design_hint(scn))
    text = (f"float32 check on the host: max |Δu| = {run.max_abs_du:.3g} N·m "
            f"({run.max_rel_du:.2g} of the torque limit) against the float64 Python "
            f"reference over {run.steps} samples")
    if run.max_rel_du > AGREEMENT:
        raise RunFailure(f"{text}: float32 does not hold here (> {AGREEMENT:g}); the files "
                         f"are kept in {folder}; use --precision float64 (cortex-m4, m7, "
                         "m0plus, host)" + ("" if compensated else " or drop --plain-sums"))
    note(text)


def _design_hint(scn) -> str:  # type: ignore[no-untyped-def]
    """What the observer's design checks say about the scenario (one line)."""
    try:
        from esoarm.scenario import scenario_warnings

        lines = scenario_warnings(scn)
    except Exception:  # noqa: BLE001 - a hint only
        lines = []
    if lines:
        return str(lines[0])
    return (f"Try a larger observer.eps (ε = {getattr(scn.observer, 'eps', '?')} s at "
            f"Ts = {scn.sample_time:g} s) or a zoh discretization.")
