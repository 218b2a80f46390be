"""Engines: run the sampled-data closed loop.

``simulation``   the readable reference engine (plain Python, one run)
``batch``        the compiled engine (numba, many runs in parallel), bit-identical to it
``fast``         the opt-in fast engine (a vectorized C kernel), agrees to round-off
``metrics``      the metric columns every engine reports (no numba)
``arm_loop``     the same loop on a URDF arm (vectors per joint, Pinocchio)
"""
