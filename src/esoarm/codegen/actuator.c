/* The actuator on the chip: saturation and, with a [motor] table, the torque ->
 * PWM duty map with back-EMF compensation and deadband pre-compensation; the C
 * twin of esoarm.plants.actuator.actuate and esoarm.plants.motor.
 * ACT_P = (torque limit, motor flag, stall gain, damping, pwm_max, deadband, PWM levels
 * 2^pwm_bits - 1 of a drive without a motor model, 0 for none).
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
