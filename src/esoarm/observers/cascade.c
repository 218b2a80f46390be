/* Observer kind "cascade": the cascade ESO of Lakomy and Madonski (2021), the C twin
 * of esoarm.observers.cascade (one joint).
 *
 * OBS_P is the kind's design vector without its CODE (cascade.design):
 *   [0] discretization (0 euler, 1 zoh, 2 current), [1] Ts, [2] b0,
 *   [3..11] Phi (row-major), [12..14] Gamma, [15] p, then p gains of 3 from [16]
 *   (level 1, the slowest, first).
 * The generator supplies esoarm_real, R(x), DIV(a, b), ESOARM_COMPENSATED and
 * OBS_N, the Python state's length 3 p; the C state holds the p levels' z (as in
 * Python, level 1 first), then (compensated form only) their carried errors.
 *
 * Level 1 measures y; level i >= 2 measures the previous level's angle estimate and
 * takes the perturbation estimated so far, w_i, as a known input b0 u + w_i; the
 * estimate is (zhat^p_1, zhat^p_2, sum_i zhat^i_3).  With ESOARM_COMPENSATED 0 every
 * operation is the Python step's, in its order (float64: the same u to the bit).
 */
#define OBS_NZ (2 * OBS_N)
#define CAS_LEVELS (OBS_N / 3)
#define CAS_GAINS 16
/* T[OBS_NP] = 1 / b0 (obs_derive): no division in the step */
#define OBS_NEXTRA 1

/* The levels are stepped one call per level with a constant level number (unrolled
 * by the preprocessor, CAS_LEVELS being a constant): the compiler then folds the
 * design constants (the linear kind's C gets the same from its constant indices);
 * a loop would load every gain at run time (measured on the ATmega328P: about
 * 1.5k cycles more per step with 2 levels). */
#if defined(__GNUC__)
#define CAS_INLINE static inline __attribute__((always_inline))
#else
#define CAS_INLINE static inline
#endif

/* Run-time tuning (esoarm_set_params): T is the instance's copy of OBS_P; b0 ([2]), Gamma
 * ([12..14]) and every level's gain ([16..]) are recomputed for the last level's epsilon
 * (level i: eps * OBS_RATIO^(p - 1 - i), level_eps) as cascade.design does. */
static int obs_retune(esoarm_real T[], esoarm_real eps, esoarm_real b0)
{
    esoarm_real ts = OBS_P[1], beta[3], level = eps;
    int i;
    for (i = CAS_LEVELS - 1; i >= 0; --i) {
        if (eso_linear_gain(OBS_P[0], ts, level, OBS_GAIN_SCALE, beta,
                            T + CAS_GAINS + 3 * i) != 0) return -1;
        level *= OBS_RATIO;
    }
    T[2] = b0;
    T[12] = OBS_P[0] == R(0.0) ? R(0.0) : b0 * (ts * ts * R(0.5));
    T[13] = ts * b0;
    T[14] = R(0.0);
    return 0;
}

static void obs_derive(esoarm_real T[])
{
    T[OBS_NP] = R(1.0) / T[2];
}

static void obs_initialize(esoarm_real z[], esoarm_real y)
{
    uint8_t i;
    for (i = 0; i < OBS_NZ; ++i) z[i] = R(0.0);
    for (i = 0; i < CAS_LEVELS; ++i) z[3 * i] = y;
}

#if ESOARM_COMPENSATED
/* z_i <- z_i + d with the rounding error of the sum carried to the next sample
 * (Kahan, as in the linear kind). */
static esoarm_real obs_accumulate(esoarm_real zi, esoarm_real d, esoarm_real *carry)
{
    esoarm_real y = d - *carry;  /* no -ffast-math: the compiler keeps this order */
    esoarm_real t = zi + y;
    *carry = (t - zi) - y;
    return t;
}
#endif

/* One level's estimate h (the state, or for "current" its correction) and its
 * innovation e = m - z1, where the level's measurement is m = base + offset.
 * Plain form: base is m itself and offset 0 (Python: e = m - z[i]).  Compensated
 * form: z1's exact value is z1 - carry1, and the measurement is kept as a base
 * (y, or the previous level's stored z1) plus a small offset, so that
 * e = (base - z1) + (offset + carry1) keeps the small quantities small. */
CAS_INLINE esoarm_real cas_level(const esoarm_real T[], const esoarm_real z[], uint8_t lv,
                                 esoarm_real base,
                                 esoarm_real offset, esoarm_real h[3])
{
    const esoarm_real *zi = z + 3 * lv;
    const esoarm_real *g = T + CAS_GAINS + 3 * lv;
    esoarm_real e;
#if ESOARM_COMPENSATED
    e = (base - zi[0]) + (offset + z[OBS_N + 3 * lv]);
#else
    (void)offset;
    e = base - zi[0];
#endif
    if (OBS_P[0] == R(2.0)) {           /* "current": zhat = z + Lc (m - z1) */
        h[0] = zi[0] + g[0] * e;
        h[1] = zi[1] + g[1] * e;
        h[2] = zi[2] + g[2] * e;
    } else {
        h[0] = zi[0]; h[1] = zi[1]; h[2] = zi[2];
    }
    return e;
}

/* The next level's measurement (base, offset) from this level's estimate h1. */
CAS_INLINE void cas_next_measurement(const esoarm_real T[], const esoarm_real z[], uint8_t lv,
                                     const esoarm_real h[3], esoarm_real e,
                                     esoarm_real *base, esoarm_real *offset)
{
#if ESOARM_COMPENSATED
    /* h1 = (z1 - carry1) [+ Lc1 e]: the stored z1 as base, the rest as offset */
    *base = z[3 * lv];
    *offset = -z[OBS_N + 3 * lv];
    if (OBS_P[0] == R(2.0)) *offset += T[CAS_GAINS + 3 * lv] * e;
    (void)h;
#else
    (void)T; (void)z; (void)lv; (void)e;
    *base = h[0];
    *offset = R(0.0);
#endif
}

CAS_INLINE void cas_estimate_level(const esoarm_real T[], const esoarm_real z[], uint8_t lv,
                                   esoarm_real *base, esoarm_real *offset, esoarm_real *w,
                                   esoarm_real h[3])
{
    esoarm_real e = cas_level(T, z, lv, *base, *offset, h);
    *w += h[2];
    cas_next_measurement(T, z, lv, h, e, base, offset);
}

static void obs_estimate(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
                         esoarm_real zhat[])
{
    esoarm_real base = y, offset = R(0.0), w = R(0.0), h[3];
    cas_estimate_level(T, z, 0, &base, &offset, &w, h);
#if CAS_LEVELS > 1
    cas_estimate_level(T, z, 1, &base, &offset, &w, h);
#endif
#if CAS_LEVELS > 2
    cas_estimate_level(T, z, 2, &base, &offset, &w, h);
#endif
#if CAS_LEVELS > 3
    cas_estimate_level(T, z, 3, &base, &offset, &w, h);
#endif
#if CAS_LEVELS > 4
    cas_estimate_level(T, z, 4, &base, &offset, &w, h);
#endif
#if CAS_LEVELS > 5
#error "the cascade ESO has at most 5 levels"
#endif
    zhat[0] = h[0]; zhat[1] = h[1]; zhat[2] = w;
}

CAS_INLINE void cas_advance_level(const esoarm_real T[], esoarm_real z[], uint8_t lv,
                                  esoarm_real *base_p,
                                  esoarm_real *offset_p, esoarm_real *w_p, esoarm_real u)
{
    esoarm_real base = *base_p, offset = *offset_p, w = *w_p, e, v, h[3];
    esoarm_real *zi = z + 3 * lv;
    const esoarm_real *g = T + CAS_GAINS + 3 * lv;
    e = cas_level(T, z, lv, base, offset, h);
#if ESOARM_RECIPROCAL
    v = u + w * T[OBS_NP];          /* the known input, as a torque: u + w_i / b0 */
#else
    v = u + w / T[2];
#endif
#if ESOARM_COMPENSATED
    {
        /* Phi = [[1, a, b], [0, 1, c], [0, 0, 1]] for every discretization: z + increment.
         * euler/zoh: the increment is (Phi - I) z + Gamma v + L e; current: the
         * correction L e plus (Phi - I) zhat + Gamma v. */
        esoarm_real s2 = zi[1], s3 = zi[2];
        esoarm_real *carry = z + OBS_N + 3 * lv;
        esoarm_real i1, i2, i3;
        if (OBS_P[0] == R(2.0)) { s2 = h[1]; s3 = h[2]; }
        /* the terms of the design's zero entries (Euler: Phi[0][2], Gamma[0]; every
         * discretization: Gamma[2]) are left out at compile time (a soft-float
         * multiplication by 0 costs as much as any other) */
        i1 = g[0] * e + OBS_P[4] * s2;
        if (OBS_P[5] != R(0.0)) i1 += OBS_P[5] * s3;
        if (OBS_P[12] != R(0.0)) i1 += T[12] * v;
        i2 = g[1] * e + OBS_P[8] * s3 + T[13] * v;
        i3 = g[2] * e;
        if (OBS_P[14] != R(0.0)) i3 += T[14] * v;
        /* the next level uses this level's estimate at k: take it before overwriting */
        cas_next_measurement(T, z, lv, h, e, &base, &offset);
        w += h[2];
        zi[0] = obs_accumulate(zi[0], i1, &carry[0]);
        zi[1] = obs_accumulate(zi[1], i2, &carry[1]);
        zi[2] = obs_accumulate(zi[2], i3, &carry[2]);
    }
#else
    {
        /* Python's _advance_joint: n = Phi s + Gamma v, z = n + c */
        esoarm_real s1, s2, s3, c1, c2, c3, n1, n2, n3;
        if (OBS_P[0] == R(2.0)) {
            s1 = h[0]; s2 = h[1]; s3 = h[2];
            c1 = c2 = c3 = R(0.0);
        } else {
            s1 = zi[0]; s2 = zi[1]; s3 = zi[2];
            c1 = g[0] * e; c2 = g[1] * e; c3 = g[2] * e;
        }
        n1 = OBS_P[3] * s1 + OBS_P[4] * s2 + OBS_P[5] * s3 + T[12] * v;
        n2 = OBS_P[6] * s1 + OBS_P[7] * s2 + OBS_P[8] * s3 + T[13] * v;
        n3 = OBS_P[9] * s1 + OBS_P[10] * s2 + OBS_P[11] * s3 + T[14] * v;
        cas_next_measurement(T, z, lv, h, e, &base, &offset);
        w += h[2];
        zi[0] = n1 + c1;
        zi[1] = n2 + c2;
        zi[2] = n3 + c3;
    }
#endif
    *base_p = base; *offset_p = offset; *w_p = w;
}

static void obs_advance(const esoarm_real T[], esoarm_real z[], const esoarm_real zhat[],
                        esoarm_real y, esoarm_real u)
{
    esoarm_real base = y, offset = R(0.0), w = R(0.0);
    (void)zhat;  /* each level's estimate is recomputed from z_k, as in Python */
    cas_advance_level(T, z, 0, &base, &offset, &w, u);
#if CAS_LEVELS > 1
    cas_advance_level(T, z, 1, &base, &offset, &w, u);
#endif
#if CAS_LEVELS > 2
    cas_advance_level(T, z, 2, &base, &offset, &w, u);
#endif
#if CAS_LEVELS > 3
    cas_advance_level(T, z, 3, &base, &offset, &w, u);
#endif
#if CAS_LEVELS > 4
    cas_advance_level(T, z, 4, &base, &offset, &w, u);
#endif
}
