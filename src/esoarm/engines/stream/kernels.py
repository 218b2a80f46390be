"""The compiled block of :mod:`esoarm.engines.stream` (imports numba; loaded on first use).

:func:`esoarm.engines.stream.block.stream_block` compiled with the registry's dispatch
functions (:func:`esoarm.engines.batch._records`, vectors as tuples or arrays:
:class:`esoarm.engines.batch.VectorsAs`), cached on disk and keyed on
the physics sources like the batch kernels.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from esoarm import kinds as _kinds
from esoarm.engines import batch as _batch
from esoarm.engines.batch import ARRAYS, TUPLES, _records
from esoarm.engines.packing import VECTOR_WIDTH, _stack
from esoarm.engines.stream.block import stream_block

_batch.cover_with_physics_stamp(__file__)

__all__ = ["runner"]

#: The block's body inlined into :func:`_block` by numba (not compiled apart and linked
#: again): one LLVM module of the whole block instead of two (less memory the first time).
_body = njit(inline="always", error_model="numpy")(stream_block)


@njit(cache=True, nogil=True, error_model="numpy")
def _block(how, log, x, noise, refs, k0, off, m, y, u, drive, applied, duty, sat, acc, v, z, zhat,
           c, hist, n, fpar, ipar, b0, pp, op, cp, ap):  # pragma: no cover - compiled
    sg, d, s = _records(how, n, fpar, ipar, b0, pp, op, cp, ap)
    return _body(log, x, noise, refs, k0, off, m, y, u, drive, applied, duty, sat, acc, v, z,
                 zhat, c, hist, sg, d, s)


def _drop_compiled() -> None:
    """After the dispatch changed (:func:`esoarm.kinds.compile_only`): compile or load the
    block again with the new dispatch (as :func:`esoarm.engines.batch._drop_compiled_kernels`)."""
    _block._reset_overloads()  # type: ignore[attr-defined]  # numba internal, as in batch
    _block.enable_caching()


_kinds.on_dispatch_change(_drop_compiled)


def runner(inp: Any) -> Callable[..., int]:
    """The compiled block for a run's inputs (:func:`.simulation.prepare_designs`).

    Parameters
    ----------
    inp : RunInputs
        The run's designs and timing.

    Returns
    -------
    callable
        ``runner(log, x, noise, refs, k0, off, m, *work, hist)`` -> rows (as
        :func:`~esoarm.engines.stream.stream_block`).
    """
    if not _kinds.covers(inp.kinds):
        _kinds.compile_only(None)
    fpar = np.array([inp.sigma, inp.q, inp.h, inp.ts])
    nj = inp.plant.n_joints
    ipar = np.array([0, inp.nsub, inp.delay, 0, nj, inp.observer.n_state,
                     inp.controller.n_state], dtype=np.int64)
    vectors = [_stack([np.asarray(vec, dtype=float)], w)[0] for vec, w in
               zip((inp.plant.vector, inp.observer.vector, inp.controller.vector, inp.actuator),
                   VECTOR_WIDTH, strict=True)]
    wide = any(len(vec) > w for vec, w in zip(vectors, VECTOR_WIDTH, strict=True))
    how = ARRAYS if wide else TUPLES
    b0 = np.asarray(inp.plant.b0, dtype=float)
    n = 0  # Sampling.n: not used by the sample functions

    def run(*args: Any) -> int:
        return int(_block(how, *args, n, fpar, ipar, b0, *vectors))  # type: ignore[call-arg]

    return run
