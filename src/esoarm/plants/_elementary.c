/*
 * esoarm.plants._elementary: tanh, cos and exp(-x) of esoarm.plants.elementary for the
 * interpreter, as a CPython extension (built by setup.py when a C compiler is present;
 * optional: without it the interpreter runs the Python forms, which give the same bits).
 *
 * These are the vectorizable forms of elementary.py (_tanh_vec, _exp_neg_vec, _cos_vec)
 * written in C with the same IEEE double operations in the same order: Cody-Waite
 * reduction, round to nearest by adding and subtracting 1.5*2^52, a truncated Taylor
 * series by Horner's rule, powers of two by exact products.  Built with
 * -ffp-contract=off and without -ffast-math, so the compiler neither fuses a*b + c into
 * an FMA nor reassociates: the results are the Python forms' bits (elementary.py checks a
 * few values when it loads this module and ignores a build that differs;
 * tests/plants/test_elementary.py compares them on random and special arguments).
 *
 * Why: the reference engine (the plain-Python loop) spends most of its time in these
 * three functions -- about 0.8 us per call in CPython against 0.05 us here.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#if defined(__FAST_MATH__)
#error "esoarm's elementary functions must not be built with -ffast-math"
#endif

static const double SHIFT = 6755399441055744.0; /* 1.5 * 2^52 */
static const double INV_LN2 = 1.4426950408889634;
static const double LN2_HI = 0.6931471803691238;
static const double LN2_LO = 1.9082149292705877e-10;
static const double TWO_OVER_PI = 0.6366197723675814;
static const double PIO2_1 = 1.5707963267341256;
static const double PIO2_2 = 6.077100506303966e-11;
static const double PIO2_3 = 2.0222662487959506e-21;

/* volatile stores keep (v + SHIFT) - SHIFT from being simplified, whatever the flags */
static double round_shift(double v) {
    volatile double t = v + SHIFT;
    return t - SHIFT;
}

static double expm1_series(double r) {
    double p = 1.0 / 87178291200.0;
    p = p * r + 1.0 / 6227020800.0;
    p = p * r + 1.0 / 479001600.0;
    p = p * r + 1.0 / 39916800.0;
    p = p * r + 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    return r + (r * r) * p;
}

static double pow2(double k) {
    /* 2^k for an integer-valued 0 <= k <= 1023 by exact products (as elementary._pow2) */
    double s = 1.0;
    s = s * (k >= 512.0 ? 0x1p512 : 1.0);
    k = k - (k >= 512.0 ? 512.0 : 0.0);
    s = s * (k >= 256.0 ? 0x1p256 : 1.0);
    k = k - (k >= 256.0 ? 256.0 : 0.0);
    s = s * (k >= 128.0 ? 0x1p128 : 1.0);
    k = k - (k >= 128.0 ? 128.0 : 0.0);
    s = s * (k >= 64.0 ? 0x1p64 : 1.0);
    k = k - (k >= 64.0 ? 64.0 : 0.0);
    s = s * (k >= 32.0 ? 0x1p32 : 1.0);
    k = k - (k >= 32.0 ? 32.0 : 0.0);
    s = s * (k >= 16.0 ? 65536.0 : 1.0);
    k = k - (k >= 16.0 ? 16.0 : 0.0);
    s = s * (k >= 8.0 ? 256.0 : 1.0);
    k = k - (k >= 8.0 ? 8.0 : 0.0);
    s = s * (k >= 4.0 ? 16.0 : 1.0);
    k = k - (k >= 4.0 ? 4.0 : 0.0);
    s = s * (k >= 2.0 ? 4.0 : 1.0);
    k = k - (k >= 2.0 ? 2.0 : 0.0);
    return s * (k >= 1.0 ? 2.0 : 1.0);
}

static double tanh_e(double x) {
    double a = fabs(x);
    a = a > 20.0 ? 20.0 : a;
    double y = a + a;
    double k = round_shift(y * INV_LN2);
    double r = (y - k * LN2_HI) - k * LN2_LO;
    double s = pow2(k);
    double em = s * expm1_series(r) + (s - 1.0);
    return copysign(em / (em + 2.0), x);
}

static double exp_neg_e(double x) {
    double y = x > 709.0 ? 709.0 : x;
    double k = round_shift(y * INV_LN2);
    double r = (k * LN2_HI - y) + k * LN2_LO;
    double v = (1.0 + expm1_series(r)) / pow2(k);
    return x > 708.0 ? 0.0 : v;
}

static double cos_series(double r2) {
    double p = 1.0 / 20922789888000.0;
    p = p * r2 - 1.0 / 87178291200.0;
    p = p * r2 + 1.0 / 479001600.0;
    p = p * r2 - 1.0 / 3628800.0;
    p = p * r2 + 1.0 / 40320.0;
    p = p * r2 - 1.0 / 720.0;
    p = p * r2 + 1.0 / 24.0;
    p = p * r2 - 0.5;
    return 1.0 + r2 * p;
}

static double sin_series(double r, double r2) {
    double p = 1.0 / 355687428096000.0;
    p = p * r2 - 1.0 / 1307674368000.0;
    p = p * r2 + 1.0 / 6227020800.0;
    p = p * r2 - 1.0 / 39916800.0;
    p = p * r2 + 1.0 / 362880.0;
    p = p * r2 - 1.0 / 5040.0;
    p = p * r2 + 1.0 / 120.0;
    p = p * r2 - 1.0 / 6.0;
    return r + (r * r2) * p;
}

static double cos_e(double x) {
    double n = round_shift(x * TWO_OVER_PI);
    double r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3;
    double r2 = r * r;
    double c = cos_series(r2);
    double s = sin_series(r, r2);
    double q = n * 0.25;
    double f = q - round_shift(q); /* n mod 4 = 0, 1, 2, 3 <-> f = 0, 0.25, +-0.5, -0.25 */
    int quarter = fabs(f) == 0.25;
    int negate = f == 0.25 || fabs(f) == 0.5;
    double v = quarter ? s : c;
    return negate ? -v : v;
}

#define WRAP(name, fn)                                              \
    static PyObject *name(PyObject *self, PyObject *arg) {          \
        (void)self;                                                 \
        double x = PyFloat_AsDouble(arg);                           \
        if (x == -1.0 && PyErr_Occurred()) return NULL;             \
        return PyFloat_FromDouble(fn(x));                           \
    }

WRAP(py_tanh, tanh_e)
WRAP(py_cos, cos_e)
WRAP(py_exp_neg, exp_neg_e)

static PyMethodDef methods[] = {
    {"tanh", py_tanh, METH_O, "tanh x, the bits of esoarm.plants.elementary.tanh."},
    {"cos", py_cos, METH_O, "cos x, the bits of esoarm.plants.elementary.cos."},
    {"exp_neg", py_exp_neg, METH_O, "e^-x, the bits of esoarm.plants.elementary.exp_neg."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_elementary",
    "tanh, cos and exp(-x) of esoarm.plants.elementary in C (same bits, for the interpreter).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__elementary(void) { return PyModule_Create(&module); }
