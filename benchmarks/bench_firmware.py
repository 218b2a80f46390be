"""Timing of the rig firmware measured on the simulated ATmega328P (simavr, 16 MHz).

Run:  python benchmarks/bench_firmware.py [--out docs/benchmarks-firmware.md]

Everything here is counted in CPU cycles of the simulated chip, so the numbers
do not depend on the machine that runs the benchmark.  A scripted host answers
every SAMPLE with a DUTY as soon as the frame is complete; the encoder lines
toggle at the highest rate the arm of ``uno-rig`` can reach (the motor's
no-load speed Vs/(N·Kt) at the arm, times 2400 counts per revolution).

1. Sample tick to frame on the wire: the tick is the instant the firmware's
   own clock (``micros()``, Timer0) reaches the sample's due time; the frame has
   left the UART when its last stop bit is out.  simavr times a UART byte as 11
   bits (it always counts a parity bit) and lets the firmware write the next
   byte only when the previous one is out; the chip sends 10-bit bytes
   back to back from its double buffer.  Reported: the cycles to the first byte
   written, plus 19 real byte times (the chip), and simavr's own figure.
2. Encoder interrupt: cycles inside the handler (attachInterrupt's dispatch,
   one read of PIND for both channels, the table step) and from the edge to the handler's return.
3. Highest sustained sample rate at 115200 and 1000000 bit/s: firmware builds
   at shorter and shorter periods; sustained = every sample arrives, in order,
   no OVERRUN or watchdog fault, and the reading never falls a period behind.
"""

from __future__ import annotations

import argparse
import math
import platform
import subprocess
from pathlib import Path

import numpy as np

from esoarm.hardware import protocol as P
from esoarm.hardware.hil.board import F_CPU, Board
from esoarm.hardware.hil.build import default_firmware_dir, firmware_elf
from esoarm.hardware.hil.twin import GRAY
from esoarm.plants.motor import MotorParams
from esoarm.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
VECTOR_TIMER0_OVF = 16 * 4  # byte address of the TIMER0_OVF vector on the ATmega328P
FRAME_BYTES = 19  # SAMPLE frame: 5 header + 12 payload + 2 CRC


def data_symbols(elf: Path) -> dict[str, int]:
    """RAM addresses (data space) of the firmware's variables, from avr-nm."""
    out = subprocess.run(["avr-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    syms = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1] in "bBdD":
            syms[parts[2]] = int(parts[0], 16) & 0xFFFF
    return syms


def u32(board: Board, addr: int) -> int:
    d = board.data
    return int(d[addr]) | int(d[addr + 1]) << 8 | int(d[addr + 2]) << 16 | int(d[addr + 3]) << 24


def micros_origin(board: Board, syms: dict[str, int]) -> int:
    """Cycle at which the firmware's micros() read 0 (Timer0 overflows every 16384 cycles)."""
    board.probe(VECTOR_TIMER0_OVF)
    est = []
    for _ in range(8):
        board.run(board.cycle + 16384)
        hits = board.probe_hits()
        n = u32(board, syms["timer0_overflow_count"])
        if len(hits) == 1:
            est.append(int(hits[0]) - 16384 * n - 4)  # 4 cycles: interrupt response
    board.probe(0xFFFFFFFF)
    return min(est)


def arm_edge_period(scn_name: str = "uno-rig") -> float:
    """Seconds between encoder edges at the arm's highest speed (motor at no load)."""
    scn = load_scenario(scn_name)
    motor = MotorParams.from_scenario(scn)
    assert motor is not None
    omega_max = motor.supply_voltage / (motor.gear_ratio * motor.torque_constant)
    counts_per_rad = 360.0 / scn.sensor.resolution_deg / (2 * math.pi)
    return 1.0 / (omega_max * counts_per_rad)


def drive(elf: Path, period_us: int, seconds: float, edge_period: float | None) -> dict:
    """Run the firmware with a scripted host; return per-sample timing and faults."""
    syms = data_symbols(elf)
    board = Board(elf)
    try:
        board.set_encoder(GRAY[0])
        board.run(round(0.05 * F_CPU))
        c_zero = micros_origin(board, syms)
        board.isr_clear()
        board.send(P.encode(P.START, 0))
        slice_c = max(160, min(1600, period_us * 16 // 10))
        end = board.cycle + round(seconds * F_CPU)
        parser = P.Parser()
        seq, pos = 1, 0
        next_edge = board.cycle + 1000
        edge_c = round(edge_period * F_CPU) if edge_period else 0
        first: int | None = None
        samples, faults = [], []
        while board.cycle < end:
            target = board.cycle + slice_c
            cycles, levels = [], []
            if edge_c:
                while next_edge < target:
                    pos += 1
                    cycles.append(next_edge)
                    levels.append(GRAY[pos % 4])
                    next_edge += edge_c
            board.run(target, np.asarray(cycles, np.uint64), np.asarray(levels, np.uint8))
            data, byte_cycles = board.take()
            for b, c in zip(data, byte_cycles.tolist(), strict=True):
                first = c if first is None else first
                for f in parser.feed(bytes((b,))):
                    if f.kind == P.SAMPLE:
                        k, t_us, _count = f.fields()
                        samples.append((k, t_us, first, c))
                        board.send(P.encode(P.DUTY, seq, k, 60))
                        seq = (seq + 1) & 0xFF
                    elif f.kind == P.FAULT:
                        faults.append(f.fields())
                    first = None
        t_start = u32(board, syms["_ZL10t_start_us"])
        isr = board.isr_stats()
        byte10 = board.uart_cycles_per_byte(10)
        byte11 = board.uart_cycles_per_byte(11)
    finally:
        board.close()
    arr = np.asarray(samples, dtype=np.int64).reshape(-1, 4)
    k, t_us, c_first, c_last = arr.T
    tick = c_zero + 16 * (t_start + k * period_us)
    read_late_us = t_us - k * period_us
    return {
        "n": len(k),
        "expected": int(seconds * 1e6 / period_us),
        "in_order": bool(len(k) and np.array_equal(k, np.arange(len(k)))),
        "faults": faults,
        "read_late_us_max": int(read_late_us.max()) if len(k) else None,
        "read_late_us": read_late_us,
        "tick_to_first": c_first - tick,
        "tick_to_wire_chip": c_first - tick + FRAME_BYTES * byte10,
        "tick_to_wire_simavr": c_last + byte11 - tick,
        "isr": isr,
        "byte10": byte10,
        "byte11": byte11,
    }


def sustained(res: dict, period_us: int) -> bool:
    return (res["in_order"] and not res["faults"] and res["n"] >= res["expected"] - 1
            and res["read_late_us_max"] is not None and res["read_late_us_max"] < period_us)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="write the Markdown tables here")
    args = ap.parse_args()
    fw = default_firmware_dir()
    edge_period = arm_edge_period()
    lines = ["# Firmware timing on the ATmega328P", "",
             "The rig firmware (`firmware/esoarm_rig`) measured cycle by cycle on simavr's "
             "ATmega328P at 16 MHz (needs the AVR toolchain and libsimavr, see "
             "[hardware.md](hardware.md)). A scripted host answers every sample at once; the "
             "encoder turns at the arm's top speed. What each line means is in the docstring "
             "of `benchmarks/bench_firmware.py`; what it means for a rig is in "
             "[hardware.md](hardware.md#timing-on-the-chip).", "",
             "Measured with `python benchmarks/bench_firmware.py --out "
             "docs/benchmarks-firmware.md` on simavr "
             f"(ATmega328P at 16 MHz; cycle counts, independent of the machine: "
             f"{platform.machine()}, Python {platform.python_version()}).", ""]

    # 1-2: the shipped build (50 Hz, 115200 bit/s), encoder at the arm's top speed
    elf = firmware_elf("l298n", fw)
    res = drive(elf, 20000, 2.0, edge_period)
    isr = res["isr"]
    us = 1e6 / F_CPU
    lines += [
        f"Shipped build (50 Hz, 115200 bit/s), {res['n']} samples, encoder at the arm's top "
        f"speed ({1 / edge_period:.0f} edges/s, one every {edge_period * 1e6:.0f} µs):", "",
        "| quantity | median | worst | unit |", "|---|---|---|---|",
        f"| tick → firmware reads the count | {np.median(res['read_late_us']):.0f} | "
        f"{res['read_late_us_max']} | µs (its own clock, 4 µs steps) |",
        f"| tick → first byte written to the UART | "
        f"{np.median(res['tick_to_first']) * us:.0f} | {res['tick_to_first'].max() * us:.0f} "
        f"| µs |",
        f"| tick → frame on the wire (chip: 19 bytes of 10 bits) | "
        f"{np.median(res['tick_to_wire_chip']) * us:.0f} | "
        f"{res['tick_to_wire_chip'].max() * us:.0f} | µs |",
        f"| tick → frame on the wire (simavr: 11-bit bytes, single-buffered) | "
        f"{np.median(res['tick_to_wire_simavr']) * us:.0f} | "
        f"{res['tick_to_wire_simavr'].max() * us:.0f} | µs |",
        f"| encoder interrupt, inside the handler | {isr['isr_sum'] / max(isr['n'], 1):.0f} | "
        f"{isr['isr_max']} | cycles |",
        f"| encoder edge → handler returned | {isr['latency_sum'] / max(isr['n'], 1):.0f} | "
        f"{isr['latency_max']} | cycles |",
        "",
        f"At the top speed the encoder interrupts take "
        f"{isr['isr_sum'] / max(isr['n'], 1) / (edge_period * F_CPU) * 100:.1f} % of the CPU.",
        "",
    ]

    # 3: highest sustained rate per baud
    lines += ["| baud [bit/s] | sample period [µs] | rate [Hz] | samples | sustained | "
              "tick → frame on the wire, worst [µs] (chip) |", "|---|---|---|---|---|---|"]
    for baud, periods in ((115200, (2000, 1800, 1700, 1500)),
                          (1000000, (1000, 800, 700, 600, 500))):
        for period in periods:
            e = firmware_elf("l298n", fw, {"SAMPLE_PERIOD_US": period, "BAUD": baud})
            r = drive(e, period, max(0.2, 300 * period * 1e-6), edge_period)
            ok = sustained(r, period)
            worst = r["tick_to_wire_chip"].max() * us if r["n"] else float("nan")
            faults = ", ".join(sorted({f"FAULT {c}" for c, _ in r["faults"]}))
            lines.append(f"| {baud} | {period} | {1e6 / period:.0f} | {r['n']}/{r['expected']} "
                         f"| {'yes' if ok else 'no' + (f' ({faults})' if faults else '')} "
                         f"| {worst:.0f} |")
            print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text, encoding="utf-8")


if __name__ == "__main__":
    main()
