/* Processor-in-the-loop shell for an ARMv6-M core without FPU (Cortex-M0+ code)
 * on QEMU's microbit (nRF51822, a Cortex-M0 at 16 MHz: an M0 runs M0+ code,
 * both are ARMv6-M): vector table at 0x0, a reset handler that copies .data and
 * clears .bss (cortex_m_startup.h), the nRF51 UART at 0x40002000 as the lockstep
 * link, SysTick (processor clock) around the step (cortex_m_pil.h: one tick =
 * 62.5 ns at 16 MHz).  Floating point is soft (libgcc).
 */
#include "cortex_m_startup.h"

#define UART_STARTRX REG(0x40002000u)
#define UART_STARTTX REG(0x40002008u)
#define UART_RXDRDY REG(0x40002108u)
#define UART_TXDRDY REG(0x4000211Cu)
#define UART_ENABLE REG(0x40002500u)
#define UART_RXD REG(0x40002518u)
#define UART_TXD REG(0x4000251Cu)

static void uart_init(void)
{
    UART_ENABLE = 4u;
    UART_STARTRX = 1u;
    UART_STARTTX = 1u;
}

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

#include "cortex_m_pil.h"
