"""The generated controller on simavr's ATmega328P at 16 MHz, stepped in lockstep.

The PIL image is the generated source and a shell (``chip/avr_pil.c``) built
with avr-gcc ``-Os`` and avr-libc's libm.  The harness (``chip/pil_simavr.c``,
built against libsimavr like the hil harness) runs it until the shell writes
GPIOR0 (data address 0x3E): between the writes 2 and 3 the step runs, and the
difference of ``avr->cycle`` at the two writes is the step's cycle count
(simavr counts the AVR's cycles per instruction; the two ``out`` instructions
add 1 cycle).  The measured angle and the reference are written into the shell's ``pil_in`` and the
command read from ``pil_out`` directly in SRAM, addresses from ``avr-nm``.
"""

from __future__ import annotations

import ctypes
import struct
import subprocess
from importlib import resources
from pathlib import Path

from esoarm.codegen.generate import HEADER, SOURCE, Generated
from esoarm.codegen.toolchain import build, tool
from esoarm.hardware.hil.build import ToolchainMissing, _simavr_flags

__all__ = ["F_CPU", "AvrChip", "avr_image", "image_sizes"]

#: The Uno's clock [Hz].
F_CPU = 16_000_000
CFLAGS = ["-std=gnu99", "-mmcu=atmega328p", "-Os", f"-DF_CPU={F_CPU}UL", "-Wall", "-Wextra",
          "-Werror"]


def _chip_file(name: str) -> str:
    return (resources.files("esoarm.codegen") / "chip" / name).read_text(encoding="utf-8")


def avr_image(gen: Generated) -> Path:
    """The PIL image (ELF) of ``gen`` for the ATmega328P, built with avr-gcc ``-Os``."""
    return build("avr-gcc", {HEADER: gen.header, SOURCE: gen.source,
                             "avr_pil.c": _chip_file("avr_pil.c")},
                 CFLAGS, "pil.elf", "esoarm-pil-avr", ["-lm"])


def image_sizes(elf: Path, size_tool: str) -> tuple[int, int]:
    """(flash, static RAM) [bytes] of an ELF: text + data, data + bss (``size``)."""
    res = subprocess.run([tool(size_tool), str(elf)], capture_output=True, text=True,
                         check=True)
    text, data, bss = (int(v) for v in res.stdout.splitlines()[1].split()[:3])
    return text + data, data + bss


def symbols(elf: Path, nm_tool: str) -> dict[str, int]:
    """Addresses of the ELF's symbols (``nm``)."""
    res = subprocess.run([tool(nm_tool), str(elf)], capture_output=True, text=True, check=True)
    out = {}
    for line in res.stdout.splitlines():
        parts = line.split()
        if len(parts) == 3:
            out[parts[2]] = int(parts[0], 16)
    return out


def _harness() -> ctypes.CDLL:
    path = build("gcc", {"pil_simavr.c": _chip_file("pil_simavr.c")},
                 ["-O2", "-Wall", "-Wextra", "-shared", "-fPIC"], "pil_simavr.so",
                 "esoarm-pil-simavr", _simavr_flags())
    lib = ctypes.CDLL(str(path))
    lib.pil_open.argtypes = [ctypes.c_char_p, ctypes.c_uint32]
    lib.pil_open.restype = ctypes.c_void_p
    lib.pil_wait.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint64]
    lib.pil_wait.restype = ctypes.c_int
    lib.pil_mark.argtypes = [ctypes.c_void_p, ctypes.c_int]
    lib.pil_mark.restype = ctypes.c_uint64
    lib.pil_data.argtypes = [ctypes.c_void_p]
    lib.pil_data.restype = ctypes.POINTER(ctypes.c_uint8)
    lib.pil_close.argtypes = [ctypes.c_void_p]
    return lib


class AvrChip:
    """The generated step on simavr's ATmega328P.

    Parameters
    ----------
    gen : Generated
        Sources for target ``avr`` (float32).
    limit_cycles : int
        A step that has not ended after this many cycles is a fault.

    Attributes
    ----------
    cycles : list of int
        Cycles of each step (simavr's count between the GPIOR0 writes).
    flash_bytes, ram_bytes : int
        The PIL image: flash (text + data) and static RAM (data + bss), stack not included.
    """

    timing = "cycles (simavr, ATmega328P at 16 MHz)"
    clock_hz = F_CPU

    def __init__(self, gen: Generated, limit_cycles: int = 10_000_000) -> None:
        if gen.target != "avr":
            raise ValueError("AvrChip needs code generated for --target avr")
        self.target, self.precision = "avr", gen.precision
        self.elf = avr_image(gen)
        self.flash_bytes, self.ram_bytes = image_sizes(self.elf, "avr-size")
        syms = symbols(self.elf, "avr-nm")
        self._y = syms["pil_in"] - 0x800000
        self._out = syms["pil_out"] - 0x800000
        self._lib = _harness()
        self._h = self._lib.pil_open(str(self.elf).encode(), F_CPU)
        if not self._h:
            raise ToolchainMissing(f"simavr could not load {self.elf}")
        self._data = self._lib.pil_data(self._h)
        self.limit = limit_cycles
        self.cycles: list[int] = []
        self._wait(1)

    def _wait(self, value: int) -> None:
        rc = self._lib.pil_wait(self._h, value, self.limit)
        if rc != 0:
            raise RuntimeError("the AVR " + ("crashed" if rc == -1 else
                                             f"did not finish a step in {self.limit} cycles"))

    def step(self, y: float, ref: tuple[float, float, float] = (0.0, 0.0, 0.0)
             ) -> tuple[float, float, float]:
        """One sample: y_k [rad] and (θd, θ̇d, θ̈d) -> (u_k [N·m], drive [N·m], duty)."""
        raw = struct.pack("<4f", y, *ref)
        for i, b in enumerate(raw):
            self._data[self._y + i] = b
        self._wait(2)
        self._wait(3)
        self.cycles.append(int(self._lib.pil_mark(self._h, 3) - self._lib.pil_mark(self._h, 2)))
        self._wait(1)
        out = bytes(self._data[self._out + i] for i in range(16))
        u, drive, duty, _ = struct.unpack("<4f", out)
        return u, drive, duty

    def close(self) -> None:
        """Free the simulated MCU."""
        if self._h:
            self._lib.pil_close(self._h)
            self._h = None
