"""Limits that protect the machine (light: importable by ``--help`` without pydantic)."""

#: Longest run a scenario may ask for, in samples (duration · rate_hz).
MAX_SAMPLES = 100_000_000
#: Most runs (grid points × seeds) a sweep may have unless the caller raises it
#: (``max_runs=``, ``--max-runs``): the result table alone takes about 80 bytes a
#: run, and every grid point is checked before the first run (~0.3 ms each).
MAX_RUNS = 1_000_000
#: Most points ``esoarm analyze --vary`` analyzes unless raised (``--max-points``): each
#: point is a linearization, a sampling and a frequency sweep, about 0.1-0.3 s.
MAX_ANALYZE_POINTS = 1_000
#: ``esoarm simulate`` runs a run of more samples than this block by block in constant memory
#: (:mod:`esoarm.engines.stream`; the reference engine keeps ~200 bytes a sample), compiled
#: where the scenario's kinds allow it.
STREAM_SAMPLES = 500_000
#: Largest gear play ``rig.backlash_deg`` [deg]: a worn toy gear train has a few degrees;
#: beyond this the arm is not driven through a gear but swings free over most of a turn.
MAX_BACKLASH_DEG = 20.0
#: ... and runs it compiled when it has more samples than this: the first time, compiling
#: the block takes ~22 s of CPU (measured), 500,000 samples of plain-Python blocks ~35 s
#: (~70 µs a sample); once it is cached, the compiled block takes ~6 µs a sample.
COMPILED_STREAM_SAMPLES = STREAM_SAMPLES
