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
 * On-board mode (make -C firmware ONBOARD=DIR) runs the generated controller on the chip
 * instead: see the ESOARM_ONBOARD block below and docs/on-the-chip.md.
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
 * `esoarm codegen SCENARIO --target avr --out DIR` run in the Timer2 compare interrupt at
 * every sample and drive the motor; the host (esoarm run --onboard) only starts, stops and
 * supervises, and keeps the watchdog fed with HEARTBEAT frames (a DUTY or TORQUE frame is a
 * bad command here: motor off until the next START).  INFO carries ESO_FLAG_ONBOARD and is
 * followed by CHIP_INFO (stream decimation, observer sums, scenario hash); every
 * STREAM_EVERY-th sample is streamed as CHIP_SAMPLE (y as the count, u, the estimate, duty).
 * Faults end the run with the motor off until the next START: the watchdog (no HEARTBEAT
 * for 100 ms), an overrun (a sample due while the previous step still runs, or loop() RING - 1
 * frames behind the stream: the chip cannot step and stream in a period), the encoder check,
 * a bad command. */
#include "esoarm_controller.c"
#include "esoarm_reference.c"
static esoarm_state ctl;
static esoarm_reference ref;  /* the scenario's moves, from START */
static const esoarm_real COUNT_TO_RAD = (esoarm_real)(6.283185307179586 / COUNTS_PER_REV);

/* A CHIP_SAMPLE frame is 37 bytes of 10 bits on the wire; stream every STREAM_EVERY-th
 * sample so that the frames use at most 90 % of the line (1 at 1 kHz and 1 Mbit/s). */
#define CHIP_FRAME_BITS 370ULL
#define STREAM_EVERY_MIN ((CHIP_FRAME_BITS * 1000000ULL * 10ULL \
    + 9ULL * BAUD * SAMPLE_PERIOD_US - 1ULL) / (9ULL * BAUD * SAMPLE_PERIOD_US))
#ifndef STREAM_EVERY
#define STREAM_EVERY ((uint16_t)STREAM_EVERY_MIN)
#elif STREAM_EVERY < STREAM_EVERY_MIN || STREAM_EVERY > 65535
#error "STREAM_EVERY: the line cannot carry a frame that often (or it is over 65535)"
#endif
#if SAMPLE_PERIOD_US % 4 != 0
#error "on-board mode: SAMPLE_PERIOD_US must be a multiple of 4 us (Timer2 ticks at 4 us)"
#endif
#define TIMER2_TICKS (SAMPLE_PERIOD_US / 4UL)  /* Timer2 at clk/64: 4 us a tick */

typedef struct {
    uint32_t k, t_us;
    int32_t count;
    float u, z1, z2, z3;
    int16_t duty;
} chip_record_t;
#define RING 4u                                /* records between the ISR and loop() */
static chip_record_t ring[RING];
static volatile uint8_t ring_head = 0, ring_tail = 0;  /* ISR writes head, loop() tail */
static volatile bool step_busy = false;       /* a step is running (interrupts on) */
static volatile bool halted = false;          /* a fault: motor off until START */
static volatile uint8_t pending_fault = 0;    /* for loop() to report */
static volatile uint32_t pending_detail = 0;
static uint8_t subticks = 1;                  /* Timer2 compares per sample */
static volatile uint8_t subtick = 0;
static uint16_t stream_countdown = 0;         /* samples until the next streamed one */
static const char SCENARIO_HASH8[8] = {ESOARM_SCENARIO_HASH[0], ESOARM_SCENARIO_HASH[1],
    ESOARM_SCENARIO_HASH[2], ESOARM_SCENARIO_HASH[3], ESOARM_SCENARIO_HASH[4],
    ESOARM_SCENARIO_HASH[5], ESOARM_SCENARIO_HASH[6], ESOARM_SCENARIO_HASH[7]};
#endif

static eso_parser_t parser;
static uint8_t tx_seq = 0;
static uint8_t frame_buf[ESO_MAX_FRAME];

static volatile bool running = false;  /* read by the on-board ISR */
static bool watchdog_tripped = false;
static bool encoder_fault = false;
static volatile uint32_t sample_k = 0;
static volatile uint32_t t_start_us = 0;
static uint32_t next_sample_us = 0;
static volatile uint32_t last_command_ms = 0;

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

#ifndef ESOARM_ONBOARD
static int32_t read_encoder()
{
    int32_t c;
    noInterrupts();
    c = encoder_count;
    interrupts();
    return c;
}
#endif

static int16_t applied_duty = 0;  /* the duty on the pins (written by one side at a time) */

static void motor_write(int16_t duty)
{
    if (duty > PWM_MAX) duty = PWM_MAX;
    if (duty < -PWM_MAX) duty = -PWM_MAX;
    applied_duty = duty;
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

#ifdef ESOARM_ONBOARD
/* Interrupts off: stop the run with the motor off and leave the fault for loop(). */
static void halt_from_isr(uint8_t code, uint32_t detail)
{
    motor_off();
    halted = true;
    if (!pending_fault) {
        pending_fault = code;
        pending_detail = detail;
    }
}

/* The sample clock: Timer2 in CTC mode, `subticks` compares per sample. */
ISR(TIMER2_COMPA_vect)
{
    if (++subtick < subticks) return;
    subtick = 0;
    if (!running || halted) return;
    if (step_busy) { /* the previous step still runs: a whole period late */
        halt_from_isr(ESO_FAULT_OVERRUN, sample_k);
        return;
    }
    uint32_t now = micros();
    int32_t count = encoder_count;  /* interrupts are off: one read */
    if ((uint32_t)(millis() - last_command_ms) > WATCHDOG_MS) {
        halt_from_isr(ESO_FAULT_WATCHDOG, sample_k);
        return;
    }
    if (encoder_errors != 0) {  /* the angle can no longer be trusted */
        halt_from_isr(ESO_FAULT_ENCODER, sample_k);
        return;
    }
    if (sample_k == 0) t_start_us = now;  /* device time counts from sample 0 */
    uint32_t k = sample_k++;
    step_busy = true;
    sei();  /* the encoder and the UART keep running while the controller steps */
    esoarm_real r[3];
    esoarm_reference_next(&ref, r);
    esoarm_step(&ctl, (esoarm_real)count * COUNT_TO_RAD, r[0], r[1], r[2]);
    int16_t duty = (int16_t)ctl.duty;
    cli();
    if (running && !halted) {
        if (duty != applied_duty) motor_write(duty);  /* the pins cost ~300 cycles */
        /* every STREAM_EVERY-th sample from k = 0 (a countdown: k % n costs a 32-bit
         * division when n is not a power of two) */
        bool stream = stream_countdown == 0;
        stream_countdown = stream ? (uint16_t)(STREAM_EVERY - 1u) : (uint16_t)(stream_countdown - 1u);
        if (stream) {
            uint8_t next = (uint8_t)((ring_head + 1u) % RING);
            if (next == ring_tail) {
                /* loop() has not sent the last RING - 1 samples: step plus stream take more
                 * than a period, so samples would go unlogged -- an overrun too */
                halt_from_isr(ESO_FAULT_OVERRUN, k);
            } else {
                chip_record_t *r = &ring[ring_head];
                r->k = k;
                r->t_us = now - t_start_us;
                r->count = count;
                r->u = (float)ctl.applied;
                r->z1 = (float)ctl.zhat[0];
                r->z2 = (float)ctl.zhat[1];
                r->z3 = (float)ctl.zhat[2];
                r->duty = duty;
                ring_head = next;
            }
        }
    }
    step_busy = false;
}
#endif

#if defined(ESOARM_ONBOARD) && defined(__AVR_ATmega328P__)
/* On board the UART is driven here, not by HardwareSerial (never referenced, so the core's
 * HardwareSerial0 and its interrupts are not linked): its buffered write costs about 170
 * cycles a byte, 6k of the 16k cycles of a 1 kHz sample for a CHIP_SAMPLE frame; these
 * queues cost about 40 (measured in simavr: see docs/on-the-chip.md). */
#define TXQ 128u  /* powers of two */
#define RXQ 64u
static uint8_t txq[TXQ], rxq[RXQ];
static volatile uint8_t txq_head = 0, txq_tail = 0, rxq_head = 0, rxq_tail = 0;

ISR(USART_RX_vect)
{
    uint8_t b = UDR0;
    uint8_t next = (uint8_t)((rxq_head + 1u) & (RXQ - 1u));
    if (next != rxq_tail) {  /* full: the byte is lost, the parser resynchronises */
        rxq[rxq_head] = b;
        rxq_head = next;
    }
}

ISR(USART_UDRE_vect)
{
    uint8_t tail = txq_tail;
    if (tail == txq_head) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = txq[tail];
    txq_tail = (uint8_t)((tail + 1u) & (TXQ - 1u));
}

static void uart_begin()
{
    uint16_t ubrr = (uint16_t)((F_CPU / 4UL / BAUD - 1UL) / 2UL);  /* U2X, as the core */
    UCSR0A = _BV(U2X0);
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

static int uart_read()
{
    uint8_t tail = rxq_tail;
    if (tail == rxq_head) return -1;
    uint8_t b = rxq[tail];
    rxq_tail = (uint8_t)((tail + 1u) & (RXQ - 1u));
    return b;
}

#ifdef ESOARM_STREAM_POLLED
/* Polled streaming (make ... STREAM_POLLED=1): no transmit interrupt.  loop() hands the line
 * one byte whenever its data register is empty, and builds each CHIP_SAMPLE frame byte by byte
 * from the ring's record as it goes (the record's fields are the payload's, in order and
 * little-endian, so its bytes are the payload's), the CRC carried from byte to byte.  At a
 * line rate where a frame spans several samples the frame's cost spreads over them, about
 * 40 cycles a byte instead of the interrupt's ~100 (docs/on-the-chip.md, "The cycle
 * budget").  Control frames (INFO, FAULT, STOPPED) go through txq, never inside a streamed
 * frame. */
typedef char chip_record_is_the_payload[(sizeof(chip_record_t) == 30u) ? 1 : -1];
static chip_record_t tx_rec;
static uint8_t tx_pos = 0;  /* next byte of the streamed frame (0: none in progress) */
static uint16_t tx_crc;
/* No byte written yet: the data register is empty.  (A real USART sets UDRE0 at reset;
 * simavr 1.6 sets it only once a written byte has gone out, so the first write goes on this.) */
static bool tx_first = true;

static void tx_poll()
{
    uint8_t b;
    if (tx_pos == 0 && txq_tail == txq_head && ring_tail == ring_head) return;  /* nothing */
    if (!(UCSR0A & _BV(UDRE0)) && !tx_first) return;  /* the line is busy */
    if (tx_pos == 0) {
        uint8_t tail = txq_tail;
        if (tail != txq_head) {
            UDR0 = txq[tail];
            tx_first = false;
            txq_tail = (uint8_t)((tail + 1u) & (TXQ - 1u));
            return;
        }
        if (ring_tail == ring_head) return;
        noInterrupts();
        tx_rec = ring[ring_tail];
        interrupts();
        ring_tail = (uint8_t)((ring_tail + 1u) % RING);
        tx_crc = 0xFFFFu;
        b = ESO_SYNC0;
    } else if (tx_pos == 1) {
        b = ESO_SYNC1;
    } else if (tx_pos == 2) {
        b = ESO_CHIP_SAMPLE;
    } else if (tx_pos == 3) {
        b = tx_seq;
    } else if (tx_pos == 4) {
        b = 30u;
    } else if (tx_pos < ESO_HEADER_SIZE + 30u) {
        b = ((const uint8_t *)&tx_rec)[tx_pos - ESO_HEADER_SIZE];
    } else if (tx_pos == ESO_HEADER_SIZE + 30u) {
        b = (uint8_t)tx_crc;
    } else {
        b = (uint8_t)(tx_crc >> 8);
    }
    if (tx_pos >= 2u && tx_pos < ESO_HEADER_SIZE + 30u) tx_crc = eso_crc16_update(tx_crc, b);
    UDR0 = b;
    tx_first = false;
    if (++tx_pos == ESO_HEADER_SIZE + 30u + ESO_CRC_SIZE) {
        tx_pos = 0;
        tx_seq++;
    }
}
#endif

static void send_frame(uint8_t len)
{
    uint8_t i;
    for (i = 0; i < len; i++) {
        uint8_t next = (uint8_t)((txq_head + 1u) & (TXQ - 1u));
#ifdef ESOARM_STREAM_POLLED
        while (next == txq_tail) tx_poll();  /* full: feed the line (loop() only) */
        txq[txq_head] = frame_buf[i];
        txq_head = next;
#else
        while (next == txq_tail) {}  /* full: wait for the line (loop() only) */
        txq[txq_head] = frame_buf[i];
        txq_head = next;
        /* Not atomic (lds/ori/sts), but the only bit an ISR changes is UDRIE0 itself, and
         * setting it with bytes queued is right whatever the ISR did in between. */
        UCSR0B |= _BV(UDRIE0);
#endif
    }
    tx_seq++;
}
#else
static void uart_begin() { Serial.begin(BAUD); }

static int uart_read() { return Serial.available() > 0 ? Serial.read() : -1; }

static void send_frame(uint8_t len)
{
    if (len) Serial.write(frame_buf, len);
    tx_seq++;
}
#endif

static void send_empty(uint8_t type)
{
    send_frame(eso_encode(frame_buf, type, tx_seq, 0, 0));
}

static void handle_frame(const eso_frame_t *f)
{
    switch (f->type) {
    case ESO_HELLO:
#ifdef ESOARM_ONBOARD
        send_frame(eso_encode_info(frame_buf, tx_seq, ESO_FLAG_ONBOARD, COUNTS_PER_REV, PWM_MAX,
                                   SAMPLE_PERIOD_US));
        send_frame(eso_encode_chip_info(frame_buf, tx_seq, STREAM_EVERY,
                                        ESOARM_COMPENSATED ? ESO_SUMS_COMPENSATED : ESO_SUMS_PLAIN,
                                        SCENARIO_HASH8));
#else
        send_frame(eso_encode_info(frame_buf, tx_seq, 0, COUNTS_PER_REV, PWM_MAX,
                                   SAMPLE_PERIOD_US));
#endif
        break;
    case ESO_START:
#ifdef ESOARM_ONBOARD
        noInterrupts();
        running = false;
        interrupts();  /* (loop() never runs inside the ISR: no step is half done here) */
#endif
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
        esoarm_reference_init(&ref);
        noInterrupts();
        halted = false;
        pending_fault = 0;
        ring_head = ring_tail = 0;
        stream_countdown = 0;
        subtick = (uint8_t)(subticks - 1u);  /* sample 0 at the next compare */
        TCNT2 = 0;
        t_start_us = micros();
        running = true;
        interrupts();
#else
        running = true;
#endif
        break;
#ifdef ESOARM_ONBOARD
    case ESO_HEARTBEAT:
        noInterrupts();  /* the ISR reads it */
        if (running && !halted) last_command_ms = millis();
        interrupts();
        break;
    case ESO_DUTY:
    case ESO_TORQUE:  /* the chip runs its own controller: a host commanding it is wrong */
        noInterrupts();
        if (running && !halted) {
            motor_off();
            halted = true;
        }
        interrupts();
        send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_BAD_COMMAND, f->type));
        break;
#else
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
        motor_write(duty);
        break;
    }
#endif
    case ESO_STOP:
        noInterrupts();  /* the ISR writes the motor only while running */
        running = false;
        interrupts();
        motor_off();
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
    uart_begin();
#ifdef ESOARM_ONBOARD
    /* Timer2 (its PWM pins 3 and 11 are unused: D3 is encoder B) as the sample clock: CTC at
     * clk/64, the fewest compares per sample with at most 256 ticks each. */
    {
        uint32_t n = (TIMER2_TICKS + 255UL) / 256UL;
        while (TIMER2_TICKS % n) n++;
        subticks = (uint8_t)n;
        TCCR2A = _BV(WGM21);
        TCCR2B = _BV(CS22);
        OCR2A = (uint8_t)(TIMER2_TICKS / n - 1UL);
        TIMSK2 = _BV(OCIE2A);
    }
#endif
}

void loop()
{
    eso_frame_t f;
    int c;
    while ((c = uart_read()) >= 0) {
        eso_parser_push(&parser, (uint8_t)c);
        while (eso_parser_next(&parser, &f)) handle_frame(&f);
    }
#ifdef ESOARM_ONBOARD
    /* Stream what the ISR recorded, then report a fault it raised (after the samples
     * before it, so the host logs every one of them). */
#if defined(ESOARM_STREAM_POLLED) && defined(__AVR_ATmega328P__)
    tx_poll();
    if (pending_fault && ring_tail == ring_head && tx_pos == 0) {
#else
    while (ring_tail != ring_head) {
        chip_record_t r;
        noInterrupts();
        r = ring[ring_tail];
        interrupts();
        ring_tail = (uint8_t)((ring_tail + 1u) % RING);
        send_frame(eso_encode_chip_sample(frame_buf, tx_seq, r.k, r.t_us, r.count, r.u, r.z1,
                                          r.z2, r.z3, r.duty));
    }
    if (pending_fault) {
#endif
        uint8_t code;
        uint32_t detail;
        noInterrupts();
        code = pending_fault;
        detail = pending_detail;
        pending_fault = 0;
        interrupts();
        send_frame(eso_encode_fault(frame_buf, tx_seq, code, detail));
    }
#else
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
        if ((uint32_t)(now - next_sample_us) > SAMPLE_PERIOD_US) {
            /* more than a whole period late: report it, then keep the grid */
            send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_OVERRUN, sample_k));
        }
        send_frame(eso_encode_sample(frame_buf, tx_seq, sample_k, now - t_start_us, count));
        sample_k++;
        next_sample_us += SAMPLE_PERIOD_US;
    }
#endif
}
