/* Processor-in-the-loop shell for a Cortex-M4 with FPU on QEMU's mps2-an386:
 * vector table at 0x0, a reset handler that copies .data, clears .bss and
 * enables the FPU (CPACR) before any float (cortex_m_startup.h), the CMSDK UART0
 * at 0x40004000 as the lockstep link, SysTick (processor clock) around the step
 * (cortex_m_pil.h: one tick = 40 ns at 25 MHz).
 */
#define CORTEX_M_FPU
#include "cortex_m_startup.h"

#define UART_DATA REG(0x40004000u)
#define UART_STATE REG(0x40004004u)
#define UART_CTRL REG(0x40004008u)
#define UART_BAUDDIV REG(0x40004010u)

static void uart_init(void)
{
    UART_BAUDDIV = 16;
    UART_CTRL = 3u;                         /* TX and RX enable */
}

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

#include "cortex_m_pil.h"
