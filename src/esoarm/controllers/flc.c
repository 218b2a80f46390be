/* Controller kind "flc": feedback linearization (eq. 14-16), the C twin of
 * esoarm.controllers.flc.  CTL_P is the design vector without its CODE:
 *   [0] k1, [1] k2, [2] I0, [3] gcoef, [4] compensation (0 eso, 1 model), [5] torque limit.
 * ref = (theta_d, omega_d, accel_d) at sample k.  Returns the raw command [N m].
 */
#define CTL_NC 1

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    (void)y;
    c[0] = R(0.0);
}

static esoarm_real ctl_control(esoarm_real c[], const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint32_t k)
{
    esoarm_real alpha, beta_hat;
    (void)c; (void)y; (void)k;
    /* alpha = accel_d - k1 (z2 - omega_d) - k2 (z1 - theta_d)      (eq. 16) */
    alpha = ref[2] - CTL_P[0] * (zhat[1] - ref[1]) - CTL_P[1] * (zhat[0] - ref[0]);
    if (CTL_P[4] == R(0.0)) beta_hat = zhat[2];
    else beta_hat = DIV(-(CTL_P[3] * COS(zhat[0])), CTL_P[2]);
    /* u = I0 (alpha - beta_hat)                                      (eq. 14) */
    return CTL_P[2] * (alpha - beta_hat);
}
