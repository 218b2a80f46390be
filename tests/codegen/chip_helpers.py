"""Helpers shared by the processor-in-the-loop tests (``test_pil.py``, ``test_m0plus.py``):
the ``esoarm pil --json`` call and QEMU's exec trace of ``esoarm_step``."""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

#: The inputs (y, θd, θ̇d, θ̈d) the traced steps get: in and out of fal's zone of the
#: nonlinear observer, so the steps have different lengths.
TRACE_INPUTS = (0.0, 0.01, 0.6, -0.6, 0.6, 0.002, -0.3, 0.0)


def missing(*tools: tuple[str, bool | str | None]) -> list[str]:
    """The names of the tools that are not installed; raises in CI (``ESOARM_REQUIRE_HIL``).

    Parameters
    ----------
    *tools : (str, object)
        A tool's name (with its Debian package) and whether it is there (truthy).

    Returns
    -------
    list of str
        The names of the missing tools.
    """
    gone = [name for name, ok in tools if not ok]
    if gone and os.environ.get("ESOARM_REQUIRE_HIL"):  # CI: the PIL tests must run
        raise RuntimeError(f"ESOARM_REQUIRE_HIL is set but not installed: {', '.join(gone)}")
    return gone


#: avr-gcc, arduino-mk, simavr's headers and gcc: the firmware on the simulated Uno.
AVR_TOOLS = (("avr-gcc (gcc-avr)", shutil.which("avr-gcc")),
             ("arduino-mk", Path("/usr/share/arduino/Arduino.mk").exists()),
             ("libsimavr-dev", Path("/usr/include/simavr/sim_avr.h").exists()),
             ("gcc", shutil.which("gcc")))

#: arm-none-eabi-gcc and QEMU, the Cortex-M tools.
ARM_TOOLS = (("arm-none-eabi-gcc (gcc-arm-none-eabi)", shutil.which("arm-none-eabi-gcc")),
             ("qemu-system-arm", shutil.which("qemu-system-arm")))


def on_chip(*tools: tuple[str, bool | str | None]):  # type: ignore[no-untyped-def]
    """A decorator marking a test slow and hil, skipped with the reason where one of
    ``tools`` (as for :func:`missing`, which raises in CI) is not installed.

    Parameters
    ----------
    *tools : (str, object)
        A tool's name (with its Debian package) and whether it is there (truthy).

    Returns
    -------
    callable
        The decorator.
    """
    import pytest

    gone = missing(*tools)

    def mark(test):  # type: ignore[no-untyped-def]
        for m in (pytest.mark.slow, pytest.mark.hil,
                  pytest.mark.skipif(bool(gone), reason=f"not installed: {', '.join(gone)}")):
            test = m(test)
        return test
    return mark


def load_benchmark(name: str):  # type: ignore[no-untyped-def]
    """The module ``benchmarks/NAME.py``, loaded as its script would be (the benchmarks'
    folder on the path, for their shared modules such as ``doc_block``)."""
    import importlib.util

    folder = Path(__file__).resolve().parents[2] / "benchmarks"
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pil(*args: str, code: int = 0) -> dict:
    """``esoarm pil ARGS --json``: its JSON, the exit status checked."""
    res = subprocess.run([sys.executable, "-m", "esoarm", "pil", *args, "--json"],
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == code, res.stderr
    return json.loads(res.stdout)


def traced_steps(elf: Path, machine: str, clock_hz: float,
                 log: Path, shift: int = 8) -> tuple[list[int], list[int]]:
    """Run ``elf`` on QEMU's ``machine`` one instruction per translation block with its exec
    trace, one step per :data:`TRACE_INPUTS`: (the chip's instruction proxy of each step,
    the instructions QEMU traced from ``esoarm_step``'s entry to the return into the shell).

    Parameters
    ----------
    elf : Path
        The PIL image (its shell answers each 16-byte input with 16 bytes, the SysTick
        ticks last).
    machine : str
        QEMU's ``-M`` machine (``mps2-an386``, ``microbit``).
    clock_hz : float
        The chip's clock [Hz]: a tick is 1e9/clock_hz ns, an instruction 2^shift ns.
    log : Path
        Where QEMU writes its trace.
    shift : int
        QEMU's ``-icount`` shift.

    Returns
    -------
    (list of int, list of int)
        The proxy and the traced count of each step.
    """
    from esoarm.codegen.avr import symbols
    from esoarm.codegen.toolchain import tool

    entry = symbols(elf, "arm-none-eabi-nm")["esoarm_step"] & ~1
    dis = subprocess.run([tool("arm-none-eabi-objdump"), "-d", str(elf)], capture_output=True,
                         text=True, check=True).stdout.splitlines()
    calls = [i for i, line in enumerate(dis) if re.search(r"\sbl\s.*<esoarm_step>", line)]
    assert len(calls) == 1
    back = int(dis[calls[0] + 1].split(":")[0], 16)  # the instruction after the call
    qemu = tool("qemu-system-arm")
    version = re.search(r"version (\d+)\.(\d+)", subprocess.run(
        [qemu, "--version"], capture_output=True, text=True, check=True).stdout)
    assert version is not None
    # one instruction per translation block: -singlestep until QEMU 8.1 renamed it
    one_insn = (["-accel", "tcg,one-insn-per-tb=on"]
                if (int(version[1]), int(version[2])) >= (8, 1) else ["-singlestep"])
    proc = subprocess.Popen(
        [qemu, "-M", machine, "-display", "none", "-monitor", "none",
         "-serial", "stdio", "-icount", f"shift={shift}", *one_insn, "-d", "exec,nochain",
         "-D", str(log), "-kernel", str(elf)], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert proc.stdin is not None and proc.stdout is not None
    proxy = []
    try:
        for y in TRACE_INPUTS:
            proc.stdin.write(struct.pack("<4f", y, 0.0, 0.0, 0.0))  # y, (θd, θ̇d, θ̈d)
            proc.stdin.flush()
            (ticks,) = struct.unpack("<I", proc.stdout.read(16)[12:])
            proxy.append(round(ticks * (1e9 / clock_hz) / 2 ** shift))  # as the chip
    finally:
        proc.kill()
        proc.wait()
    pcs = [int(m.group(1), 16) for m in
           re.finditer(r"Trace \d+: 0x[0-9a-f]+ \[[0-9a-f]+/([0-9a-f]+)/", log.read_text())]
    traced, i = [], 0
    while i < len(pcs):
        if pcs[i] == entry:
            j = pcs.index(back, i)
            traced.append(j - i)
            i = j
        i += 1
    assert len(traced) == len(proxy)
    return proxy, traced
