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
from typing import Any, TypeVar

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


#: numba's options for the compiled copies of the physics: called only from kernels.
_LINK_ONLY: dict[str, Any] = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}


def _register(func: Callable[..., object], compiled: Callable[..., object] | None,
              array_arg: int | None = None) -> None:
    try:
        from numba import types
        from numba.extending import overload, register_jitable
    except ImportError:  # pragma: no cover - the reference engine needs no numba
        return
    if compiled is None:
        # returns func itself: the interpreter keeps calling it (numba's compiled copy needs
        # no wrapper for the interpreter; see _link_only_physics)
        register_jitable(**_LINK_ONLY)(func)
    else:
        noop = _noop_like(func) if array_arg is not None else None

        @functools.wraps(func)  # the typer takes func's signature, as numba requires
        def typer(*args: object) -> Callable[..., object]:
            if noop is not None and isinstance(args[array_arg], types.BaseTuple):  # type: ignore[index]
                return noop
            return compiled

        overload(func, jit_options=_LINK_ONLY)(typer)  # type: ignore[arg-type]


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
    :mod:`esoarm.plants.rigid_body` compiled (the same numbers to rounding;
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


def register_all() -> None:
    """Register every function marked :func:`jitable` with numba (idempotent).

    Compiled engines call this once, after importing the physics they use and
    before their kernels are compiled or loaded from the cache.
    """
    global _registered
    if not _registered:
        _tolerate_cache_write_errors()
        _inline_physics()
        _defer_blas_probe()
        _link_only_physics()
    _registered = True
    while _pending:
        _register(*_pending.pop(0))


#: LLVM's inlining threshold for the kernels (its default is 225).
INLINE_THRESHOLD = 20000


def _inline_physics() -> None:
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
    llvm.set_option("esoarm", f"-inline-threshold={INLINE_THRESHOLD}")


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


def _link_only_physics() -> None:
    """Compile the physics functions for linking into the kernels only: no machine code.

    numba compiles every function a kernel calls as a library of its own, links
    it into its callers and, as for a kernel, turns it into machine code for the
    interpreter to call (each library with everything it calls linked in, so
    the sample loop's functions were translated again at every level of calls:
    4.6 s of the 22 s of CPU a first compile of :func:`esoarm.engines.batch._run`
    takes, load 3).  The interpreter never calls these compiled copies: a
    :func:`jitable` function stays the plain Python function there, and numba
    compiles them without a wrapper for the interpreter (:data:`_LINK_ONLY`).
    So a library without that wrapper is optimized and linked into its callers
    as before, but not handed to the code generator unless its address is
    asked for; the kernels' machine code, and so every number, is unchanged.
    (An ``njit`` of a jitable function, called from the interpreter, has the
    wrapper and is compiled as usual.)  Falls back to numba's own behaviour if
    its (internal) layout is not the expected one.
    """
    try:
        from numba.core import codegen, cpu
    except ImportError:  # pragma: no cover - the reference engine needs no numba
        return
    context = getattr(cpu, "CPUContext", None)
    library = getattr(codegen, "CPUCodeLibrary", None)
    jit_library = getattr(codegen, "JITCodeLibrary", None)
    get_executable = getattr(context, "get_executable", None)
    finalize_module = getattr(library, "_finalize_final_module", None)
    get_pointer = getattr(jit_library, "get_pointer_to_function", None)
    if (get_executable is None or finalize_module is None or get_pointer is None
            or not hasattr(jit_library, "_finalize_specific")
            or not all(hasattr(library, n) for n in ("_finalize_dynamic_globals",
                                                     "_verify_declare_only_symbols"))
            or getattr(get_executable, "_esoarm_link_only", False)):
        return  # pragma: no cover - numba's layout changed, or already done
    try:
        from numba import _dynfunc  # type: ignore[attr-defined]
    except ImportError:  # pragma: no cover
        return

    def executable(self, lib, fndesc, env):  # type: ignore[no-untyped-def]
        try:  # compiled without a wrapper for the interpreter (_LINK_ONLY)?
            lib._final_module.get_function(fndesc.llvm_cpython_wrapper_name)
        except (NameError, AttributeError):
            pass
        else:  # the interpreter may call it (an njit of a jitable function): as numba does
            return get_executable(self, lib, fndesc, env)
        lib._esoarm_link_only = True
        # the interpreter cannot call it (no wrapper): no address needed
        return _dynfunc.make_function(fndesc.lookup_module(), fndesc.qualname.split(".")[-1],
                                      f"link-only {fndesc.qualname!r}", 0, env, (lib,))

    def finalize(self):  # type: ignore[no-untyped-def]
        if not getattr(self, "_esoarm_link_only", False):
            return finalize_module(self)
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True
        self._esoarm_link_only = "pending"  # machine code made if an address is asked for
        return None

    def pointer(self, name):  # type: ignore[no-untyped-def]
        self._ensure_finalized()
        if getattr(self, "_esoarm_link_only", False) == "pending":
            self._esoarm_link_only = "built"
            self._codegen._add_module(self._final_module)
            self._finalize_specific()
        return get_pointer(self, name)

    executable._esoarm_link_only = True  # type: ignore[attr-defined]
    context.get_executable = executable  # type: ignore[union-attr]
    library._finalize_final_module = finalize  # type: ignore[union-attr]
    jit_library.get_pointer_to_function = pointer  # type: ignore[union-attr]


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
