/* Observer kind "nonlinear": Han's fal-ESO, the C twin of esoarm.observers.nonlinear.
 *
 * OBS_P is the design vector without its CODE: the linear ESO's 21 entries
 * (see observers/linear.c), then [21] alpha2, [22] alpha3, [23] delta.
 * With ESOARM_COMPENSATED 1 the increments are summed with their rounding
 * error carried (as in the linear kind); 0 is the Python step's arithmetic.
 */
#define OBS_NZ 6

/* Run-time tuning (esoarm_set_params): T is the instance's copy of OBS_P; its entries
 * that depend on epsilon and b0 -- [2] b0, [3..5] beta, [15..17] Gamma, [18..20] the
 * discrete gain -- are recomputed as design_observer does; Ts, the discretization and
 * Phi stay the design's. */
static int obs_retune(esoarm_real T[], esoarm_real eps, esoarm_real b0)
{
    esoarm_real ts = OBS_P[1];
    if (eso_linear_gain(OBS_P[0], ts, eps, OBS_GAIN_SCALE, T + 3, T + 18) != 0) return -1;
    T[2] = b0;
    T[15] = OBS_P[0] == R(0.0) ? R(0.0) : b0 * (ts * ts * R(0.5));
    T[16] = ts * b0;
    T[17] = R(0.0);
    return 0;
}

static esoarm_real obs_fal(esoarm_real e, esoarm_real alpha, esoarm_real delta)
{
    /* e / delta^(1 - alpha) for |e| <= delta, else |e|^alpha sign(e) */
    if (FABS(e) <= delta) return DIV(e, POW(delta, R(1.0) - alpha));
    return COPYSIGN(POW(FABS(e), alpha), e);
}

static void obs_initialize(esoarm_real z[], esoarm_real y)
{
    z[0] = y; z[1] = R(0.0); z[2] = R(0.0);
    z[3] = R(0.0); z[4] = R(0.0); z[5] = R(0.0);
}

static esoarm_real obs_innovation(const esoarm_real z[], esoarm_real y)
{
#if ESOARM_COMPENSATED
    return (y - z[0]) + z[3];
#else
    return y - z[0];
#endif
}

static esoarm_real obs_accumulate(esoarm_real zi, esoarm_real d, esoarm_real *carry)
{
#if ESOARM_COMPENSATED
    esoarm_real y = d - *carry;
    esoarm_real t = zi + y;
    *carry = (t - zi) - y;
    return t;
#else
    (void)carry;
    return zi + d;
#endif
}

static void obs_estimate(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
                         esoarm_real zhat[])
{
    if (OBS_P[0] == R(2.0)) {
        esoarm_real e = obs_innovation(z, y);
        esoarm_real d = OBS_P[23];
        zhat[0] = z[0] + T[18] * e;
        zhat[1] = z[1] + T[19] * obs_fal(e, OBS_P[21], d);
        zhat[2] = z[2] + T[20] * obs_fal(e, OBS_P[22], d);
    } else {
        zhat[0] = z[0]; zhat[1] = z[1]; zhat[2] = z[2];
    }
}

static void obs_advance(const esoarm_real T[], esoarm_real z[], const esoarm_real zhat[],
                        esoarm_real y, esoarm_real u)
{
    esoarm_real z1 = z[0], z2 = z[1], z3 = z[2];
    if (OBS_P[0] == R(0.0)) {           /* "euler" */
        esoarm_real ts = OBS_P[1];
        esoarm_real e = obs_innovation(z, y);
        esoarm_real f2 = obs_fal(e, OBS_P[21], OBS_P[23]);
        esoarm_real f3 = obs_fal(e, OBS_P[22], OBS_P[23]);
        esoarm_real d1 = z2 + T[3] * e;
        esoarm_real d2 = z3 + T[2] * u + T[4] * f2;
        esoarm_real d3 = T[5] * f3;
        z[0] = obs_accumulate(z1, ts * d1, &z[3]);
        z[1] = obs_accumulate(z2, ts * d2, &z[4]);
        z[2] = obs_accumulate(z3, ts * d3, &z[5]);
    } else if (OBS_P[0] == R(1.0)) {    /* "zoh" */
        esoarm_real e = obs_innovation(z, y);
        esoarm_real f2 = obs_fal(e, OBS_P[21], OBS_P[23]);
        esoarm_real f3 = obs_fal(e, OBS_P[22], OBS_P[23]);
#if ESOARM_COMPENSATED
        esoarm_real i1 = OBS_P[7] * z2 + OBS_P[8] * z3 + T[15] * u + T[18] * e;
        esoarm_real i2 = OBS_P[11] * z3 + T[16] * u + T[19] * f2;
        esoarm_real i3 = T[17] * u + T[20] * f3;
        z[0] = obs_accumulate(z1, i1, &z[3]);
        z[1] = obs_accumulate(z2, i2, &z[4]);
        z[2] = obs_accumulate(z3, i3, &z[5]);
#else
        esoarm_real n1 = OBS_P[6] * z1 + OBS_P[7] * z2 + OBS_P[8] * z3 + T[15] * u;
        esoarm_real n2 = OBS_P[9] * z1 + OBS_P[10] * z2 + OBS_P[11] * z3 + T[16] * u;
        esoarm_real n3 = OBS_P[12] * z1 + OBS_P[13] * z2 + OBS_P[14] * z3 + T[17] * u;
        z[0] = n1 + T[18] * e;
        z[1] = n2 + T[19] * f2;
        z[2] = n3 + T[20] * f3;
#endif
    } else {                            /* "current": Phi zhat + Gamma u */
        esoarm_real h1 = zhat[0], h2 = zhat[1], h3 = zhat[2];
#if ESOARM_COMPENSATED
        esoarm_real e = obs_innovation(z, y);
        esoarm_real i1 = T[18] * e + OBS_P[7] * h2 + OBS_P[8] * h3 + T[15] * u;
        esoarm_real i2 = T[19] * obs_fal(e, OBS_P[21], OBS_P[23]) + OBS_P[11] * h3
                         + T[16] * u;
        esoarm_real i3 = T[20] * obs_fal(e, OBS_P[22], OBS_P[23]) + T[17] * u;
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
