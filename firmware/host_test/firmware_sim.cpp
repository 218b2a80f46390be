/*
 * Runs esoarm_rig.ino on the host against arduino_stub.h, driven by a script
 * on stdin (tests/hardware/test_firmware.py):
 *
 *   send HEX        bytes arrive on the serial port
 *   advance US      time passes in 100 us steps, loop() called at each
 *   enc STEPS       the encoder turns by STEPS quadrature edges (sign = direction)
 *   print           prints "tx HEX" (bytes sent since the last print, '-' if none)
 *                   and "motor PWM IN1 IN2" (L298N pins)
 *
 * Build: g++ -std=c++11 -Wall -Wextra -Werror -x c++ -include arduino_stub.h \
 *        -I firmware/esoarm_rig -I firmware/host_test esoarm_rig.ino firmware_sim.cpp
 */
#include <stdio.h>
#include <string.h>

#include "arduino_stub.h"

uint32_t stub_micros = 1000000u;
int stub_pin[32];
void (*stub_isr[32])(void);
StubSerial Serial;

void setup();
void loop();

static size_t printed = 0;
static int enc_phase = 0; /* Gray code position 0..3: AB = 00, 01, 11, 10 */

static void set_encoder(int phase)
{
    static const int A[4] = {0, 0, 1, 1};
    static const int B[4] = {0, 1, 1, 0};
    int old_a = stub_pin[2];
    stub_pin[2] = A[phase];
    stub_pin[3] = B[phase];
    if (stub_pin[2] != old_a) { if (stub_isr[2]) stub_isr[2](); }
    else if (stub_isr[3]) stub_isr[3]();
}

int main()
{
    char cmd[32];
    stub_pin[2] = stub_pin[3] = 0;
    setup();
    while (scanf("%31s", cmd) == 1) {
        if (strcmp(cmd, "send") == 0) {
            char hex[256];
            if (scanf("%255s", hex) != 1) return 3;
            for (size_t i = 0; hex[2 * i] && hex[2 * i + 1]; i++) {
                unsigned v;
                sscanf(hex + 2 * i, "%2x", &v);
                Serial.rx[Serial.rx_tail++] = (uint8_t)v;
            }
            loop();
        } else if (strcmp(cmd, "advance") == 0) {
            unsigned long us;
            if (scanf("%lu", &us) != 1) return 3;
            for (unsigned long t = 0; t < us; t += 100) { stub_micros += 100; loop(); }
        } else if (strcmp(cmd, "enc") == 0) {
            long steps;
            if (scanf("%ld", &steps) != 1) return 3;
            for (long i = 0; i < (steps < 0 ? -steps : steps); i++) {
                enc_phase = (enc_phase + (steps > 0 ? 1 : 3)) % 4;
                set_encoder(enc_phase);
            }
        } else if (strcmp(cmd, "print") == 0) {
            printf("tx ");
            if (Serial.tx_n == printed) printf("-");
            for (; printed < Serial.tx_n; printed++) printf("%02x", Serial.tx[printed]);
            printf("\nmotor %d %d %d\n", stub_pin[9], stub_pin[7], stub_pin[8]);
        } else {
            return 3;
        }
    }
    return 0;
}
