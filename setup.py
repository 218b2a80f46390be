"""Packaging hook: the installed package carries the firmware sources.

``esoarm hil`` builds the Uno firmware (``firmware/``) with the AVR toolchain
when it is first run; an installed esoarm (a wheel, ``pip install .``) has no
checkout to build from, so the sources are copied into the package, as
``esoarm/hardware/hil/firmware/`` (build output left out). Everything else is
in pyproject.toml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

FIRMWARE = Path(__file__).resolve().parent / "firmware"


class BuildWithFirmware(build_py):
    """``build_py`` that also copies ``firmware/`` (without ``build/``) into the package."""

    def run(self) -> None:
        super().run()
        if not FIRMWARE.is_dir():  # an sdist made without it: nothing to carry
            return
        target = Path(self.build_lib) / "esoarm" / "hardware" / "hil" / "firmware"
        if target.exists():
            shutil.rmtree(target)
        shutil.copytree(FIRMWARE, target, ignore=shutil.ignore_patterns("build", "*.o", "*.elf",
                                                                         "*.hex"))


setup(cmdclass={"build_py": BuildWithFirmware})
