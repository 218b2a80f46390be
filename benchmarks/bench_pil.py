"""The generated controller on the chips: cycles, flash, RAM, and float32 against float64.

Run:  python benchmarks/bench_pil.py [--update docs/on-the-chip.md]

1. Cycles per kind × target × precision, measured processor in the loop
   (:func:`esoarm.codegen.pil.run_pil`) over the whole ``uno-rig`` run (50 Hz,
   motor: torque -> duty) -- ATmega328P at 16 MHz in simavr (cycles), Cortex-M4 on
   QEMU's mps2-an386 and the Cortex-M0+ build (soft float) on QEMU's microbit, whose
   nRF51 Cortex-M0 runs the same ARMv6-M instructions (both an instruction-count
   proxy: QEMU models no cycle counter) --
   plus a *forced* worst case: the same chip fed 400 samples that jump ±0.6 rad
   every 4 samples, which drives the innovation past δ (fal's ``pow`` branch) with
   both signs, saturates the command both ways and crosses the motor's deadband.
   "% of 1 kHz" is the larger of the two maxima over one 1 kHz sample period at
   the chip's clock (16 000 cycles; 16 000 instructions at the microbit's 16 MHz;
   25 000 at the mps2's 25 MHz).
2. Precision: worst |Δu| of the generated float32 code against the Python
   float64 reference over the test-1 run (the first 5 s at 10 kHz; an ideal torque
   source, so no duty rounding is involved; host build, lockstep with the twin),
   plain and compensated observer sums, for the linear and the cascade ESO (ε is
   the last level's), ε × rate × discretization.

Everything is counted on the emulated chips, so the numbers do not depend on the
machine that runs the benchmark (the cycles table names it and its load anyway).
With ``--update`` the tables replace the text between the
``<!-- bench_pil:NAME -->`` and ``<!-- /bench_pil:NAME -->`` markers; with
``--targets`` (e.g. ``--targets cortex-m0plus --only cycles``) only those
targets' rows are measured and replace theirs in the file's table, the other
rows are kept as they were measured.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from doc_block import read_block, write_block

from esoarm.codegen.generate import generate
from esoarm.codegen.lockstep import lockstep
from esoarm.codegen.pil import open_chip
from esoarm.scenario import load_scenario

KINDS = [
    ("linear ESO (euler) + FLC", {}),
    ("linear ESO (zoh) + FLC", {"observer.discretization": "zoh"}),
    ("linear ESO (current) + FLC", {"observer.discretization": "current"}),
    ("nonlinear ESO (euler) + FLC", {"observer.kind": "nonlinear"}),
    ("linear ESO + FLC, model compensation (cos)", {"controller.compensation": "model"}),
    ("linear ESO + PID", {"controller.kind": "pid"}),
    ("cascade ESO (euler, 2 levels) + FLC", {"observer.kind": "cascade"}),
    ("cascade ESO (euler, 3 levels) + FLC", {"observer.kind": "cascade", "observer.levels": 3}),
    ("cascade ESO (2 levels) + PID", {"observer.kind": "cascade", "controller.kind": "pid"}),
    ("linear ESO (euler, half-gain) + FLC", {"observer.tuning": "half-gain"}),
    ("linear ESO (euler), input delay 2, predictor + FLC",
     {"observer.input_delay": 2, "observer.delay_form": "predictor",
      "actuator.delay_samples": 2}),
    ("linear ESO + PID + ESO compensation", {"controller.kind": "pid",
                                             "controller.compensation": "eso"}),
    ("error-based ADRC (euler; + linear ESO beside)", {"controller.kind": "adrc-error"}),
    ("ADRC TF form (euler; + linear ESO beside)", {"controller.kind": "adrc-tf"}),
    ("linear ESO + switch PID → FLC at 2 s, back at 11 s",
     {"controller.kind": "switch", "controller.switch_at": 2.0,
      "controller.switch_back": 11.0}),
]
#: (target, precision, compensated observer sums); avr-gcc's double is 32 bits, so the
#: AVR has no float64 row (``codegen`` refuses it), its plain sums are listed instead.
TARGETS = [("avr", "float32", True), ("avr", "float32", False), ("cortex-m0plus", "float32", True),
           ("cortex-m0plus", "float64", False), ("cortex-m4", "float32", True),
           ("cortex-m4", "float64", False)]


#: label substrings of the rows to measure (--kinds; empty: every row)
ONLY_KINDS: list[str] = []
#: targets to measure (--targets; empty: every target)
ONLY_TARGETS: list[str] = []


def machine() -> str:
    """The machine and the toolchains that measured (one markdown line)."""
    import os
    import platform
    import subprocess

    def first_line(*cmd: str) -> str:
        try:
            out = subprocess.run(cmd, capture_output=True, text=True, check=False).stdout
        except OSError:
            return "missing"
        return out.splitlines()[0].strip() if out else "missing"

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    simavr = first_line("dpkg-query", "-W", "-f", "${Version}", "simavr")
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    return (f"Measured on {platform.node()} ({cpu}, {os.cpu_count()} cores, load average "
            f"{load}; Linux {platform.release()}) with {first_line('avr-gcc', '--version')}, "
            f"simavr {simavr}, {first_line('arm-none-eabi-gcc', '--version')}, "
            f"{first_line('qemu-system-arm', '--version')}. The counts come from the "
            "emulated chips, so they do not depend on the host's speed or load.")


def forced_worst(gen) -> int:  # type: ignore[no-untyped-def]
    """Max per-step count over a sequence that forces every branch."""
    chip = open_chip(gen)
    try:
        for k in range(400):
            chip.step(0.6 if (k // 4) % 2 else -0.6)
        return max(chip.cycles)
    finally:
        chip.close()


def cycles_table() -> str:
    rows = [machine(), "",
            "| kind | target | precision | observer sums | per step (run): min / median / max "
            "| forced max | % of 1 kHz | flash [B] | static RAM [B] | max \\|Δu\\|/limit |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for label, over in KINDS:
        if ONLY_KINDS and not any(w in label for w in ONLY_KINDS):
            continue
        scn = load_scenario("uno-rig", over)
        for target, precision, comp in TARGETS:
            if ONLY_TARGETS and target not in ONLY_TARGETS:
                continue
            gen = generate(scn, target, precision, comp)
            chip = open_chip(gen)
            try:
                run = lockstep(scn, chip)
            finally:
                chip.close()
            c = np.asarray(run.cycles)
            worst = max(int(c.max()), forced_worst(gen))
            budget = chip.clock_hz / 1000.0  # type: ignore[attr-defined]
            unit = " cycles" if target == "avr" else " instr."
            rows.append(f"| {label} | {target} | {precision} | "
                        f"{'compensated' if comp else 'plain'} | {c.min()} / "
                        f"{int(np.median(c))} / {c.max()}{unit} | {worst} | "
                        f"{100 * worst / budget:.0f} % | {chip.flash_bytes} | {chip.ram_bytes} | "
                        f"{run.max_rel_du:.1e} |")
            print(rows[-1], flush=True)
    return "\n".join(rows)


def precision_table() -> str:
    rows = ["| ε [s] | rate [Hz] | discretization | Ts/ε | linear ESO, float32 plain: "
            "max \\|Δu\\| [N·m] | linear, float32 compensated | cascade ESO (2 levels, α = 1.8), "
            "float32 plain | cascade, float32 compensated |",
            "|---|---|---|---|---|---|---|---|"]
    for eps in (0.09, 0.03, 0.01):
        for rate in (50, 1000, 10000):
            for disc in ("euler", "zoh", "current"):
                cells = []
                for kind in ("linear", "cascade"):
                    over: dict[str, object] = {"observer.kind": kind, "observer.eps": eps,
                                               "sensor.rate_hz": rate,
                                               "observer.discretization": disc}
                    if rate > 1000:  # the RK4 step divides Ts; 5 s of the run (50 000 samples)
                        over.update({"rig.step": 1.0 / rate, "duration": 5.0})
                    scn = load_scenario("test-1", over)
                    for comp in (False, True):
                        chip = open_chip(generate(scn, "host", "float32", comp))
                        run = lockstep(scn, chip)
                        ok = run.steps == scn.n_samples and math.isfinite(run.max_abs_du) \
                            and np.all(np.abs(run.theta) < 1e3)
                        text = f"{run.max_abs_du:.1e}" if ok else "diverged"
                        if ok and run.max_rel_du > 1e-4:
                            text = f"**{text}**"
                        if disc == "euler" and scn.sample_time / eps >= 2.0:
                            text += " (Euler unstable: Ts/ε ≥ 2)"
                        cells.append(text)
                rows.append(f"| {eps:g} | {rate} | {disc} | {1.0 / rate / eps:.3g} | "
                            + " | ".join(cells) + " |")
                print(rows[-1], flush=True)
    return "\n".join(rows)


def _row_key(line: str) -> tuple[str, ...]:
    """(kind, target, precision, sums) of a cycles-table row."""
    return tuple(c.strip() for c in line.strip().strip("|").split("|")[:4])


def merge_rows(old: str, new: str) -> str:
    """``old`` cycles table with the rows of ``new``'s targets replaced (or added) by
    ``new``'s, in KINDS × TARGETS order; ``old``'s machine line is kept and ``new``'s is
    added for those targets' rows (replacing an earlier one for the same targets)."""
    old_lines = old.splitlines()
    old_rows = [ln for ln in old_lines if ln.startswith("| ") and "---" not in ln][1:]
    new_lines = new.splitlines()
    new_rows = [ln for ln in new_lines if ln.startswith("| ") and "---" not in ln][1:]
    fresh = {_row_key(r)[1] for r in new_rows}
    tag = f"The {', '.join(sorted(fresh))} rows: "
    machine_lines = [ln for ln in old_lines[:old_lines.index(new_lines[2])]
                     if ln and not ln.startswith(tag)]
    machine_lines.append(tag + new_lines[0])
    rows = {_row_key(r): r for r in old_rows if _row_key(r)[1] not in fresh}
    rows.update({_row_key(r): r for r in new_rows})
    order: dict[tuple[str, ...], int] = {
        (label, target, precision, "compensated" if comp else "plain"): i
        for i, (label, target, precision, comp) in enumerate(
            (lb, *tg) for lb, _ in KINDS for tg in TARGETS)}
    body = sorted(rows.values(), key=lambda r: order.get(_row_key(r), len(order)))
    return "\n\n".join(machine_lines) + "\n\n" + "\n".join(new_lines[2:4] + body)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update", type=Path, help="markdown file with bench_pil markers")
    parser.add_argument("--only", choices=["cycles", "precision"])
    parser.add_argument("--kinds", default="", help="comma-separated label substrings: measure "
                        "only those rows (printed; the markers are not updated)")
    parser.add_argument("--targets", default="", help="comma-separated targets: measure only "
                        "their rows (with --update they replace those rows, the rest is kept)")
    args = parser.parse_args()
    ONLY_KINDS.extend(k for k in args.kinds.split(",") if k)
    ONLY_TARGETS.extend(k for k in args.targets.split(",") if k)
    known = {t for t, _, _ in TARGETS}
    if set(ONLY_TARGETS) - known:
        raise SystemExit(f"--targets: one of {', '.join(sorted(known))}")
    if ONLY_KINDS and args.update:
        raise SystemExit("--kinds measures a part of the table: print it, do not --update")
    if ONLY_TARGETS and args.only != "cycles":
        raise SystemExit("--targets applies to the cycles table: add --only cycles")
    tables = {}
    if args.only in (None, "cycles"):
        tables["cycles"] = cycles_table()
        if ONLY_TARGETS and args.update:
            tables["cycles"] = merge_rows(read_block(args.update, "bench_pil:cycles"),
                                          tables["cycles"])
    if args.only in (None, "precision"):
        tables["precision"] = precision_table()
    for name, table in tables.items():
        if args.update:
            write_block(args.update, f"bench_pil:{name}", table)
        else:
            print(table)


if __name__ == "__main__":
    main()
