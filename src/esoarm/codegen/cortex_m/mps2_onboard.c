/* On-board firmware for a Cortex-M4 with FPU on QEMU's mps2-an386: the generated observer and
 * controller run on the chip, the rig protocol (esoarm_protocol.h, the Uno firmware's) on UART1.
 *
 * QEMU models no motor and no encoder pins, so the arm's side of the board is a second UART,
 * the "pin link" (UART0), in lockstep with the digital twin on the host: it stands for the
 * timer in encoder mode (the count) and the PWM compare register (the duty) of a real board.
 * Per sample k of a run the chip sends the request 'S' k(u32) on the pin link, the twin answers
 * k(u32) and the encoder count (i32) of sample k -- that answer is the sample tick --, the chip steps the
 * controller on y = count * 2 pi / COUNTS_PER_REV and writes 'U' drive(f32) duty(i16)
 * running(u8) back: the twin holds that over [t_k, t_k+1).  On UART1 it streams CHIP_SAMPLE
 * frames (count, u, estimate, duty) to 'esoarm run --onboard', takes HELLO, START, STOP and the
 * HEARTBEAT that feeds its watchdog, and reports faults:
 *   - watchdog: no HEARTBEAT for WATCHDOG_SAMPLES samples (100 ms of the chip's clock);
 *   - overrun: a sample's work (step and frame) took more instructions than a sample period
 *     at CLOCK_HZ (QEMU's -icount: SysTick counts executed instructions, see cortex_m4.py);
 *   - bad command: a DUTY or TORQUE frame (the chip runs its own controller).
 * Every fault turns the motor off (drive 0, duty 0) until the next START.  The chip's clock is
 * the sample tick: t_us = k * SAMPLE_PERIOD_US.
 *
 * Between bytes the core sleeps (WFI, the UARTs' receive interrupts pending with PRIMASK set),
 * so QEMU does not spin a host core.
 */
#include <stdint.h>
#include <string.h>
#include "esoarm_protocol.h"
#include "esoarm_controller.h"
#include "esoarm_reference.h"

#ifndef SAMPLE_PERIOD_US
#error "SAMPLE_PERIOD_US is required"
#endif
#ifndef COUNTS_PER_REV
#error "COUNTS_PER_REV is required"
#endif
#ifndef PWM_MAX
#define PWM_MAX 255
#endif
#ifndef CLOCK_HZ
#define CLOCK_HZ 25000000UL
#endif
#ifndef ICOUNT_SHIFT
#define ICOUNT_SHIFT 8
#endif
#ifndef ONBOARD_SUMS
#error "ONBOARD_SUMS (ESO_SUMS_PLAIN or ESO_SUMS_COMPENSATED) is required"
#endif
#ifndef ONBOARD_FLAGS
#define ONBOARD_FLAGS ESO_FLAG_ONBOARD
#endif
#define WATCHDOG_SAMPLES ((100000UL + SAMPLE_PERIOD_US - 1UL) / SAMPLE_PERIOD_US)
/* SysTick ticks (40 ns at 25 MHz) -> instructions: n = ticks * (1e9 / CLOCK_HZ) / 2^shift */
#define BUDGET_INSTRUCTIONS ((uint32_t)((uint64_t)CLOCK_HZ * SAMPLE_PERIOD_US / 1000000ULL))

#define CORTEX_M_FPU
#include "cortex_m_startup.h"

#define UART_DATA(b) REG((b) + 0x000u)
#define UART_STATE(b) REG((b) + 0x004u)
#define UART_CTRL(b) REG((b) + 0x008u)
#define UART_INT(b) REG((b) + 0x00Cu)
#define UART_BAUDDIV(b) REG((b) + 0x010u)
#define PINS 0x40004000u /* UART0: the pin link to the twin */
#define HOST 0x40005000u /* UART1: the rig protocol */
#define NVIC_ISER0 REG(0xE000E100u)
#define NVIC_ICPR0 REG(0xE000E280u)
#define IRQ_UART0_RX 0u
#define IRQ_UART1_RX 2u

static int rx_ready(uint32_t base) { return (UART_STATE(base) & 2u) != 0u; }

static void put(uint32_t base, const uint8_t *p, unsigned n)
{
    while (n--) {
        while (UART_STATE(base) & 1u) {}
        UART_DATA(base) = *p++;
    }
}

static uint32_t ticks_now(void) { return SYST_CVR; }

static uint32_t instructions_since(uint32_t t0)
{
    uint32_t ticks = (t0 - SYST_CVR) & 0x00FFFFFFu; /* SysTick counts down */
    return (uint32_t)(((uint64_t)ticks * (1000000000ULL / CLOCK_HZ)) >> ICOUNT_SHIFT);
}

static esoarm_state ctl;
static esoarm_reference ref;  /* the scenario's moves, from START */
static eso_parser_t parser;
static uint8_t frame_buf[ESO_MAX_FRAME];
static uint8_t tx_seq;
static uint8_t running;     /* a run is in progress (START .. STOP or fault) */
static uint8_t waiting;     /* a count was requested from the twin */
static uint32_t sample_k;   /* the next sample */
static uint32_t beat_k;     /* sample of the last HEARTBEAT (or START) */
static uint8_t pin_buf[8];
static uint8_t pin_n;
static const char SCENARIO_HASH8[8] = {ESOARM_SCENARIO_HASH[0], ESOARM_SCENARIO_HASH[1],
    ESOARM_SCENARIO_HASH[2], ESOARM_SCENARIO_HASH[3], ESOARM_SCENARIO_HASH[4],
    ESOARM_SCENARIO_HASH[5], ESOARM_SCENARIO_HASH[6], ESOARM_SCENARIO_HASH[7]};
static const esoarm_real COUNT_TO_RAD = (esoarm_real)(6.283185307179586 / COUNTS_PER_REV);

static void send_frame(uint8_t len)
{
    if (len) put(HOST, frame_buf, len);
    tx_seq++;
}

/* 'U' drive(f32) duty(i16) running(u8): what the motor does from now on. */
static void pins_write(float drive, int16_t duty, uint8_t on)
{
    uint8_t b[8];
    b[0] = 'U';
    eso_put_f32(b + 1, drive);
    eso_put_u16(b + 5, (uint16_t)duty);
    b[7] = on;
    put(PINS, b, sizeof b);
}

static void request_count(void)
{
    uint8_t b[5];
    b[0] = 'S';
    eso_put_u32(b + 1, sample_k);
    put(PINS, b, sizeof b);
    waiting = 1;
}

static void fault(uint8_t code, uint32_t detail)
{
    running = 0;
    pins_write(0.0f, 0, 0);
    send_frame(eso_encode_fault(frame_buf, tx_seq, code, detail));
}

static void handle_frame(const eso_frame_t *f)
{
    switch (f->type) {
    case ESO_HELLO:
        send_frame(eso_encode_info(frame_buf, tx_seq, ONBOARD_FLAGS, COUNTS_PER_REV, PWM_MAX,
                                   SAMPLE_PERIOD_US));
        send_frame(eso_encode_chip_info(frame_buf, tx_seq, 1u,
                                        ONBOARD_SUMS,
                                        SCENARIO_HASH8));
        break;
    case ESO_START:
        esoarm_init(&ctl);
        esoarm_reference_init(&ref);
        sample_k = 0;
        beat_k = 0;
        running = 1;
        request_count(); /* an answer still due from before is for another k: dropped */
        break;
    case ESO_HEARTBEAT:
        if (running) beat_k = sample_k;
        break;
    case ESO_STOP:
        running = 0;
        pins_write(0.0f, 0, 0);
        send_frame(eso_encode(frame_buf, ESO_STOPPED, tx_seq, 0, 0));
        break;
    default: /* DUTY, TORQUE: the chip runs its own controller */
        if (running) {
            running = 0;
            pins_write(0.0f, 0, 0);
        }
        send_frame(eso_encode_fault(frame_buf, tx_seq, ESO_FAULT_BAD_COMMAND, f->type));
        break;
    }
}

/* The twin's count of sample k arrived: the sample tick. */
static void on_sample(int32_t count)
{
    uint32_t t0 = ticks_now(), used;
    uint32_t k = sample_k;
    int16_t duty;
    float drive;
    waiting = 0;
    if (!running) return;
    if (k - beat_k > WATCHDOG_SAMPLES) {
        fault(ESO_FAULT_WATCHDOG, k);
        return;
    }
    {
        esoarm_real r[3];
        esoarm_reference_next(&ref, r);
        (void)esoarm_step(&ctl, (esoarm_real)count * COUNT_TO_RAD, r[0], r[1], r[2]);
    }
    duty = (int16_t)ctl.duty;
    drive = (float)ctl.drive;
    pins_write(drive, duty, 1);
    send_frame(eso_encode_chip_sample(frame_buf, tx_seq, k, k * (uint32_t)SAMPLE_PERIOD_US, count,
                                      (float)ctl.applied, (float)ctl.zhat[0],
                                      (float)ctl.zhat[1], (float)ctl.zhat[2], duty));
    used = instructions_since(t0);
    if (used > BUDGET_INSTRUCTIONS) {
        fault(ESO_FAULT_OVERRUN, k);
        return;
    }
    sample_k = k + 1u;
    request_count();
}

int main(void)
{
    eso_frame_t f;
    UART_BAUDDIV(PINS) = 16;
    UART_BAUDDIV(HOST) = 16;
    UART_CTRL(PINS) = 0xBu; /* TX, RX, RX interrupt (bit 3) */
    UART_CTRL(HOST) = 0xBu;
    systick_start();
    eso_parser_init(&parser);
    __asm volatile("cpsid i" ::: "memory"); /* interrupts only wake the core (WFI) */
    NVIC_ISER0 = (1u << IRQ_UART0_RX) | (1u << IRQ_UART1_RX);
    pins_write(0.0f, 0, 0);
    for (;;) {
        UART_INT(PINS) = 0x2u; /* clear the latched receive interrupts, then look */
        UART_INT(HOST) = 0x2u;
        NVIC_ICPR0 = (1u << IRQ_UART0_RX) | (1u << IRQ_UART1_RX);
        while (rx_ready(HOST)) {
            eso_parser_push(&parser, (uint8_t)UART_DATA(HOST));
            while (eso_parser_next(&parser, &f)) handle_frame(&f);
        }
        while (rx_ready(PINS)) {
            uint8_t b = (uint8_t)UART_DATA(PINS);
            pin_buf[pin_n++] = b;
            if (pin_n == 8u) {
                pin_n = 0;
                if (waiting && eso_get_u32(pin_buf) == sample_k) on_sample((int32_t)eso_get_u32(pin_buf + 4));
            }
        }
        if (!rx_ready(HOST) && !rx_ready(PINS)) __asm volatile("wfi" ::: "memory");
    }
}
