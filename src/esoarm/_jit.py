"""Mark plain physics functions as callable from compiled (numba) kernels.

The physics of esoarm -- the rig derivative, the ESO step and the FLC law -- is
written once, as plain Python functions of floats and small NumPy arrays.  The
reference simulator and the real-time loop call them as ordinary Python; the
fast batch engine calls the very same functions from inside ``numba.njit``
kernels.  :func:`jitable` is numba's ``register_jitable``: in the interpreter it
returns the function unchanged, and it teaches numba to compile the function
when a jitted kernel calls it.  Without numba installed it is the identity, so
the reference engine works without a compiler.

Registration is deferred: :func:`jitable` only records the function, and
:func:`register_all` (called by the compiled engines when they are imported)
hands every recorded function to numba.  Importing the physics therefore does
not import numba (~0.15 s), which keeps the command line and the reference
engine quick to start.
"""

from __future__ import annotations

import functools
import importlib.util
import pickle
import sys
from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable[..., object])

_pending: list[tuple[Callable[..., object], Callable[..., object] | None, int | None]] = []
_registered = False
#: Every function marked :func:`jitable` or :func:`jitable_as` (by id).
_marked: set[int] = set()


def _noop_like(func: Callable[..., object]) -> Callable[..., object]:
    """A function with ``func``'s parameter names that does nothing (numba checks the names)."""
    import inspect

    signature = inspect.signature(func)
    scope: dict[str, object] = {}
    exec(f"def noop({', '.join(signature.parameters)}):\n    return None\n",  # noqa: S102
         scope)  # (func's parameter names only)
    noop = scope["noop"]
    noop.__signature__ = signature  # type: ignore[attr-defined]  # numba compares annotations
    return noop  # type: ignore[return-value]


def _register(func: Callable[..., object], compiled: Callable[..., object] | None,
              array_arg: int | None = None) -> None:
    try:
        from numba import types
        from numba.extending import overload, register_jitable
    except ImportError:  # pragma: no cover - the reference engine needs no numba
        return
    if compiled is None:
        register_jitable(func)  # returns func itself: the interpreter keeps calling it
    else:
        noop = _noop_like(func) if array_arg is not None else None

        @functools.wraps(func)  # the typer takes func's signature, as numba requires
        def typer(*args: object) -> Callable[..., object]:
            if noop is not None and isinstance(args[array_arg], types.BaseTuple):  # type: ignore[index]
                return noop
            return compiled

        overload(func)(typer)


def jitable(func: F) -> F:
    """Return ``func`` unchanged, recorded for use inside numba kernels."""
    _marked.add(id(func))
    if _registered:
        _register(func, None)
    else:
        _pending.append((func, None, None))
    return func


def jitable_as(compiled: Callable[..., object], *,
               array_arg: int | None = None) -> Callable[[F], F]:
    """Like :func:`jitable`, but kernels compile ``compiled`` in place of the function.

    For a function written twice, once for the interpreter and once for the
    compiler, with the same floating-point operations in the same order (so the
    same bits; the tests compare the two): e.g. a power of two by
    :func:`math.ldexp` in Python and by exact products in a vector loop.
    Or, for a URDF arm, Pinocchio in the interpreter (the reference) and
    :mod:`esoarm.plants.arms.rigid_body` compiled (the same numbers to rounding;
    the tests state the tolerance).  ``compiled`` must itself be :func:`jitable`.

    ``array_arg``: the position of a parameter vector that ``compiled`` needs as
    an array (it slices it).  Where a kernel passes a tuple there -- the
    kernels of the short vectors (:data:`esoarm.engines.packing.VECTOR_WIDTH`),
    which never carry this kind's vector -- a function that does nothing is
    compiled instead, so those kernels compile without it.
    """

    def mark(func: F) -> F:
        _marked.add(id(func))
        if _registered:
            _register(func, compiled, array_arg)
        else:
            _pending.append((func, compiled, array_arg))
        return func

    return mark


def is_jitable(func: object) -> bool:
    """``func`` was marked :func:`jitable` (or :func:`jitable_as`): kernels can call it."""
    return id(func) in _marked


def register_all(inline_threshold: int | None = None) -> None:
    """Register every function marked :func:`jitable` with numba (idempotent).

    Compiled engines call this once, after importing the physics they use and
    before their kernels are compiled or loaded from the cache.

    Parameters
    ----------
    inline_threshold : int, optional
        LLVM's inlining threshold for this process (default :data:`INLINE_THRESHOLD`);
        only the first call sets it (a process that compiles one streamed block
        only, :mod:`esoarm.engines.stream.prepare`, gives LLVM's default).
    """
    global _registered
    if not _registered:
        _tolerate_cache_write_errors()
        _inline_physics(INLINE_THRESHOLD if inline_threshold is None else inline_threshold)
        _defer_blas_probe()
    _registered = True
    while _pending:
        _register(*_pending.pop(0))


#: LLVM's inlining threshold for the kernels (its default is 225).
INLINE_THRESHOLD = 20000


def _inline_physics(threshold: int = INLINE_THRESHOLD) -> None:
    """Let LLVM inline the whole physics into the kernels' loops.

    The step functions are small, but one RK4 step of the lever arm inlines
    four accelerations, each with a tanh, an exp and a cos from
    :mod:`esoarm.plants.elementary`; above LLVM's default threshold the
    loop over a block of runs keeps calls and cannot be vectorized (measured:
    ~110 ns per run and RK4 step with the default, ~45 ns inlined, AVX-512).
    Inlining changes no arithmetic, so the numbers stay the same bits.  The
    option is process-wide for llvmlite; it only affects how much LLVM inlines.
    """
    try:
        import llvmlite.binding as llvm
    except ImportError:  # pragma: no cover
        return
    llvm.set_option("esoarm", f"-inline-threshold={threshold}")


def _defer_blas_probe() -> None:
    """Keep numba from importing :mod:`scipy.linalg` when it loads a cached kernel.

    The first compile or cache load of a process imports numba's array
    implementations, whose import probes for BLAS by importing
    ``scipy.linalg.cython_blas``, i.e. all of :mod:`scipy.linalg` (0.3 s, a
    quarter of a warm sweep's start-up; measured with ``python -X importtime``).
    The probe only sets a flag (whether ``np.cov``-like inner products may call
    ``np.dot``); every linear-algebra function numba compiles imports SciPy
    itself when it is lowered.  Until its first call, numba's probe is replaced
    by one that asks only whether SciPy is installed (without importing it)
    and then puts numba's own back, so the flag is the same and nothing else
    changes.  The kernels here use no BLAS.
    """
    if "numba.np.arraymath" in sys.modules:
        return  # the probe has run already
    try:
        from numba.np import linalg
    except ImportError:  # pragma: no cover - the reference engine needs no numba
        return
    probe = getattr(linalg, "ensure_blas", None)
    if probe is None:  # pragma: no cover - numba's layout changed: leave it alone
        return

    def ensure_blas() -> None:
        linalg.ensure_blas = probe  # once only: numba's own from now on
        if importlib.util.find_spec("scipy") is None:
            raise ImportError("scipy 0.16+ is required for linear algebra")

    linalg.ensure_blas = ensure_blas


def _tolerate_cache_write_errors() -> None:
    """A compiled kernel that cannot be saved to numba's disk cache still runs.

    numba writes its cache beside the sources (or in NUMBA_CACHE_DIR); a full
    disk, a file-size limit or a read-only tree would otherwise end the run
    with an OSError that has nothing to do with the user's outputs; and a
    kernel whose compiled form holds a function value numba cannot pickle (a
    record of first-class dispatch functions compiled after the arm kernels,
    "cannot pickle '_dynfunc._Closure'") would end it with a TypeError.  The
    kernel is then simply compiled again next time; nothing is written, since
    numba pickles an entry before it opens the cache file.
    """
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover
        return
    cache = getattr(caching, "Cache", None)
    original = getattr(cache, "save_overload", None)
    if original is None or getattr(original, "_esoarm_tolerant", False):
        return  # pragma: no cover - numba's layout changed, or already done

    def save_overload(self, sig, data):  # type: ignore[no-untyped-def]
        try:
            original(self, sig, data)
        except (OSError, TypeError, pickle.PicklingError):
            pass  # not cached; compiled again on the next start

    save_overload._esoarm_tolerant = True  # type: ignore[attr-defined]
    cache.save_overload = save_overload  # type: ignore[union-attr]
