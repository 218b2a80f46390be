/* The actuator on the chip: saturation and, with a [motor] table, the torque ->
 * PWM duty map with back-EMF compensation and deadband pre-compensation; the C
 * twin of esoarm.plants.actuator.actuate and esoarm.plants.motor.
 * ACT_P = (torque limit, motor flag, stall gain, damping, pwm_max, deadband, PWM levels
 * 2^pwm_bits - 1 of a drive without a motor model, 0 for none, 1 when the observer is fed
 * the command before saturation, the ESO's gate band at an end stop [rad] (0 none), the
 * lower and upper stop [rad]; with a learned table (ACT_FF_N > 0 bins): N.  The table's N
 * torques -I0 m_i [N m] at theta_i = 2 pi i / N are ACT_FF, their slopes to the next node
 * ACT_FF_D, read as ACT_FF_AT(i) and ACT_FF_D_AT(i) (on the AVR from flash, PROGMEM).  The
 * motor's maps use constants the generator folded (ACT_DUTY_*, ACT_TORQUE_*).
 * DIV(a, b): a / b (float64), a · (1/b) with 1/b folded by the compiler (float32).
 */
#if defined(__AVR__)
/* avr-gcc compares floats in software (about 70 cycles a comparison); binary32 magnitudes
 * are ordered as their bit patterns (NaN's above infinity's), so a comparison of |x| with a
 * non-negative constant is one of two integers, the constant's folded by the compiler. */
typedef union { esoarm_real f; uint32_t u; } act_bits;
static inline uint32_t act_mag(esoarm_real x) { act_bits b; b.f = x; return b.u & 0x7FFFFFFFul; }
static inline uint8_t act_sign(esoarm_real x) { act_bits b; b.f = x; return (uint8_t)(b.u >> 31); }
#define ACT_MAG_LE(x, c) (act_mag(x) <= act_mag(c))   /* |x| <= c; false for NaN */
#define ACT_MAG_LT(x, c) (act_mag(x) < act_mag(c))     /* |x| < c; false for NaN */
#define ACT_NEGATIVE(x) (act_sign(x) != 0)             /* x < 0, or -0 */
#define ACT_ZERO(x) (act_mag(x) == 0ul)                /* x == 0 */
#else
#define ACT_MAG_LE(x, c) (FABS(x) <= (c))
#define ACT_MAG_LT(x, c) (FABS(x) < (c))
#define ACT_NEGATIVE(x) ((x) < R(0.0))
#define ACT_ZERO(x) ((x) == R(0.0))
#endif

static esoarm_real act_saturate(esoarm_real u, esoarm_real limit)
{
    if (ACT_MAG_LE(u, limit) || isnan(u)) return u;   /* NaN passes through */
    return COPYSIGN(limit, u);
}

#if ESOARM_RECIPROCAL
/* float32: motor.torque_to_duty of t = torque + D omega [N m]: frac = t / K clipped to +-1,
 * then +-(db + (1 - db) |frac|) times P, rounded half to even.  Returned: its magnitude
 * rint(P db + min(|t| P (1 - db) / K, P (1 - db))) [counts] (the constants folded by the
 * generator, ACT_DUTY_*: one product and one sum), whose sign is t's; 0 for a t that is 0
 * or not finite. */
static long act_duty_counts(esoarm_real t)
{
    esoarm_real mag;
    if (!ISFINITE(t) || ACT_ZERO(t)) return 0;
    mag = FABS(t) * ACT_DUTY_GAIN;
    if (!ACT_MAG_LE(mag, ACT_DUTY_TOP)) mag = ACT_DUTY_TOP;
    return LRINT(mag + ACT_DUTY_DB);
}
#else
/* float64: motor.torque_to_duty and motor.source_torque operation by operation (the
 * Python's roundings: float64 repeats the reference's u to the bit). */
static esoarm_real act_torque_to_duty(esoarm_real t)
{
    esoarm_real frac = t / ACT_P[2];
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
    esoarm_real frac = duty / ACT_P[4];
    esoarm_real db = ACT_P[5];
    esoarm_real mag = (FABS(frac) - db) / (R(1.0) - db);
    if (mag <= R(0.0)) return ACT_P[2] * R(0.0);
    if (mag > R(1.0)) mag = R(1.0);
    return ACT_P[2] * COPYSIGN(mag, frac);
}
#endif

/* The ESO's b0 u term gated: y [rad] within the band of an end stop and the observer's
 * input u [N m] pushing into it (esoarm.plants.actuator.gated). */
static int act_gated(esoarm_real y, esoarm_real u)
{
    esoarm_real band = ACT_P[8];
    if (!(band > R(0.0))) return 0;
    return (y >= ACT_P[10] - band && u > R(0.0)) || (y <= ACT_P[9] + band && u < R(0.0));
}

/* The back-EMF compensation D rate [N m] at the estimated rate [rad/s] (0 without a motor):
 * what the torque -> duty map adds, and what the host's torque lacks. */
static esoarm_real act_back_emf(esoarm_real rate)
{
    if (ACT_P[1] == R(0.0)) return R(0.0);
    return ACT_P[3] * rate;
}

/* u: saturated command [N m]; emf: act_back_emf.  Sets the torque driving the plant and the
 * duty [counts] (0 without a motor).  With a motor (float32) the drive is motor.source_torque
 * of the duty d: K sign(d) min(max(0, (|d| / P - db) / (1 - db)), 1), as |d| K / (P (1 - db)) -
 * K db / (1 - db) (ACT_TORQUE_*) for the |d| above the deadband's ACT_DUTY_DEAD counts, 0 at
 * or below; |d| <= P, so the min is 1 only where the product is K. */
static void act_drive(esoarm_real u, esoarm_real emf, esoarm_real *drive, esoarm_real *duty)
{
    esoarm_real t;
    if (ACT_P[1] == R(0.0)) {
        if (ACT_P[6] > R(0.0)) {   /* actuator.pwm_bits: M = ACT_P[6] levels per sign */
            *duty = RINT(DIV(u, ACT_P[0]) * ACT_P[6]);
            *drive = DIV(ACT_P[0] * *duty, ACT_P[6]);
            return;
        }
        *drive = u; *duty = R(0.0);
        return;
    }
    t = u + emf;
#if ESOARM_RECIPROCAL
    {
        long n = act_duty_counts(t);
        esoarm_real counts = (esoarm_real)n;
        *duty = COPYSIGN(counts, t);
        *drive = n > ACT_DUTY_DEAD ? COPYSIGN(counts * ACT_TORQUE_GAIN - ACT_TORQUE_DB, t)
                                   : R(0.0);
    }
#else
    *duty = act_torque_to_duty(t);
    *drive = act_source_torque(*duty);
#endif
}

/* act_drive, and the torque the controller believes it applies (fed to the observer): the
 * drive less the back-EMF the map compensated. */
static void act_actuate(esoarm_real u, esoarm_real emf, esoarm_real *applied,
                        esoarm_real *drive, esoarm_real *duty)
{
    act_drive(u, emf, drive, duty);
    *applied = ACT_P[1] == R(0.0) ? *drive : *drive - emf;
}

#if ACT_FF_N > 0
/* The learned table's torque at the estimated angle [rad]: -I0 m(angle), linear between
 * the N nodes theta_i = 2 pi i / N, periodic; the C twin of esoarm.plants.actuator.feedforward.
 * x = angle N / (2 pi) is one product (ACT_FF_SCALE = N / (2 pi): no division, which the
 * AVR does in software); the node below x is x truncated to an integer, one less where x is
 * negative and not whole, and its fraction x less that integer (exact); the node is wrapped
 * into [0, N) by subtracting N 2^k where it is not larger, k from the largest that fits in
 * 16 bits (ACT_FF_TOP) down to 0 (no division; ACT_FF_OFFSET, a multiple of N, makes it
 * non-negative first); the value is node plus fraction times the node's slope (ACT_FF_D:
 * one product).  On the ATmega328P
 * (uno-rig at 1 kHz) the lookup and the sum of its torque take 0.88k cycles a step, where
 * floorf, a 16-bit modulo and two products took 1.43k.  |x| >= 30000 (a diverged estimate,
 * or NaN) gives 0. */
static esoarm_real act_feedforward(esoarm_real angle)
{
    esoarm_real x = angle * ACT_FF_SCALE;
    esoarm_real frac;
    long below;
    uint16_t i, m;
    if (!ACT_MAG_LT(x, R(30000.0))) return R(0.0);
    below = (long)x;   /* toward zero */
    frac = x - (esoarm_real)below;
    if (ACT_NEGATIVE(frac)) {
        frac += R(1.0);
        --below;
    }
    i = (uint16_t)(below + (long)ACT_FF_OFFSET);
    for (m = ACT_FF_TOP; m >= ACT_FF_N; m = (uint16_t)(m >> 1))
        if (i >= m) i = (uint16_t)(i - m);
    return ACT_FF_AT(i) + frac * ACT_FF_D_AT(i);
}
#endif
