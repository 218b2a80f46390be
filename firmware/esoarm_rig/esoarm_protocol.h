/*
 * esoarm serial protocol, plain C99 (no Arduino dependency).
 *
 * The same framing and parsing rule as src/esoarm/hardware/protocol.py; the
 * test suite compiles this header with gcc on the host and checks it against
 * the Python implementation with the shared vectors in
 * firmware/test_vectors.txt.  See docs/protocol.md.
 *
 * Frame: 0xA5 0x5A | type u8 | seq u8 | len u8 | payload | crc16 (LE)
 * crc16 = CRC-16/CCITT-FALSE over type, seq, len, payload.
 * All integers little-endian; f64 is IEEE 754 binary64, little-endian.
 */
#ifndef ESOARM_PROTOCOL_H
#define ESOARM_PROTOCOL_H

#include <stdint.h>
#include <string.h>

#define ESO_PROTOCOL_VERSION 2 /* 2: on-board mode (HEARTBEAT, CHIP_INFO, CHIP_SAMPLE) */
#define ESO_SYNC0 0xA5u
#define ESO_SYNC1 0x5Au
#define ESO_HEADER_SIZE 5u
#define ESO_CRC_SIZE 2u
#define ESO_MAX_PAYLOAD 30u
#define ESO_MAX_FRAME (ESO_HEADER_SIZE + ESO_MAX_PAYLOAD + ESO_CRC_SIZE)

/* host -> device */
#define ESO_HELLO 0x01u   /* version u8 */
#define ESO_START 0x02u   /* - */
#define ESO_DUTY 0x03u    /* k u32, duty i16 */
#define ESO_TORQUE 0x04u  /* k u32, torque f64 (emulator only) */
#define ESO_STOP 0x05u    /* - */
#define ESO_HEARTBEAT 0x06u /* k u32 (on-board devices: the watchdog) */
/* device -> host */
#define ESO_INFO 0x81u    /* version u8, flags u8, counts_per_rev u32, pwm_max u16, period_us u32 */
#define ESO_SAMPLE 0x82u  /* k u32, t_us u32, count i32 */
#define ESO_STOPPED 0x85u /* - */
#define ESO_FAULT 0x86u   /* code u8, detail u32 */
/* device -> host, on-board devices only (INFO flags has ESO_FLAG_ONBOARD) */
#define ESO_CHIP_INFO 0x87u   /* stream_every u16, sums u8, scenario hash 8 ASCII hex digits */
#define ESO_CHIP_SAMPLE 0x88u /* k u32, t_us u32, count i32, u f32, z1 f32, z2 f32, z3 f32, duty i16 */

#define ESO_FLAG_TORQUE 0x01u
#define ESO_FLAG_LOCKSTEP 0x02u
#define ESO_FLAG_ONBOARD 0x04u
#define ESO_SUMS_PLAIN 0u
#define ESO_SUMS_COMPENSATED 1u

#define ESO_FAULT_WATCHDOG 1u
#define ESO_FAULT_OVERRUN 2u
#define ESO_FAULT_BAD_COMMAND 3u
#define ESO_FAULT_ENCODER 4u      /* both encoder lines changed at once: counts lost */

/* Fixed payload length of a message type; -1 for an unknown type. */
static inline int eso_payload_size(uint8_t type)
{
    switch (type) {
    case ESO_HELLO: return 1;
    case ESO_START: return 0;
    case ESO_DUTY: return 6;
    case ESO_TORQUE: return 12;
    case ESO_STOP: return 0;
    case ESO_HEARTBEAT: return 4;
    case ESO_INFO: return 12;
    case ESO_SAMPLE: return 12;
    case ESO_STOPPED: return 0;
    case ESO_FAULT: return 5;
    case ESO_CHIP_INFO: return 11;
    case ESO_CHIP_SAMPLE: return 30;
    default: return -1;
    }
}

/* CRC-16/CCITT-FALSE update (polynomial 0x1021, not reflected).  On AVR it is avr-libc's
 * _crc_xmodem_update (the same update; XMODEM differs only in the initial value, which the
 * caller sets), about 20 cycles a byte instead of about 100 bit by bit; elsewhere (the host
 * tests) the plain bitwise form.  The frames checked by the Python parser in the simavr
 * tests prove the two agree. */
#if defined(__AVR__)
#include <util/crc16.h>
/* always inlined: -Os otherwise makes it a call, ~10 more cycles a byte */
static inline __attribute__((always_inline)) uint16_t eso_crc16_update(uint16_t crc, uint8_t byte)
{
    return _crc_xmodem_update(crc, byte);
}
#else
static inline uint16_t eso_crc16_update(uint16_t crc, uint8_t byte)
{
    uint8_t i;
    crc ^= (uint16_t)((uint16_t)byte << 8);
    for (i = 0; i < 8; i++) {
        crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}
#endif

static inline uint16_t eso_crc16(const uint8_t *data, uint16_t n)
{
    uint16_t crc = 0xFFFFu;
    uint16_t i;
    for (i = 0; i < n; i++) crc = eso_crc16_update(crc, data[i]);
    return crc;
}

/* little-endian field helpers */
static inline void eso_put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void eso_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}
static inline uint16_t eso_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | ((uint16_t)p[1] << 8)); }
static inline uint32_t eso_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/*
 * Write one frame into out (at least ESO_MAX_FRAME bytes).  Returns the frame
 * length, or 0 if len does not match the type.
 */
static inline uint8_t eso_encode(uint8_t *out, uint8_t type, uint8_t seq,
                                 const uint8_t *payload, uint8_t len)
{
    uint16_t crc;
    if (eso_payload_size(type) != (int)len) return 0;
    out[0] = ESO_SYNC0;
    out[1] = ESO_SYNC1;
    out[2] = type;
    out[3] = seq;
    out[4] = len;
    if (len) memcpy(out + ESO_HEADER_SIZE, payload, len);
    crc = eso_crc16(out + 2, (uint16_t)(3u + len));
    eso_put_u16(out + ESO_HEADER_SIZE + len, crc);
    return (uint8_t)(ESO_HEADER_SIZE + len + ESO_CRC_SIZE);
}

/* Convenience encoders for the device side. */
static inline uint8_t eso_encode_sample(uint8_t *out, uint8_t seq, uint32_t k, uint32_t t_us,
                                        int32_t count)
{
    uint8_t p[12];
    eso_put_u32(p, k);
    eso_put_u32(p + 4, t_us);
    eso_put_u32(p + 8, (uint32_t)count);
    return eso_encode(out, ESO_SAMPLE, seq, p, 12);
}

static inline uint8_t eso_encode_info(uint8_t *out, uint8_t seq, uint8_t flags,
                                      uint32_t counts_per_rev, uint16_t pwm_max, uint32_t period_us)
{
    uint8_t p[12];
    p[0] = ESO_PROTOCOL_VERSION;
    p[1] = flags;
    eso_put_u32(p + 2, counts_per_rev);
    eso_put_u16(p + 6, pwm_max);
    eso_put_u32(p + 8, period_us);
    return eso_encode(out, ESO_INFO, seq, p, 12);
}

static inline uint8_t eso_encode_fault(uint8_t *out, uint8_t seq, uint8_t code, uint32_t detail)
{
    uint8_t p[5];
    p[0] = code;
    eso_put_u32(p + 1, detail);
    return eso_encode(out, ESO_FAULT, seq, p, 5);
}

/* IEEE 754 binary32 (float is binary32 on AVR, Cortex-M and the host compilers). */
static inline void eso_put_f32(uint8_t *p, float v)
{
    uint32_t bits;
    memcpy(&bits, &v, 4);
    eso_put_u32(p, bits);
}

static inline uint8_t eso_encode_chip_info(uint8_t *out, uint8_t seq, uint16_t stream_every,
                                           uint8_t sums, const char *hash8)
{
    uint8_t p[11];
    eso_put_u16(p, stream_every);
    p[2] = sums;
    memcpy(p + 3, hash8, 8);
    return eso_encode(out, ESO_CHIP_INFO, seq, p, 11);
}

static inline uint8_t eso_encode_chip_sample(uint8_t *out, uint8_t seq, uint32_t k, uint32_t t_us,
                                             int32_t count, float u, float z1, float z2, float z3,
                                             int16_t duty)
{
    uint8_t p[30];
    eso_put_u32(p, k);
    eso_put_u32(p + 4, t_us);
    eso_put_u32(p + 8, (uint32_t)count);
    eso_put_f32(p + 12, u);
    eso_put_f32(p + 16, z1);
    eso_put_f32(p + 20, z2);
    eso_put_f32(p + 24, z3);
    eso_put_u16(p + 28, (uint16_t)duty);
    return eso_encode(out, ESO_CHIP_SAMPLE, seq, p, 30);
}

/* A received frame. */
typedef struct {
    uint8_t type;
    uint8_t seq;
    uint8_t len;
    uint8_t payload[ESO_MAX_PAYLOAD];
} eso_frame_t;

/*
 * Incremental parser.  Rule: a frame is recognised at the start of the buffer
 * when the sync bytes, a known type with its length and the CRC all match;
 * otherwise the first byte is discarded and the search resumes at the next.
 * Push bytes with eso_parser_push(), then call eso_parser_next() until it
 * returns 0 (one pushed byte can complete more than one frame after a
 * rejected candidate).
 */
typedef struct {
    uint8_t buf[ESO_MAX_FRAME];
    uint8_t n;
    uint32_t frames;
    uint32_t crc_errors;
    uint32_t header_errors;
    uint32_t skipped;
} eso_parser_t;

static inline void eso_parser_init(eso_parser_t *p) { memset(p, 0, sizeof(*p)); }

static inline void eso_parser_drop(eso_parser_t *p, uint8_t count)
{
    memmove(p->buf, p->buf + count, (size_t)(p->n - count));
    p->n = (uint8_t)(p->n - count);
}

/* Returns 1 and fills *f when a frame is complete; 0 when more bytes are needed. */
static inline int eso_parser_next(eso_parser_t *p, eso_frame_t *f)
{
    for (;;) {
        int size;
        uint8_t total;
        uint16_t crc;
        if (p->n == 0) return 0;
        if (p->buf[0] != ESO_SYNC0) { p->skipped++; eso_parser_drop(p, 1); continue; }
        if (p->n < 2) return 0;
        if (p->buf[1] != ESO_SYNC1) { p->skipped++; eso_parser_drop(p, 1); continue; }
        if (p->n < ESO_HEADER_SIZE) return 0;
        size = eso_payload_size(p->buf[2]);
        if (size < 0 || size != (int)p->buf[4]) {
            p->header_errors++; p->skipped++; eso_parser_drop(p, 1); continue;
        }
        total = (uint8_t)(ESO_HEADER_SIZE + (uint8_t)size + ESO_CRC_SIZE);
        if (p->n < total) return 0;
        crc = eso_crc16(p->buf + 2, (uint16_t)(3 + size));
        if (crc != eso_get_u16(p->buf + ESO_HEADER_SIZE + size)) {
            p->crc_errors++; p->skipped++; eso_parser_drop(p, 1); continue;
        }
        f->type = p->buf[2];
        f->seq = p->buf[3];
        f->len = (uint8_t)size;
        if (size) memcpy(f->payload, p->buf + ESO_HEADER_SIZE, (size_t)size);
        p->frames++;
        eso_parser_drop(p, total);
        return 1;
    }
}

/*
 * Append one byte.  The buffer never overflows: it is only full when it holds
 * a complete candidate, which eso_parser_next() consumes or rejects; call
 * eso_parser_next() until it returns 0 before pushing the next byte.
 */
static inline void eso_parser_push(eso_parser_t *p, uint8_t byte)
{
    if (p->n >= ESO_MAX_FRAME) { p->skipped++; eso_parser_drop(p, 1); }
    p->buf[p->n++] = byte;
}

#endif /* ESOARM_PROTOCOL_H */
