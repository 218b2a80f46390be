/*
 * esoarm fast engine: the sampled-data closed loop of esoarm.engines.simulation for a
 * block of LANES runs advanced together, runs as the innermost loop.
 *
 * Built at run time by esoarm.engines.fast with the system C compiler:
 *     cc -O3 -march=native -ffast-math -fopenmp-simd -fPIC -c   (then linked without
 *     -ffast-math, so the library does not switch the process to flush-to-zero)
 * Under -ffast-math glibc declares tanh, cos and sin as SIMD functions and the
 * lane loops call libmvec's vector versions (AVX-512: 8 runs per call).  The
 * results agree with the exact engine to round-off (relative 1e-9 is the
 * documented and tested tolerance), not bit for bit: vector transcendentals
 * and re-associated arithmetic differ from libm in the last bits.
 *
 * Semantics per sample k and run (see esoarm.engines.simulation.run_reference):
 *   y = Q(theta + sigma n_k); zhat from the ESO; u = sat(FLC(zhat, ref_k)), rounded to the
 *   PWM levels with actuator.pwm_bits;
 *   metrics of e = theta - ref, u, zhat3 - f; ESO update; rig RK4 over Ts with
 *   u_{k-delay} held, d(t) = damp sin(dfreq t) at each stage time.  With gear backlash
 *   the rig's state grows by the motor side (thm, omm) and the arm is driven by the
 *   gear's dead-zone torque (esoarm.plants.lever_arm.geared_advance).
 *   With actuator.observer_sees = "commanded" (P_SEES = 1) the ESO is fed, and the
 *   metrics see, the command before saturation and PWM (esoarm.engines.sample
 *   saturate_into/actuate_into); the plant gets the saturated one.  With rig.end_stops
 *   (stops_on) the arm stops dead after every RK4 step past a stop
 *   (esoarm.plants.lever_arm.stopped_advance) and its acceleration is 0 while pushed
 *   into one (stop_held); actuator.stop_gate (P_GATE > 0) feeds the ESO 0 while y is
 *   within the band of a stop and the command pushes into it
 *   (esoarm.plants.actuator.gated).
 *   With rig.cogging (cog_on) the arm feels A cos(n theta + phi) besides the drive in every
 *   derivative (esoarm.plants.lever_arm.cogging_torque); with controller.feedforward_map
 *   (ff_on) the drive is sat(u + t(zhat1)), t the lane's table of P_FF_N torques
 *   -I0 m_i linearly interpolated (esoarm.plants.actuator.actuate_with_table), while the
 *   ESO and the metrics see u.
 * Everything that is shared by the block (N, substeps, step, Ts, delay,
 * discretization, compensation, lag on/off, disturbance) is a scalar argument;
 * everything else is one value per lane in par[NPAR][LANES].
 *
 * Divergence (a value not finite, |theta| or |z1| >= limit) is detected with
 * bit tests, which -ffinite-math-only cannot optimise away.  The metrics of a
 * diverged lane are not trusted: esoarm.engines.fast re-runs such runs on the exact
 * engine.
 */
#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#include <stdint.h>
#include <string.h>

#define LANES 64

enum {
    P_THETA0, P_SIGMA, P_Q, P_B0,
    P_INERTIA, P_GCOEF, P_FC, P_VS, P_VISC, P_LAG,
    P_BETA1, P_BETA2, P_BETA3,
    P_PHI, P_GAMMA = P_PHI + 9, P_GAIN = P_GAMMA + 3,
    P_K1 = P_GAIN + 3, P_K2, P_I0, P_CGCOEF, P_LIMIT, P_PWM,
    P_ALPHA, P_JM, P_KGEAR, P_CGEAR,
    P_SEES, P_GATE, P_STOP_LO, P_STOP_HI,
    P_COG_A, P_COG_N, P_COG_P, P_FF_N,
    NPAR
};
enum { KIND_EULER, KIND_ZOH, KIND_CURRENT };
enum { M_SE, M_SU, M_ME, M_MU, M_SF, M_SR, M_SD, M_SAT, M_ROWS, M_DIV, NOUT };

int esoarm_fast_lanes(void) { return LANES; }
int esoarm_fast_npar(void) { return NPAR; }

/* esoarm.plants.backlash.gear_torque: the torque a gear with play +-alpha transmits
   (0 in the gap, else the spring-damper torque clamped to the side of contact), written
   with selects so that the lane loops stay vector loops */
static inline double gear_torque(double dl, double dd, double al, double k, double c) {
    double tp = k * (dl - al) + c * dd;
    double tn = k * (dl + al) + c * dd;
    tp = tp > 0.0 ? tp : 0.0;
    tn = tn < 0.0 ? tn : 0.0;
    return dl > al ? tp : (dl < -al ? tn : 0.0);
}

static inline int finite_bits(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return ((b >> 52) & 0x7ff) != 0x7ff;
}

static inline double lt_limit(double x, double lim) {
    /* |x| < lim, false for NaN, written with the bits of |x| so that it stays
       correct under -ffinite-math-only */
    uint64_t b, l;
    memcpy(&b, &x, sizeof b);
    memcpy(&l, &lim, sizeof l);
    return (b & 0x7fffffffffffffffULL) < l;
}

/*
 * Run one block (the body of esoarm_fast_block, at the end).
 *   nl                   lanes used (1 ... LANES); the loops run over nl rounded up to a
 *                        multiple of 8 (the extra lanes repeat valid data and are ignored)
 *   n, nsub, delay       samples, RK4 steps per sample, transport delay [samples]
 *   kind, comp, lag_on   discretization (0 euler, 1 zoh, 2 current), compensation
 *                        (0 eso, 1 model), actuator lag present (0/1)
 *   gear_on              gear backlash present (0/1): the plant is the two-mass drive
 *                        train of esoarm.plants.backlash, with the motor-side state
 *                        (thm, omm) starting at (theta0, 0); 0 is the rigid gear
 *   stops_on             hard end stops present (0/1): P_STOP_LO, P_STOP_HI per lane
 *   cog_on               a cogging torque present (0/1): P_COG_A, P_COG_N, P_COG_P per lane
 *   ff_on, ffmax, ff     a learned feedforward table present (0/1); lane l's P_FF_N torques
 *                        [N m] at ff[l * ffmax + i]
 *   h, ts, damp, dfreq   RK4 step [s], sample period [s], disturbance amplitude and
 *                        frequency
 *   limit                divergence limit on |theta|, |z1|
 *   par                  NPAR x LANES per-lane parameters
 *   refs                 reference rows; lane l uses refs[ref_off[l] + k] (theta_ref),
 *                        + stride (omega_ref), + 2 stride (accel_ref)
 *   noise                lane l uses noise[noise_off[l] + k]
 *   uhist                scratch, (delay + 1) x LANES doubles (used when delay > 0)
 *   out                  NOUT x LANES: sums of e^2, u^2, max|e|, max|u|, sum (z3-f)^2,
 *                        sum (z2-omega)^2, sum (u_k - u_{k-1})^2, saturated samples,
 *                        rows, diverged
 */
static inline __attribute__((always_inline)) void
block(int nl, long n, long nsub, long delay, int kind, int comp, int lag_on,
      int gear_on, int stops_on, int cog_on, int ff_on, long ffmax,
      const double *restrict ff, double h, double ts, double damp, double dfreq, double limit,
                       const double *restrict par, const double *restrict refs,
                       long stride, const int64_t *restrict ref_off,
                       const double *restrict noise, const int64_t *restrict noise_off,
                       double *restrict uhist, double *restrict out) {
    double th[LANES], om[LANES], ta[LANES], z1[LANES], z2[LANES], z3[LANES];
    double ua[LANES], alive[LANES];
    double se[LANES], su[LANES], sf[LANES], me[LANES], mu[LANES], rows[LANES];
    double sr[LANES], sd[LANES], ssat[LANES], uprev[LANES];
    double ref[LANES], dref[LANES], ddref[LANES], nz[LANES];
    double ivs[LANES], iin[LANES], ilag[LANES], iq[LANES];
    double thm[LANES], omm[LANES]; /* motor side with gear backlash (gear_on) */
#define P(i) (par + (i) * LANES)
    const double *theta0 = P(P_THETA0), *sigma = P(P_SIGMA), *q = P(P_Q), *b0 = P(P_B0);
    const double *inertia = P(P_INERTIA), *gcoef = P(P_GCOEF), *fc = P(P_FC), *vs = P(P_VS);
    const double *visc = P(P_VISC), *lag = P(P_LAG);
    const double *beta1 = P(P_BETA1), *beta2 = P(P_BETA2), *beta3 = P(P_BETA3);
    const double *k1 = P(P_K1), *k2 = P(P_K2), *i0 = P(P_I0), *cg = P(P_CGCOEF);
    const double *lim = P(P_LIMIT), *pwm = P(P_PWM);
    const double *galpha = P(P_ALPHA), *jm = P(P_JM), *kgear = P(P_KGEAR), *cgear = P(P_CGEAR);
    const double *sees = P(P_SEES), *gate = P(P_GATE), *slo = P(P_STOP_LO), *shi = P(P_STOP_HI);
    const double *coga = P(P_COG_A), *cogn = P(P_COG_N), *cogp = P(P_COG_P), *ffn = P(P_FF_N);
    const double *phi[9], *gam[3], *gain[3];
    for (int i = 0; i < 9; i++) phi[i] = P(P_PHI + i);
    for (int i = 0; i < 3; i++) { gam[i] = P(P_GAMMA + i); gain[i] = P(P_GAIN + i); }
#undef P
    const int nv = nl >= LANES ? LANES : ((nl + 7) / 8) * 8;
    for (int l = 0; l < LANES; l++) {
        th[l] = theta0[l]; om[l] = 0.0; ta[l] = 0.0;
        thm[l] = theta0[l]; omm[l] = 0.0; /* the gear centred in its play */
        double x = theta0[l] + sigma[l] * noise[noise_off[l]];
        z1[l] = q[l] > 0.0 ? q[l] * floor(x / q[l] + 0.5) : x;
        z2[l] = 0.0; z3[l] = 0.0;
        se[l] = su[l] = sf[l] = me[l] = mu[l] = 0.0;
        sr[l] = sd[l] = ssat[l] = uprev[l] = 0.0;
        rows[l] = (double)n; alive[l] = 1.0;
        ivs[l] = 1.0 / vs[l]; iin[l] = 1.0 / inertia[l];
        ilag[l] = lag[l] > 0.0 ? 1.0 / lag[l] : 0.0;
        iq[l] = q[l] > 0.0 ? 1.0 / q[l] : 1.0;
    }
    const double half = 0.5 * h, sixth = h / 6.0;
    /* rig.end_stops after an RK4 step (esoarm.plants.lever_arm.stopped_advance): an angle
       past a stop is set onto it and a rate into it to 0 (end stops exclude backlash) */
    /* rig.cogging's torque at angle X, in a lane loop with ca, cn, cp (0 without cogging) */
#define COG(X) (cog_on ? ca * cos(cn * (X) + cp) : 0.0)
#define STOP_DEAD(l)                                                                      \
    do {                                                                                  \
        double t_ = th[l], w_ = om[l];                                                    \
        int up_ = t_ >= shi[l], lo_ = !up_ && t_ <= slo[l];                               \
        th[l] = up_ ? shi[l] : (lo_ ? slo[l] : t_);                                       \
        om[l] = up_ ? (w_ < 0.0 ? w_ : 0.0) : (lo_ ? (w_ > 0.0 ? w_ : 0.0) : w_);         \
    } while (0)
    for (long k = 0; k < n; k++) {
        const double tk = k * ts;
        const double dk = damp * sin(dfreq * tk);
        for (int l = 0; l < nv; l++) {
            ref[l] = refs[ref_off[l] + k];
            dref[l] = refs[ref_off[l] + stride + k];
            ddref[l] = refs[ref_off[l] + 2 * stride + k];
            nz[l] = noise[noise_off[l] + k];
        }
        double *urow = delay > 0 ? uhist + (k % (delay + 1)) * LANES : ua;
        const double *uold = delay > 0 ? uhist + ((k + 1) % (delay + 1)) * LANES : ua;
        int any_dead = 0;
#pragma omp simd reduction(| : any_dead)
        for (int l = 0; l < nv; l++) {
            double x = th[l] + sigma[l] * nz[l];
            double y = q[l] > 0.0 ? q[l] * floor(x * iq[l] + 0.5) : x;
            double e = y - z1[l];
            double h1 = z1[l], h2 = z2[l], h3 = z3[l];
            if (kind == KIND_CURRENT) {
                h1 += gain[0][l] * e; h2 += gain[1][l] * e; h3 += gain[2][l] * e;
            }
            double alpha = ddref[l] - k1[l] * (h2 - dref[l]) - k2[l] * (h1 - ref[l]);
            double bh = comp == 0 ? h3 : -(cg[l] * cos(h1)) / i0[l];
            double raw = i0[l] * (alpha - bh);
            double sat = raw > lim[l] || raw < -lim[l] ? 1.0 : 0.0;
            const double usat = raw > lim[l] ? lim[l] : (raw < -lim[l] ? -lim[l] : raw);
            double u = usat;
            /* actuator.pwm_bits: the torque rounded to pwm = 2^bits - 1 levels per sign
               (esoarm.plants.actuator.actuate); pwm = 0: an ideal torque source */
            if (pwm[l] > 0.0) { double d = rint(u / lim[l] * pwm[l]); u = lim[l] * d / pwm[l]; }
            double drive = u;
            if (ff_on && ffn[l] > 0.0) {
                /* controller.feedforward_map: t(zhat1) in the drive, not in u
                   (esoarm.plants.actuator.feedforward; a non-finite estimate gives 0) */
                const double nb = ffn[l];
                double x = h1 / (2.0 * M_PI) * nb, tff = 0.0;
                if (lt_limit(x, 1e15)) {
                    x = x - nb * floor(x / nb);
                    long i = (long)floor(x);
                    long n_i = (long)nb;
                    i = i >= n_i ? n_i - 1 : (i < 0 ? 0 : i);
                    double frac = x - (double)i;
                    long j = i + 1 < n_i ? i + 1 : 0;
                    const double *tab = ff + (long)l * ffmax;
                    tff = (1.0 - frac) * tab[i] + frac * tab[j];
                }
                double ud = usat + tff;
                ud = ud > lim[l] ? lim[l] : (ud < -lim[l] ? -lim[l] : ud);
                if (pwm[l] > 0.0) {
                    double d = rint(ud / lim[l] * pwm[l]); ud = lim[l] * d / pwm[l];
                }
                drive = ud;
            }
            /* actuator.observer_sees = "commanded": the ESO is fed (and the log shows) the
               command itself; the plant is driven by its saturation */
            u = sees[l] != 0.0 ? raw : u;
            /* actuator.stop_gate: the ESO's input v = 0 at a stop while u pushes into it */
            const double v = gate[l] > 0.0 && ((y >= shi[l] - gate[l] && u > 0.0) ||
                                               (y <= slo[l] + gate[l] && u < 0.0)) ? 0.0 : u;
            double uap;
            if (delay > 0) {
                urow[l] = drive;
                uap = k >= delay ? uold[l] : 0.0;
            } else {
                uap = drive;
            }
            ua[l] = uap;
            double tq = gear_on ? gear_torque(thm[l] - th[l], omm[l] - om[l], galpha[l],
                                              kgear[l], cgear[l])
                                : (lag_on ? ta[l] : uap);
            double tcog = cog_on ? coga[l] * cos(cogn[l] * th[l] + cogp[l]) : 0.0;
            double acc = (tq + tcog - gcoef[l] * cos(th[l]) - (fc[l] * tanh(om[l] * ivs[l]) +
                          visc[l] * om[l])) * iin[l] + dk;
            if (stops_on && ((th[l] >= shi[l] && om[l] >= 0.0 && acc > 0.0) ||
                             (th[l] <= slo[l] && om[l] <= 0.0 && acc < 0.0)))
                acc = 0.0; /* held at an end stop (stop_held) */
            double f = acc - b0[l] * u;
            double err = th[l] - ref[l];
            double a = alive[l];
            se[l] += a * err * err; su[l] += a * u * u; sf[l] += a * (h3 - f) * (h3 - f);
            double dr = h2 - om[l], du = k > 0 ? u - uprev[l] : 0.0;
            sr[l] += a * dr * dr; sd[l] += a * du * du; ssat[l] += a * sat;
            uprev[l] = u;
            double ae = fabs(err) * a, au = fabs(u) * a;
            me[l] = ae > me[l] ? ae : me[l];
            mu[l] = au > mu[l] ? au : mu[l];
            int ok = finite_bits(th[l] + h2 + h3 + u) && lt_limit(th[l], limit) &&
                     lt_limit(h1, limit);
            if (!ok && a != 0.0) { rows[l] = (double)(k + 1); }
            double na = ok ? a : 0.0;
            alive[l] = na;
            any_dead |= !ok;
            /* ESO update */
            double n1, n2, n3;
            if (kind == KIND_EULER) {
                n1 = z1[l] + ts * (z2[l] + beta1[l] * e);
                n2 = z2[l] + ts * (z3[l] + b0[l] * v + beta2[l] * e);
                n3 = z3[l] + ts * (beta3[l] * e);
            } else {
                double a1 = kind == KIND_ZOH ? z1[l] : h1;
                double a2 = kind == KIND_ZOH ? z2[l] : h2;
                double a3 = kind == KIND_ZOH ? z3[l] : h3;
                n1 = phi[0][l] * a1 + phi[1][l] * a2 + phi[2][l] * a3 + gam[0][l] * v;
                n2 = phi[3][l] * a1 + phi[4][l] * a2 + phi[5][l] * a3 + gam[1][l] * v;
                n3 = phi[6][l] * a1 + phi[7][l] * a2 + phi[8][l] * a3 + gam[2][l] * v;
                if (kind == KIND_ZOH) {
                    n1 += gain[0][l] * e; n2 += gain[1][l] * e; n3 += gain[2][l] * e;
                }
            }
            /* a dead lane is parked at rest so it cannot produce inf/NaN work */
            z1[l] = na != 0.0 ? n1 : 0.0;
            z2[l] = na != 0.0 ? n2 : 0.0;
            z3[l] = na != 0.0 ? n3 : 0.0;
            th[l] = na != 0.0 ? th[l] : 0.0;
            om[l] = na != 0.0 ? om[l] : 0.0;
            ta[l] = na != 0.0 ? ta[l] : 0.0;
            thm[l] = na != 0.0 ? thm[l] : 0.0;
            omm[l] = na != 0.0 ? omm[l] : 0.0;
            ua[l] = na != 0.0 ? uap : 0.0;
        }
        (void)any_dead;
        /* rig: nsub RK4 steps, u held; d(t) shared by the block */
        for (long j = 0; j < nsub; j++) {
            const double t = tk + j * h;
            const double d1 = j == 0 ? dk : damp * sin(dfreq * t);
            const double d2 = damp * sin(dfreq * (t + half));
            const double d4 = damp * sin(dfreq * (t + h));
            if (gear_on) {
                /* the two-mass drive train (esoarm.plants.lever_arm.geared_advance):
                   I th'' = ts - G(th) - F(th') + I d, Jm thm'' = tau_a - ts */
#pragma omp simd
                for (int l = 0; l < nv; l++) {
                    double x0 = th[l], v0 = om[l], q0 = ta[l], m0 = thm[l], w0 = omm[l];
                    double uu = ua[l];
                    double gc = gcoef[l], f0 = fc[l], iv = ivs[l], vi = visc[l], ii = iin[l];
                    double il = ilag[l], al = galpha[l], kg = kgear[l], cgr = cgear[l];
                    double jj = jm[l];
                    double ca = coga[l], cn = cogn[l], cp = cogp[l];
#define GEAR_DERIV(X, V, Q, M, W, D, DX, DV, DQ, DM, DW)                                  \
                    do {                                                                  \
                        double tsg = gear_torque((M) - (X), (W) - (V), al, kg, cgr);      \
                        double tqa = lag_on ? (Q) : uu;                                   \
                        DX = (V);                                                         \
                        DV = (tsg + COG(X) - gc * cos(X) - (f0 * tanh((V) * iv) + vi * (V))) \
                             * ii                                                         \
                             + (D);                                                       \
                        DQ = lag_on ? (uu - (Q)) * il : 0.0;                              \
                        DM = (W);                                                         \
                        DW = (tqa - tsg) / jj;                                            \
                    } while (0)
                    double a1, b1, c1, e1, g1, a2, b2, c2, e2, g2;
                    double a3, b3, c3, e3, g3, a4, b4, c4, e4, g4;
                    GEAR_DERIV(x0, v0, q0, m0, w0, d1, a1, b1, c1, e1, g1);
                    GEAR_DERIV(x0 + half * a1, v0 + half * b1, q0 + half * c1,
                               m0 + half * e1, w0 + half * g1, d2, a2, b2, c2, e2, g2);
                    GEAR_DERIV(x0 + half * a2, v0 + half * b2, q0 + half * c2,
                               m0 + half * e2, w0 + half * g2, d2, a3, b3, c3, e3, g3);
                    GEAR_DERIV(x0 + h * a3, v0 + h * b3, q0 + h * c3,
                               m0 + h * e3, w0 + h * g3, d4, a4, b4, c4, e4, g4);
#undef GEAR_DERIV
                    th[l] = x0 + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                    om[l] = v0 + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
                    ta[l] = q0 + sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4);
                    thm[l] = m0 + sixth * (e1 + 2.0 * e2 + 2.0 * e3 + e4);
                    omm[l] = w0 + sixth * (g1 + 2.0 * g2 + 2.0 * g3 + g4);
                }
            } else if (lag_on) {
#pragma omp simd
                for (int l = 0; l < nv; l++) {
                    double x0 = th[l], v0 = om[l], q0 = ta[l], uu = ua[l];
                    double gc = gcoef[l], f0 = fc[l], iv = ivs[l], vi = visc[l], ii = iin[l];
                    double il = ilag[l];
                    double ca = coga[l], cn = cogn[l], cp = cogp[l];
                    double a1 = v0;
                    double b1 = (q0 + COG(x0) - gc * cos(x0) - (f0 * tanh(v0 * iv) + vi * v0)) * ii + d1;
                    double c1 = (uu - q0) * il;
                    double x2 = x0 + half * a1, v2 = v0 + half * b1, q2 = q0 + half * c1;
                    double a2 = v2;
                    double b2 = (q2 + COG(x2) - gc * cos(x2) - (f0 * tanh(v2 * iv) + vi * v2)) * ii + d2;
                    double c2 = (uu - q2) * il;
                    double x3 = x0 + half * a2, v3 = v0 + half * b2, q3 = q0 + half * c2;
                    double a3 = v3;
                    double b3 = (q3 + COG(x3) - gc * cos(x3) - (f0 * tanh(v3 * iv) + vi * v3)) * ii + d2;
                    double c3 = (uu - q3) * il;
                    double x4 = x0 + h * a3, v4 = v0 + h * b3, q4 = q0 + h * c3;
                    double a4 = v4;
                    double b4 = (q4 + COG(x4) - gc * cos(x4) - (f0 * tanh(v4 * iv) + vi * v4)) * ii + d4;
                    double c4 = (uu - q4) * il;
                    th[l] = x0 + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                    om[l] = v0 + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
                    ta[l] = q0 + sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4);
                    if (stops_on) STOP_DEAD(l);
                }
            } else {
#pragma omp simd
                for (int l = 0; l < nv; l++) {
                    double x0 = th[l], v0 = om[l], uu = ua[l];
                    double gc = gcoef[l], f0 = fc[l], iv = ivs[l], vi = visc[l], ii = iin[l];
                    double ca = coga[l], cn = cogn[l], cp = cogp[l];
                    double a1 = v0;
                    double b1 = (uu + COG(x0) - gc * cos(x0) - (f0 * tanh(v0 * iv) + vi * v0)) * ii + d1;
                    double x2 = x0 + half * a1, v2 = v0 + half * b1;
                    double a2 = v2;
                    double b2 = (uu + COG(x2) - gc * cos(x2) - (f0 * tanh(v2 * iv) + vi * v2)) * ii + d2;
                    double x3 = x0 + half * a2, v3 = v0 + half * b2;
                    double a3 = v3;
                    double b3 = (uu + COG(x3) - gc * cos(x3) - (f0 * tanh(v3 * iv) + vi * v3)) * ii + d2;
                    double x4 = x0 + h * a3, v4 = v0 + h * b3;
                    double a4 = v4;
                    double b4 = (uu + COG(x4) - gc * cos(x4) - (f0 * tanh(v4 * iv) + vi * v4)) * ii + d4;
                    th[l] = x0 + sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
                    om[l] = v0 + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
                    if (stops_on) STOP_DEAD(l);
                }
            }
        }
    }
#undef STOP_DEAD
#undef COG
    for (int l = 0; l < LANES; l++) {
        out[M_SE * LANES + l] = se[l];
        out[M_SU * LANES + l] = su[l];
        out[M_ME * LANES + l] = me[l];
        out[M_MU * LANES + l] = mu[l];
        out[M_SF * LANES + l] = sf[l];
        out[M_SR * LANES + l] = sr[l];
        out[M_SD * LANES + l] = sd[l];
        out[M_SAT * LANES + l] = ssat[l];
        out[M_ROWS * LANES + l] = rows[l];
        out[M_DIV * LANES + l] = alive[l] != 0.0 ? 0.0 : 1.0;
    }
}

/* The entry point (arguments: block above).  The block's flags for end stops, cogging and
 * a learned table are passed to the inlined body as constants in the common case where all
 * three are off, so that the compiler drops their code from the lane loops there (measured,
 * CPU time of 256 test-1 runs on one core: 1940 runs/s, within 1 % of the kernel before these
 * three were added; with the flags read at run time about 1600, 17 % slower). */
void esoarm_fast_block(int nl, long n, long nsub, long delay, int kind, int comp, int lag_on,
                       int gear_on, int stops_on, int cog_on, int ff_on, long ffmax,
                       const double *restrict ff, double h, double ts, double damp,
                       double dfreq, double limit, const double *restrict par,
                       const double *restrict refs, long stride,
                       const int64_t *restrict ref_off, const double *restrict noise,
                       const int64_t *restrict noise_off, double *restrict uhist,
                       double *restrict out) {
    if (!stops_on && !cog_on && !ff_on)
        block(nl, n, nsub, delay, kind, comp, lag_on, gear_on, 0, 0, 0, ffmax, ff, h, ts,
              damp, dfreq, limit, par, refs, stride, ref_off, noise, noise_off, uhist, out);
    else
        block(nl, n, nsub, delay, kind, comp, lag_on, gear_on, stops_on, cog_on, ff_on, ffmax,
              ff, h, ts, damp, dfreq, limit, par, refs, stride, ref_off, noise, noise_off,
              uhist, out);
}
