/*
 * Host-side check of esoarm_protocol.h, driven by tests/hardware/test_c_protocol.py.
 *
 *   protocol_check encode   stdin: lines "TYPE SEQ PAYLOADHEX" (hex, '-' for empty)
 *                           stdout: one line per input, the frame in hex
 *   protocol_check parse    stdin: raw bytes
 *                           stdout: "frame TYPE SEQ PAYLOADHEX" per frame, then
 *                           "stats FRAMES CRC_ERRORS HEADER_ERRORS SKIPPED PENDING"
 *
 * Build: gcc -std=c99 -Wall -Wextra -Werror -I firmware/esoarm_rig protocol_check.c
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "esoarm_protocol.h"

static int hexval(int c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static void print_hex(const uint8_t *p, unsigned n)
{
    unsigned i;
    if (n == 0) { fputs("-", stdout); return; }
    for (i = 0; i < n; i++) printf("%02x", p[i]);
}

static int do_encode(void)
{
    char line[256];
    while (fgets(line, sizeof line, stdin)) {
        unsigned type, seq;
        char hex[128];
        uint8_t payload[64], frame[ESO_MAX_FRAME];
        unsigned n = 0, i;
        uint8_t len;
        if (sscanf(line, "%x %u %127s", &type, &seq, hex) != 3) continue;
        if (strcmp(hex, "-") != 0) {
            size_t h = strlen(hex);
            if (h % 2 || h / 2 > sizeof payload) return 3;
            for (i = 0; i < h / 2; i++) {
                int hi = hexval(hex[2 * i]), lo = hexval(hex[2 * i + 1]);
                if (hi < 0 || lo < 0) return 3;
                payload[n++] = (uint8_t)(hi * 16 + lo);
            }
        }
        len = eso_encode(frame, (uint8_t)type, (uint8_t)seq, payload, (uint8_t)n);
        print_hex(frame, len);
        putchar('\n');
    }
    return 0;
}

static int do_parse(void)
{
    eso_parser_t p;
    eso_frame_t f;
    int c;
    eso_parser_init(&p);
    while ((c = getchar()) != EOF) {
        eso_parser_push(&p, (uint8_t)c);
        while (eso_parser_next(&p, &f)) {
            printf("frame %02x %u ", f.type, f.seq);
            print_hex(f.payload, f.len);
            putchar('\n');
        }
    }
    printf("stats %lu %lu %lu %lu %u\n", (unsigned long)p.frames, (unsigned long)p.crc_errors,
           (unsigned long)p.header_errors, (unsigned long)p.skipped, (unsigned)p.n);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "encode") == 0) return do_encode();
    if (argc == 2 && strcmp(argv[1], "parse") == 0) return do_parse();
    fprintf(stderr, "usage: protocol_check encode|parse\n");
    return 2;
}
