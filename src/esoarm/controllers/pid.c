/* Controller kind "pid": the discrete PID of esoarm.controllers.pid in C.
 * CTL_P is the design vector without its CODE: [0] kp, [1] ki, [2] kd, [3] Tf,
 * [4] torque limit, [5] Ts, [6] compensation (0 none, 1 eso: u -= zhat3 / b0), [7] 1/b0.
 * State c = (integrator, filtered derivative, previous error).
 */
#define CTL_NC 3

/* The PID's gains are not among the run-time parameters (k1, k2 are the FLC's): a change
 * of k1 or k2 is refused; b0 sets [7] = 1/b0 (read from T, the instance's copy of CTL_P). */
static int ctl_retune(esoarm_real T[], esoarm_real k1, esoarm_real k2, esoarm_real b0)
{
    T[7] = R(1.0) / b0;
    return (k1 == R(0.0) && k2 == R(0.0)) ? 0 : -1;
}

static void ctl_initialize(esoarm_real c[], esoarm_real y)
{
    (void)y;
    c[0] = R(0.0); c[1] = R(0.0); c[2] = R(0.0);
}

static esoarm_real ctl_control(const esoarm_real T[], esoarm_real c[],
                               const esoarm_real zhat[], esoarm_real y,
                               const esoarm_real ref[3], uint8_t first)
{
    esoarm_real ts = CTL_P[5];
    esoarm_real e = ref[0] - y;
    esoarm_real e_prev = first ? e : c[2];
    esoarm_real a = DIV(CTL_P[3], CTL_P[3] + ts);
    esoarm_real der = a * c[1] + DIV(CTL_P[2] * (R(1.0) - a) * (e - e_prev), ts);
    esoarm_real comp = CTL_P[6] == R(1.0) ? -T[7] * zhat[2] : R(0.0);
    esoarm_real u = CTL_P[0] * e + c[0] + der + comp;
    esoarm_real limit = CTL_P[4];
    int saturated = (u > limit && e > R(0.0)) || (u < -limit && e < R(0.0));
    if (!saturated) c[0] = c[0] + CTL_P[1] * ts * e;
    c[1] = der;
    c[2] = e;
    return u;
}
