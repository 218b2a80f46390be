/* Processor-in-the-loop shell for an ARMv6-M core without FPU (Cortex-M0+ code)
 * on QEMU's microbit (nRF51822, a Cortex-M0 at 16 MHz: an M0 runs M0+ code,
 * both are ARMv6-M): vector table at 0x0, a reset handler that copies .data and
 * clears .bss, the nRF51 UART at 0x40002000 as the lockstep link, SysTick
 * (processor clock) around the step.  Floating point is soft (libgcc).
 *
 * Per sample: the host sends y, theta_d, omega_d, accel_d (sizeof(esoarm_real)
 * bytes each, little endian); the shell steps the controller and answers u,
 * drive, duty (esoarm_real each) and the SysTick ticks the step took (uint32).
 * QEMU models no cycle counter: run with -icount shift=N, the ticks count
 * executed instructions (one instruction = 2^N ns of virtual time, one tick =
 * 62.5 ns at 16 MHz).
 */
#include <stdint.h>
#include "esoarm_controller.h"

#define REG(a) (*(volatile uint32_t *)(a))
#define UART_STARTRX REG(0x40002000u)
#define UART_STARTTX REG(0x40002008u)
#define UART_RXDRDY REG(0x40002108u)
#define UART_TXDRDY REG(0x4000211Cu)
#define UART_ENABLE REG(0x40002500u)
#define UART_RXD REG(0x40002518u)
#define UART_TXD REG(0x4000251Cu)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);

void reset_handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata) *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss; ++dst) *dst = 0;
    main();
    for (;;) {}
}

static void halt(void)
{
    for (;;) {}
}

__attribute__((section(".vectors"), used))
static void (*const vectors[16])(void) = {
    (void (*)(void))(&_estack), reset_handler, halt, halt, 0, 0, 0, 0, 0, 0, 0,
    halt, 0, 0, halt, halt,
};

static uint8_t getc_uart(void)
{
    while (!UART_RXDRDY) {}
    UART_RXDRDY = 0;                        /* reading RXD sets it again while bytes wait */
    return (uint8_t)UART_RXD;
}

static void putc_uart(uint8_t c)
{
    UART_TXDRDY = 0;
    UART_TXD = c;
    while (!UART_TXDRDY) {}
}

static void put(const void *p, unsigned n)
{
    const uint8_t *b = (const uint8_t *)p;
    while (n--) putc_uart(*b++);
}

static esoarm_state S;

int main(void)
{
    UART_ENABLE = 4u;
    UART_STARTRX = 1u;
    UART_STARTTX = 1u;
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 5u;                          /* enable, processor clock */
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
