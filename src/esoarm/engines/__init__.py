"""Engines: run the sampled-data closed loop.

``loop``         the sample loop, written once (run as Python and compiled)
``simulation``   the readable reference engine (plain Python, one run)
``batch``        the compiled engine (numba, many runs in parallel), bit-identical to it
``fast``         the opt-in fast engine (a vectorized C kernel), agrees to round-off
``metrics``      the log layout and every metric, for every engine (no numba)
``diagnosis``    what left the range when a run diverges, and the likely causes

A URDF arm runs through the same ``loop`` (its plant kind is not compilable, so the reference
engine runs it, in worker processes for sweeps).
"""
