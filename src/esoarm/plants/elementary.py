"""tanh, cos and exp(−x) in plain float arithmetic, the same bits in every engine.

The twin's friction needs tanh (and exp for the Stribeck term), its gravity
torque cos.  libm's versions are branchy scalar code: a compiled loop that
advances a block of runs together cannot turn them into vector instructions,
and a vector library (SVML, libmvec) gives other last bits than libm, which
would break the bit-for-bit agreement between the reference engine and the
compiled one.  The functions here are written only with +, −, ×, ÷, ``abs``,
``copysign`` and comparisons (conditional expressions, which compile to
selects), so

* Python evaluates them to exactly the bits a compiled kernel does (IEEE
  double arithmetic in the same order; numba does not contract a·b + c into an
  FMA unless asked to), and
* LLVM vectorizes them across the runs of a block.

Method (the classical one): a rounded multiple of a constant is taken off the
argument (Cody-Waite reduction: the constant split in parts so that the
products are exact), a truncated Taylor series is summed on the reduced
argument by Horner's rule, and the result is rebuilt.  Round to the nearest
integer is done by adding and subtracting 1.5·2⁵² (exact for |v| < 2⁵¹,
ties to even); powers of two are built by exact multiplications.

Accuracy against 200-bit references (``tests/plants/test_elementary.py`` checks the
bounds below on random and special arguments):

========  ===================  =====================================================
function  domain               error
========  ===================  =====================================================
tanh      all doubles          ≤ 3 ulp (libm ≤ 1 ulp); ±0, ±inf, NaN as libm
cos       |x| ≤ 1e5            ≤ 2.5 ulp; beyond, the reduction loses bits (the loop
                               ends a run as diverged at |θ| ≥ 1e6 anyway)
exp_neg   x ≥ 0                ≤ 2 ulp down to e^−708; 0 beyond (no subnormals)
========  ===================  =====================================================
"""

from __future__ import annotations

import math
from collections.abc import Callable

from esoarm._jit import jitable, jitable_as

__all__ = ["cos", "exp_neg", "tanh"]

#: 1.5·2⁵²: (v + SHIFT) − SHIFT is v rounded to the nearest integer (|v| < 2⁵¹).
SHIFT = 6755399441055744.0
INV_LN2 = 1.4426950408889634  # 1/ln 2
# ln 2 = LN2_HI + LN2_LO, LN2_HI with 32 significant bits (k·LN2_HI exact for |k| < 2²¹)
LN2_HI = 0.6931471803691238
LN2_LO = 1.9082149292705877e-10
TWO_OVER_PI = 0.6366197723675814  # 2/π
# π/2 = PIO2_1 + PIO2_2 + PIO2_3 (+ 1e-37), the first two with 33 significant bits
PIO2_1 = 1.5707963267341256
PIO2_2 = 6.077100506303966e-11
PIO2_3 = 2.0222662487959506e-21
# powers of two for _pow2 (module constants: a compiled kernel sees literals)
_P512, _P256, _P128, _P64, _P32 = 2.0**512, 2.0**256, 2.0**128, 2.0**64, 2.0**32


@jitable
def _round(v: float) -> float:
    """v rounded to the nearest integer, ties to even (|v| < 2⁵¹; NaN stays NaN)."""
    return (v + SHIFT) - SHIFT


@jitable
def _expm1_series(r: float) -> float:
    """e^r − 1 for |r| ≤ ln 2 / 2: the Taylor series to r¹⁴ (truncation < 1e-18 relative)."""
    p = 1.0 / 87178291200.0
    p = p * r + 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    return r + (r * r) * p


@jitable
def _pow2(k: float) -> float:
    """2^k for an integer-valued 0 ≤ k ≤ 1023, by exact products (no bit tricks)."""
    s = 1.0
    s = s * (_P512 if k >= 512.0 else 1.0)
    k = k - (512.0 if k >= 512.0 else 0.0)
    s = s * (_P256 if k >= 256.0 else 1.0)
    k = k - (256.0 if k >= 256.0 else 0.0)
    s = s * (_P128 if k >= 128.0 else 1.0)
    k = k - (128.0 if k >= 128.0 else 0.0)
    s = s * (_P64 if k >= 64.0 else 1.0)
    k = k - (64.0 if k >= 64.0 else 0.0)
    s = s * (_P32 if k >= 32.0 else 1.0)
    k = k - (32.0 if k >= 32.0 else 0.0)
    s = s * (65536.0 if k >= 16.0 else 1.0)
    k = k - (16.0 if k >= 16.0 else 0.0)
    s = s * (256.0 if k >= 8.0 else 1.0)
    k = k - (8.0 if k >= 8.0 else 0.0)
    s = s * (16.0 if k >= 4.0 else 1.0)
    k = k - (4.0 if k >= 4.0 else 0.0)
    s = s * (4.0 if k >= 2.0 else 1.0)
    k = k - (2.0 if k >= 2.0 else 0.0)
    return s * (2.0 if k >= 1.0 else 1.0)


@jitable
def _tanh_vec(x: float) -> float:
    """Hyperbolic tangent: e/(e + 2) with e = e^{2|x|} − 1, the sign of x (|x| > 20: ±1)."""
    a = abs(x)
    a = 20.0 if a > 20.0 else a  # tanh(20) is 1 to 17 digits; NaN passes (the test is false)
    y = a + a
    k = _round(y * INV_LN2)
    r = (y - k * LN2_HI) - k * LN2_LO  # |r| ≤ ln 2 / 2
    s = _pow2(k)
    em = s * _expm1_series(r) + (s - 1.0)  # e^y − 1 = 2^k (e^r − 1) + 2^k − 1
    return math.copysign(em / (em + 2.0), x)


@jitable
def _exp_neg_vec(x: float) -> float:
    """e^{−x} for x ≥ 0; 0 for x > 708 (where e^{−x} is below the normal doubles)."""
    y = 709.0 if x > 709.0 else x
    k = _round(y * INV_LN2)
    r = (k * LN2_HI - y) + k * LN2_LO  # e^{−y} = e^r / 2^k, |r| ≤ ln 2 / 2
    v = (1.0 + _expm1_series(r)) / _pow2(k)
    return 0.0 if x > 708.0 else v


@jitable
def _cos_series(r2: float) -> float:
    """cos r for |r| ≤ π/4 from r² (Taylor to r¹⁶, truncation < 3e-18)."""
    p = 1.0 / 20922789888000.0
    p = p * r2 - 1.0 / 87178291200.0
    p = p * r2 + 1.0 / 479001600.0
    p = p * r2 - 1.0 / 3628800.0
    p = p * r2 + 1.0 / 40320.0
    p = p * r2 - 1.0 / 720.0
    p = p * r2 + 1.0 / 24.0
    p = p * r2 - 0.5
    return 1.0 + r2 * p


@jitable
def _sin_series(r: float, r2: float) -> float:
    """sin r for |r| ≤ π/4 (Taylor to r¹⁷, truncation < 1e-19)."""
    p = 1.0 / 355687428096000.0
    p = p * r2 - 1.0 / 1307674368000.0
    p = p * r2 + 1.0 / 6227020800.0
    p = p * r2 - 1.0 / 39916800.0
    p = p * r2 + 1.0 / 362880.0
    p = p * r2 - 1.0 / 5040.0
    p = p * r2 + 1.0 / 120.0
    p = p * r2 - 1.0 / 6.0
    return r + (r * r2) * p


@jitable
def _cos_vec(x: float) -> float:
    """Cosine: x = n·π/2 + r, |r| ≤ π/4, then ±cos r or ±sin r by n mod 4."""
    n = _round(x * TWO_OVER_PI)
    r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3
    r2 = r * r
    c = _cos_series(r2)
    s = _sin_series(r, r2)
    q = n * 0.25
    f = q - _round(q)  # n mod 4 = 0, 1, 2, 3  <->  f = 0, 0.25, ±0.5, −0.25
    quarter = abs(f) == 0.25
    negate = f == 0.25 or abs(f) == 0.5
    v = s if quarter else c
    return -v if negate else v


# ---------------------------------------------------------------------------
# The interpreter's forms.  Compiled kernels use the forms above (jitable_as); the
# interpreter runs these, which take the same floating-point operations in the same
# order on the arguments they handle (so the same bits; tests/plants/test_elementary.py
# compares the two) and hand everything else (NaN, ±inf, huge arguments) to the forms
# above.  The differences: 2^k from a table or math.ldexp instead of ten exact
# products, n mod 4 by an integer, and only the series that is needed -- about twice as
# fast in CPython.  Where the C extension esoarm.plants._elementary was built (setup.py,
# with a C compiler), the interpreter calls it instead: the forms above in C, the same
# bits again, ten times quicker than these.

#: 2^k for the k that tanh meets (0 ≤ k ≤ 58 for |x| ≤ 20): a lookup, not a call.
_POW2 = tuple(2.0**k for k in range(64))


def _tanh_py(x: float) -> float:
    a = abs(x)
    if a > 20.0:
        a = 20.0  # as _tanh_vec: tanh(20) is 1 to 17 digits
    elif not a <= 20.0:
        return _tanh_vec(x)  # NaN
    y = a + a
    k = (y * INV_LN2 + SHIFT) - SHIFT
    r = (y - k * LN2_HI) - k * LN2_LO
    s = _POW2[int(k)]
    em = s * _expm1_series(r) + (s - 1.0)
    return math.copysign(em / (em + 2.0), x)


def _exp_neg_py(x: float) -> float:
    if not 0.0 <= x <= 708.0:
        return _exp_neg_vec(x)
    k = (x * INV_LN2 + SHIFT) - SHIFT
    r = (k * LN2_HI - x) + k * LN2_LO
    return (1.0 + _expm1_series(r)) / math.ldexp(1.0, int(k))


def _cos_py(x: float) -> float:
    if not abs(x) < 1e9:
        return _cos_vec(x)
    n = (x * TWO_OVER_PI + SHIFT) - SHIFT
    r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3
    r2 = r * r
    q = int(n) & 3
    v = _sin_series(r, r2) if q & 1 else _cos_series(r2)
    return -v if q == 1 or q == 2 else v


def _load_c() -> tuple[Callable[[float], float], ...] | None:
    """The C extension's (tanh, exp_neg, cos), or None where it is missing or differs.

    A build that gives other bits than the Python forms on a few arguments that exercise
    every branch (a compiler flag such as -ffast-math or FMA contraction would) is not
    used, with a warning: the engines' bit-for-bit agreement comes first.
    """
    try:
        from esoarm.plants import _elementary as c  # type: ignore[attr-defined]
    except ImportError:
        return None
    probe = (0.0, -0.0, 1e-9, 0.37, -0.9, 2.5, -7.25, 19.5, 21.0, 300.0, 1e5, -3e8, 2e9)
    for x in probe:
        pairs = [(c.tanh(x), _tanh_py(x)), (c.cos(x), _cos_py(x))]
        if x >= 0.0:
            pairs.append((c.exp_neg(x), _exp_neg_py(x)))
        if any(math.copysign(1.0, a) != math.copysign(1.0, b) or a != b for a, b in pairs):
            import warnings

            warnings.warn("esoarm.plants._elementary gives other bits than the Python forms "
                          "(built with -ffast-math or FMA contraction?); not used, the "
                          "reference engine runs slower", RuntimeWarning, stacklevel=2)
            return None
    return c.tanh, c.exp_neg, c.cos


_C = _load_c()
_tanh, _exp_neg, _cos = _C if _C is not None else (_tanh_py, _exp_neg_py, _cos_py)
#: True where the interpreter runs the C extension's forms.
COMPILED = _C is not None


# ---------------------------------------------------------------------------
# The public functions (what the interpreter calls; kernels compile the forms above)


@jitable_as(_tanh_vec)
def tanh(x: float) -> float:
    """Hyperbolic tangent, ≤ 3 ulp (see the module docstring); NaN, ±0, ±inf as libm.

    Parameters
    ----------
    x : float
        Argument (dimensionless).

    Returns
    -------
    float
        tanh x, in [−1, 1], odd in x.

    Examples
    --------
    >>> tanh(0.0), tanh(30.0), tanh(-30.0)
    (0.0, 1.0, -1.0)
    """
    return _tanh(x)


@jitable_as(_exp_neg_vec)
def exp_neg(x: float) -> float:
    """e^{−x} for x ≥ 0, ≤ 2 ulp; 0 for x > 708.

    Parameters
    ----------
    x : float
        Argument (dimensionless), x ≥ 0 (other values go to the vectorizable fallback).

    Returns
    -------
    float
        e^{−x}, in [0, 1] for x ≥ 0.

    Examples
    --------
    >>> exp_neg(0.0), exp_neg(800.0)
    (1.0, 0.0)
    """
    return _exp_neg(x)


@jitable_as(_cos_vec)
def cos(x: float) -> float:
    """Cosine, ≤ 2.5 ulp for |x| ≤ 1e5 (see the module docstring); NaN for ±inf.

    Parameters
    ----------
    x : float
        Angle [rad].

    Returns
    -------
    float
        cos x, in [−1, 1].

    Examples
    --------
    >>> cos(0.0)
    1.0
    """
    return _cos(x)
