/* Bare-metal start of esoarm's Cortex-M images on QEMU (the PIL shells m0_startup.c and
 * m4_startup.c, the on-board firmware cortex_m/mps2_onboard.c): the register macro, SysTick,
 * a reset handler that copies .data and clears .bss (and, with CORTEX_M_FPU defined, gives
 * CP10/CP11 full access before any float) and calls main(), and the vector table at 0x0
 * (the linker scripts m0.ld and m4.ld place .vectors there).
 *
 * ARMv7-M (CORTEX_M_FPU, the M4) has MemManage, BusFault, UsageFault and DebugMonitor
 * entries; ARMv6-M (the M0/M0+) reserves them (0).  Every fault halts.
 */
#ifndef ESOARM_CORTEX_M_STARTUP_H
#define ESOARM_CORTEX_M_STARTUP_H

#include <stdint.h>

#define REG(a) (*(volatile uint32_t *)(a))
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)
#define SCB_CPACR REG(0xE000ED88u)

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);

void reset_handler(void);

void reset_handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata) *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss; ++dst) *dst = 0;
#ifdef CORTEX_M_FPU
    SCB_CPACR |= (0xFu << 20);             /* CP10, CP11 full access: the FPU */
    __asm volatile ("dsb\n\tisb" ::: "memory");
#endif
    main();
    for (;;) {}
}

static void halt(void)
{
    for (;;) {}
}

#ifdef CORTEX_M_FPU
#define ARMV7M_FAULT halt
#else
#define ARMV7M_FAULT 0
#endif

__attribute__((section(".vectors"), used))
static void (*const vectors[16])(void) = {
    (void (*)(void))(&_estack), reset_handler, halt /* NMI */, halt /* HardFault */,
    ARMV7M_FAULT, ARMV7M_FAULT, ARMV7M_FAULT, 0, 0, 0, 0,
    halt /* SVCall */, ARMV7M_FAULT /* DebugMonitor */, 0, halt /* PendSV */, halt /* SysTick */,
};

/* Start SysTick free-running on the processor clock, from its largest count. */
static void systick_start(void)
{
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0;
    SYST_CSR = 5u;                          /* enable, processor clock */
}

#endif
