/*
 * esoarm hardware-in-the-loop harness: the rig firmware's ELF on a simulated
 * ATmega328P (simavr), with its pins and UART exposed to Python (ctypes).
 *
 * This file only moves pins and bytes; the physics (arm, motor, encoder
 * geometry) stays in Python (esoarm.hardware.hil), which decides when each
 * encoder edge happens and reads the motor pins back from the AVR's registers.
 *
 *   hil_open(elf, freq)                 load the firmware, reset the MCU
 *   hil_run(h, until, cycles, ab, n)    run to cycle `until`, applying the
 *                                       quadrature levels ab[i] (bit1 = A on
 *                                       D2/INT0, bit0 = B on D3/INT1) at cycles[i]
 *   hil_uart_send(h, buf, n)            bytes from the host, fed to the UART as
 *                                       fast as its receiver takes them (XON/XOFF)
 *   hil_uart_take(h, buf, cycles, max)  bytes the firmware wrote to UDR0 since
 *                                       the last call, with the cycle of each write
 *   hil_data(h)                         the AVR's data space (registers, I/O, SRAM)
 *   hil_reset(h)                        reset the MCU (brown-out); the cycle count goes on
 *   hil_probe(h, pc) / hil_probe_take   cycles at which the program counter reached
 *                                       the byte address pc (timing measurements)
 *
 * Measurement of the encoder interrupt: after each applied edge the harness
 * follows the program counter to the INT0/INT1 vector and back to the
 * interrupted instruction; hil_isr_stats() returns the count, the sum and the
 * maximum of the cycles spent in the handler and from the edge to its return.
 *
 * Build (done by esoarm.hardware.hil.build):
 *   gcc -O2 -shared -fPIC harness.c $(pkg-config --cflags --libs simavr) -lelf -o harness.so
 */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>

#define RX_QUEUE 4096
#define TX_QUEUE 8192
#define ENC_PORT 'D'
#define ENC_PIN_A 2   /* D2 = PD2 = INT0 */
#define ENC_PIN_B 3   /* D3 = PD3 = INT1 */
#define VECTOR_INT0 (1 * 4) /* byte addresses of the vectors (2-word entries) */
#define VECTOR_INT1 (2 * 4)
#define PROBE_MAX 4096
#define NO_PROBE 0xFFFFFFFFu

typedef struct hil {
    avr_t *avr;
    avr_irq_t *pin_a, *pin_b, *uart_in;
    uint8_t ab;
    /* host -> AVR */
    uint8_t rx[RX_QUEUE];
    int rx_head, rx_tail;
    int xon;
    /* AVR -> host */
    uint8_t tx[TX_QUEUE];
    uint64_t tx_cycle[TX_QUEUE];
    int tx_n;
    uint32_t tx_dropped;
    /* encoder ISR measurement */
    int track;               /* 0 idle, 1 edge raised, 2 inside the handler */
    uint64_t t_edge, t_entry;
    uint32_t ret_pc;
    uint16_t sp_entry;
    uint64_t isr_n, isr_sum, isr_max, lat_sum, lat_max;
    /* program-counter probe: cycles at which the PC reached probe_pc */
    uint32_t probe_pc;
    uint64_t probe[PROBE_MAX];
    int probe_n;
} hil_t;

static char last_error[256];

static void quiet_logger(avr_t *avr, const int level, const char *format, va_list ap)
{
    (void)avr;
    if (level <= LOG_ERROR) vsnprintf(last_error, sizeof last_error, format, ap);
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    hil_t *h = (hil_t *)param;
    (void)irq;
    if (h->tx_n < TX_QUEUE) {
        h->tx[h->tx_n] = (uint8_t)value;
        h->tx_cycle[h->tx_n] = h->avr->cycle;
        h->tx_n++;
    } else {
        h->tx_dropped++;
    }
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    if (value) ((hil_t *)param)->xon = 1;
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    if (value) ((hil_t *)param)->xon = 0;
}

static void feed_uart(hil_t *h)
{
    while (h->xon && h->rx_head != h->rx_tail) {
        uint8_t b = h->rx[h->rx_head];
        h->rx_head = (h->rx_head + 1) % RX_QUEUE;
        avr_raise_irq(h->uart_in, b);
    }
}

/* Drive the encoder lines.  An input with its pull-up on is re-driven by simavr
 * on every PORTD write; declaring the levels "external" keeps them ours. */
static void set_encoder(hil_t *h, uint8_t ab)
{
    avr_ioport_external_t ext;
    uint8_t a = (ab >> 1) & 1u, b = ab & 1u;
    memset(&ext, 0, sizeof ext);
    ext.name = ENC_PORT;
    ext.mask = (1u << ENC_PIN_A) | (1u << ENC_PIN_B);
    ext.value = (uint8_t)((a << ENC_PIN_A) | (b << ENC_PIN_B));
    avr_ioctl(h->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(ENC_PORT), &ext);
    if (((h->ab >> 1) & 1u) != a) avr_raise_irq(h->pin_a, a);
    if ((h->ab & 1u) != b) avr_raise_irq(h->pin_b, b);
    if (h->ab != ab && h->track == 0) {
        h->track = 1;
        h->t_edge = h->avr->cycle;
    }
    h->ab = ab;
}

static uint16_t read_sp(avr_t *avr) { return (uint16_t)(avr->data[R_SPL] | (avr->data[R_SPH] << 8)); }

static void follow_isr(hil_t *h)
{
    avr_t *avr = h->avr;
    if (h->track == 1) {
        if (avr->pc == VECTOR_INT0 || avr->pc == VECTOR_INT1) {
            uint16_t sp = read_sp(avr);
            h->sp_entry = sp;
            h->ret_pc = (uint32_t)((avr->data[sp + 1] << 8) | avr->data[sp + 2]) * 2u;
            h->t_entry = avr->cycle;
            h->track = 2;
        }
    } else if (h->track == 2) {
        if (avr->pc == h->ret_pc && read_sp(avr) == (uint16_t)(h->sp_entry + 2)) {
            uint64_t isr = avr->cycle - h->t_entry, lat = avr->cycle - h->t_edge;
            h->isr_n++;
            h->isr_sum += isr;
            h->lat_sum += lat;
            if (isr > h->isr_max) h->isr_max = isr;
            if (lat > h->lat_max) h->lat_max = lat;
            h->track = 0;
        }
    }
}

const char *hil_last_error(void) { return last_error; }

hil_t *hil_open(const char *elf_path, uint32_t frequency)
{
    elf_firmware_t fw;
    hil_t *h;
    uint32_t flags = 0;
    avr_global_logger_set(quiet_logger);
    memset(&fw, 0, sizeof fw);
    last_error[0] = 0;
    if (elf_read_firmware(elf_path, &fw) != 0) {
        snprintf(last_error, sizeof last_error, "cannot read the firmware ELF '%s'", elf_path);
        return NULL;
    }
    h = (hil_t *)calloc(1, sizeof *h);
    if (!h) return NULL;
    h->avr = avr_make_mcu_by_name("atmega328p");
    if (!h->avr) {
        snprintf(last_error, sizeof last_error, "simavr has no atmega328p core");
        free(h);
        return NULL;
    }
    avr_init(h->avr);
    h->avr->log = LOG_ERROR;
    fw.frequency = frequency;
    strcpy(fw.mmcu, "atmega328p");
    avr_load_firmware(h->avr, &fw);
    h->avr->frequency = frequency;
    /* no console echo of the UART and no sleeping while the firmware polls it */
    avr_ioctl(h->avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    h->pin_a = avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(ENC_PORT), ENC_PIN_A);
    h->pin_b = avr_io_getirq(h->avr, AVR_IOCTL_IOPORT_GETIRQ(ENC_PORT), ENC_PIN_B);
    h->uart_in = avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            on_uart_out, h);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            on_xon, h);
    avr_irq_register_notify(avr_io_getirq(h->avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            on_xoff, h);
    h->ab = 0;
    set_encoder(h, 3); /* both lines idle high (open collector with pull-ups) */
    h->track = 0;
    h->probe_pc = NO_PROBE;
    return h;
}

void hil_close(hil_t *h)
{
    if (!h) return;
    avr_terminate(h->avr);
    free(h);
}

uint8_t *hil_data(hil_t *h) { return h->avr->data; }

uint64_t hil_cycle(hil_t *h) { return h->avr->cycle; }

/* Run until the cycle counter reaches `until`; returns the number of edges
 * applied, or -1 if the core stopped (crash or end of program). */
int hil_run(hil_t *h, uint64_t until, const uint64_t *cycles, const uint8_t *ab, int n)
{
    avr_t *avr = h->avr;
    int i = 0;
    while (avr->cycle < until) {
        while (i < n && cycles[i] <= avr->cycle) set_encoder(h, ab[i++]);
        if (h->rx_head != h->rx_tail) feed_uart(h);
        int state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed) return -1;
        if (h->track) follow_isr(h);
        if (avr->pc == h->probe_pc && h->probe_n < PROBE_MAX) h->probe[h->probe_n++] = avr->cycle;
    }
    while (i < n && cycles[i] <= avr->cycle) set_encoder(h, ab[i++]);
    return i;
}

/* Set the encoder lines now (outside hil_run). */
void hil_set_encoder(hil_t *h, uint8_t ab) { set_encoder(h, ab); }

/* Queue host bytes; returns how many were taken (the queue holds RX_QUEUE - 1). */
int hil_uart_send(hil_t *h, const uint8_t *buf, int n)
{
    int k = 0;
    while (k < n && (h->rx_tail + 1) % RX_QUEUE != h->rx_head) {
        h->rx[h->rx_tail] = buf[k++];
        h->rx_tail = (h->rx_tail + 1) % RX_QUEUE;
    }
    return k;
}

/* Bytes written by the firmware since the last call, with their cycles. */
int hil_uart_take(hil_t *h, uint8_t *buf, uint64_t *cycles, int max)
{
    int n = h->tx_n < max ? h->tx_n : max;
    memcpy(buf, h->tx, (size_t)n);
    memcpy(cycles, h->tx_cycle, (size_t)n * sizeof(uint64_t));
    memmove(h->tx, h->tx + n, (size_t)(h->tx_n - n));
    memmove(h->tx_cycle, h->tx_cycle + n, (size_t)(h->tx_n - n) * sizeof(uint64_t));
    h->tx_n -= n;
    return n;
}

/* Brown-out: the MCU restarts from its reset vector; pins go back to inputs. */
void hil_reset(hil_t *h)
{
    uint8_t ab = h->ab;
    avr_reset(h->avr);
    h->xon = 0;
    h->rx_head = h->rx_tail = 0;
    h->track = 0;
    h->ab = (uint8_t)(~ab & 3u); /* force both lines to be re-driven */
    set_encoder(h, ab);
    h->track = 0;
}

/* Encoder ISR statistics: n, sum and max of handler cycles, sum and max of
 * cycles from the edge to the handler's return. */
void hil_isr_stats(hil_t *h, uint64_t *out)
{
    out[0] = h->isr_n;
    out[1] = h->isr_sum;
    out[2] = h->isr_max;
    out[3] = h->lat_sum;
    out[4] = h->lat_max;
}

/* Record the cycles at which the program counter reaches byte address pc (one probe). */
void hil_probe(hil_t *h, uint32_t pc)
{
    h->probe_pc = pc;
    h->probe_n = 0;
}

int hil_probe_take(hil_t *h, uint64_t *out, int max)
{
    int n = h->probe_n < max ? h->probe_n : max;
    memcpy(out, h->probe, (size_t)n * sizeof(uint64_t));
    memmove(h->probe, h->probe + n, (size_t)(h->probe_n - n) * sizeof(uint64_t));
    h->probe_n -= n;
    return n;
}

/* Forget the encoder interrupt statistics (after boot, before a measurement). */
void hil_isr_clear(hil_t *h)
{
    h->isr_n = h->isr_sum = h->isr_max = h->lat_sum = h->lat_max = 0;
    h->track = 0;
}
