"""The house: what the review of issue 31 tidied stays tidy.

The compiled kernels' disk cache is keyed on every physics file, sub-packages included
(the URDF arms moved into ``esoarm.plants.arms``).
"""

from __future__ import annotations

from pathlib import Path

import esoarm

PACKAGE = Path(esoarm.__file__).resolve().parent


def test_the_kernel_cache_is_keyed_on_the_arms_too() -> None:
    from esoarm.engines import batch

    files = {p.relative_to(PACKAGE).as_posix() for p in batch._physics_files()}
    for name in ("plants/arms/rigid_body.py", "plants/arms/compiled.py", "plants/arms/urdf.py",
                 "plants/lever_arm.py", "engines/loop.py", "kinds.py"):
        assert name in files
    every = {p.relative_to(PACKAGE).as_posix() for folder in batch._PHYSICS_DIRS
             for p in (PACKAGE / folder).rglob("*.py")}
    assert every <= files
