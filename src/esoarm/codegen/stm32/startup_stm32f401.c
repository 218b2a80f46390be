/* Startup of the STM32F401 (Cortex-M4F), register level, no CMSIS: the vector table (the
 * core's 16 entries and the device's 85 interrupts; the unused ones go to default_handler),
 * the reset handler (.data copied, .bss cleared, the FPU enabled before any float), then
 * main(). */
#include <stdint.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);
void TIM4_IRQHandler(void);
void USART2_IRQHandler(void);

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)

void reset_handler(void);
void reset_handler(void)
{
    uint32_t *src = &_sidata, *dst = &_sdata;
    while (dst < &_edata) *dst++ = *src++;
    for (dst = &_sbss; dst < &_ebss; ++dst) *dst = 0u;
    SCB_CPACR |= (0xFu << 20); /* CP10, CP11: the FPU */
    __asm volatile("dsb\n\tisb" ::: "memory");
    (void)main();
    for (;;) {}
}

static void default_handler(void)
{
    for (;;) {} /* an unexpected interrupt or fault: stop here (the motor timer keeps its
                 * last duty only until the host's or the board's watchdog; see README) */
}

#define D default_handler
typedef void (*vector_t)(void);

/* The core's 16 entries, then the device's 85 interrupts by number (RM0368, table 38):
 * TIM4 is 30, USART2 38, every other one stops in default_handler. */
__attribute__((section(".isr_vector"), used))
static const vector_t vectors[16 + 85] = {
    (vector_t)(uintptr_t)&_estack, reset_handler,
    D, D, D, D, D, 0, 0, 0, 0, D, D, 0, D, D,  /* NMI .. SysTick */
    D, D, D, D, D, D, D, D, D, D,  /* IRQ 0-9 */
    D, D, D, D, D, D, D, D, D, D,  /* 10-19 */
    D, D, D, D, D, D, D, D, D, D,  /* 20-29 */
    TIM4_IRQHandler, D, D, D, D, D, D, D, USART2_IRQHandler, D,  /* 30-39 */
    D, D, D, D, D, D, D, D, D, D,  /* 40-49 */
    D, D, D, D, D, D, D, D, D, D,  /* 50-59 */
    D, D, D, D, D, D, D, D, D, D,  /* 60-69 */
    D, D, D, D, D, D, D, D, D, D,  /* 70-79 */
    D, D, D, D, D,  /* 80-84 */
};
