/*
 * esoarm rig firmware: encoder, fixed-rate sampling, PWM motor drive, protocol.
 *
 * Board: Arduino Uno/Nano class (ATmega328P, 16 MHz) or any Arduino core board
 * with two interrupt pins.  Encoder: HN3806-style quadrature encoder (A/B open
 * collector, pull-ups), decoded x4 by interrupts on both channels.  Driver:
 * L298N-style (ENA = PWM, IN1/IN2 = direction) by default, or BTS7960-style
 * (RPWM/LPWM) with -DESOARM_DRIVER_BTS7960 or the #define below.
 *
 * The host (esoarm run) owns the control law; this device only measures,
 * applies the duty and keeps the motor safe:
 *   - HELLO -> INFO (protocol version, counts/rev, PWM range, sample period)
 *   - START -> sample counter and clock reset, SAMPLE every SAMPLE_PERIOD_US
 *   - DUTY  -> motor duty (signed, |duty| <= PWM_MAX), held until the next one
 *   - STOP  -> motor off, sampling stops, STOPPED
 *   - watchdog: no valid DUTY within 100 ms -> motor off, FAULT(WATCHDOG);
 *     the motor stays off until the next START
 *   - encoder check: both lines changed between two interrupts (a glitch, or an
 *     edge missed) -> motor off, FAULT(ENCODER); off until the next START
 * Corrupted or partial frames are counted and skipped by the parser in
 * esoarm_protocol.h (the same rule as the Python host; see docs/protocol.md).
 * See docs/hardware.md for wiring, flashing and the first run.
 */
#include "esoarm_protocol.h"

/* ---- configuration (match the scenario: sensor.rate_hz, sensor.resolution_deg) ---- */
/* Each can also be set from the build: make -C firmware SAMPLE_PERIOD_US=1000 BAUD=1000000 */
#ifndef SAMPLE_PERIOD_US
#define SAMPLE_PERIOD_US 20000UL   /* 50 Hz, as in the paper */
#endif
#ifndef ENCODER_PPR
#define ENCODER_PPR 600UL          /* HN3806-600BM: 600 pulses/rev per channel */
#endif
#define COUNTS_PER_REV (4UL * ENCODER_PPR) /* x4 decoding: 2400 -> 0.15 deg */
#define PWM_MAX 255                /* analogWrite range on AVR */
#define WATCHDOG_MS 100UL
#ifndef BAUD
#define BAUD 115200UL              /* 1000000 for 1 kHz sampling (see docs/hardware.md) */
#endif

#define PIN_ENC_A 2                /* interrupt pins on Uno/Nano */
#define PIN_ENC_B 3
/* #define ESOARM_DRIVER_BTS7960 */
#ifdef ESOARM_DRIVER_BTS7960
#define PIN_RPWM 9
#define PIN_LPWM 10
#else
#define PIN_PWM 9                  /* L298N ENA */
#define PIN_IN1 7
#define PIN_IN2 8
#endif

static volatile int32_t encoder_count = 0;
static volatile uint8_t encoder_state = 0;
static volatile uint8_t encoder_errors = 0;   /* invalid transitions since START (saturates) */
/* x4 quadrature table: index = (previous AB << 2) | current AB -> step; QUAD_BAD where
 * both lines changed between two reads (a glitch, or an edge missed): the count is wrong */
#define QUAD_BAD 2
static const int8_t QUAD_TABLE[16] = {0, +1, -1, QUAD_BAD, -1, 0, QUAD_BAD, +1,
                                      +1, QUAD_BAD, 0, -1, QUAD_BAD, -1, +1, 0};

#ifdef ESOARM_ONBOARD
/* On-board mode (make -C firmware ONBOARD=DIR): the generated observer and controller of
 * `esoarm codegen SCENARIO --target avr --out DIR` run here at every sample and drive the
 * motor; DUTY frames are then only the host's heartbeat (the watchdog still needs them),
 * their duty is ignored.  SAMPLE frames stream every sample's count as before. */
#include "esoarm_controller.c"
static esoarm_state ctl;
static const esoarm_real COUNT_TO_RAD = (esoarm_real)(6.283185307179586 / COUNTS_PER_REV);
#endif

static eso_parser_t parser;
static uint8_t tx_seq = 0;
static uint8_t frame_buf[ESO_MAX_FRAME];

static bool running = false;
static bool watchdog_tripped = false;
static bool encoder_fault = false;
static uint32_t sample_k = 0;
static uint32_t t_start_us = 0;
static uint32_t next_sample_us = 0;
static uint32_t last_command_ms = 0;

/* The encoder levels AB (bit 1 = A, bit 0 = B). */
static inline uint8_t read_ab()
{
#if defined(__AVR_ATmega328P__) && PIN_ENC_A == 2 && PIN_ENC_B == 3
    uint8_t pins = PIND; /* Uno/Nano: A = PD2, B = PD3, sampled in one instruction */
    return (uint8_t)(((pins >> 1) & 0x02u) | ((pins >> 3) & 0x01u));
#else
    return (uint8_t)((digitalRead(PIN_ENC_A) << 1) | digitalRead(PIN_ENC_B));
#endif
}

static void encoder_isr()
{
    uint8_t ab = read_ab();
    int8_t step = QUAD_TABLE[(encoder_state << 2) | ab];
    if (step == QUAD_BAD) {
        if (encoder_errors < 255) encoder_errors++;
    } else {
        encoder_count += step;
    }
    encoder_state = ab;
}

static int32_t read_encoder()
{
    int32_t c;
    noInterrupts();
    c = encoder_count;
    interrupts();
    return c;
}

static void motor_write(int16_t duty)
{
    if (duty > PWM_MAX) duty = PWM_MAX;
    if (duty < -PWM_MAX) duty = -PWM_MAX;
#ifdef ESOARM_DRIVER_BTS7960
    analogWrite(PIN_RPWM, duty > 0 ? duty : 0);
    analogWrite(PIN_LPWM, duty < 0 ? -duty : 0);
#else
    digitalWrite(PIN_IN1, duty > 0 ? HIGH : LOW);
    digitalWrite(PIN_IN2, duty < 0 ? HIGH : LOW);
    analogWrite(PIN_PWM, duty >= 0 ? duty : -duty);
#endif
}

static void motor_off() { motor_write(0); }

static void send_frame(uint8_t len)
{
    if (len) Serial.write(frame_buf, len);
    tx_seq++;
}

static void send_empty(uint8_t type)
{
    send_frame(eso_encode(frame_buf, type, tx_seq, 0, 0));
}

static void handle_frame(const eso_frame_t *f)
{
    switch (f->type) {
    case ESO_HELLO:
        send_frame(eso_encode_info(frame_buf, tx_seq, 0, COUNTS_PER_REV, PWM_MAX,
                                   SAMPLE_PERIOD_US));
        break;
    case ESO_START:
        motor_off();
        noInterrupts();
        encoder_count = 0;   /* the angle at START is theta = 0 */
        encoder_errors = 0;
        interrupts();
        encoder_fault = false;
        sample_k = 0;
        t_start_us = micros();
        next_sample_us = t_start_us;
        last_command_ms = millis();
        watchdog_tripped = false;
#ifdef ESOARM_ONBOARD
        esoarm_init(&ctl);
#endif
        running = true;
        break;
    case ESO_DUTY: {
        int16_t duty = (int16_t)eso_get_u16(f->payload + 4);
        if (duty > PWM_MAX || duty < -PWM_MAX) {
            motor_off();
            send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_BAD_COMMAND,
                                        eso_get_u32(f->payload)));
            break;
        }
        if (!running || watchdog_tripped || encoder_fault) break;
        last_command_ms = millis();
#ifndef ESOARM_ONBOARD
        motor_write(duty);
#endif
        break;
    }
    case ESO_STOP:
        motor_off();
        running = false;
        send_empty(ESO_STOPPED);
        break;
    default: /* TORQUE is for the emulator only */
        send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_BAD_COMMAND, f->type));
        break;
    }
}

void setup()
{
    pinMode(PIN_ENC_A, INPUT_PULLUP);
    pinMode(PIN_ENC_B, INPUT_PULLUP);
#ifdef ESOARM_DRIVER_BTS7960
    pinMode(PIN_RPWM, OUTPUT);
    pinMode(PIN_LPWM, OUTPUT);
#else
    pinMode(PIN_PWM, OUTPUT);
    pinMode(PIN_IN1, OUTPUT);
    pinMode(PIN_IN2, OUTPUT);
#endif
    motor_off();
    encoder_state = read_ab();
    attachInterrupt(digitalPinToInterrupt(PIN_ENC_A), encoder_isr, CHANGE);
    attachInterrupt(digitalPinToInterrupt(PIN_ENC_B), encoder_isr, CHANGE);
    eso_parser_init(&parser);
    Serial.begin(BAUD);
}

void loop()
{
    eso_frame_t f;
    while (Serial.available() > 0) {
        eso_parser_push(&parser, (uint8_t)Serial.read());
        while (eso_parser_next(&parser, &f)) handle_frame(&f);
    }
    if (!running) return;

    if (!watchdog_tripped && (uint32_t)(millis() - last_command_ms) > WATCHDOG_MS) {
        motor_off();
        watchdog_tripped = true;
        send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_WATCHDOG, sample_k));
    }

    if (!encoder_fault && encoder_errors != 0) {
        /* the angle can no longer be trusted: motor off until the next START */
        motor_off();
        encoder_fault = true;
        send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_ENCODER, sample_k));
    }

    uint32_t now = micros();
    if ((int32_t)(now - next_sample_us) >= 0) {
        int32_t count = read_encoder();
#ifdef ESOARM_ONBOARD
        if (!watchdog_tripped && !encoder_fault) {
            esoarm_step(&ctl, (esoarm_real)count * COUNT_TO_RAD);
            motor_write((int16_t)ctl.duty);
        }
#endif
        if ((uint32_t)(now - next_sample_us) > SAMPLE_PERIOD_US) {
            /* more than a whole period late: report it, then keep the grid */
            send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_OVERRUN, sample_k));
        }
        send_frame(eso_encode_sample(frame_buf, tx_seq, sample_k, now - t_start_us, count));
        sample_k++;
        next_sample_us += SAMPLE_PERIOD_US;
    }
}
