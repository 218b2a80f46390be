/* The actuator on the chip: saturation and, with a [motor] table, the torque ->
 * PWM duty map with back-EMF compensation and deadband pre-compensation; the C
 * twin of esoarm.plants.actuator.actuate and esoarm.plants.motor.
 * ACT_P = (torque limit, motor flag, stall gain, damping, pwm_max, deadband, PWM levels
 * 2^pwm_bits - 1 of a drive without a motor model, 0 for none, 1 when the observer is fed
 * the command before saturation, the ESO's gate band at an end stop [rad] (0 none), the
 * lower and upper stop [rad]; with a learned table (ACT_FF_N > 0 bins): N.  The table's N
 * torques -I0 m_i [N m] at theta_i = 2 pi i / N are ACT_FF, read as ACT_FF_AT(i) (on the
 * AVR from flash, PROGMEM).
 * DIV(a, b): a / b (float64), a · (1/b) with 1/b folded by the compiler (float32).
 */
static esoarm_real act_saturate(esoarm_real u, esoarm_real limit)
{
    if (u > limit) return limit;
    if (u < -limit) return -limit;
    return u;   /* NaN passes through */
}

static esoarm_real act_torque_to_duty(esoarm_real torque, esoarm_real omega)
{
    esoarm_real frac = DIV(torque + ACT_P[3] * omega, ACT_P[2]);
    if (!ISFINITE(frac)) return R(0.0);
    if (frac > R(1.0)) frac = R(1.0);
    else if (frac < R(-1.0)) frac = R(-1.0);
    if (frac != R(0.0)) {
        esoarm_real db = ACT_P[5];
        frac = COPYSIGN(db + (R(1.0) - db) * FABS(frac), frac);
    }
    return RINT(frac * ACT_P[4]);   /* round half to even */
}

static esoarm_real act_source_torque(esoarm_real duty)
{
    esoarm_real frac = DIV(duty, ACT_P[4]);
    esoarm_real db = ACT_P[5];
    esoarm_real mag = DIV(FABS(frac) - db, R(1.0) - db);
    if (mag <= R(0.0)) return ACT_P[2] * R(0.0);
    if (mag > R(1.0)) mag = R(1.0);
    return ACT_P[2] * COPYSIGN(mag, frac);
}

/* The ESO's b0 u term gated: y [rad] within the band of an end stop and the observer's
 * input u [N m] pushing into it (esoarm.plants.actuator.gated). */
static int act_gated(esoarm_real y, esoarm_real u)
{
    esoarm_real band = ACT_P[8];
    if (!(band > R(0.0))) return 0;
    return (y >= ACT_P[10] - band && u > R(0.0)) || (y <= ACT_P[9] + band && u < R(0.0));
}

/* u: saturated command [N m]; rate: estimated rate [rad/s].  Sets the torque the
 * controller believes it applies (fed to the observer), the torque driving the
 * plant and the duty [counts] (0 without a motor). */
static void act_actuate(esoarm_real u, esoarm_real rate, esoarm_real *applied,
                        esoarm_real *drive, esoarm_real *duty)
{
    if (ACT_P[1] == R(0.0)) {
        if (ACT_P[6] > R(0.0)) {   /* actuator.pwm_bits: M = ACT_P[6] levels per sign */
            *duty = RINT(DIV(u, ACT_P[0]) * ACT_P[6]);
            *drive = DIV(ACT_P[0] * *duty, ACT_P[6]);
            *applied = *drive;
            return;
        }
        *applied = u; *drive = u; *duty = R(0.0);
        return;
    }
    *duty = act_torque_to_duty(u, rate);
    *drive = act_source_torque(*duty);
    *applied = *drive - ACT_P[3] * rate;
}

#if ACT_FF_N > 0
/* The learned table's torque at the estimated angle [rad]: -I0 m(angle), linear between
 * the N nodes theta_i = 2 pi i / N, periodic; the C twin of esoarm.plants.actuator.feedforward.
 * x = angle N / (2 pi) is one product (ACT_FF_SCALE = N / (2 pi): no division, which the
 * AVR does in software), and the node below x is wrapped into [0, N) in integer arithmetic:
 * the same node and fraction as the Python's to round-off, about 1.2k cycles fewer a step on
 * the ATmega328P.  |x| >= 30000 (a diverged estimate, or NaN) gives 0. */
static esoarm_real act_feedforward(esoarm_real angle)
{
    esoarm_real x = angle * ACT_FF_SCALE;
    esoarm_real below, frac;
    int i, j;
    if (!(FABS(x) < R(30000.0))) return R(0.0);
    below = FLOOR(x);
    frac = x - below;
    i = (int)below % ACT_FF_N;
    if (i < 0) i += ACT_FF_N;
    j = i + 1 < ACT_FF_N ? i + 1 : 0;
    return (R(1.0) - frac) * ACT_FF_AT(i) + frac * ACT_FF_AT(j);
}
#endif
