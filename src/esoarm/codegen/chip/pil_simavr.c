/* esoarm PIL harness: a PIL image on simavr's ATmega328P, driven from Python (ctypes).
 *
 *   pil_open(elf, freq)        load the ELF, reset
 *   pil_wait(h, value, limit)  run until the firmware writes `value` to GPIOR0
 *                              (data address 0x3E); 0 ok, -1 crashed/stopped, -2 no
 *                              such write within `limit` cycles
 *   pil_mark(h, value)         avr->cycle at the latest write of `value`
 *   pil_data(h)                the data space (registers, I/O, SRAM)
 *   pil_close(h)
 */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sim_avr.h>
#include <sim_elf.h>

#define GPIOR0_DATA 0x3E

typedef struct pil {
    avr_t *avr;
    uint64_t mark[256];
    int seen;       /* value of the latest GPIOR0 write, -1 none pending */
} pil_t;

static void quiet_logger(avr_t *avr, const int level, const char *format, va_list ap)
{
    (void)avr; (void)level; (void)format; (void)ap;
}

static void on_gpior0(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    pil_t *h = (pil_t *)param;
    (void)addr;
    avr->data[GPIOR0_DATA] = v;
    h->mark[v] = avr->cycle;
    h->seen = v;
}

void *pil_open(const char *elf, uint32_t freq)
{
    elf_firmware_t fw;
    pil_t *h;
    memset(&fw, 0, sizeof fw);
    avr_global_logger_set(quiet_logger);
    if (elf_read_firmware(elf, &fw) != 0) return NULL;
    h = (pil_t *)calloc(1, sizeof *h);
    if (!h) return NULL;
    h->avr = avr_make_mcu_by_name("atmega328p");
    if (!h->avr) { free(h); return NULL; }
    avr_init(h->avr);
    h->avr->frequency = freq;
    avr_load_firmware(h->avr, &fw);
    avr_register_io_write(h->avr, GPIOR0_DATA, on_gpior0, h);
    h->seen = -1;
    return h;
}

int pil_wait(void *handle, int value, uint64_t limit)
{
    pil_t *h = (pil_t *)handle;
    uint64_t end = h->avr->cycle + limit;
    for (;;) {
        int state;
        if (h->seen == value) { h->seen = -1; return 0; }
        h->seen = -1;
        if (h->avr->cycle > end) return -2;
        state = avr_run(h->avr);
        if (state == cpu_Done || state == cpu_Crashed) return -1;
    }
}

uint64_t pil_mark(void *handle, int value)
{
    return ((pil_t *)handle)->mark[value & 0xFF];
}

uint8_t *pil_data(void *handle)
{
    return ((pil_t *)handle)->avr->data;
}

void pil_close(void *handle)
{
    pil_t *h = (pil_t *)handle;
    if (!h) return;
    avr_terminate(h->avr);
    free(h);
}
