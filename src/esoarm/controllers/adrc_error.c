/* Controller kind "adrc-error": error-based linear ADRC, the C twin of
 * esoarm.controllers.adrc_error.  CTL_P is the design vector without its CODE:
 *   [0] discretization (0 euler, 1 zoh, 2 current), [1] Ts, [2] b0, [3..5] gain G,
 *   [6] Phi[0][2], [7] Gamma[0], [8] Gamma[1], [9] k1, [10] k2, [11] I0, [12] the clip of
 *   the ESO's input: the torque limit, or 1e30 (observer_sees = "commanded": none).
 * State c = the error ESO's z (e, de/dt, F).  Returns the raw command [N m].
 */
#define CTL_NC 3

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    (void)y;
    c[0] = R(0.0); c[1] = R(0.0); c[2] = R(0.0);
}

static esoarm_real ctl_control(const esoarm_real T[], esoarm_real c[],
                               const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint8_t first)
{
    esoarm_real e = ref[0] - y;
    esoarm_real z1, z2, z3, inno, h1, h2, h3, u, us, ts = CTL_P[1], limit = CTL_P[12];
    (void)zhat; (void)T;
    if (first) { c[0] = e; c[1] = R(0.0); c[2] = R(0.0); }
    z1 = c[0]; z2 = c[1]; z3 = c[2];
    inno = e - z1;
    h1 = z1; h2 = z2; h3 = z3;
    if (CTL_P[0] == R(2.0)) {           /* "current": zhat = z + Lc (e - z1) */
        h1 = z1 + CTL_P[3] * inno; h2 = z2 + CTL_P[4] * inno; h3 = z3 + CTL_P[5] * inno;
    }
    /* u = I0 (k2 zhat1 + k1 zhat2 + zhat3) */
    u = CTL_P[11] * (CTL_P[10] * h1 + CTL_P[9] * h2 + h3);
    us = u > limit ? limit : (u < -limit ? -limit : u);
    if (CTL_P[0] == R(2.0)) {           /* z+ = Phi zhat - Gamma u */
        c[0] = h1 + ts * h2 + CTL_P[6] * h3 - CTL_P[7] * us;
        c[1] = h2 + ts * h3 - CTL_P[8] * us;
        c[2] = h3;
    } else {                            /* z+ = Phi z - Gamma u + G (e - z1) */
        c[0] = z1 + ts * z2 + CTL_P[6] * z3 - CTL_P[7] * us + CTL_P[3] * inno;
        c[1] = z2 + ts * z3 - CTL_P[8] * us + CTL_P[4] * inno;
        c[2] = z3 + CTL_P[5] * inno;
    }
    return u;
}
