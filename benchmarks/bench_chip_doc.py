"""The numbers docs/on-the-chip.md quotes, measured on the current code and written into it.

Run:  python benchmarks/bench_chip_doc.py [--doc docs/on-the-chip.md]

Between the markers ``<!-- chip-example:begin -->`` / ``<!-- chip-example:end -->``: the
console of ``esoarm codegen uno-rig --target avr --out build/ctl`` as it prints today
(scenario hash, check numbers).  Between ``<!-- chip-sizes:begin -->`` /
``<!-- chip-sizes:end -->``: flash and static RAM of the uno-rig on-board firmware at 1 kHz
(plain sums), of the host-controlled firmware, and of the Arduino library's example
(``esoarm codegen uno-rig --arduino-library``, built with arduino-mk), from avr-size.
Nothing is typed by hand: rerun after a change to the generator or the firmware.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _sizes(elf: Path) -> tuple[int, int]:
    """(flash, static RAM) [bytes]: .text + .data, .data + .bss (avr-size -A)."""
    out = subprocess.run(["avr-size", "-A", str(elf)], capture_output=True, text=True,
                         check=True).stdout
    sec = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\.\w+)\s+(\d+)", out, re.M)}
    return sec.get(".text", 0) + sec.get(".data", 0), sec.get(".data", 0) + sec.get(".bss", 0)


def _replace(doc: str, name: str, body: str) -> str:
    pattern = re.compile(rf"(<!-- {name}:begin -->\n).*?(<!-- {name}:end -->)", re.S)
    if not pattern.search(doc):
        raise SystemExit(f"docs: markers '{name}' not found")
    return pattern.sub(lambda m: m.group(1) + body + m.group(2), doc)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "on-the-chip.md")
    args = ap.parse_args()
    from esoarm.codegen.onboard import onboard_firmware
    from esoarm.hardware.hil.build import firmware_elf
    from esoarm.scenario import load_scenario

    with tempfile.TemporaryDirectory() as tmp:
        res = subprocess.run([sys.executable, "-m", "esoarm", "codegen", "uno-rig", "--target",
                              "avr", "--out", "build/ctl"], capture_output=True,
                             text=True, cwd=tmp, check=True)
        lines = [ln for ln in res.stderr.splitlines() if ln.startswith("esoarm:")]
        console = "```console\n$ esoarm codegen uno-rig --target avr --out build/ctl\n"
        console += "\n".join(lines) + "\n```\n"
        lib = Path(tmp) / "EsoarmUnoRig"
        subprocess.run([sys.executable, "-m", "esoarm", "codegen", "uno-rig",
                        "--arduino-library", str(lib), "--no-check"], capture_output=True,
                       check=True)
        subprocess.run(["make", "-s"], cwd=lib / "examples" / "OnBoard", capture_output=True,
                       check=True)
        example = _sizes(lib / "examples" / "OnBoard" / "build-uno" / "OnBoard.elf")
    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000})
    onboard = _sizes(onboard_firmware(scn, compensated=False))
    host = _sizes(firmware_elf("l298n"))
    sizes = (f"The uno-rig on-board build (1 kHz, plain sums) takes {onboard[0]:,} bytes of "
             f"flash and {onboard[1]:,} bytes of static RAM (the host-controlled firmware: "
             f"{host[0]:,} and {host[1]:,}; the Arduino library's example at the scenario's "
             f"50 Hz, built by arduino-mk with LTO: {example[0]:,} and {example[1]:,}), of the "
             "ATmega328P's 32,256 bytes of flash (the bootloader has the rest) and 2,048 of "
             "RAM. Measured by `python benchmarks/bench_chip_doc.py`, which writes these "
             "numbers here.\n")
    doc = args.doc.read_text(encoding="utf-8")
    doc = _replace(doc, "chip-example", console)
    doc = _replace(doc, "chip-sizes", sizes)
    args.doc.write_text(doc, encoding="utf-8")
    print(console + sizes)


if __name__ == "__main__":
    main()
