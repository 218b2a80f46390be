/* Observer kind "linear": the ESO of eq. 8, the C twin of esoarm.observers.linear.
 *
 * OBS_P is the kind's design vector without its CODE (ESODesign.vector):
 *   [0] discretization (0 euler, 1 zoh, 2 current), [1] Ts, [2] b0, [3..5] beta,
 *   [6..14] Phi (row-major), [15..17] Gamma, [18..20] gain (Lp, Lc or Ts*beta),
 *   [21] input delay N [samples], [22] form (0 the ESO fed u_{k-N}, 1 also the predictor,
 *   2 the model form), and with the model form (OBS_MODEL_FORM 1, from the generator) [23]
 *   gravity's (m1 l1 - m2 l2) g [N m], [24] Coulomb Fc [N m], [25] its tanh velocity vs
 *   [rad/s], [26] viscous Fv [N m s/rad].
 * The entries that depend on epsilon and b0 are read from T, the instance's copy of the
 * vector (obs_retune).
 * The generator supplies esoarm_real, R(x) (a literal in that precision) and
 * ESOARM_COMPENSATED (1: the increments are summed with their rounding error
 * carried, see docs/on-the-chip.md; 0: exactly the Python step's arithmetic).
 * The state holds z1..z3, then (compensated form only) their carried errors, then the N
 * commands u_{k-N} .. u_{k-1} of the input delay (Python's state: z, then the commands).
 */
#define OBS_NZ (OBS_N + 3)
#define OBS_DELAY ((uint8_t)OBS_P[21])

/* Run-time tuning (esoarm_set_params): T is the instance's copy of OBS_P; its entries
 * that depend on epsilon and b0 -- [2] b0, [3..5] beta, [15..17] Gamma, [18..20] the
 * discrete gain (times OBS_GAIN_SCALE: 0.5 for the half-gain tuning) -- are recomputed as
 * design_observer does; Ts, the discretization, Phi and the input delay stay the design's. */
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

static void obs_initialize(esoarm_real z[], esoarm_real y)
{
    uint8_t i;
    z[0] = y; z[1] = R(0.0); z[2] = R(0.0);
    for (i = 3; i < OBS_NZ; ++i) z[i] = R(0.0);
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

static void obs_correct(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
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

#if OBS_MODEL_FORM
/* The nominal model's acceleration m = -(G(th) + Fc tanh(om/vs) + Fv om) b0
 * (model_acceleration). */
static esoarm_real obs_model(const esoarm_real T[], esoarm_real th, esoarm_real om)
{
    esoarm_real friction = OBS_P[24] * TANH(DIV(om, OBS_P[25])) + OBS_P[26] * om;
    return -(OBS_P[23] * COS(th) + friction) * T[2];
}
#endif

/* The estimate; the predictor form moves angle and rate N samples ahead with the commands
 * already sent (exact held-input model of the triple integrator, f held); the model form
 * adds the model's acceleration at each step and hands over the perturbation z3 + m there
 * (model_predict). */
static void obs_estimate(const esoarm_real T[], const esoarm_real z[], esoarm_real y,
                         esoarm_real zhat[])
{
    uint8_t nd = OBS_DELAY;
    obs_correct(T, z, y, zhat);
#if OBS_MODEL_FORM
    {
        esoarm_real ts = OBS_P[1], half = R(0.5) * OBS_P[1] * OBS_P[1];
        uint8_t i;
        for (i = 0; i < nd; ++i) {
            esoarm_real acc = zhat[2] + T[2] * z[6 + i] + obs_model(T, zhat[0], zhat[1]);
            zhat[0] = zhat[0] + ts * zhat[1] + half * acc;
            zhat[1] = zhat[1] + ts * acc;
        }
        zhat[2] = zhat[2] + obs_model(T, zhat[0], zhat[1]);
        return;
    }
#endif
    if (nd > 0 && OBS_P[22] == R(1.0)) {
        esoarm_real ts = OBS_P[1], half = R(0.5) * OBS_P[1] * OBS_P[1];
        uint8_t i;
        for (i = 0; i < nd; ++i) {
            esoarm_real acc = zhat[2] + T[2] * z[6 + i];
            zhat[0] = zhat[0] + ts * zhat[1] + half * acc;
            zhat[1] = zhat[1] + ts * acc;
        }
    }
}

/* u_{k-N} from the commands held; u_k shifted in. */
static esoarm_real obs_delayed(esoarm_real z[], esoarm_real u)
{
    uint8_t i, nd = OBS_DELAY;
    esoarm_real old;
    if (nd == 0) return u;
    old = z[6];
    for (i = 0; i + 1 < nd; ++i) z[6 + i] = z[7 + i];
    z[6 + nd - 1] = u;
    return old;
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

static void obs_advance(const esoarm_real T[], esoarm_real z[], const esoarm_real zhat_in[],
                        esoarm_real y, esoarm_real u_in)
{
    esoarm_real z1 = z[0], z2 = z[1], z3 = z[2];
    esoarm_real corrected[3];
    const esoarm_real *zhat = zhat_in;
    esoarm_real u = obs_delayed(z, u_in);
    if ((OBS_DELAY > 0 && OBS_P[22] == R(1.0)) || OBS_MODEL_FORM) {  /* zhat_in: a prediction */
        obs_correct(T, z, y, corrected);
        zhat = corrected;
    }
#if OBS_MODEL_FORM
    u = u + DIV(obs_model(T, zhat[0], zhat[1]), T[2]);  /* the model's acceleration as input */
#endif
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
