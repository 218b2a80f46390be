"""Building what the hardware-in-the-loop run needs: the harness and the firmware.

- The harness (``harness.c``, shipped with the package) is compiled with the
  host's gcc against libsimavr into esoarm's per-user cache directory
  (:func:`esoarm._cache.cache_dir`: ``$ESOARM_CACHE_DIR``, ``~/.cache/esoarm``,
  else one in the temporary directory), named by a hash of its source, so it is
  rebuilt only when the source changes.
- The firmware is built by ``make -C firmware`` (arduino-mk and the Debian AVR
  toolchain).  Its sources are those of the checkout this package runs from,
  else the copy an installed package carries (``esoarm/hardware/hil/firmware``,
  put there by ``setup.py``).  A checkout's firmware is built into its
  ``firmware/build/`` when that can be written; otherwise (an installed
  package, a read-only checkout) into the cache directory, in a folder named by
  a hash of the sources.

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

__all__ = ["ToolchainMissing", "default_build_root", "default_firmware_dir", "firmware_elf",
           "harness_library", "packaged_firmware_dir"]

#: Debian packages for the whole chain (the CI installs these).
PACKAGES = "gcc-avr avr-libc arduino-core-avr arduino-mk simavr libsimavr-dev libelf-dev"


class ToolchainMissing(RuntimeError):
    """A compiler, library or header is not installed; the message names the package."""


def _cache_dir() -> Path:
    from esoarm._cache import cache_dir

    return cache_dir()


def _unwritable(path: Path, exc: OSError) -> ToolchainMissing:
    return ToolchainMissing(f"cannot write {path} ({exc.strerror or exc}): set ESOARM_CACHE_DIR "
                            "to a writable directory")


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
    src = out.with_suffix(".c")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        src.write_bytes(text)
    except OSError as exc:
        raise _unwritable(out.parent, exc) from None
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


def _is_firmware(folder: Path) -> bool:
    return (folder / "Makefile").is_file() and (folder / "esoarm_rig" / "esoarm_rig.ino").is_file()


def packaged_firmware_dir() -> Path | None:
    """The firmware sources an installed package carries (None in a source checkout)."""
    cand = Path(__file__).resolve().parent / "firmware"
    return cand if _is_firmware(cand) else None


def default_firmware_dir() -> Path | None:
    """The firmware sources: the checkout's ``firmware/``, else the installed package's copy.

    Returns
    -------
    Path or None
        ``firmware/`` of the source checkout this package runs from, else the
        copy carried by an installed package, else ``firmware/`` of the current
        directory; None if there is none of these.
    """
    here = Path(__file__).resolve()
    for parent in here.parents:
        if _is_firmware(parent / "firmware"):
            return parent / "firmware"
    packaged = packaged_firmware_dir()
    if packaged is not None:
        return packaged
    cwd = Path.cwd() / "firmware"
    if _is_firmware(cwd):
        return cwd
    return None


def _sources_digest(fw: Path) -> str:
    """A hash of the firmware sources (build output left out)."""
    h = hashlib.sha256()
    for path in sorted(p for p in fw.rglob("*") if p.is_file() and "build" not in
                       p.relative_to(fw).parts):
        h.update(str(path.relative_to(fw)).encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:16]


def default_build_root(fw: Path) -> Path:
    """Where the variants of the firmware in ``fw`` are built by default.

    ``fw/build`` for a checkout whose ``build`` folder can be written; else
    (the installed package's copy, a read-only checkout)
    ``<cache>/firmware-<hash of the sources>``.
    """
    from esoarm._cache import writable

    if fw != packaged_firmware_dir() and writable(fw / "build"):
        return fw / "build"
    return _cache_dir() / f"firmware-{_sources_digest(fw)}"


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
        Where the variant is built (default
        ``default_build_root(firmware_dir)/uno-DRIVER[-settings]``).
    quiet : bool
        Print make's size line when False.

    Returns
    -------
    Path
        The ELF file built (or found up to date).

    Raises
    ------
    ToolchainMissing
        A tool is missing, the sources are not found, the build fails or its
        folder cannot be written (one line naming what to do).
    """
    fw = firmware_dir or default_firmware_dir()
    if fw is None:
        raise ToolchainMissing(
            "the firmware sources were not found (neither firmware/ of an esoarm checkout nor "
            "the copy an installed esoarm carries): reinstall esoarm or pass --elf FILE")
    if shutil.which("make") is None:
        raise ToolchainMissing("make not found: apt-get install make")
    settings = dict(settings or {})
    tag = "".join(f"-{k.lower()}{v}" for k, v in sorted(settings.items()))
    out_dir = build_dir or default_build_root(fw) / f"uno-{driver}{tag}"
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _unwritable(out_dir, exc) from None
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
