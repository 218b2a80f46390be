"""``esoarm flash``: SCENARIO's on-board firmware onto an Arduino Uno through its bootloader."""

from __future__ import annotations

import json

import click

from esoarm.cli._common import (
    BadInput,
    RunFailure,
    bad_input_guard,
    lever_only,
    note,
    resolve_scenario,
    scenario_argument,
    set_option,
)
from esoarm.cli.board.stream import stream_options


@click.command()
@scenario_argument
@set_option
@click.option("--port", required=True, metavar="PATH",
              help="The Uno's serial device (/dev/ttyACM0, /dev/ttyUSB0).")
@click.option("--sums", type=click.Choice(["auto", "plain", "compensated"]), default="auto",
              show_default=True,
              help="The generated observer's float32 sums, as 'esoarm hil --onboard': auto "
              "takes compensated where PIL says it fits the period on board, else plain.")
@stream_options("The firmware's stream")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@bad_input_guard
def flash(scenario: str, overrides: tuple[str, ...], port: str, sums: str,
          every: int | None, baud: int | None, polled: bool, as_json: bool) -> None:
    """Build SCENARIO's on-board firmware and write it to the Uno on PORT.

    The firmware is the rig firmware with the generated observer and
    controller ('esoarm hil SCENARIO --onboard' runs the same build in
    simavr). First avrdude (-c arduino, 115200 baud) asks the port for the
    chip's signature: a port where no Uno bootloader answers is refused
    (exit 2) before anything is built or written. After the write avrdude verifies
    the flash, and the firmware is asked for its scenario hash, which must be
    SCENARIO's (exit 1 otherwise). Then run it with 'esoarm run SCENARIO
    --port PATH --onboard' (with --baud BITS/S when the build sets one). Needs
    avrdude, gcc-avr, avr-libc, arduino-core-avr and arduino-mk.
    """
    from esoarm.codegen import CodegenError
    from esoarm.codegen.generate import scenario_hash
    from esoarm.codegen.onboard import BAUD, check_stream, choose_sums, onboard_firmware
    from esoarm.hardware.flash import NotABootloader, check_uno
    from esoarm.hardware.flash import flash as write_flash
    from esoarm.hardware.hil.build import ToolchainMissing
    from esoarm.hardware.link import LinkError

    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "flash")
    if scn.motor is None:
        raise BadInput("the Uno firmware drives a PWM duty: the scenario needs a [motor] "
                       "table (see 'esoarm show uno-rig')")
    baud = BAUD if baud is None else baud
    try:  # the stream's options before the port: nothing is touched for a bad value
        check_stream(scn.sensor.rate_hz, baud, every)
    except CodegenError as exc:
        raise BadInput(str(exc)) from None
    try:  # the port first: a wrong one is refused before anything is built
        signature = check_uno(port)
    except NotABootloader as exc:
        raise BadInput(str(exc)) from None
    except ToolchainMissing as exc:
        raise RunFailure(str(exc)) from None
    note(f"{port}: an Uno bootloader answers (signature {signature}, ATmega328P)")
    try:
        why = ""
        if sums == "auto":
            choice = choose_sums(scn, say=note)
            sums, why = choice.name, f" (auto: {choice.reason})"
        elf = onboard_firmware(scn, compensated=sums == "compensated", baud=baud,
                               every=every, polled=polled)
    except CodegenError as exc:
        raise BadInput(str(exc)) from None
    except ToolchainMissing as exc:
        raise RunFailure(str(exc)) from None
    hex_path = elf.with_suffix(".hex")
    digest = scenario_hash(scn)
    note(f"firmware: {hex_path} (scenario '{scn.name}', sha256 {digest}, float32 {sums} "
         f"observer sums{why}); writing it to {port} with avrdude")
    try:
        rep = write_flash(hex_path, port, digest, baud, signature=signature)
    except NotABootloader as exc:
        raise BadInput(str(exc)) from None
    except (ToolchainMissing, RuntimeError, LinkError) as exc:
        raise RunFailure(str(exc)) from None
    data = {"scenario": scn.name, "sha256": digest, "port": port, "hex": str(rep.hex_path),
            "flash_bytes": rep.flash_bytes, "signature": rep.signature,
            "hash_read": rep.hash_read, "observer_sums": sums, "seconds": round(rep.seconds, 2),
            "baud": baud, "ok": rep.ok}
    if as_json:
        click.echo(json.dumps(data))
    else:
        click.echo(f"wrote {rep.flash_bytes} bytes to the ATmega328P on {port} (signature "
                   f"{rep.signature}, verified) in {rep.seconds:.1f} s; the firmware reports "
                   f"scenario hash {rep.hash_read} ({'matches' if rep.ok else 'DIFFERS'})")
    if not rep.ok:
        raise RunFailure(f"the board reports scenario hash {rep.hash_read}, not "
                         f"{digest[:8]}: the write did not take")
