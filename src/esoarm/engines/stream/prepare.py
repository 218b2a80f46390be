"""The compiled block of a streamed run, compiled once in a child process (first run only).

numba compiling the block (:mod:`esoarm.engines.stream.kernels`) is the largest
memory cost of a long ``simulate``: LLVM keeps every function it compiled on the
way, so a process that compiled the block peaked at 357-387 MB where a process
that loads it from numba's disk cache peaks at about 195 MB (``/usr/bin/time -v``,
test-1, 6·10⁵ samples; measured before this module).  A fresh process (one that
has not imported numba yet) therefore has the block compiled by a short-lived
child, ``python -m esoarm.engines.stream.compile_child``, which writes numba's cache and
exits; the parent, which has not imported numba meanwhile, then loads the block
from the cache.  The child compiles

* the dispatch of the run's kinds only (:func:`esoarm.kinds.compile_only`), not
  of every registered kind;
* with LLVM's default inlining threshold (225) instead of the batch kernels'
  (:data:`esoarm._jit.INLINE_THRESHOLD`, which the batch kernels need to
  vectorize over runs; one run's sample loop gains ~6 % CPU from it, measured).

The numbers are the same bits either way (inlining changes no arithmetic).  A
marker file in esoarm's cache directory (:func:`esoarm._cache.cache_dir`) keyed
on esoarm's sources, numba's version and the run's kinds says the child has run;
where anything fails the parent simply compiles in its own process, as before.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from esoarm.scenario import Scenario

__all__ = ["SELECTION_INLINE_THRESHOLD", "apart", "marker"]

#: LLVM inlining threshold the child compiles the block with (LLVM's default).
SELECTION_INLINE_THRESHOLD = 225

_PACKAGE = Path(__file__).resolve().parent.parent.parent


def _key(inp: Any) -> str:
    """Hash of what the cached block depends on: sources, numba, kinds, vector widths, cache
    place."""
    from importlib import metadata

    digest = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*.py")):
        st = path.stat()
        digest.update(f"{path.relative_to(_PACKAGE)}:{st.st_size}:{st.st_mtime_ns};".encode())
    try:
        numba_version = metadata.version("numba")
    except metadata.PackageNotFoundError:  # pragma: no cover - no numba: never compiled
        numba_version = "none"
    from esoarm.engines.packing import VECTOR_WIDTH

    kinds = ".".join(m.KIND for m in inp.kinds)
    # the block is compiled for vectors as tuples, or as arrays where one is wider than its
    # tuple (esoarm.engines.stream.kernels.runner): two signatures
    wide = any(len(vec) > w for vec, w in zip(
        (inp.plant.vector, inp.observer.vector, inp.controller.vector, inp.actuator),
        VECTOR_WIDTH, strict=True))
    digest.update(f"{sys.version}|{numba_version}|{kinds}|{wide}|"
                  f"{os.environ.get('NUMBA_CACHE_DIR', '')}".encode())
    return digest.hexdigest()[:24]


def marker(inp: Any) -> Path:
    """The file that says the block of these inputs' kinds is in numba's cache.

    Parameters
    ----------
    inp : RunInputs
        The run's designs (:func:`esoarm.engines.simulation.prepare_designs`).

    Returns
    -------
    Path
        ``cache_dir()/stream/<key>`` (it may not exist).
    """
    from esoarm._cache import cache_dir

    return cache_dir() / "stream" / _key(inp)


def apart(scn: Scenario, inp: Any) -> bool:
    """Have the compiled block of ``scn`` compiled by a child process, if it pays.

    Only in a process that has not imported numba yet (a fresh ``esoarm simulate``),
    for the package's own kinds, and once (:func:`marker`).

    Parameters
    ----------
    scn : Scenario
        The run's scenario.
    inp : RunInputs
        Its designs.

    Returns
    -------
    bool
        True: this process should load the block for the run's kinds only
        (:func:`esoarm.kinds.compile_only`), from the cache the child wrote.
        False: compile as before (numba already loaded here, kinds added at run
        time, or the child failed).

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C while the child compiled (the child is stopped).
    """
    from esoarm import kinds as _kinds

    if "numba" in sys.modules or _kinds.registry_stamp() or not _kinds.covers(inp.kinds):
        return False
    try:
        done = marker(inp)
        if done.exists():
            return True
        short = scn.with_overrides({"duration": 2.0 / scn.sensor.rate_hz})
        proc = subprocess.run([sys.executable, "-m", "esoarm.engines.stream.compile_child"],
                              input=short.to_toml(), text=True, capture_output=True,
                              timeout=1800, check=False)
        if proc.returncode != 0:
            return False
        done.parent.mkdir(parents=True, exist_ok=True)
        done.write_text(proc.stdout)
        return True
    except (OSError, ValueError, subprocess.SubprocessError):
        return False
