"""Cycle budget of the on-board firmware on the simulated ATmega328P (simavr, 16 MHz).

    python benchmarks/bench_onboard.py [--scenario uno-rig] [--rate 1000] [--seconds 5]

For plain and compensated observer sums it builds the rig firmware with the scenario's
generated controller (``esoarm.codegen.onboard.onboard_firmware``, 1 Mbit/s), runs it in
simavr with the twin on its pins and a scripted host (START, a HEARTBEAT every 20 ms), and
reads three program-counter probes (``Board.probe``):

- the ``sei`` and the following ``cli`` of the Timer2 compare interrupt: the controller
  step as it runs on board, interrupts on (encoder and UART interrupts inside it count);
- the first instruction of ``loop()``'s receive check: each idle pass of ``loop()`` hits
  it once, ``idle`` cycles apart, so the busy cycles of each 1 ms window are
  ``16000 − idle · (passes that found nothing to do)``.

``overhead = busy − step`` per sample is everything the firmware does besides the
controller (interrupt entry, encoder, motor pins, the CHIP_SAMPLE frame: its CRC, queue
and UART interrupts).  ``esoarm hil --onboard --sums auto`` adds
:data:`esoarm.codegen.onboard.OVERHEAD_CYCLES` to the worst step PIL measures.
"""

from __future__ import annotations

import argparse
import subprocess
import time

import numpy as np

from esoarm.codegen.onboard import onboard_firmware
from esoarm.hardware import protocol as P
from esoarm.hardware.hil.board import F_CPU, Board
from esoarm.hardware.hil.twin import PinTwin
from esoarm.scenario import load_scenario


def _disassembly(elf: str) -> list[str]:
    return subprocess.run(["avr-objdump", "-d", elf], capture_output=True, text=True,
                          check=True).stdout.splitlines()


def probes(elf: str) -> tuple[int, int, int]:
    """(sei, cli) of the Timer2 compare interrupt and loop()'s receive check [byte address]."""
    lines = _disassembly(elf)
    sei = cli = rx = None
    section = ""
    for ln in lines:
        if ln.endswith(">:"):
            section = ln.split("<", 1)[1][:-2]
            continue
        parts = ln.split("\t")
        if len(parts) < 3:
            continue
        addr = int(parts[0].strip().rstrip(":"), 16)
        op = parts[2].strip()
        if section == "__vector_7" and op == "sei" and sei is None:
            sei = addr
        elif section == "__vector_7" and op == "cli" and sei is not None and cli is None:
            cli = addr
        elif section == "main" and rx is None and "<_ZL8rxq_tail>" in ln and "lds" in op:
            rx = addr
    if sei is None or cli is None or rx is None:
        raise SystemExit(f"{elf}: probes not found (sei {sei}, cli {cli}, rx check {rx})")
    return sei, cli, rx


def run_probe(scn, elf: str, pc: int, seconds: float) -> tuple[np.ndarray, int, int, list]:  # type: ignore[no-untyped-def]
    """Cycles at which the PC reached ``pc`` (sample 0 on), cycle of sample 0, samples, faults.

    Deterministic: the same firmware, twin and scripted host give the same run for every
    probe, so the three probes' runs line up cycle for cycle.
    """
    twin = PinTwin(scn, F_CPU)
    board = Board(elf)
    parser = P.Parser()
    board.set_encoder(twin.levels)
    board.run(round(0.05 * F_CPU))
    board.probe(pc)
    board.send(P.encode(P.START, 0))
    started, next_beat, seq, n, faults = False, 0, 1, 0, []
    hits: list[np.ndarray] = []
    t_first = 0
    end = board.cycle + round((seconds + 0.1) * F_CPU)
    while board.cycle < end:
        c0 = board.cycle
        edges = twin.step(board.motor().duty, c0) if started else (None, None)
        board.run(c0 + twin.step_cycles, *edges)
        hits.append(board.probe_hits())
        data, _ = board.take()
        for f in parser.feed(data):
            if f.kind == P.CHIP_SAMPLE:
                n += 1
                if not started:
                    started, t_first = True, board.cycle
                    twin.start()
                    next_beat = board.cycle
                if board.cycle >= next_beat:
                    board.send(P.encode(P.HEARTBEAT, seq & 0xFF, P.ChipSample.from_frame(f).k))
                    seq += 1
                    next_beat = board.cycle + round(0.02 * F_CPU)
            elif f.kind == P.FAULT:
                faults.append(f.fields())
    board.close()
    h = np.concatenate(hits).astype(np.int64)
    return h, t_first, n, faults


def measure(scn, compensated: bool, seconds: float) -> dict:  # type: ignore[no-untyped-def]
    """Per 1 ms sample window: step cycles, busy cycles, overhead; and the run's faults."""
    elf = str(onboard_firmware(scn, compensated=compensated))
    sei, cli, rx = probes(elf)
    per = round(F_CPU * scn.sample_time)
    h_sei, t0, n, faults = run_probe(scn, elf, sei, seconds)
    h_cli, t0b, _, _ = run_probe(scn, elf, cli, seconds)
    h_rx, t0c, _, _ = run_probe(scn, elf, rx, seconds)
    assert t0 == t0b == t0c, "the probe runs differ: not deterministic"
    m = min(len(h_sei), len(h_cli))
    step = (h_cli[:m] - h_sei[:m])  # one sei/cli pair per sample
    idle = int(np.diff(h_rx).min())
    d = np.diff(h_rx)
    w = (h_rx[:-1] - t0) // per
    ok = (w >= 0) & (d == idle)
    windows = int(seconds / scn.sample_time) - 1
    idle_c = np.bincount(w[ok], minlength=windows)[:windows] * idle
    busy = per - idle_c
    k = min(len(step), windows)
    return {"sums": "compensated" if compensated else "plain", "samples": n, "faults": faults,
            "step": step[:k], "busy": busy[:k], "overhead": busy[:k] - step[:k],
            "budget": per, "idle_pass": idle}


def _stats(a: np.ndarray) -> str:
    return f"{np.median(a):.0f} / {np.percentile(a, 99):.0f} / {a.max():.0f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="uno-rig")
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    scn = load_scenario(args.scenario, {"sensor.rate_hz": args.rate})
    print(f"{scn.name} at {args.rate:g} Hz on board (simavr ATmega328P, 16 MHz, 1 Mbit/s), "
          f"{args.seconds:g} s; cycles per sample, median / p99 / max")
    print("| observer sums | samples | faults | step (ISR, interrupts on) | busy | "
          "overhead = busy − step | budget |")
    print("|---|---|---|---|---|---|---|")
    for compensated in (False, True):
        t = time.perf_counter()
        r = measure(scn, compensated, args.seconds)
        print(f"| {r['sums']} | {r['samples']} | {r['faults'] or 'none'} | {_stats(r['step'])} "
              f"| {_stats(r['busy'])} | {_stats(r['overhead'])} | {r['budget']} |", flush=True)
        print(f"<!-- {time.perf_counter() - t:.0f} s wall, idle pass {r['idle_pass']} cycles -->")


if __name__ == "__main__":
    main()
