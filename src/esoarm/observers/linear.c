/* Observer kind "linear": the ESO of eq. 8, the C twin of esoarm.observers.linear.
 *
 * OBS_P is the kind's design vector without its CODE (ESODesign.vector):
 *   [0] discretization (0 euler, 1 zoh, 2 current), [1] Ts, [2] b0, [3..5] beta,
 *   [6..14] Phi (row-major), [15..17] Gamma, [18..20] gain (Lp, Lc or Ts*beta).
 * The tunable entries are read from T, the instance's copy of the vector (obs_retune).
 * The generator supplies esoarm_real, R(x) (a literal in that precision) and
 * ESOARM_COMPENSATED (1: the increments are summed with their rounding error
 * carried, see docs/on-the-chip.md; 0: exactly the Python step's arithmetic).
 * The state holds z1..z3, then (compensated form only) their carried errors.
 */
#define OBS_NZ 6

/* Run-time tuning (esoarm_set_params): T is the instance's copy of OBS_P; its entries
 * that depend on epsilon and b0 -- [2] b0, [3..5] beta, [15..17] Gamma, [18..20] the
 * discrete gain -- are recomputed as design_observer does; Ts, the discretization and
 * Phi stay the design's. */
static int obs_retune(esoarm_real T[], esoarm_real eps, esoarm_real b0)
{
    esoarm_real ts = OBS_P[1];
    if (eso_linear_gain(OBS_P[0], ts, eps, T + 3, T + 18) != 0) return -1;
    T[2] = b0;
    T[15] = OBS_P[0] == R(0.0) ? R(0.0) : b0 * (ts * ts * R(0.5));
    T[16] = ts * b0;
    T[17] = R(0.0);
    return 0;
}

static void obs_initialize(esoarm_real z[], esoarm_real y)
{
    z[0] = y; z[1] = R(0.0); z[2] = R(0.0);
    z[3] = R(0.0); z[4] = R(0.0); z[5] = R(0.0);
}

/* The innovation y - z1; the compensated form adds back z1's carried error. */
static esoarm_real obs_innovation(const esoarm_real z[], esoarm_real y)
{
#if ESOARM_COMPENSATED
    return (y - z[0]) + z[3];
#else
    return y - z[0];
#endif
}

static void obs_estimate(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
                         esoarm_real zhat[])
{
    if (OBS_P[0] == R(2.0)) {           /* "current": z + Lc (y - z1) */
        esoarm_real e = obs_innovation(z, y);
        zhat[0] = z[0] + T[18] * e;
        zhat[1] = z[1] + T[19] * e;
        zhat[2] = z[2] + T[20] * e;
    } else {
        zhat[0] = z[0]; zhat[1] = z[1]; zhat[2] = z[2];
    }
}

/* z_i <- z_i + d with the rounding error of the sum carried to the next sample
 * (Kahan); with ESOARM_COMPENSATED 0 a plain sum. */
static esoarm_real obs_accumulate(esoarm_real zi, esoarm_real d, esoarm_real *carry)
{
#if ESOARM_COMPENSATED
    esoarm_real y = d - *carry;  /* no -ffast-math: the compiler keeps this order */
    esoarm_real t = zi + y;
    *carry = (t - zi) - y;
    return t;
#else
    (void)carry;
    return zi + d;
#endif
}

static void obs_advance(const esoarm_real T[], esoarm_real z[], const esoarm_real zhat[],
                        esoarm_real y, esoarm_real u)
{
    esoarm_real z1 = z[0], z2 = z[1], z3 = z[2];
    if (OBS_P[0] == R(0.0)) {           /* "euler": z + Ts (eq. 8) */
        esoarm_real ts = OBS_P[1];
        esoarm_real e = obs_innovation(z, y);
        esoarm_real d1 = z2 + T[3] * e;
        esoarm_real d2 = z3 + T[2] * u + T[4] * e;
        esoarm_real d3 = T[5] * e;
        z[0] = obs_accumulate(z1, ts * d1, &z[3]);
        z[1] = obs_accumulate(z2, ts * d2, &z[4]);
        z[2] = obs_accumulate(z3, ts * d3, &z[5]);
    } else if (OBS_P[0] == R(1.0)) {    /* "zoh": Phi z + Gamma u + Lp (y - z1) */
        esoarm_real e = obs_innovation(z, y);
#if ESOARM_COMPENSATED
        /* Phi = [[1, Ts, Ts^2/2], [0, 1, Ts], [0, 0, 1]]: z + increment */
        esoarm_real i1 = OBS_P[7] * z2 + OBS_P[8] * z3 + T[15] * u + T[18] * e;
        esoarm_real i2 = OBS_P[11] * z3 + T[16] * u + T[19] * e;
        esoarm_real i3 = T[17] * u + T[20] * e;
        z[0] = obs_accumulate(z1, i1, &z[3]);
        z[1] = obs_accumulate(z2, i2, &z[4]);
        z[2] = obs_accumulate(z3, i3, &z[5]);
#else
        esoarm_real n1 = OBS_P[6] * z1 + OBS_P[7] * z2 + OBS_P[8] * z3 + T[15] * u;
        esoarm_real n2 = OBS_P[9] * z1 + OBS_P[10] * z2 + OBS_P[11] * z3 + T[16] * u;
        esoarm_real n3 = OBS_P[12] * z1 + OBS_P[13] * z2 + OBS_P[14] * z3 + T[17] * u;
        z[0] = n1 + T[18] * e;
        z[1] = n2 + T[19] * e;
        z[2] = n3 + T[20] * e;
#endif
    } else {                            /* "current": Phi zhat + Gamma u */
        esoarm_real h1 = zhat[0], h2 = zhat[1], h3 = zhat[2];
#if ESOARM_COMPENSATED
        /* the correction zhat - z and the prediction's increment, added to z */
        esoarm_real e = obs_innovation(z, y);
        esoarm_real i1 = T[18] * e + OBS_P[7] * h2 + OBS_P[8] * h3 + T[15] * u;
        esoarm_real i2 = T[19] * e + OBS_P[11] * h3 + T[16] * u;
        esoarm_real i3 = T[20] * e + T[17] * u;
        (void)h1;
        z[0] = obs_accumulate(z1, i1, &z[3]);
        z[1] = obs_accumulate(z2, i2, &z[4]);
        z[2] = obs_accumulate(z3, i3, &z[5]);
#else
        z[0] = OBS_P[6] * h1 + OBS_P[7] * h2 + OBS_P[8] * h3 + T[15] * u;
        z[1] = OBS_P[9] * h1 + OBS_P[10] * h2 + OBS_P[11] * h3 + T[16] * u;
        z[2] = OBS_P[12] * h1 + OBS_P[13] * h2 + OBS_P[14] * h3 + T[17] * u;
#endif
    }
}
