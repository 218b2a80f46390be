/* Controller kind "adrc-tf": linear ADRC in its minimum-footprint transfer-function form
 * (Herbst, arXiv:2104.01943) in the delta operator, the C twin of esoarm.controllers.adrc_tf.
 * CTL_P is the design vector without its CODE:
 *   [0..2] alpha1..3 * Ts, [3] Ts, [4..6] beta1..3 (y), [7..9] gamma1..3 (u_lim), [10] d,
 *   [11..13] feedforward I0 (k2, k1, 1), [14] the clip of the fed-back command: the torque
 *   limit, or 1e30 (observer_sees = "commanded": none).
 * State c = (x1, x2, x3).  Returns the raw command [N m].
 */
#define CTL_NC 3

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    /* the loop at rest at y0: every increment zero under y = y0, u = 0 */
    esoarm_real x1 = DIV(CTL_P[6] * y, CTL_P[2]);
    c[0] = x1;
    c[1] = DIV(CTL_P[0] * x1 - CTL_P[4] * y, CTL_P[3]);
    c[2] = DIV(CTL_P[1] * x1 - CTL_P[5] * y, CTL_P[3]);
}

static esoarm_real ctl_control(const esoarm_real T[], esoarm_real c[],
                               const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint8_t first)
{
    esoarm_real x1 = c[0], x2 = c[1], x3 = c[2], ts = CTL_P[3];
    esoarm_real ck = CTL_P[10] * y + x1;
    esoarm_real u = CTL_P[11] * ref[0] + CTL_P[12] * ref[1] + CTL_P[13] * ref[2] - ck;
    esoarm_real limit = CTL_P[14];
    esoarm_real ul = u > limit ? limit : (u < -limit ? -limit : u);
    (void)zhat; (void)first; (void)T;
    c[0] = x1 + (ts * x2 - CTL_P[0] * x1 + CTL_P[4] * y + CTL_P[7] * ul);
    c[1] = x2 + (ts * x3 - CTL_P[1] * x1 + CTL_P[5] * y + CTL_P[8] * ul);
    c[2] = x3 + (-CTL_P[2] * x1 + CTL_P[6] * y + CTL_P[9] * ul);
    return u;
}
