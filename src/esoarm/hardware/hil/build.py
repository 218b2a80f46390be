"""Building what the hardware-in-the-loop run needs: the harness and the firmware.

- The harness (``harness.c``, shipped with the package) is compiled with the
  host's gcc against libsimavr into a per-user cache directory
  (``$ESOARM_CACHE`` or ``~/.cache/esoarm``), named by a hash of its source, so
  it is rebuilt only when the source changes.
- The firmware is built by ``make -C firmware`` (arduino-mk and the Debian AVR
  toolchain) into ``firmware/build/`` of the source checkout.

Both raise :class:`ToolchainMissing` with one line naming the Debian package to
install when a tool is absent.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from importlib import resources
from pathlib import Path

__all__ = ["ToolchainMissing", "default_firmware_dir", "firmware_elf", "harness_library"]

#: Debian packages for the whole chain (the CI installs these).
PACKAGES = "gcc-avr avr-libc arduino-core-avr arduino-mk simavr libsimavr-dev libelf-dev"


class ToolchainMissing(RuntimeError):
    """A compiler, library or header is not installed; the message names the package."""


def _cache_dir() -> Path:
    root = os.environ.get("ESOARM_CACHE")
    if root:
        return Path(root)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "esoarm"


def _simavr_flags() -> list[str]:
    """Compiler and linker flags for libsimavr (pkg-config, else the Debian paths)."""
    if shutil.which("pkg-config"):
        res = subprocess.run(["pkg-config", "--cflags", "--libs", "simavr"],
                             capture_output=True, text=True)
        if res.returncode == 0 and res.stdout.strip():
            return res.stdout.split() + ["-lelf"]
    if not Path("/usr/include/simavr/sim_avr.h").exists():
        raise ToolchainMissing(
            "libsimavr headers not found: apt-get install libsimavr-dev libelf-dev")
    return ["-I/usr/include/simavr", "-lsimavr", "-lelf"]


def harness_library() -> Path:
    """Path of the compiled harness (built on first use, cached by source hash)."""
    source = resources.files("esoarm.hardware.hil") / "harness.c"
    text = source.read_bytes()
    digest = hashlib.sha256(text).hexdigest()[:16]
    out = _cache_dir() / f"esoarm-hil-{digest}.so"
    if out.exists():
        return out
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        raise ToolchainMissing("no C compiler to build the simavr harness: apt-get install gcc")
    flags = _simavr_flags()
    out.parent.mkdir(parents=True, exist_ok=True)
    src = out.with_suffix(".c")
    src.write_bytes(text)
    tmp = out.with_name(out.name + f".{os.getpid()}.tmp")
    res = subprocess.run([gcc, "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC",
                          str(src), "-o", str(tmp), *flags], capture_output=True, text=True)
    if res.returncode != 0:
        first = next((ln for ln in res.stderr.splitlines() if "error" in ln),
                     res.stderr.strip().splitlines()[-1] if res.stderr.strip() else "")
        if "simavr" in res.stderr and ("No such file" in res.stderr or "cannot find" in res.stderr):
            raise ToolchainMissing(
                "libsimavr not found: apt-get install libsimavr-dev libelf-dev") from None
        if "-lelf" in res.stderr or "libelf" in res.stderr:
            raise ToolchainMissing("libelf not found: apt-get install libelf-dev") from None
        raise ToolchainMissing(f"building the simavr harness failed: {first}")
    os.replace(tmp, out)
    return out


def default_firmware_dir() -> Path | None:
    """``firmware/`` of the source checkout this package runs from (None if installed)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / "firmware" / "Makefile"
        if cand.exists() and (parent / "firmware" / "esoarm_rig" / "esoarm_rig.ino").exists():
            return parent / "firmware"
    cwd = Path.cwd() / "firmware"
    if (cwd / "Makefile").exists():
        return cwd
    return None


def firmware_elf(driver: str = "l298n", firmware_dir: Path | None = None,
                 settings: dict[str, int] | None = None, build_dir: Path | None = None,
                 quiet: bool = True) -> Path:
    """Build the firmware (``make -C firmware DRIVER``) if needed; return its ELF.

    Parameters
    ----------
    driver : {"l298n", "bts7960"}
        Motor driver variant.
    firmware_dir : Path, optional
        The ``firmware/`` folder (default: the source checkout's).
    settings : dict, optional
        Build settings (``SAMPLE_PERIOD_US``, ``ENCODER_PPR``, ``BAUD``); a
        non-default build goes to its own folder.
    build_dir : Path, optional
        Where the variant is built (default ``firmware/build/uno-DRIVER[-settings]``).
    """
    fw = firmware_dir or default_firmware_dir()
    if fw is None:
        raise ToolchainMissing(
            "the firmware sources (firmware/ of the esoarm checkout) were not found: "
            "run from the checkout or pass --elf FILE")
    if shutil.which("make") is None:
        raise ToolchainMissing("make not found: apt-get install make")
    settings = dict(settings or {})
    tag = "".join(f"-{k.lower()}{v}" for k, v in sorted(settings.items()))
    out_dir = build_dir or fw / "build" / f"uno-{driver}{tag}"
    cmd = ["make", "-s", "--no-print-directory", "-C", str(fw), driver,
           f"VARIANT_DIR={out_dir}", *(f"{k}={v}" for k, v in sorted(settings.items()))]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        msg = next((ln for ln in lines if ln.startswith("firmware:")), None)
        if msg is None:
            msg = "firmware build failed: " + (lines[-1] if lines else f"exit {res.returncode}")
        raise ToolchainMissing(msg.removeprefix("firmware: "))
    if not quiet:
        print(res.stdout.strip())
    return out_dir / "esoarm_rig.elf"
