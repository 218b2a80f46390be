/* Controller kind "switch": the PID, then ESO + FLC from switch_at (and back), bumpless; the
 * C twin of esoarm.controllers.switch.  CTL_P is the design vector without its CODE:
 *   [0..5] the PID's (kp, ki, kd, Tf, limit, Ts), [6..11] the FLC's (k1, k2, I0, gcoef,
 *   bumpless flag, limit), [12] k_switch, [13] k_back (-1: never), [14] offset decay.
 * State c = (I, D, e_{k-1}, mode, u_{k-1} applied, offset), then (C only) the sample
 * index k, counted here (exact in float32 up to 2^24 samples).  Returns the raw command [N m].
 */
#define CTL_NC 7

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    uint8_t i;
    (void)y;
    for (i = 0; i < CTL_NC; ++i) c[i] = R(0.0);
}

static esoarm_real ctl_control(const esoarm_real T[], esoarm_real c[],
                               const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint8_t first)
{
    esoarm_real kk = first ? R(0.0) : c[6];
    int flc_mode = kk >= CTL_P[12] && !(CTL_P[13] >= R(0.0) && kk >= CTL_P[13]);
    int bumpless = CTL_P[10] == R(1.0);
    esoarm_real e = ref[0] - y;
    esoarm_real u, limit = CTL_P[11];
    if (flc_mode) {
        /* u = I0 (accel_d - k1 (z2 - omega_d) - k2 (z1 - theta_d) - z3)      (eq. 14-16) */
        esoarm_real alpha = ref[2] - CTL_P[6] * (zhat[1] - ref[1]) - CTL_P[7] * (zhat[0] - ref[0]);
        esoarm_real u_flc = CTL_P[8] * (alpha - zhat[2]);
        if (c[3] == R(0.0)) {           /* PID -> FLC: enter from the last command */
            c[5] = (bumpless && !first) ? c[4] - u_flc : R(0.0);
            c[3] = R(1.0);
        }
        u = u_flc + c[5];
        c[5] = c[5] * CTL_P[14];
    } else {
        esoarm_real ts = CTL_P[5], e_prev, a, der;
        int saturated;
        if (c[3] == R(1.0)) {           /* FLC -> PID: restart from the last command */
            c[0] = bumpless ? c[4] - CTL_P[0] * e : R(0.0);
            c[1] = R(0.0);
            c[2] = e;
            c[3] = R(0.0);
        }
        e_prev = first ? e : c[2];
        a = DIV(CTL_P[3], CTL_P[3] + ts);
        der = a * c[1] + DIV(CTL_P[2] * (R(1.0) - a) * (e - e_prev), ts);
        u = CTL_P[0] * e + c[0] + der + R(0.0);
        saturated = (u > limit && e > R(0.0)) || (u < -limit && e < R(0.0));
        if (!saturated) c[0] = c[0] + CTL_P[1] * ts * e;
        c[1] = der;
        c[2] = e;
    }
    c[4] = u > limit ? limit : (u < -limit ? -limit : u);
    c[6] = kk + R(1.0);
    (void)T;
    return u;
}
