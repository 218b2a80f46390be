"""Mark plain physics functions as callable from compiled (numba) kernels.

The physics of esoarm -- the rig derivative, the ESO step and the FLC law -- is
written once, as plain Python functions of floats and small NumPy arrays.  The
reference simulator and the real-time loop call them as ordinary Python; the
fast batch engine calls the very same functions from inside ``numba.njit``
kernels.  :func:`jitable` is numba's ``register_jitable``: in the interpreter it
returns the function unchanged, and it teaches numba to compile the function
when a jitted kernel calls it.  Without numba installed it is the identity, so
the reference engine works without a compiler.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable[..., object])

try:  # pragma: no cover - exercised by whichever branch the environment has
    from numba.extending import register_jitable as _register_jitable
except ImportError:  # pragma: no cover
    _register_jitable = None


def jitable(func: F) -> F:
    """Return ``func`` unchanged, registered for use inside numba kernels."""
    if _register_jitable is None:
        return func
    return _register_jitable(func)  # type: ignore[no-any-return]
