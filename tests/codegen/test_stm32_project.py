"""``esoarm codegen SCENARIO --project stm32 --out DIR``: the STM32F401 Makefile project.

The build test runs ``make`` in the written project with arm-none-eabi-gcc (``-Wall -Wextra
-Werror``) and checks the image (vector table at the flash's start, the handlers the
project uses); it is skipped with the reason where the toolchain is missing.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

from esoarm.cli import cli

MISSING = [t for t in ("arm-none-eabi-gcc", "make", "arm-none-eabi-nm") if not shutil.which(t)]


def test_project_files_and_settings(tmp_path: Path) -> None:
    res = CliRunner().invoke(cli, ["codegen", "uno-rig", "--project", "stm32", "--out",
                                   str(tmp_path / "p"), "--set", "sensor.rate_hz=1000"])
    assert res.exit_code == 0, res.output
    names = sorted(str(p.relative_to(tmp_path / "p")) for p in (tmp_path / "p").rglob("*")
                   if p.is_file())
    assert names == ["Makefile", "README.md", "src/esoarm_board.h", "src/esoarm_controller.c",
                     "src/esoarm_controller.h", "src/esoarm_protocol.h",
                     "src/esoarm_reference.c", "src/esoarm_reference.h", "src/main.c",
                     "src/startup_stm32f401.c", "stm32f401re.ld"]
    board = (tmp_path / "p" / "src" / "esoarm_board.h").read_text()
    assert "#define SAMPLE_PERIOD_US 1000UL" in board
    assert "#define COUNTS_PER_REV 2400UL" in board  # 0.15° = 600 pulses/rev decoded x4
    assert "ESO_SUMS_COMPENSATED" in board
    header = (tmp_path / "p" / "src" / "esoarm_controller.h").read_text()
    assert "target: cortex-m4   precision: float32" in header


@pytest.mark.parametrize("args, words", [
    (["test-1"], "needs a [motor] table"),  # the project drives a PWM duty
    (["uno-rig", "--target", "avr"], "drop --target avr"),
    (["uno-rig", "--precision", "float64"], "float32"),
    (["uno-rig", "--set", "sensor.rate_hz=10"], "whole number of µs from 10 to 65536"),
])
def test_bad_input_is_refused(tmp_path: Path, args: list[str], words: str) -> None:
    res = CliRunner().invoke(cli, ["codegen", *args, "--project", "stm32", "--out",
                                   str(tmp_path / "p")])
    assert res.exit_code == 2, res.output
    assert words in res.output
    assert not (tmp_path / "p" / "Makefile").exists()


def test_target_still_required_without_project(tmp_path: Path) -> None:
    res = CliRunner().invoke(cli, ["codegen", "uno-rig", "--out", str(tmp_path / "c")])
    assert res.exit_code == 2 and "--target is required" in res.output


@pytest.mark.slow
@pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}")
def test_project_builds_with_make(tmp_path: Path) -> None:
    out = tmp_path / "p"
    res = CliRunner().invoke(cli, ["codegen", "uno-rig", "--project", "stm32", "--out",
                                   str(out), "--set", "sensor.rate_hz=1000"])
    assert res.exit_code == 0, res.output
    run = subprocess.run(["make", "-C", str(out)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    elf = out / "build" / "esoarm_stm32.elf"
    assert (out / "build" / "esoarm_stm32.bin").stat().st_size > 1000
    assert "warning" not in run.stderr.lower()
    nm = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True,
                        check=True).stdout
    symbols = {line.split()[-1]: int(line.split()[0], 16) for line in nm.splitlines()
               if len(line.split()) == 3}
    assert symbols["vectors"] == 0x08000000  # the vector table at the start of the flash
    for name in ("reset_handler", "TIM4_IRQHandler", "USART2_IRQHandler", "esoarm_step"):
        assert 0x08000000 < symbols[name] < 0x08080000, name
    vectors = (out / "build" / "esoarm_stm32.bin").read_bytes()[:4 * (16 + 85)]
    word = [int.from_bytes(vectors[4 * i:4 * i + 4], "little") for i in range(16 + 85)]
    assert word[0] == 0x20018000  # the stack at the end of the 96 KiB SRAM
    assert word[1] == symbols["reset_handler"] | 1  # Thumb
    assert word[16 + 30] == symbols["TIM4_IRQHandler"] | 1
    assert word[16 + 38] == symbols["USART2_IRQHandler"] | 1
