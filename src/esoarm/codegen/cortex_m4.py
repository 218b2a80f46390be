"""The generated controller on a Cortex-M4 with FPU under QEMU (``mps2-an386``), in lockstep.

The PIL image is the generated source and a bare-metal shell
(``chip/m4_startup.c``, ``chip/m4.ld``: vector table at 0x0, FPU enabled in the
reset handler, CMSDK UART0 at 0x40004000) built with arm-none-eabi-gcc ``-O2
-mfpu=fpv4-sp-d16 -mfloat-abi=hard`` and newlib's libm.  QEMU runs it with the
UART on its standard input and output; per sample the host writes y and the
reference (θd, θ̇d, θ̈d) and reads
(u, drive, SysTick ticks).

Timing is an **instruction-count proxy**, not cycles: QEMU models no cycle
counter (the DWT reads 0).  With ``-icount shift=N`` every instruction takes
2^N ns of virtual time and SysTick counts the 25 MHz processor clock, so the
ticks of a step give its executed instructions: n instructions last n·2^N ns,
i.e. n·2^N / 40 ticks of 40 ns, so n = ticks · 40 / 2^N, to within 40 / 2^N
instructions (N = 8: ±0.16, so the rounded count is exact).  Checked in the
tests: the same count for N = 8 and 10, and the count of QEMU's own instruction
trace (``-singlestep -d exec,nochain``) of the step plus the 2 instructions of
the call and the SysTick read.  A Cortex-M4 retires most
instructions in one cycle, but loads, branches, divisions (14 cycles) and
double-precision library calls take more: real cycles are higher.
"""

from __future__ import annotations

import os
import select
import struct
import subprocess
from importlib import resources
from pathlib import Path

from esoarm.codegen.avr import image_sizes
from esoarm.codegen.generate import HEADER, SOURCE, Generated
from esoarm.codegen.toolchain import build, tool

__all__ = ["CLOCK_HZ", "CortexM4Chip", "m4_image", "startup_files"]

#: The mps2-an386 processor clock QEMU models [Hz] (SysTick's clock).
CLOCK_HZ = 25_000_000
ICOUNT_SHIFT = 8
CFLAGS = ["-std=c99", "-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard",
          "-O2", "-ffunction-sections", "-fdata-sections", "-Wall", "-Wextra", "-Werror",
          "-nostartfiles", "--specs=nano.specs", "-Tm4.ld", "-Wl,--gc-sections"]


def _chip_file(name: str) -> str:
    return (resources.files("esoarm.codegen") / "chip" / name).read_text(encoding="utf-8")


def startup_files(*names: str) -> dict[str, str]:
    """The bare-metal start shared by the Cortex-M images (``chip/cortex_m_startup.h``: reset
    handler, vector table, SysTick), with the chip files ``names``, by file name.

    Parameters
    ----------
    *names : str
        The chip files (``esoarm/codegen/chip/``) to add, e.g. ``"m4_startup.c"``.

    Returns
    -------
    dict of str to str
        File name -> its text, the shared header first.
    """
    return {name: _chip_file(name) for name in ("cortex_m_startup.h", *names)}


def m4_image(gen: Generated) -> Path:
    """The PIL image (ELF) of ``gen`` for the Cortex-M4 (arm-none-eabi-gcc ``-O2``)."""
    return build("arm-none-eabi-gcc",
                 {HEADER: gen.header, SOURCE: gen.source,
                  **startup_files("cortex_m_pil.h", "m4_startup.c", "m4.ld")},
                 CFLAGS, "pil.elf", "esoarm-pil-m4", ["-lm"])


class CortexM4Chip:
    """The generated step on QEMU's Cortex-M4 (mps2-an386), stepped over its UART.

    Parameters
    ----------
    gen : Generated
        Sources for target ``cortex-m4``.
    timeout : float
        Seconds to wait for an answer before the chip is declared hung.
    icount_shift : int
        QEMU's ``-icount shift``: one instruction = 2^shift ns of virtual time.

    Attributes
    ----------
    cycles : list of int
        Executed instructions of each step (the instruction-count proxy).
    flash_bytes, ram_bytes : int
        The PIL image: flash (text + data) and static RAM (data + bss), stack not included.
    """

    timing = "instructions (QEMU -icount proxy; no cycle counter is modelled)"
    clock_hz = CLOCK_HZ
    #: ``gen.target`` this chip runs, QEMU's machine, and a name for messages.
    target_name, machine, chip_name = "cortex-m4", "mps2-an386", "Cortex-M4"

    def __init__(self, gen: Generated, timeout: float = 10.0,
                 icount_shift: int = ICOUNT_SHIFT) -> None:
        if gen.target != self.target_name:
            raise ValueError(f"{type(self).__name__} needs code generated for "
                             f"--target {self.target_name}")
        self.target, self.precision = self.target_name, gen.precision
        self._fmt = "<f" if gen.precision == "float32" else "<d"
        self._size = struct.calcsize(self._fmt)
        self.elf = self._image(gen)
        self.flash_bytes, self.ram_bytes = image_sizes(self.elf, "arm-none-eabi-size")
        self.timeout = timeout
        self.shift = icount_shift
        self.cycles: list[int] = []
        self._proc: subprocess.Popen[bytes] | None = subprocess.Popen(
            [tool("qemu-system-arm"), "-M", self.machine, "-display", "none", "-monitor",
             "none", "-serial", "stdio", "-icount", f"shift={icount_shift}", "-kernel",
             str(self.elf)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL)

    def _image(self, gen: Generated) -> Path:
        return m4_image(gen)

    def _read(self, n: int) -> bytes:
        assert self._proc is not None and self._proc.stdout is not None
        fd = self._proc.stdout.fileno()
        buf = b""
        while len(buf) < n:
            ready, _, _ = select.select([fd], [], [], self.timeout)
            if not ready:
                raise RuntimeError(f"the {self.chip_name} did not answer within "
                                   f"{self.timeout:g} s")
            chunk = os.read(fd, n - len(buf))
            if not chunk:
                raise RuntimeError("QEMU exited")
            buf += chunk
        return buf

    def step(self, y: float, ref: tuple[float, float, float] = (0.0, 0.0, 0.0)
             ) -> tuple[float, float, float]:
        """One sample: y_k [rad] and (θd, θ̇d, θ̈d) -> (u_k [N·m], drive [N·m], duty)."""
        assert self._proc is not None and self._proc.stdin is not None
        self._proc.stdin.write(struct.pack(self._fmt[0] + 4 * self._fmt[1], y, *ref))
        self._proc.stdin.flush()
        raw = self._read(3 * self._size + 4)
        u, drive, duty = struct.unpack(self._fmt[0] + 3 * self._fmt[1], raw[:3 * self._size])
        (ticks,) = struct.unpack("<I", raw[3 * self._size:])
        self.cycles.append(round(ticks * (1e9 / self.clock_hz) / 2 ** self.shift))
        return u, drive, duty

    def close(self) -> None:
        """Stop QEMU."""
        if self._proc is not None:
            self._proc.kill()
            self._proc.wait()
            self._proc = None
