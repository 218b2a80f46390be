"""The child that :mod:`esoarm.engines.stream.prepare` starts: compile one run's block.

``python -m esoarm.engines.stream.compile_child`` reads a scenario (TOML) on stdin,
compiles the streamed block of its kinds into numba's disk cache, runs it once and
prints the kinds' tags.  It sits above the streaming engine, which it runs; the
engine only names it (as a module to start), so the imports point down.
"""

from __future__ import annotations

import sys

from esoarm.engines.stream.prepare import SELECTION_INLINE_THRESHOLD

__all__ = ["main"]


def main() -> int:
    """Child: read a scenario (TOML) on stdin, compile its block, run it, print its kinds.

    Returns
    -------
    int
        Exit status (0: the block compiled, ran and is cached).
    """
    import tomllib

    from esoarm import _jit
    from esoarm.scenario.schema import build

    _jit.register_all(inline_threshold=SELECTION_INLINE_THRESHOLD)
    scn = build(tomllib.loads(sys.stdin.read()), {}, source="stdin")

    from esoarm import kinds as _kinds
    from esoarm.engines.simulation import prepare_designs
    from esoarm.engines.stream import stream

    inp = prepare_designs(scn)
    _kinds.compile_only([inp.kinds])
    stream(scn, compiled=True)
    print(".".join(m.KIND for m in inp.kinds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
