/* Controller kind "flc": feedback linearization (eq. 14-16), the C twin of
 * esoarm.controllers.flc.  CTL_P is the design vector without its CODE:
 *   [0] k1, [1] k2, [2] I0, [3] gcoef, [4] compensation (0 eso, 1 model), [5] torque limit.
 * [0..2] are read from T, the instance's copy (ctl_retune).
 * ref = (theta_d, omega_d, accel_d) at this sample; first: the first sample of a run.
 * Returns the raw command [N m].
 */
#define CTL_NC 1
/* T[CTL_NP] = 1 / I0 (ctl_derive): no division in the step */
#define CTL_NEXTRA 1

/* Run-time tuning (esoarm_set_params): T is the instance's copy of CTL_P; k1, k2 and
 * I0 = 1 / b0 (the plant's nominal input gain) are replaced. */
static int ctl_retune(esoarm_real T[], esoarm_real k1, esoarm_real k2, esoarm_real b0)
{
    T[0] = k1;
    T[1] = k2;
    T[2] = R(1.0) / b0;
    return 0;
}

static void ctl_derive(esoarm_real T[])
{
    T[CTL_NP] = R(1.0) / T[2];
}

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    (void)y;
    c[0] = R(0.0);
}

static esoarm_real ctl_control(const esoarm_real T[], esoarm_real c[],
                               const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint8_t first)
{
    esoarm_real alpha, beta_hat;
    (void)c; (void)y; (void)first;
    /* alpha = accel_d - k1 (z2 - omega_d) - k2 (z1 - theta_d)      (eq. 16) */
    alpha = ref[2] - T[0] * (zhat[1] - ref[1]) - T[1] * (zhat[0] - ref[0]);
    if (CTL_P[4] == R(0.0)) beta_hat = zhat[2];
#if ESOARM_RECIPROCAL
    else beta_hat = -(CTL_P[3] * COS(zhat[0])) * T[CTL_NP];
#else
    else beta_hat = -(CTL_P[3] * COS(zhat[0])) / T[2];
#endif
    /* u = I0 (alpha - beta_hat)                                      (eq. 14) */
    return T[2] * (alpha - beta_hat);
}
