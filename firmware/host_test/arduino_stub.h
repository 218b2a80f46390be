/*
 * Minimal host stand-in for the Arduino core, enough to compile esoarm_rig.ino
 * with g++ and drive it from firmware_sim.cpp (tests/hardware/test_firmware.py).
 * Time, pins and the serial port are plain variables the harness controls.
 */
#ifndef ESOARM_ARDUINO_STUB_H
#define ESOARM_ARDUINO_STUB_H

#include <stdint.h>
#include <stddef.h>

#define HIGH 1
#define LOW 0
#define INPUT 0
#define OUTPUT 1
#define INPUT_PULLUP 2
#define CHANGE 1

extern uint32_t stub_micros;
extern int stub_pin[32];
extern void (*stub_isr[32])(void);

inline uint32_t micros() { return stub_micros; }
inline uint32_t millis() { return stub_micros / 1000u; }
inline void pinMode(int, int) {}
inline int digitalRead(int pin) { return stub_pin[pin]; }
inline void digitalWrite(int pin, int v) { stub_pin[pin] = v; }
inline void analogWrite(int pin, int v) { stub_pin[pin] = v; }
inline int digitalPinToInterrupt(int pin) { return pin; }
inline void attachInterrupt(int irq, void (*isr)(void), int) { stub_isr[irq] = isr; }
inline void noInterrupts() {}
inline void interrupts() {}

struct StubSerial {
    uint8_t rx[4096];
    size_t rx_head = 0, rx_tail = 0;
    uint8_t tx[65536];
    size_t tx_n = 0;
    void begin(unsigned long) {}
    int available() { return (int)(rx_tail - rx_head); }
    int read() { return rx_head < rx_tail ? rx[rx_head++] : -1; }
    size_t write(const uint8_t *p, size_t n)
    {
        for (size_t i = 0; i < n && tx_n < sizeof tx; i++) tx[tx_n++] = p[i];
        return n;
    }
};
extern StubSerial Serial;

#endif
