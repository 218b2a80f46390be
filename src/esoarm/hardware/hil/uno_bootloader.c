/*
 * esoarm: an Arduino Uno with its bootloader, for testing `esoarm flash` without a board.
 *
 * simavr's ATmega328P at 16 MHz with the Uno's bootloader (optiboot, from Debian's
 * arduino-core-avr) loaded at its address and the reset vector there (the BOOTRST fuse),
 * the empty application flash erased (0xFF), UART0 on a pseudo-terminal.  avrdude
 * (-c arduino -b 115200) programs it through the bootloader's STK500 protocol exactly as
 * on a board (the flash writes are the bootloader's SPM instructions); the bootloader then
 * starts the application, which answers on the same terminal.
 *
 * What a board does and this cannot: a pseudo-terminal carries no DTR line, so the Uno's
 * auto-reset on opening the port is emulated by the byte pair a host sends first, the STK500
 * GET_SYNC ("0 "): arriving while the application runs, it resets the MCU into the
 * bootloader (MCUSR = EXTRF) and is dropped (avrdude repeats it until in sync).  The clock is
 * paced to the wall clock (the bootloader's 1 s timeout is real time).
 *
 *   uno_bootloader BOOTLOADER.hex LINK     LINK: a symlink to the terminal, made here
 *
 * Build (esoarm.hardware.flash): gcc -O2 uno_bootloader.c $(simavr flags) -lutil
 */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pty.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_cycle_timers.h>
#include <sim_hex.h>

#define F_CPU 16000000UL
#define MCUSR_ADDR 0x54
#define WDTCSR_ADDR 0x60
#define EXTRF 0x02
#define QUEUE 8192
#define FLASH_SPACE 0x8100u

static volatile sig_atomic_t stop = 0;
static uint8_t rx[QUEUE];
static int rx_head = 0, rx_tail = 0, xon = 1;
static uint32_t boot_base = 0x7E00;
static uint8_t written[FLASH_SPACE];

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    int fd = *(int *)param;
    uint8_t b = (uint8_t)value;
    (void)irq;
    if (write(fd, &b, 1) < 0 && errno != EAGAIN) stop = 1;
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq; (void)value; (void)param;
    xon = 1;
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq; (void)value; (void)param;
    xon = 0;
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* appStart: Debian's optiboot_atmega328.hex is 532 bytes, 20 more than the 512-byte boot
 * section, so its appStart (watchdog off, jump to 0) lies at 0x8004, past the 32 KB, and its
 * rcall there wraps to 0x0004 on the chip (and in simavr) -- into the application's vector
 * table.  The factory Uno bootloader is 500 bytes and has it in place.  So a call from the
 * bootloader that lands at 0x0004 is taken for appStart and done here: WDTCSR cleared, the
 * pending cycle timers dropped (simavr keeps its watchdog timer after a watchdog reset; the
 * application arms its own timers), the return address popped, and the jump to 0. */
static void app_start(avr_t *avr)
{
    uint16_t sp = (uint16_t)(avr->data[0x5D] | (avr->data[0x5E] << 8));
    avr->data[WDTCSR_ADDR] = 0;
    avr_cycle_timer_reset(avr);
    sp = (uint16_t)(sp + 2u);
    avr->data[0x5D] = (uint8_t)sp;
    avr->data[0x5E] = (uint8_t)(sp >> 8);
    avr->pc = 0;
}

static void into_bootloader(avr_t *avr)
{
    avr_reset(avr);
    avr->pc = boot_base;
    avr->data[MCUSR_ADDR] |= EXTRF;
}

int main(int argc, char **argv)
{
    ihex_chunk_p chunks = NULL;
    int n, i, master, slave, fd_arg;
    char name[256];
    avr_t *avr;
    avr_irq_t *uart_in;
    uint32_t flags = 0;
    double t0;
    struct termios tio;
    uint8_t last = 0;
    uint32_t lowest = 0;
    int in_boot = 1;

    if (argc != 3) {
        fprintf(stderr, "usage: %s BOOTLOADER.hex LINK\n", argv[0]);
        return 2;
    }
    n = read_ihex_chunks(argv[1], &chunks);
    if (n <= 0) {
        fprintf(stderr, "uno_bootloader: cannot read %s\n", argv[1]);
        return 2;
    }
    avr = avr_make_mcu_by_name("atmega328p");
    if (!avr) return 2;
    avr_init(avr);
    avr->frequency = F_CPU;
    /* Debian's optiboot_atmega328.hex is 532 bytes: its compiler makes it 20 bytes longer
     * than the 512-byte boot section, so appStart lands at 0x8000-0x8013, past the 32 KB
     * (a real Uno's optiboot is 500 bytes).  Those bytes are kept past the end of the flash
     * (code may run there; the application's flash stays the 328P's 32 KB). */
    avr->flash = realloc(avr->flash, FLASH_SPACE);
    if (!avr->flash) return 1;
    memset(avr->flash, 0xFF, FLASH_SPACE);
    memset(written, 0, sizeof written);
    for (i = 0; i < n; ++i) {
        /* the first record to write a byte wins: Debian's hex also puts optiboot's version
         * word at 0x7FFE, where its overlong code already is (a 500-byte build has room) */
        uint32_t a, size = chunks[i].size;
        if (chunks[i].baseaddr >= FLASH_SPACE) continue;
        if (chunks[i].baseaddr + size > FLASH_SPACE) size = FLASH_SPACE - chunks[i].baseaddr;
        for (a = 0; a < size; ++a) {
            uint32_t at = chunks[i].baseaddr + a;
            if (written[at]) continue;
            avr->flash[at] = chunks[i].data[a];
            written[at] = 1;
        }
        if (chunks[i].baseaddr > 0 && (lowest == 0 || chunks[i].baseaddr < lowest))
            lowest = chunks[i].baseaddr;
    }
    if (lowest == 0) {
        fprintf(stderr, "uno_bootloader: %s holds no bootloader (nothing above 0)\n", argv[1]);
        return 2;
    }
    boot_base = lowest;
    avr->codeend = FLASH_SPACE - 1;     /* the bootloader writes code (and runs past 32 KB) */
    avr->reset_pc = boot_base;          /* BOOTRST: every reset enters the bootloader */
    into_bootloader(avr);

    if (openpty(&master, &slave, name, NULL, NULL) != 0) {
        perror("uno_bootloader: openpty");
        return 1;
    }
    tcgetattr(slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave, TCSANOW, &tio);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    unlink(argv[2]);
    if (symlink(name, argv[2]) != 0) {
        perror("uno_bootloader: symlink");
        return 1;
    }
    printf("device: %s\n", argv[2]);
    fflush(stdout);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);

    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);  /* no stdio echo, no poll sleep */
    uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    fd_arg = master;
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            on_uart_out, &fd_arg);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            on_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            on_xoff, NULL);

    t0 = now_s();
    while (!stop) {
        uint8_t buf[256];
        ssize_t got = read(master, buf, sizeof buf);
        int state, k;
        for (k = 0; k < got; ++k) {
            /* GET_SYNC while the application runs: the auto-reset of opening the port */
            if (last == 0x30 && buf[k] == 0x20 && avr->pc < boot_base) {
                into_bootloader(avr);
                rx_head = rx_tail = 0;
                last = 0;
                continue;
            }
            last = buf[k];
            if ((rx_head + 1) % QUEUE != rx_tail) {
                rx[rx_head] = buf[k];
                rx_head = (rx_head + 1) % QUEUE;
            }
        }
        for (k = 0; k < 2000 && !stop; ++k) {
            if (xon && rx_head != rx_tail) {
                avr_raise_irq(uart_in, rx[rx_tail]);
                rx_tail = (rx_tail + 1) % QUEUE;
            }
            state = avr_run(avr);
            if (avr->pc == 4 && in_boot) app_start(avr);
            in_boot = avr->pc >= boot_base;
            if (state == cpu_Done || state == cpu_Crashed) {
                fprintf(stderr, "uno_bootloader: the MCU stopped (state %d)\n", state);
                stop = 1;
            }
        }
        /* pace: no further ahead of the wall clock than 2 ms */
        {
            double ahead = (double)avr->cycle / (double)F_CPU - (now_s() - t0);
            if (ahead > 0.002) usleep((useconds_t)(1e6 * (ahead - 0.001)));
        }
    }
    unlink(argv[2]);
    free_ihex_chunks(chunks);
    avr_terminate(avr);
    close(slave);
    close(master);
    return 0;
}
