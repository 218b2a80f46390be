"""Engines: run the sampled-data closed loop.

``loop``         the sample loop, written once (run as Python and compiled)
``simulation``   the readable reference engine (plain Python, one run)
``batch``        the compiled engine (numba, many runs in parallel), bit-identical to it
``fast``         the opt-in fast engine (a vectorized C kernel), agrees to round-off
``metrics``      the log layout and every metric, for every engine (no numba)
``arm_loop``     the same loop on a URDF arm (vectors per joint, Pinocchio)
"""
