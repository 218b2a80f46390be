/* Processor-in-the-loop shell for a Cortex-M4 with FPU on QEMU's mps2-an386:
 * vector table at 0x0, a reset handler that copies .data, clears .bss and
 * enables the FPU (CPACR) before any float, the CMSDK UART0 at 0x40004000 as
 * the lockstep link, SysTick (processor clock) around the step.
 *
 * Per sample: the host sends y, theta_d, omega_d, accel_d (sizeof(esoarm_real) bytes
 * each, little endian); the
 * shell steps the controller and answers u, drive, duty (esoarm_real each) and the
 * SysTick ticks the step took (uint32).  QEMU models no cycle counter (DWT
 * reads 0): run with -icount shift=N, the ticks count executed instructions
 * (one instruction = 2^N ns of virtual time, one tick = 40 ns at 25 MHz).
 */
#include <stdint.h>
#include "esoarm_controller.h"

#define REG(a) (*(volatile uint32_t *)(a))
#define UART_DATA REG(0x40004000u)
#define UART_STATE REG(0x40004004u)
#define UART_CTRL REG(0x40004008u)
#define UART_BAUDDIV REG(0x40004010u)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)
#define SCB_CPACR REG(0xE000ED88u)

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);

void reset_handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata) *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss; ++dst) *dst = 0;
    SCB_CPACR |= (0xFu << 20);             /* CP10, CP11 full access: the FPU */
    __asm volatile ("dsb\n\tisb" ::: "memory");
    main();
    for (;;) {}
}

static void halt(void)
{
    for (;;) {}
}

__attribute__((section(".vectors"), used))
static void (*const vectors[16])(void) = {
    (void (*)(void))(&_estack), reset_handler, halt, halt, halt, halt, halt, 0, 0, 0, 0,
    halt, halt, 0, halt, halt,
};

static uint8_t getc_uart(void)
{
    while (!(UART_STATE & 2u)) {}
    return (uint8_t)UART_DATA;
}

static void putc_uart(uint8_t c)
{
    while (UART_STATE & 1u) {}
    UART_DATA = c;
}

static void put(const void *p, unsigned n)
{
    const uint8_t *b = (const uint8_t *)p;
    while (n--) putc_uart(*b++);
}

static esoarm_state S;

int main(void)
{
    UART_BAUDDIV = 16;
    UART_CTRL = 3u;                         /* TX and RX enable */
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
