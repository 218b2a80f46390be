/* The processor-in-the-loop shell's main loop, shared by the Cortex-M0+ and Cortex-M4 shells
 * (m0_startup.c, m4_startup.c): each defines its UART (uart_init, getc_uart, putc_uart) and
 * includes this after cortex_m_startup.h.
 *
 * Per sample: the host sends y, theta_d, omega_d, accel_d (sizeof(esoarm_real) bytes each,
 * little endian); the shell steps the controller and answers u, drive, duty (esoarm_real
 * each) and the SysTick ticks the step took (uint32).  QEMU models no cycle counter: run
 * with -icount shift=N, the ticks count executed instructions (one instruction = 2^N ns of
 * virtual time).
 */
#ifndef ESOARM_CORTEX_M_PIL_H
#define ESOARM_CORTEX_M_PIL_H

#include "esoarm_controller.h"

static void put(const void *p, unsigned n)
{
    const uint8_t *b = (const uint8_t *)p;
    while (n--) putc_uart(*b++);
}

static esoarm_state S;

int main(void)
{
    uart_init();
    systick_start();
    esoarm_init(&S);
    for (;;) {
        union { esoarm_real r[4]; uint8_t b[4 * sizeof(esoarm_real)]; } in;
        uint32_t t0, t1, ticks;
        unsigned i;
        esoarm_real out[3];
        for (i = 0; i < sizeof in.b; ++i) in.b[i] = getc_uart();
        t0 = SYST_CVR;
        esoarm_step(&S, in.r[0], in.r[1], in.r[2], in.r[3]);
        t1 = SYST_CVR;
        ticks = (t0 - t1) & 0x00FFFFFFu;    /* SysTick counts down */
        out[0] = S.u;
        out[1] = S.drive;
        out[2] = S.duty;
        put(out, sizeof out);
        put(&ticks, sizeof ticks);
    }
}

#endif
