"""``esoarm hil SCENARIO --onboard --target cortex-m4``: the on-board firmware in QEMU."""

from __future__ import annotations

from esoarm.cli._common import (
    BadInput,
    RunFailure,
    lever_only,
    resolve_scenario,
    warn_line,
)
from esoarm.cli.board.hil_serve import finish, serve_until
from esoarm.cli.board.hil_serve import say as _say


def hil_cortex_m(scenario: str, overrides: tuple[str, ...], faults: tuple[str, ...],
                 realtime: bool, elf: str | None, onboard: bool, sums: str, once: bool) -> None:
    """Serve the on-board Cortex-M4 firmware of ``scenario`` until stopped (see ``esoarm hil``).

    Parameters
    ----------
    scenario : str
        A built-in scenario's name or a TOML file.
    overrides : tuple of str
        ``KEY=VALUE`` items of ``--set``.
    faults : tuple of str
        ``--fault`` items: refused here (the on-board run takes its faults from ``esoarm run``).
    realtime : bool
        ``--realtime``: refused here (QEMU runs in lockstep with the twin).
    elf : str, optional
        ``--elf``: refused here (the firmware is built from the scenario).
    onboard : bool
        ``--onboard``: required (the chip runs the generated controller).
    sums : {"auto", "compensated", "plain"}
        The observer's float32 sums (auto: compensated, the FPU makes them cheap).
    once : bool
        Stop after one run (when the motor is off again, or the device faulted).
    """
    from esoarm.codegen import CodegenError
    from esoarm.codegen.cortex_m_onboard import m4_onboard_firmware
    from esoarm.hardware.hil.build import ToolchainMissing
    from esoarm.hardware.hil.qemu import LAG_S, QemuError, QemuOnboardServer

    if not onboard:
        raise BadInput("--target cortex-m4 runs the generated controller on the chip: add "
                       "--onboard (the host-controlled rig firmware is the Uno's, --target avr)")
    for flag, given in (("--fault", bool(faults)), ("--elf", elf is not None),
                        ("--realtime", realtime)):
        if given:
            raise BadInput(f"{flag} is for --target avr (simavr's pins); the Cortex-M4 on board "
                           "takes its faults from 'esoarm run' (watchdog, limits)")
    scn = resolve_scenario(scenario, overrides)
    lever_only(scn, "hil")
    compensated = {"auto": True, "compensated": True, "plain": False}[sums]
    try:
        fw = m4_onboard_firmware(scn, compensated)
        server = QemuOnboardServer(scn, fw, echo=_say)
    except (CodegenError, ValueError) as exc:  # ScenarioError is a ValueError
        raise BadInput(str(exc)) from None
    except (ToolchainMissing, QemuError) as exc:
        raise RunFailure(str(exc)) from None
    _say(f"device: {server.path}")
    _say(f"scenario '{scn.name}': firmware {fw.elf} (flash {fw.flash_bytes} B, static RAM "
         f"{fw.ram_bytes} B), {fw.counts_per_rev} counts/rev, Cortex-M4 (QEMU mps2-an386), "
         f"the twin in lockstep on the pin link, paced to at most real time")
    why = " (auto: the FPU makes them cheap)" if sums == "auto" else ""
    _say(f"on board: {scn.name}'s controller, float32 {'compensated' if compensated else 'plain'}"
         f" observer sums{why}, at {scn.sensor.rate_hz:g} Hz, "
         + ("ideal torque source" if fw.torque else "PWM duty to the motor model"))
    def done() -> bool:
        return (
            once and server.run_started and not server.motor_on
            and (server.host_quiet(5.0) or (server.stop_seen and server.host_quiet(0.3))
                 or bool(server.device_faults) and server.host_quiet(1.0)))

    interrupted = serve_until(server, done, (QemuError,), "qemu", server.close)
    if server.run_started:
        _say(f"twin: {server.samples} samples served")
    if server.host_waits:
        _say(f"the twin waited for the host at {server.host_waits} samples (its heartbeat more "
             "than 50 ms of samples behind: the machine is busy)")
    if server.lags:
        warn_line(f"the simulation fell more than {LAG_S * 1e3:.0f} ms behind the wall clock "
                  f"at {server.lags} samples (worst {server.worst_lag * 1e3:.0f} ms; the machine "
                  "is busy): the run took longer than real time; the chip's clock (its samples) "
                  "is unaffected")
    finish(interrupted)
