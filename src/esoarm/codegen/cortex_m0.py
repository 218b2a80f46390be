"""The generated controller on an ARMv6-M core without FPU (Cortex-M0+ code) under QEMU.

``--target cortex-m0plus`` code (soft float: ``-mcpu=cortex-m0plus
-mfloat-abi=soft``, as on an RP2040) runs on QEMU's ``microbit`` machine: an
nRF51822, whose core is a Cortex-M0.  The M0 and the M0+ implement the same
instruction set (ARMv6-M, Thumb with a few Thumb-2 system instructions), so
the image built for the M0+ runs unchanged; the two cores differ in their
pipelines (M0: 3 stages, M0+: 2) and cycle timings, which QEMU does not model
anyway.  QEMU models no RP2040.

The PIL image is the generated source and a bare-metal shell
(``chip/m0_startup.c``, ``chip/m0.ld``: vector table at 0x0, 256 kB flash,
16 kB RAM, the nRF51 UART at 0x40002000) built with arm-none-eabi-gcc ``-O2``,
newlib-nano's libm and libgcc's software floating point.  Timing is the same
**instruction-count proxy** as :mod:`esoarm.codegen.cortex_m4`: with ``-icount
shift=N`` SysTick, clocked from the nRF51's 16 MHz processor clock, gives the
executed instructions of a step (n = ticks · 62.5 / 2^N, to within 62.5 / 2^N
instructions: N = 8, ±0.24, so the rounded count is exact).  Real cycles are
higher: on an M0+ loads, stores and taken branches take 2 cycles, and the
soft-float routines are mostly those.
"""

from __future__ import annotations

from pathlib import Path

from esoarm.codegen.cortex_m4 import CortexM4Chip, startup_files
from esoarm.codegen.generate import HEADER, SOURCE, Generated
from esoarm.codegen.toolchain import build

__all__ = ["CLOCK_HZ", "CortexM0PlusChip", "m0plus_image"]

#: The nRF51822's processor clock that QEMU's microbit models [Hz] (SysTick's clock).
CLOCK_HZ = 16_000_000
CFLAGS = ["-std=c99", "-mcpu=cortex-m0plus", "-mthumb", "-mfloat-abi=soft", "-O2",
          "-ffunction-sections", "-fdata-sections", "-Wall", "-Wextra", "-Werror",
          "-nostartfiles", "--specs=nano.specs", "-Tm0.ld", "-Wl,--gc-sections"]


def m0plus_image(gen: Generated) -> Path:
    """The PIL image (ELF) of ``gen`` for the Cortex-M0+ (arm-none-eabi-gcc ``-O2``, soft float).

    Parameters
    ----------
    gen : Generated
        The generated header and source, for target ``cortex-m0plus``; linked with the
        bare-metal shell (``m0_startup.c``, ``m0.ld``: 256 kB flash, 16 kB RAM) and libm.

    Returns
    -------
    pathlib.Path
        The built ELF (``pil.elf``) in the build cache (``esoarm-pil-m0plus``), reused while
        the sources and flags are unchanged.
    """
    return build("arm-none-eabi-gcc",
                 {HEADER: gen.header, SOURCE: gen.source,
                  **startup_files("cortex_m_pil.h", "m0_startup.c", "m0.ld")},
                 CFLAGS, "pil.elf", "esoarm-pil-m0plus", ["-lm"])


class CortexM0PlusChip(CortexM4Chip):
    """The generated step (Cortex-M0+ build) on QEMU's microbit (Cortex-M0), over its UART.

    Parameters and attributes as :class:`esoarm.codegen.cortex_m4.CortexM4Chip`;
    ``gen`` is generated for target ``cortex-m0plus``.
    """

    timing = ("instructions (QEMU -icount proxy on the microbit's ARMv6-M core; "
              "no cycle counter is modelled)")
    clock_hz = CLOCK_HZ
    target_name, machine, chip_name = "cortex-m0plus", "microbit", "Cortex-M0+ (microbit)"

    def _image(self, gen: Generated) -> Path:
        return m0plus_image(gen)
