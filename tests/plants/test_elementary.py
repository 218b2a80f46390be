"""esoarm.plants.elementary: accuracy against 200-bit references, special values, and the
same bits compiled as interpreted (which is what lets every engine agree bit for bit)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from esoarm.plants import elementary as el

mpmath = pytest.importorskip("mpmath")
mpmath.mp.prec = 200


def _ulps(value: float, exact) -> float:
    """|value − exact| in units in the last place of the correctly rounded result."""
    rounded = float(exact)
    if rounded == 0.0:
        return 0.0 if value == 0.0 else math.inf
    return float(abs(mpmath.mpf(value) - exact) / mpmath.mpf(math.ulp(rounded)))


def _worst(f, ref, xs) -> float:
    return max(_ulps(f(float(x)), ref(mpmath.mpf(float(x)))) for x in xs)


RNG = np.random.default_rng(20261201)


def test_constants_split_pi_over_two_and_ln2():
    pio2 = mpmath.mpf(el.PIO2_1) + el.PIO2_2 + el.PIO2_3
    assert abs(pio2 - mpmath.pi / 2) < 1e-36
    assert abs(mpmath.mpf(el.LN2_HI) + el.LN2_LO - mpmath.log(2)) < 2e-26
    # the high parts have few enough bits that k·HI is exact for the k that occur
    for hi, bits in ((el.PIO2_1, 33), (el.PIO2_2, 33), (el.LN2_HI, 32)):
        m, _ = math.frexp(hi)
        assert (m * 2**bits).is_integer()


def test_tanh_within_3_ulp():
    xs = np.concatenate([RNG.uniform(-25, 25, 3000), RNG.normal(0, 1, 3000),
                         10 ** RNG.uniform(-300, 1.4, 2000) * RNG.choice([-1, 1], 2000)])
    assert _worst(el.tanh, mpmath.tanh, xs) <= 3.0


def test_cos_within_2_5_ulp_up_to_1e5():
    xs = np.concatenate([RNG.uniform(-10, 10, 3000), RNG.uniform(-1e5, 1e5, 2000),
                         RNG.normal(0, 1e-3, 500), np.arange(-200, 200) * (math.pi / 2),
                         np.arange(-50, 50) * (math.pi / 4)])
    assert _worst(el.cos, mpmath.cos, xs) <= 2.5


def test_exp_neg_within_2_ulp():
    xs = np.concatenate([RNG.uniform(0, 1, 2000), RNG.uniform(0, 40, 2000),
                         RNG.uniform(0, 708, 2000), [0.0, 1e-300, 0.5 * math.log(2)]])
    assert _worst(el.exp_neg, lambda x: mpmath.exp(-x), xs) <= 2.0


@pytest.mark.parametrize(("x", "tanh", "cos", "exp_neg"), [
    (0.0, 0.0, 1.0, 1.0),
    (math.inf, 1.0, math.nan, 0.0),
    (-math.inf, -1.0, math.nan, None),
    (math.nan, math.nan, math.nan, math.nan),
    (800.0, 1.0, None, 0.0),
])
def test_special_values(x, tanh, cos, exp_neg):
    for f, want in ((el.tanh, tanh), (el.cos, cos), (el.exp_neg, exp_neg)):
        if want is None:
            continue
        got = f(x)
        assert (math.isnan(got) and math.isnan(want)) or got == want, (f.__name__, x, got)
    assert math.copysign(1.0, el.tanh(-0.0)) == -1.0  # tanh(−0) = −0, as libm


@given(st.floats(-1e5, 1e5))
@settings(max_examples=300, deadline=None)
def test_identities(x):
    assert abs(el.cos(x) - el.cos(-x)) == 0.0  # even, exactly (the reduction is odd-symmetric)
    assert el.tanh(-x) == -el.tanh(x)
    assert -1.0 <= el.tanh(x) <= 1.0 and -1.0 <= el.cos(x) <= 1.0


def test_compiled_gives_the_same_bits_and_vectorizes():
    numba = pytest.importorskip("numba")
    from esoarm import _jit

    _jit.register_all()

    @numba.njit(error_model="numpy")
    def apply(xs, out):  # pragma: no cover - compiled
        for i in range(xs.shape[0]):
            out[i, 0] = el.tanh(xs[i])
            out[i, 1] = el.cos(xs[i])
            out[i, 2] = el.exp_neg(abs(xs[i]))

    xs = np.concatenate([RNG.normal(0, 3, 5000), RNG.uniform(-1e4, 1e4, 1000),
                         [0.0, -0.0, math.inf, -math.inf, math.nan, 25.0, 709.5]])
    out = np.empty((len(xs), 3))
    apply(xs, out)
    want = np.array([[el.tanh(x), el.cos(x), el.exp_neg(abs(x))] for x in xs.tolist()])
    assert np.array_equal(out.view(np.uint64), want.view(np.uint64))


def _c_form(name: str):
    """The C extension's function; skipped where it was not built, except in CI
    (``ESOARM_REQUIRE_C_EXTENSION=1``, set by ``.ci/run``), where that fails."""
    import os

    try:
        from esoarm.plants import _elementary as c  # type: ignore[attr-defined]
    except ImportError:
        if os.environ.get("ESOARM_REQUIRE_C_EXTENSION") == "1":
            pytest.fail("esoarm.plants._elementary was not built (pip install needs a C "
                        "compiler and Python's headers)")
        pytest.skip("the C extension was not built (no C compiler or Python headers)")
    return getattr(c, name)


FORMS = {"public": lambda name: getattr(el, name),
         "python": lambda name: getattr(el, f"_{name}_py"),
         "c": _c_form}


@pytest.mark.parametrize("form", sorted(FORMS))
@pytest.mark.parametrize("name", ["tanh", "cos", "exp_neg"])
def test_interpreter_form_is_the_compiled_form(name, form):
    """The interpreter's forms of each function (Python, and the C extension where it was
    built) give the compiled form's bits."""
    fast, vec = FORMS[form](name), getattr(el, f"_{name}_vec")
    xs = np.concatenate([RNG.normal(0, 3, 20000), RNG.uniform(-30, 30, 20000),
                         RNG.uniform(-1e6, 1e6, 5000), 10 ** RNG.uniform(-300, 12, 5000),
                         -(10 ** RNG.uniform(-300, 12, 5000)), np.arange(-100, 100) * math.pi / 4,
                         [0.0, -0.0, 20.0, -20.0, 708.0, 709.0, 1e9, -1e9, math.inf, -math.inf,
                          5e-324, -5e-324, 1e300, -1e300, 708.5, 710.0]])
    if name == "exp_neg":
        xs = np.abs(xs)
    got = np.array([fast(x) for x in xs.tolist()])
    want = np.array([vec(x) for x in xs.tolist()])
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
    assert math.isnan(fast(math.nan)) and math.isnan(vec(math.nan))


def test_the_c_extension_is_used_where_built():
    """Where the extension was built (and gives the Python forms' bits), the interpreter
    calls it: the reference engine's speed depends on it."""
    _c_form("tanh")
    assert el.COMPILED
    assert el._tanh is _c_form("tanh") and el._cos is _c_form("cos")


@given(st.floats(allow_nan=False, allow_infinity=True))
@settings(max_examples=3000, deadline=None)
def test_c_extension_same_bits_on_any_double(x):
    """The C extension against the Python forms on any double (hypothesis' edge cases)."""
    for name in ("tanh", "cos", "exp_neg"):
        if name == "exp_neg":
            x = abs(x)
        got, want = _c_form(name)(x), getattr(el, f"_{name}_py")(x)
        assert np.float64(got).view(np.uint64) == np.float64(want).view(np.uint64)


def test_a_c_build_with_other_bits_is_refused(monkeypatch):
    """A miscompiled extension (other bits) is not used, with a warning."""
    import sys
    import types

    fake = types.ModuleType("esoarm.plants._elementary")
    fake.tanh = lambda x: el._tanh_py(x) + 1e-16  # type: ignore[attr-defined]
    fake.cos, fake.exp_neg = el._cos_py, el._exp_neg_py  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "esoarm.plants._elementary", fake)
    monkeypatch.setattr("esoarm.plants._elementary", fake, raising=False)
    with pytest.warns(RuntimeWarning, match="other bits"):
        assert el._load_c() is None
