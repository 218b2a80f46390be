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
  16000 less the cycles of the passes that found nothing to do (at most
  :data:`IDLE_SLACK` cycles longer than the shortest pass).

The table's columns "arm moving" take only the windows in which the scenario's reference
moves (θ̇d or θ̈d not zero): the issue's budget is "at least 30 % of the period free at p99
while the arm moves".  ``--set KEY=VALUE`` builds another form (e.g.
``controller.kind=adrc-error``), ``--baud``/``--every`` stream every n-th sample (the chip
still controls at every one), ``--polled`` feeds the line from ``loop()`` without the
transmit interrupt.  ``--learn-map BINS`` first learns a table of BINS bins from a 40 s
run of the scenario at 50 Hz (as the ``--table`` row does) and builds with it, e.g.
``python benchmarks/bench_onboard.py --stream-every 10 --baud 115200 --stream-polled
--sums plain --seconds 3.2 --set rig.cogging.amplitude=0.08 --set rig.cogging.periods=6
--learn-map 72`` (the learned table at 1 kHz).  ``--stream-every`` and ``--stream-polled``
are the same options under the names ``esoarm hil --onboard`` and ``esoarm codegen
--arduino-library`` give them: the same arguments build the same firmware (one
``onboard_firmware`` call, one cached ELF), e.g.
``python benchmarks/bench_onboard.py --stream-every 10 --baud 115200 --stream-polled --sums
plain`` measures what ``esoarm hil uno-rig --onboard --set sensor.rate_hz=1000 --sums plain
--stream-every 10 --baud 115200 --stream-polled`` runs.

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
from doc_block import write_block

from esoarm.codegen.onboard import BAUD, onboard_firmware, stream_every
from esoarm.hardware import protocol as P
from esoarm.hardware.hil.board import F_CPU, Board
from esoarm.hardware.hil.twin import PinTwin
from esoarm.reference import evaluate_reference
from esoarm.scenario import load_scenario
from esoarm.scenario.schema import parse_override


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
        elif (section == "main" and rx is None and "<_ZL8rxq_tail" in ln and "lds" in op):
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


#: A pass of loop() at most this many cycles longer than the shortest one did nothing
#: either: with the polled transmit (``--polled``) a pass that finds the line still busy
#: takes a few cycles more than one that finds nothing to send.
IDLE_SLACK = 12


def moving(scn, n: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Samples 0..n-1 at which the reference moves (θ̇d or θ̈d not zero): the arm moves."""
    _, vel, acc = evaluate_reference(scn.reference, np.arange(n) * scn.sample_time)
    return (vel != 0.0) | (acc != 0.0)


def measure(scn, compensated: bool, seconds: float, baud: int = BAUD,  # type: ignore[no-untyped-def]
            every: int | None = None, polled: bool = False) -> dict:
    """Per sample window: step cycles, busy cycles, overhead; and the run's faults.

    ``every`` streams every n-th sample (the firmware's STREAM_EVERY; default the fewest
    ``baud`` needs).  ``moving`` marks the windows in which the reference moves.
    """
    elf = str(onboard_firmware(scn, compensated=compensated, baud=baud, every=every,
                               polled=polled))
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
    ok = (w >= 0) & (d <= idle + IDLE_SLACK)
    windows = int(seconds / scn.sample_time) - 1
    idle_c = np.bincount(w[ok], weights=d[ok], minlength=windows)[:windows].astype(np.int64)
    busy = per - idle_c
    k = min(len(step), windows)
    return {"sums": "compensated" if compensated else "plain", "samples": n, "faults": faults,
            "step": step[:k], "busy": busy[:k], "overhead": busy[:k] - step[:k],
            "moving": moving(scn, k), "budget": per, "idle_pass": idle,
            "every": every if every is not None else stream_every(scn.sensor.rate_hz, baud),
            "baud": baud, "polled": polled}


def _stats(a: np.ndarray) -> str:
    if len(a) == 0:
        return "—"
    return f"{np.median(a):.0f} / {np.percentile(a, 99):.0f} / {a.max():.0f}"


def row(r: dict, label: str) -> str:
    """One table row: the whole run, then the windows in which the arm moves."""
    mv = r["moving"]
    busy_mv = r["busy"][mv]
    p99 = float(np.percentile(busy_mv, 99)) if len(busy_mv) else float("nan")
    free = 1.0 - p99 / r["budget"]
    return (f"| {label} | {r['sums']} | {r['baud']} | {r['every']} "
            f"| {'polled' if r['polled'] else 'interrupt'} | {r['samples']} "
            f"| {r['faults'] or 'none'} | {_stats(r['step'][mv])} | {_stats(r['busy'][mv])} "
            f"| {_stats(r['overhead'][mv])} | {_stats(r['busy'])} | {r['budget']} "
            f"| {100 * free:.0f} % |")


HEADER = ("| build | observer sums | baud [bit/s] | streamed: every n-th sample | transmit "
          "| samples | faults | step (ISR, interrupts on), arm moving | busy, arm moving "
          "| overhead = busy − step, arm moving | busy, whole run | budget "
          "| free at p99, arm moving |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|")


#: A key of a build's overrides: learn a table of this many bins (:func:`with_learned_table`).
LEARN = "learn_map_bins"
#: The builds of the table in docs/on-the-chip.md (``--table``): (label, sums, baud, every,
#: polled[, scenario overrides]).  Every one controls at every sample; they differ in what
#: they stream and how, and the last two in the controller's form.
TABLE_BUILDS: list[tuple] = [
    ("every sample, 1 Mbit/s (the default build)", False, 1_000_000, None, False),
    ("every sample, 1 Mbit/s (the default build)", True, 1_000_000, None, False),
    ("every 4th, 115200 bit/s", False, 115_200, None, False),
    ("every 10th, 1 Mbit/s", False, 1_000_000, 10, False),
    ("every 10th, 1 Mbit/s, polled", False, 1_000_000, 10, True),
    ("every 8th, 115200 bit/s, polled", False, 115_200, 8, True),
    ("every 10th, 115200 bit/s, polled (the cheapest)", False, 115_200, 10, True),
    ("every 10th, 115200 bit/s, polled (the cheapest)", True, 115_200, 10, True),
    ("error-based ADRC, every 10th, 115200 bit/s, polled", False, 115_200, 10, True,
     {"controller.kind": "adrc-error"}),
    ("ADRC TF form, every 10th, 115200 bit/s, polled", False, 115_200, 10, True,
     {"controller.kind": "adrc-tf"}),
    ("learned table (72 bins, in flash), cogging, every 10th, 115200 bit/s, polled", False,
     115_200, 10, True, {"rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6,
                         LEARN: 72}),
]



def with_learned_table(scn, bins: int):  # type: ignore[no-untyped-def]
    """``scn`` with the table ``esoarm learn-map --bins BINS`` learns from a 40 s run of it
    at 50 Hz (as docs/adrc.md's hil map row; the twin's cogging is ``scn``'s)."""
    from esoarm.studies.adrc.learn_map import learned_from_run, with_map

    learning = load_scenario(scn, {"sensor.rate_hz": 50.0, "duration": 40.0})
    return with_map(scn, learned_from_run(learning, bins).table)


def table(scn, seconds: float) -> str:  # type: ignore[no-untyped-def]
    """Every build of :data:`TABLE_BUILDS` on ``scn``: the table, markdown."""
    import os
    import platform

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    lines = [f"`python benchmarks/bench_onboard.py --table --seconds {seconds:g}` "
             f"({scn.name} at {scn.sensor.rate_hz:g} Hz in simavr, {seconds:g} s from START "
             f"with the first move from 1 s to 3 s; on {platform.node()}, load {load}: the "
             "load slows the simulation, not the simulated cycles). Cycles per "
             f"{1e3 * scn.sample_time:g} ms sample, median / p99 / max.", "", HEADER]
    for label, compensated, baud, every, polled, *keys in TABLE_BUILDS:
        over = dict(keys[0]) if keys else {}
        bins = over.pop(LEARN, None)
        point = load_scenario(scn, over) if over else scn
        if bins:
            point = with_learned_table(point, bins)
        r = measure(point, compensated, seconds, baud, every, polled)
        lines.append(row(r, label))
        print(lines[-1], flush=True)
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="uno-rig")
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--sums", choices=("plain", "compensated", "both"), default="both")
    ap.add_argument("--baud", type=int, default=BAUD, help="line rate [bit/s]")
    ap.add_argument("--every", "--stream-every", dest="every", type=int, default=None,
                    help="stream every n-th sample (default: the fewest the line needs); "
                    "the same build as esoarm hil --onboard --stream-every N")
    ap.add_argument("--polled", "--stream-polled", dest="polled", action="store_true",
                    help="feed the line from loop() a byte at a time (no transmit interrupt; "
                    "esoarm hil --onboard --stream-polled)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                    help="a scenario override, e.g. controller.kind=adrc-error (repeatable)")
    ap.add_argument("--learn-map", dest="learn_map", type=int, default=0, metavar="BINS",
                    help="first learn a table of BINS bins from a 40 s run of the scenario at "
                    "50 Hz (esoarm learn-map --bins BINS, as the --table row) and build with it")
    ap.add_argument("--label", default="", help="the build's name in the table")
    ap.add_argument("--header", action="store_true", help="print the table's header")
    ap.add_argument("--table", action="store_true",
                    help="every build of the docs' table (TABLE_BUILDS), one after another")
    ap.add_argument("--update", default=None, metavar="MD",
                    help="with --table: write it between the markers in this file")
    args = ap.parse_args()
    overrides: dict[str, object] = {"sensor.rate_hz": args.rate}
    for kv in args.overrides:
        key, value = parse_override(kv)
        overrides[key] = value
    scn = load_scenario(args.scenario, overrides)
    if args.learn_map:
        scn = with_learned_table(scn, args.learn_map)
    if args.table:
        text = table(scn, args.seconds)
        if args.update:
            write_block(args.update, "bench_onboard:table", text)
            print(f"wrote the table into {args.update}")
        return
    print(f"<!-- {scn.name} at {args.rate:g} Hz on board (simavr ATmega328P, 16 MHz), "
          f"{args.seconds:g} s from START; cycles per sample, median / p99 / max; "
          f"{' '.join(args.overrides) or 'the scenario as written'} -->")
    if args.header:
        print(HEADER)
    sums = {"plain": [False], "compensated": [True], "both": [False, True]}[args.sums]
    for compensated in sums:
        t = time.perf_counter()
        r = measure(scn, compensated, args.seconds, args.baud, args.every, args.polled)
        print(row(r, args.label or "as generated"), flush=True)
        elf = onboard_firmware(scn, compensated=compensated, baud=args.baud, every=args.every,
                               polled=args.polled)  # cached: the build measure() ran
        print(f"<!-- firmware {elf} -->")
        print(f"<!-- {time.perf_counter() - t:.0f} s wall, idle pass {r['idle_pass']} cycles, "
              f"{int(r['moving'].sum())} windows with the arm moving -->")


if __name__ == "__main__":
    main()
