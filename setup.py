"""Packaging hook: the installed package carries the firmware sources.

``esoarm hil`` builds the Uno firmware (``firmware/``) with the AVR toolchain
when it is first run; an installed esoarm (a wheel, ``pip install .``) has no
checkout to build from, so the sources are copied into the package, as
``esoarm/hardware/hil/firmware/`` (build output left out).

One optional C extension, ``esoarm.plants._elementary``: tanh, cos and e^-x of
:mod:`esoarm.plants.elementary` for the interpreter (the reference engine spends
most of its time in them), the same bits as the Python forms. It is built where a
C compiler and Python's headers are present; elsewhere the install goes on without
it and the interpreter runs the Python forms (same numbers, slower). Everything
else is in pyproject.toml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import Extension, setup
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


#: Exact IEEE arithmetic in source order: no FMA contraction, no -ffast-math (the
#: module refuses to compile under it), so the C gives the Python forms' bits.
ELEMENTARY = Extension(
    "esoarm.plants._elementary",
    sources=["src/esoarm/plants/_elementary.c"],
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"],
    optional=True,
)

setup(cmdclass={"build_py": BuildWithFirmware}, ext_modules=[ELEMENTARY])
