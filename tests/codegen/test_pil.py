"""Processor in the loop: the generated controller on simavr's ATmega328P and QEMU's Cortex-M4.

Marked ``hil`` and ``slow`` like the firmware tests: skipped with the reason
shown where a toolchain is missing, and required in CI (``ESOARM_REQUIRE_HIL``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from esoarm.scenario import load_scenario

from .chip_helpers import ARM_TOOLS, missing, traced_steps
from .chip_helpers import pil as _pil

MISSING = missing(("avr-gcc (gcc-avr)", shutil.which("avr-gcc")),
                  ("libsimavr-dev", Path("/usr/include/simavr/sim_avr.h").exists()),
                  ("gcc", shutil.which("gcc")), *ARM_TOOLS)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.hil,
    pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}"),
]


def test_uno_rig_on_avr() -> None:
    """The whole uno-rig run (motor, 50 Hz) on the ATmega328P: agrees and fits."""
    data = _pil("uno-rig", "--target", "avr")
    assert data["steps"] == 1000 and data["ok"]
    assert data["max_rel_du"] <= 1e-4
    assert 0 < data["cycles"]["min"] <= data["cycles"]["median"] <= data["cycles"]["max"]
    assert data["budget_cycles"] == 320_000 and data["cycles"]["max"] < data["budget_cycles"]
    assert data["flash_bytes"] > 1000 and 0 < data["ram_bytes"] < 2048


def test_nonlinear_eso_on_avr() -> None:
    data = _pil("uno-rig", "--target", "avr", "--set", "observer.kind=nonlinear")
    assert data["ok"] and data["max_rel_du"] <= 1e-4


def test_avr_cycles_are_deterministic() -> None:
    from esoarm.codegen.avr import AvrChip
    from esoarm.codegen.generate import generate
    from esoarm.codegen.lockstep import lockstep

    scn = load_scenario("uno-rig", {"duration": 2.0})
    runs = []
    for _ in range(2):
        chip = AvrChip(generate(scn, "avr", "float32"))
        runs.append(lockstep(scn, chip))
        chip.close()
    assert runs[0].cycles == runs[1].cycles
    assert (runs[0].u_chip == runs[1].u_chip).all()


def test_over_budget_exits_1() -> None:
    """At 10 kHz one sample is 1600 AVR cycles: the step does not fit."""
    data = _pil("uno-rig", "--target", "avr", "--set", "sensor.rate_hz=10000",
                "--set", "rig.step=0.0001", "--steps", "50", code=1)
    assert data["cycles"]["max"] > data["budget_cycles"] == 1600 and not data["ok"]


def test_test1_on_cortex_m4_at_1khz() -> None:
    data = _pil("test-1", "--target", "cortex-m4", "--set", "sensor.rate_hz=1000",
                "--steps", "4000")
    assert data["ok"] and data["max_rel_du"] <= 1e-4
    assert "instruction" in data["cycles_are"]
    assert data["budget_cycles"] == 25_000


def test_cortex_m4_float64_repeats_python() -> None:
    data = _pil("test-1", "--target", "cortex-m4", "--precision", "float64", "--steps", "300",
                "--set", "observer.kind=nonlinear")
    assert data["max_abs_du"] <= 1e-12


def test_instruction_proxy_does_not_depend_on_the_icount_shift() -> None:
    """ticks · 40 ns / 2^shift is an instruction count only if it is the same for every shift."""
    from esoarm.codegen.cortex_m4 import CortexM4Chip
    from esoarm.codegen.generate import generate
    from esoarm.codegen.lockstep import lockstep

    scn = load_scenario("test-1", {"duration": 1.0})
    gen = generate(scn, "cortex-m4", "float32")
    counts = []
    for shift in (8, 10):
        chip = CortexM4Chip(gen, icount_shift=shift)
        counts.append(lockstep(scn, chip).cycles)
        chip.close()
    assert counts[0] == counts[1]


def test_cascade_eso_on_avr_and_cortex_m4() -> None:
    """The cascade ESO (observer.kind = "cascade") on both chips: agrees and fits."""
    data = _pil("test-1", "--target", "avr", "--set", "observer.kind=cascade")
    assert data["ok"] and data["max_rel_du"] <= 1e-4 and data["steps"] == 1000
    m4 = _pil("test-1", "--target", "cortex-m4", "--set", "sensor.rate_hz=1000", "--set",
              "observer.kind=cascade", "--steps", "4000")
    assert m4["ok"] and m4["max_rel_du"] <= 1e-4
    exact = _pil("test-1", "--target", "cortex-m4", "--precision", "float64", "--steps", "300",
                 "--set", "observer.kind=cascade", "--set", "observer.levels=3")
    assert exact["max_abs_du"] == 0.0


def test_instruction_proxy_matches_qemus_exec_trace(tmp_path) -> None:
    """The proxy ticks · 40 / 2^shift against an independent count: QEMU's own trace of every
    executed instruction (``-singlestep -d exec,nochain``), from esoarm_step's entry to the
    return into the shell.  The proxy must exceed it by the same few instructions (the call
    and the second SysTick read: measured 2) at every step, whatever the step's length; the
    inverted conversion ticks · 2^shift / 40 would be 41 times too large at shift 8.
    (A tick is 40 ns, an instruction 2^8 ns: the unrounded proxy is within ±0.16.)"""
    from esoarm.codegen.cortex_m4 import CLOCK_HZ, m4_image
    from esoarm.codegen.generate import generate

    scn = load_scenario("test-1", {"observer.kind": "nonlinear"})  # fal: steps of two lengths
    elf = m4_image(generate(scn, "cortex-m4", "float32"))
    proxy, traced = traced_steps(elf, "mps2-an386", CLOCK_HZ, tmp_path / "exec.log")
    assert len(set(traced)) > 1  # steps of different lengths
    extra = {p - t for p, t in zip(proxy, traced, strict=True)}
    assert len(extra) == 1 and 0 < extra.pop() <= 4, (proxy, traced)
