"""Compiling generated C: the host's gcc, avr-gcc, arm-none-eabi-gcc; a cache by content hash.

Every build goes to a per-user cache folder (``$ESOARM_CACHE`` or
``~/.cache/esoarm``, as the hil harness) named by a hash of its sources and
flags, so a repeated PIL run does not recompile.  A missing tool raises
:class:`esoarm.hardware.hil.build.ToolchainMissing` naming the Debian package.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from esoarm.hardware.hil.build import ToolchainMissing, _cache_dir

__all__ = ["ToolchainMissing", "build", "tool"]

#: Debian package of each tool (the CI installs these).
PACKAGES = {"gcc": "gcc", "avr-gcc": "gcc-avr avr-libc", "avr-size": "binutils-avr",
            "avr-nm": "binutils-avr", "arm-none-eabi-gcc":
            "gcc-arm-none-eabi libnewlib-arm-none-eabi",
            "arm-none-eabi-size": "binutils-arm-none-eabi", "arm-none-eabi-nm":
            "binutils-arm-none-eabi", "qemu-system-arm": "qemu-system-arm"}


def tool(name: str) -> str:
    """Path of the program ``name``; :class:`ToolchainMissing` naming its package if absent."""
    path = shutil.which(name)
    if path is None:
        raise ToolchainMissing(f"{name} not found: apt-get install {PACKAGES.get(name, name)}")
    return path


def build(compiler: str, files: dict[str, str], flags: Sequence[str], output: str,
          tag: str, libs: Sequence[str] = ()) -> Path:
    """Compile ``files`` (name -> text) with ``compiler`` and ``flags`` into the cache.

    Parameters
    ----------
    compiler : str
        Program name (``gcc``, ``avr-gcc``, ``arm-none-eabi-gcc``).
    files : dict
        Source files by name; the ``.c`` ones are compiled, all are written.
    flags : sequence of str
        Compiler and linker flags, given before the sources.
    output : str
        Output file name (``controller.so``, ``pil.elf``).
    tag : str
        A prefix of the cache folder's name.
    libs : sequence of str
        Libraries, given after the sources (``-lm``).

    Returns
    -------
    Path
        The built file (reused when the same sources and flags were built before).
    """
    cc = tool(compiler)
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + files[name].encode() + b"\0")
    digest.update(" ".join([compiler, *flags, "|", *libs]).encode())
    folder = _cache_dir() / f"{tag}-{digest.hexdigest()[:16]}"
    out = folder / output
    if out.exists():
        return out
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")
    sources = [str(folder / n) for n in sorted(files) if n.endswith((".c", ".s", ".S"))]
    tmp = folder / f"{output}.{os.getpid()}.tmp"
    res = subprocess.run([cc, *flags, *sources, *libs, "-o", str(tmp)],
                         capture_output=True, text=True, cwd=folder)
    if res.returncode != 0:
        lines = [ln for ln in res.stderr.splitlines() if "error" in ln] or \
            res.stderr.strip().splitlines() or [f"exit {res.returncode}"]
        raise ToolchainMissing(f"{compiler} failed on the generated C: {lines[0]}")
    os.replace(tmp, out)
    return out
