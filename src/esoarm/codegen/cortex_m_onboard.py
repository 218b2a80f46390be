"""On-board mode on a Cortex-M4: the generated controller in a firmware for QEMU's mps2-an386.

:func:`m4_onboard_firmware` generates the scenario's observer and controller for
``cortex-m4`` and links them with ``cortex_m/mps2_onboard.c``: the rig protocol of
the Uno firmware (``esoarm_protocol.h``: INFO with ``FLAG_ONBOARD``, CHIP_INFO,
CHIP_SAMPLE, HEARTBEAT, STOP, FAULT) on the board's UART1 and, on UART0, a
"pin link" in lockstep with the digital twin on the host (QEMU models no
encoder or motor pins): per sample the chip asks for the encoder count, steps
the controller and answers the drive torque and duty.  The host side is
:class:`esoarm.hardware.hil.qemu.QemuOnboardServer` (``esoarm hil SCENARIO
--onboard --target cortex-m4``) and ``esoarm run SCENARIO --onboard``.

Built with arm-none-eabi-gcc ``-O2 -mfpu=fpv4-sp-d16 -mfloat-abi=hard`` (the PIL
flags of :mod:`esoarm.codegen.cortex_m4`) and the PIL linker script.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from esoarm.codegen.avr import image_sizes
from esoarm.codegen.cortex_m4 import CFLAGS, CLOCK_HZ, ICOUNT_SHIFT, startup_files
from esoarm.codegen.generate import Generated, generate
from esoarm.codegen.toolchain import build
from esoarm.hardware.hil.build import ToolchainMissing, default_firmware_dir
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["M4Firmware", "m4_onboard_firmware"]


@dataclass(frozen=True)
class M4Firmware:
    """An on-board firmware image for the mps2-an386.

    Attributes
    ----------
    elf : Path
        The image (in esoarm's cache directory).
    gen : Generated
        The generated controller it carries.
    counts_per_rev : int
        Encoder counts per revolution it converts with.
    period_us : int
        Sample period [µs] it reports in INFO.
    torque : bool
        It drives an ideal torque source (no ``[motor]`` table: INFO has ``FLAG_TORQUE``).
    flash_bytes, ram_bytes : int
        Flash (text + data) and static RAM (data + bss) of the image.
    """

    elf: Path
    gen: Generated
    counts_per_rev: int
    period_us: int
    torque: bool
    flash_bytes: int
    ram_bytes: int


def _protocol_header() -> str:
    fw = default_firmware_dir()
    if fw is None:
        raise ToolchainMissing("the firmware sources (firmware/ of the esoarm checkout, with "
                               "esoarm_rig/esoarm_protocol.h) were not found")
    return (fw / "esoarm_rig" / "esoarm_protocol.h").read_text(encoding="utf-8")


def _chip(name: str, folder: str = "cortex_m") -> str:
    return (resources.files("esoarm.codegen") / folder / name).read_text(encoding="utf-8")


def m4_onboard_firmware(scn: Scenario, compensated: bool | None = None) -> M4Firmware:
    """Generate ``scn``'s controller for the Cortex-M4 and build the on-board firmware.

    Parameters
    ----------
    scn : Scenario
        A one-joint scenario whose ``sensor.resolution_deg`` divides 360° (the encoder's
        counts) and whose sample period is a whole number of µs.
    compensated : bool, optional
        Observer sums of the float32 code (default: compensated; the Cortex-M4's FPU
        makes them cheap: about 190 instructions a step).

    Returns
    -------
    M4Firmware

    Raises
    ------
    ScenarioError
        The encoder resolution or the rate does not fit a firmware.
    esoarm.codegen.CodegenError
        The scenario's kinds have no C.
    ToolchainMissing
        arm-none-eabi-gcc (or newlib) is not installed, or the build failed.
    """
    from esoarm.hardware.emulator import encoder_counts_per_rev
    from esoarm.plants.actuator import motor_of

    cpr = encoder_counts_per_rev(scn)
    period = 1e6 / scn.sensor.rate_hz
    period_us = round(period)
    if abs(period_us - period) > 1e-6 or period_us < 1:
        raise ScenarioError(f"sensor.rate_hz = {scn.sensor.rate_hz:g}: on board the sample "
                            "period must be a whole number of µs")
    motor = motor_of(scn)
    gen = generate(scn, "cortex-m4", "float32", compensated)
    torque = motor is None
    pwm_max = motor.pwm_max if motor is not None else 255
    flags = "ESO_FLAG_ONBOARD|ESO_FLAG_TORQUE" if torque else "ESO_FLAG_ONBOARD"
    defines = [f"-DSAMPLE_PERIOD_US={period_us}UL", f"-DCOUNTS_PER_REV={cpr}UL",
               f"-DPWM_MAX={pwm_max}", f"-DCLOCK_HZ={CLOCK_HZ}UL",
               f"-DICOUNT_SHIFT={ICOUNT_SHIFT}", f"-DONBOARD_FLAGS=({flags})",
               "-DONBOARD_SUMS=" + ("ESO_SUMS_COMPENSATED" if gen.compensated
                                    else "ESO_SUMS_PLAIN")]
    files = {**gen.files, "esoarm_protocol.h": _protocol_header(),
             "mps2_onboard.c": _chip("mps2_onboard.c"), **startup_files("m4.ld")}
    elf = build("arm-none-eabi-gcc", files, [*CFLAGS, *defines], "onboard.elf",
                "esoarm-onboard-m4", ["-lm"])
    flash, ram = image_sizes(elf, "arm-none-eabi-size")
    return M4Firmware(elf, gen, cpr, period_us, torque, flash, ram)
