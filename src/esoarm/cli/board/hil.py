"""``esoarm hil``: the compiled firmware in simavr with the twin on its pins."""

from __future__ import annotations

from pathlib import Path

import click

from esoarm.cli._common import (
    BadInput,
    RunFailure,
    bad_input_guard,
    lever_only,
    resolve_scenario,
    scenario_argument,
    set_option,
    warn_line,
)
from esoarm.cli.board.hil_serve import finish, serve_until
from esoarm.cli.board.hil_serve import say as _say
from esoarm.cli.board.stream import stream_given, stream_options


def _progress(line: str) -> None:
    """Progress before the device exists: on stderr ('device: PATH' stays stdout's first line)."""
    click.echo(f"esoarm: {line}", err=True)


#: ELF e_machine of the AVR.
EM_AVR = 83


def _check_avr_elf(path: Path) -> None:
    """Bad input (exit 2) unless ``path`` is an ELF file for the AVR."""
    if not path.is_file():
        raise BadInput(f"--elf '{path}': no such file")
    try:
        head = path.read_bytes()[:20]
    except OSError as exc:
        raise BadInput(f"--elf '{path}': cannot read it ({exc.strerror})") from None
    if head[:4] != b"\x7fELF" or len(head) < 20:
        raise BadInput(f"--elf '{path}': not an AVR ELF file (no ELF header; build one with "
                       "make -C firmware, or drop --elf)")
    machine = int.from_bytes(head[18:20], "little" if head[5] == 1 else "big")
    if machine != EM_AVR:
        raise BadInput(f"--elf '{path}': not an AVR ELF file (ELF machine {machine}, the AVR "
                       f"is {EM_AVR}): build the Uno firmware with make -C firmware")


@click.command()
@scenario_argument
@set_option
@click.option("--fault", "faults", multiple=True, metavar="KIND@SECONDS",
              help="Inject a pin-level fault at twin time SECONDS [s] after START: "
              "encoder-break (channel A stuck high), encoder-noise (1-20 µs glitches, "
              "2000/s), driver (the motor pins stop reaching the motor), brownout (the MCU "
              "resets), unplug (the serial link goes away, the MCU runs on). Repeatable.")
@click.option("--realtime", is_flag=True,
              help="Pace the simulated MCU to the wall clock all the time (for timing "
              "measurements by the host). Default: the AVR's time runs at wall-clock speed "
              "while the host owes an answer and free in between.")
@click.option("--elf", "elf", metavar="FILE.elf", type=click.Path(dir_okay=False),
              help="Firmware to run (default: build the firmware sources -- firmware/ of this "
              "checkout, else the copy the installed package carries -- with make and the AVR "
              "toolchain, into firmware/build/uno-DRIVER/ of a checkout or esoarm's cache "
              "directory, and run that).")
@click.option("--driver", type=click.Choice(["l298n", "bts7960"]), default="l298n",
              show_default=True, help="Driver variant to build when --elf is not given.")
@click.option("--onboard", is_flag=True,
              help="On-board mode: build the firmware with SCENARIO's generated observer and "
              "controller (esoarm codegen ... --target avr; make -C firmware ONBOARD=DIR at the "
              "scenario's rate, 1 Mbit/s), which step in the chip's timer interrupt and drive "
              "the motor themselves; drive it with 'esoarm run SCENARIO --port PATH --onboard'.")
@click.option("--sums", type=click.Choice(["auto", "plain", "compensated"]), default=None,
              help="With --onboard [default: auto]: the generated observer's float32 sums. "
              "compensated (Kahan) "
              "is more accurate at high rates and costs about 1.9k more cycles a step on the "
              "ATmega328P; auto times both with PIL (esoarm pil SCENARIO --target avr, cached) "
              "and takes compensated where it fits the period on board, else plain, and says "
              "which and why; a forced choice that does not fit is warned about.")
@stream_options("With --onboard")
@click.option("--target", type=click.Choice(["avr", "cortex-m4"]), default="avr",
              show_default=True,
              help="The simulated chip: avr (the Uno firmware in simavr) or cortex-m4 (with "
              "--onboard: the generated controller on QEMU's mps2-an386, the twin in lockstep "
              "on a second UART standing for the encoder and motor pins).")
@click.option("--once", is_flag=True,
              help="Exit after the first run: once the motor pins are off and the host has "
              "sent STOP (or the link is unplugged, or the host is silent for 5 s).")
@bad_input_guard
def hil(scenario: str, overrides: tuple[str, ...], faults: tuple[str, ...], realtime: bool,
        elf: str | None, driver: str, onboard: bool, sums: str | None, every: int | None,
        baud: int | None, polled: bool, target: str, once: bool) -> None:
    """Run the Uno firmware in simavr (ATmega328P, 16 MHz) with SCENARIO's twin on its pins.

    The first line printed is 'device: PATH'; pass PATH to 'esoarm run SCENARIO
    --port'. The encoder lines D2/D3 follow the twin's angle (one edge per count
    of 360°/sensor.resolution_deg, at the cycle the angle crosses it); the duty on
    the driver pins (D9 PWM with D7/D8 direction, or D9/D10) drives the twin's
    motor model ([motor] table); the UART is the pseudo-terminal. The physics is
    the simulator's (RK4 step rig.step [s]). Needs gcc, libsimavr-dev and
    libelf-dev; building the firmware needs gcc-avr, avr-libc, arduino-core-avr
    and arduino-mk.
    """
    from esoarm.hardware.hil.board import F_CPU, BoardError
    from esoarm.hardware.hil.build import ToolchainMissing, firmware_elf
    from esoarm.hardware.hil.server import SLIP_S, HilServer, parse_hil_fault

    if sums is not None and not onboard:
        raise BadInput(f"--sums {sums} applies to the generated observer on board: add "
                       "--onboard (the rig firmware without it runs no observer)")
    sums = sums or "auto"
    stream = stream_given(every, baud, polled)
    if stream and not onboard:
        raise BadInput(f"{stream[0]} sets the on-board firmware's stream: add --onboard (the "
                       "rig firmware without it streams a SAMPLE frame per sample)")
    if stream and target != "avr":
        raise BadInput(f"{stream[0]} sets the Uno firmware's stream (--target avr), not the "
                       "cortex-m4 build's")
    if target == "cortex-m4":
        from esoarm.cli.board.hil_cortex_m import hil_cortex_m

        hil_cortex_m(scenario, overrides, faults, realtime, elf, onboard, sums, once)
        return
    specs = [parse_hil_fault(f) for f in faults]
    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "hil")  # before the [motor] check: an arm has the wrong kind, not no motor
    if elf is not None:
        _check_avr_elf(Path(elf))
    board_note = ""
    try:
        if onboard:
            from esoarm.codegen import CodegenError
            from esoarm.codegen.onboard import onboard_firmware

            if elf is not None:
                raise BadInput("--onboard builds its own firmware: drop --elf")
            from esoarm.codegen.onboard import BAUD, check_stream, choose_sums, sums_fit

            try:
                baud = BAUD if baud is None else baud
                # checked before PIL's minutes; None (the firmware's default) keeps the build
                n_every = check_stream(scn.sensor.rate_hz, baud, every)
                why = ""
                if sums == "auto":
                    choice = choose_sums(scn, say=_progress)
                    sums, why = choice.name, f" (auto: {choice.reason})"
                else:
                    fits, numbers = sums_fit(scn, sums == "compensated", say=_progress)
                    if not fits:
                        warn_line(f"--sums {sums} does not fit the ATmega328P's period on "
                                  f"board at {scn.sensor.rate_hz:g} Hz ({numbers}): expect "
                                  "OVERRUN faults; auto would not choose it")
                elf_path = onboard_firmware(scn, compensated=sums == "compensated",
                                            baud=baud, every=every, polled=polled)
            except CodegenError as exc:
                raise BadInput(str(exc)) from None
            board_note = (f"on board: {scn.name}'s controller, float32 {sums} observer sums, "
                          f"at {scn.sensor.rate_hz:g} Hz{why}; streams every "
                          + ("sample" if n_every == 1 else f"{n_every}th sample")
                          + f" at {baud} bit/s"
                          + (", polled from loop()" if polled else ""))
        else:
            elf_path = Path(elf) if elf else firmware_elf(driver)
        server = HilServer(scn, elf_path, faults=specs, realtime=realtime, echo=_say)
    except ToolchainMissing as exc:
        raise RunFailure(str(exc)) from None
    except BoardError as exc:
        raise RunFailure(f"simavr: {exc}") from None
    _say(f"device: {server.path}")
    _say(f"scenario '{scn.name}': firmware {elf_path}, {server.twin.counts_per_rev} counts/rev, "
         f"ATmega328P at 16 MHz, {'real time' if realtime else 'paced by the host'}")
    if board_note:
        _say(board_note)

    def done() -> bool:
        # --once: a run was started, the motor pins are off, and the host has said STOP
        # (0.3 s ago, so that STOPPED reaches it), gone quiet for 5 s, or pulled the plug
        # (then the firmware's watchdog stops the motor and sends its FAULT frame, which
        # takes a few ms on the wire after the pins go off: wait for it, 1 s at most)
        return (
            once and server.log.start_cycle is not None and server.motor_duty == 0
            and (unplug_settled() or server.host_quiet(5.0)
                 or server.stop_seen and server.host_quiet(0.3)))

    def unplug_settled() -> bool:
        if server.unplug_cycle is None:
            return False
        return bool(server.device_faults) or server.board.cycle - server.unplug_cycle > F_CPU

    stats: dict[str, int] = {}

    def close() -> None:
        stats.update(server.board.isr_stats())
        server.close()

    interrupted = serve_until(server, done, (BoardError,), "simavr", close)
    if server.log.start_cycle is not None:
        _say(f"encoder: device count − arm position at the last sample: "
             f"{server.count_error:+d} counts (largest {server.count_error_max})")
    if stats["n"]:
        _say(f"encoder interrupts: {stats['n']}, {stats['isr_sum'] / stats['n']:.0f} cycles "
             f"mean, {stats['isr_max']} max in the handler")
    if server.slips:
        warn_line(f"the simulation fell behind real time {server.slips} times (worst "
             f"{server.worst_slip * 1e3:.0f} ms; the machine is busy): period jitter the host "
             "measured includes it")
    if server.lags:
        warn_line(f"the simulated AVR fell more than {SLIP_S * 1e3:.0f} ms behind the wall "
             f"clock at {server.lags} of {server.samples_tracked} samples (worst "
             f"{server.worst_lag * 1e3:.0f} ms; the machine is busy): "
             + ("on board the chip's own timing is unaffected (its samples carry the AVR's "
                "clock); only the wall-clock time of the run grows" if onboard else
                "the deadline misses and period jitter 'run' reports measure the simulator, "
                "not the host"))
    finish(interrupted)  # Ctrl-C: the summary above, then exit status 130
