"""Writing the on-board firmware to an Arduino Uno through its bootloader, with avrdude.

:func:`flash` builds the scenario's on-board firmware (:mod:`esoarm.codegen.onboard`),
asks the port whether an Uno bootloader answers there (avrdude ``-c arduino -b 115200
-n``: it reads the chip's signature and writes nothing), writes the ``.hex`` (``-D -U
flash:w:FILE:i``, the bootloader erases page by page; avrdude verifies what it wrote), then
opens the port at the firmware's line rate and reads the scenario hash back from the
firmware's CHIP_INFO frame.

:class:`SimulatedUno` is an Uno for the tests: simavr's ATmega328P with the Uno's
bootloader (Debian's optiboot) behind a pseudo-terminal (``uno_bootloader.c``), so the
whole path -- avrdude, the STK500 protocol, the bootloader's SPM writes, the application's
start, the hash read back -- runs here without a board.  What it cannot cover: the USB-serial
chip, the DTR line (a pseudo-terminal has none: the auto-reset is emulated by the first
STK500 GET_SYNC), the real flash's timing and wear, fuses and lock bits.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from esoarm.hardware.hil.build import ToolchainMissing, _cache_dir

__all__ = ["BOOTLOADER_BAUD", "FlashReport", "NotABootloader", "SimulatedUno", "check_uno",
           "flash", "probe", "read_hash"]

#: The Uno's bootloader (optiboot) talks at 115200 baud.
BOOTLOADER_BAUD = 115200
#: Debian's arduino-core-avr copy of the Uno bootloader.
OPTIBOOT = Path("/usr/share/arduino/hardware/arduino/avr/bootloaders/optiboot/"
                "optiboot_atmega328.hex")


class NotABootloader(ValueError):
    """The port does not answer as an Uno bootloader (a bad --port: exit 2)."""


@dataclass(frozen=True)
class FlashReport:
    """What :func:`flash` did.

    Attributes
    ----------
    hex_path : Path
        The image written.
    flash_bytes : int
        Bytes avrdude wrote (and verified).
    signature : str
        The chip's signature as avrdude read it (``0x1e950f``: ATmega328P).
    hash_read : str
        The scenario hash (8 hex digits) the firmware reported after the write.
    hash_expected : str
        The scenario's.
    seconds : float
        Wall-clock time of probe, write and read-back.
    """

    hex_path: Path
    flash_bytes: int
    signature: str
    hash_read: str
    hash_expected: str
    seconds: float

    @property
    def ok(self) -> bool:
        """The firmware on the board is this scenario's."""
        return self.hash_read == self.hash_expected


def _avrdude() -> str:
    path = shutil.which("avrdude")
    if path is None:
        raise ToolchainMissing("avrdude not found: apt-get install avrdude")
    return path


def _avrdude_run(args: list[str], timeout: float) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run([_avrdude(), "-c", "arduino", "-p", "atmega328p", *args],
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(args, 124, "", f"no answer within {timeout:g} s")


def _last_error(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines()
             if ln.strip() and "Thank you" not in ln and "TIOCM" not in ln]
    bad = [ln for ln in lines if "error" in ln.lower() or "not in sync" in ln
           or "not respond" in ln]
    return (bad or lines or ["no output"])[-1]


def probe(port: str, baud: int = BOOTLOADER_BAUD, timeout: float = 15.0) -> str:
    """The chip signature an Uno bootloader on ``port`` reports; nothing is written.

    Raises
    ------
    NotABootloader
        No bootloader answered (avrdude's reason in the message).
    """
    if not Path(port).exists():
        raise NotABootloader(f"--port '{port}': no such device")
    res = _avrdude_run(["-P", port, "-b", str(baud), "-n"], timeout)
    sig = re.search(r"signature\s*=\s*(0x[0-9a-fA-F]+)", res.stderr)
    if res.returncode != 0 or sig is None:
        raise NotABootloader(f"--port '{port}' does not answer as an Uno bootloader at {baud} "
                             f"baud (avrdude: {_last_error(res.stderr)}); check the port, "
                             "and that the board is an Uno (optiboot)")
    return sig.group(1).lower()


def check_uno(port: str, baud: int = BOOTLOADER_BAUD) -> str:
    """:func:`probe`, and the signature must be the ATmega328P's (NotABootloader if not)."""
    signature = probe(port, baud)
    if signature != "0x1e950f":
        raise NotABootloader(f"--port '{port}': the chip's signature is {signature}, not an "
                             "ATmega328P's (0x1e950f): not an Uno")
    return signature


def read_hash(port: str, baud: int, timeout: float = 10.0) -> str:
    """The scenario hash (8 hex digits) the on-board firmware on ``port`` reports.

    Opening the port resets a real Uno (DTR): the bootloader waits about 1 s before the
    firmware starts, so HELLO is repeated until ``timeout``.
    """
    from esoarm.hardware.link import LinkError, SerialLink

    end = time.monotonic() + timeout
    last = "no answer"
    while time.monotonic() < end:
        try:
            link = SerialLink(port, baudrate=baud)
        except LinkError as exc:
            last = str(exc)
            time.sleep(0.5)
            continue
        try:
            link.handshake(timeout=1.0, attempts=2)
            return link.chip_info().scenario_hash
        except LinkError as exc:
            last = str(exc)
        finally:
            link.close()
    raise LinkError(f"the firmware on '{port}' did not report its scenario after the write "
                    f"({last})")


def flash(hex_path: Path, port: str, expected_hash: str, firmware_baud: int,
          baud: int = BOOTLOADER_BAUD, signature: str | None = None) -> FlashReport:
    """Write ``hex_path`` to the Uno on ``port`` and read the scenario hash back.

    Parameters
    ----------
    hex_path : Path
        Intel HEX image of the firmware.
    port : str
        The Uno's serial device.
    expected_hash : str
        The scenario's hash (8 hex digits are compared).
    firmware_baud : int
        Line rate of the firmware [bit/s] (for the read-back).
    baud : int
        The bootloader's line rate.
    signature : str, optional
        From an earlier :func:`probe` of the port (else it is probed here).

    Raises
    ------
    NotABootloader
        The port does not answer as an Uno bootloader (nothing written).
    RuntimeError
        avrdude failed while writing or verifying.
    """
    start = time.monotonic()
    signature = check_uno(port, baud) if signature is None else signature
    res = _avrdude_run(["-P", port, "-b", str(baud), "-D", "-U", f"flash:w:{hex_path}:i"],
                       timeout=300.0)
    written = re.search(r"(\d+) bytes of flash verified", res.stderr)
    if res.returncode != 0 or written is None:
        raise RuntimeError(f"avrdude could not write {hex_path.name}: "
                           f"{_last_error(res.stderr)}")
    got = read_hash(port, firmware_baud)
    return FlashReport(hex_path, int(written.group(1)), signature, got, expected_hash[:8],
                       time.monotonic() - start)


def _bootloader_hex() -> Path:
    """Debian's optiboot hex without its start-address record (simavr's reader has none)."""
    if not OPTIBOOT.is_file():
        raise ToolchainMissing(f"{OPTIBOOT} not found: apt-get install arduino-core-avr")
    out = _cache_dir() / "esoarm-optiboot_atmega328.hex"
    text = "".join(ln for ln in OPTIBOOT.read_text().splitlines(keepends=True)
                   if not ln.startswith(":04000003"))
    if not out.exists() or out.read_text() != text:
        out.write_text(text)
    return out


class SimulatedUno:
    """An Uno with its bootloader in simavr behind a pseudo-terminal (see the module).

    Use as a context manager; :attr:`port` is the device path to give avrdude and
    ``esoarm flash``.
    """

    def __init__(self, folder: Path | None = None) -> None:
        from esoarm.codegen.toolchain import build
        from esoarm.hardware.hil.build import _simavr_flags

        source = (resources.files("esoarm.hardware.hil") / "uno_bootloader.c").read_text()
        exe = build("gcc", {"uno_bootloader.c": source}, ["-O2", "-Wall", "-Wextra"],
                    "uno_bootloader", "esoarm-uno-bootloader", [*_simavr_flags(), "-lutil"])
        self._dir = folder or _cache_dir()
        self.port = str(self._dir / f"esoarm-uno-{id(self):x}")
        self._proc: subprocess.Popen[str] | None = subprocess.Popen(
            [str(exe), str(_bootloader_hex()), self.port], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)
        assert self._proc.stdout is not None
        line = self._proc.stdout.readline()
        if not line.startswith("device:"):
            err = self._proc.stderr.read() if self._proc.stderr else ""
            self.close()
            raise ToolchainMissing(f"the simulated Uno did not start: {err.strip()[:200]}")

    def close(self) -> None:
        """Stop the simulator (the device link goes away)."""
        if self._proc is not None:
            self._proc.terminate()
            try:
                self._proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
            self._proc = None

    def __enter__(self) -> SimulatedUno:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
