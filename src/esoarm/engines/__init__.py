"""Engines: run the sampled-data closed loop.

``simulation``   the readable reference engine (plain Python, one run)
``batch``        the compiled engine (numba, many runs in parallel), bit-identical to it
"""
