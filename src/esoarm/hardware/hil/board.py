"""The simulated Arduino Uno: the harness library (``harness.c``) through ctypes.

:class:`Board` runs the firmware's ELF on simavr's ATmega328P at 16 MHz and
exposes what a test bench would touch: the two encoder lines, the UART bytes
(with the CPU cycle of each byte the firmware writes), the registers that set
the motor pins, and the reset line.  It knows nothing about the arm.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from esoarm.hardware.hil.build import harness_library

__all__ = ["F_CPU", "Board", "MotorPins"]

#: CPU clock of the Uno [Hz]
F_CPU = 16_000_000

# ATmega328P data-space addresses (datasheet, register summary)
DDRB, PORTB, DDRD, PORTD = 0x24, 0x25, 0x2A, 0x2B
TCCR1A, OCR1AL, OCR1BL = 0x80, 0x88, 0x8A
UCSR0A, UBRR0L, UBRR0H = 0xC0, 0xC4, 0xC5
COM1A1, COM1B1 = 0x80, 0x20  # TCCR1A bits: OC1A / OC1B connected to the pin
U2X0 = 0x02
DATA_SIZE = 0x900  # 32 registers + 224 I/O + 2048 SRAM

_TX_MAX = 8192


class BoardError(RuntimeError):
    """The simulated MCU could not be started or stopped running; one line."""


@dataclass(frozen=True)
class MotorPins:
    """Motor driver inputs as the AVR drives them.

    Attributes
    ----------
    duty : int
        Signed duty in counts of 255: the PWM compare value where the timer
        drives the pin, ±255 for a pin set high, 0 for low (``analogWrite(0)``
        and ``analogWrite(255)`` are plain digital writes on AVR).
    driver : str
        "l298n" (ENA = D9, IN1 = D7, IN2 = D8) or "bts7960" (RPWM = D9,
        LPWM = D10), told apart by which pins the firmware made outputs.
    """

    duty: int
    driver: str


class Board:
    """An ATmega328P running ``elf`` (see module docstring).

    Parameters
    ----------
    elf : Path
        Firmware built for the Uno.
    """

    def __init__(self, elf: Path) -> None:
        lib = ctypes.CDLL(str(harness_library()))
        lib.hil_open.restype = ctypes.c_void_p
        lib.hil_open.argtypes = [ctypes.c_char_p, ctypes.c_uint32]
        lib.hil_last_error.restype = ctypes.c_char_p
        lib.hil_close.argtypes = [ctypes.c_void_p]
        lib.hil_data.restype = ctypes.POINTER(ctypes.c_uint8)
        lib.hil_data.argtypes = [ctypes.c_void_p]
        lib.hil_cycle.restype = ctypes.c_uint64
        lib.hil_cycle.argtypes = [ctypes.c_void_p]
        lib.hil_run.restype = ctypes.c_int
        lib.hil_run.argtypes = [ctypes.c_void_p, ctypes.c_uint64, ctypes.c_void_p,
                                ctypes.c_void_p, ctypes.c_int]
        lib.hil_set_encoder.argtypes = [ctypes.c_void_p, ctypes.c_uint8]
        lib.hil_uart_send.restype = ctypes.c_int
        lib.hil_uart_send.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
        lib.hil_uart_take.restype = ctypes.c_int
        lib.hil_uart_take.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                                      ctypes.c_int]
        lib.hil_reset.argtypes = [ctypes.c_void_p]
        lib.hil_isr_stats.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
        lib.hil_isr_clear.argtypes = [ctypes.c_void_p]
        lib.hil_probe.argtypes = [ctypes.c_void_p, ctypes.c_uint32]
        lib.hil_probe_take.restype = ctypes.c_int
        lib.hil_probe_take.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
        self._lib = lib
        handle = lib.hil_open(str(elf).encode(), F_CPU)
        if not handle:
            reason = (lib.hil_last_error() or b"").decode(errors="replace").strip()
            raise BoardError(reason or f"simavr could not load '{elf}'")
        self._h: ctypes.c_void_p | None = ctypes.c_void_p(handle)
        ptr = lib.hil_data(self._h)
        self.data = np.ctypeslib.as_array(ptr, shape=(DATA_SIZE,))
        self._tx = np.zeros(_TX_MAX, dtype=np.uint8)
        self._tx_cycles = np.zeros(_TX_MAX, dtype=np.uint64)
        self._empty_c = np.zeros(0, dtype=np.uint64)
        self._empty_ab = np.zeros(0, dtype=np.uint8)

    @property
    def cycle(self) -> int:
        """CPU cycles since power-on."""
        return int(self._lib.hil_cycle(self._h))

    def run(self, until: int, edge_cycles: np.ndarray | None = None,
            edge_ab: np.ndarray | None = None) -> None:
        """Run to cycle ``until``, setting the encoder lines to ``edge_ab[i]``
        (bit 1 = A, bit 0 = B) at ``edge_cycles[i]`` (ascending)."""
        c = self._empty_c if edge_cycles is None else np.ascontiguousarray(edge_cycles, np.uint64)
        ab = self._empty_ab if edge_ab is None else np.ascontiguousarray(edge_ab, np.uint8)
        if self._lib.hil_run(self._h, int(until), c.ctypes.data, ab.ctypes.data, len(c)) < 0:
            raise BoardError("the simulated MCU stopped (crash or end of program)")

    def set_encoder(self, ab: int) -> None:
        """Set the encoder lines now (bit 1 = A on D2, bit 0 = B on D3)."""
        self._lib.hil_set_encoder(self._h, ab & 3)

    def send(self, data: bytes) -> int:
        """Bytes from the host into the UART receiver; returns how many were queued."""
        return int(self._lib.hil_uart_send(self._h, data, len(data))) if data else 0

    def take(self) -> tuple[bytes, np.ndarray]:
        """Bytes the firmware wrote to its UART since the last call, and their cycles."""
        n = self._lib.hil_uart_take(self._h, self._tx.ctypes.data, self._tx_cycles.ctypes.data,
                                    _TX_MAX)
        return self._tx[:n].tobytes(), self._tx_cycles[:n].copy()

    def reset(self) -> None:
        """Pull the reset line (a brown-out): the firmware restarts from setup()."""
        self._lib.hil_reset(self._h)

    def isr_stats(self) -> dict[str, int]:
        """Encoder interrupt cost: handler cycles and edge-to-return cycles (n, sum, max)."""
        out = np.zeros(5, dtype=np.uint64)
        self._lib.hil_isr_stats(self._h, out.ctypes.data)
        n, s, mx, ls, lmx = (int(v) for v in out)
        return {"n": n, "isr_sum": s, "isr_max": mx, "latency_sum": ls, "latency_max": lmx}

    def isr_clear(self) -> None:
        """Forget the encoder interrupt statistics."""
        self._lib.hil_isr_clear(self._h)

    def probe(self, pc: int) -> None:
        """Record the cycles at which the program counter reaches byte address ``pc``."""
        self._lib.hil_probe(self._h, pc)

    def probe_hits(self) -> np.ndarray:
        """Cycles recorded by :meth:`probe` since the last call."""
        out = np.zeros(4096, dtype=np.uint64)
        n = self._lib.hil_probe_take(self._h, out.ctypes.data, len(out))
        return out[:n].copy()

    def motor(self) -> MotorPins:
        """The motor driver inputs, read from the port and Timer1 registers."""
        d = self.data
        ddrb, portb, ddrd, portd, tccr1a = (int(d[DDRB]), int(d[PORTB]), int(d[DDRD]),
                                            int(d[PORTD]), int(d[TCCR1A]))

        def level(ddr: int, port: int, bit: int, com: int, ocr: int) -> int:
            if not ddr & (1 << bit):
                return 0  # an input (after reset): the driver sees no drive
            if tccr1a & com:
                return ocr
            return 255 if port & (1 << bit) else 0

        pwm_a = level(ddrb, portb, 1, COM1A1, int(d[OCR1AL]))
        if ddrb & (1 << 2):  # D10 is an output: BTS7960 (RPWM = D9, LPWM = D10)
            pwm_b = level(ddrb, portb, 2, COM1B1, int(d[OCR1BL]))
            return MotorPins(pwm_a - pwm_b, "bts7960")
        in1 = bool(ddrd & 0x80 and portd & 0x80)
        in2 = bool(ddrb & 0x01 and portb & 0x01)
        sign = 1 if in1 and not in2 else -1 if in2 and not in1 else 0
        return MotorPins(sign * pwm_a, "l298n")

    def uart_cycles_per_byte(self, bits: int = 10) -> int:
        """Cycles of one UART frame of ``bits`` bits at the firmware's UBRR0 / U2X0 setting."""
        d = self.data
        ubrr = int(d[UBRR0L]) | (int(d[UBRR0H]) & 0x0F) << 8
        per_bit = (ubrr + 1) * (8 if d[UCSR0A] & U2X0 else 16)
        return per_bit * bits

    def close(self) -> None:
        """Free the simulated MCU."""
        if getattr(self, "_h", None) is not None:
            self._lib.hil_close(self._h)
            self._h = None
            self.data = np.zeros(DATA_SIZE, dtype=np.uint8)

    def __enter__(self) -> Board:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
