"""The Cortex-M0+ (soft float) processor in the loop: ``esoarm pil --target cortex-m0plus``.

QEMU models no RP2040; its ``microbit`` machine is an nRF51822 whose Cortex-M0
runs the same ARMv6-M instructions, so the ``-mcpu=cortex-m0plus
-mfloat-abi=soft`` image runs there.  Marked ``hil`` and ``slow`` like the
other PIL tests: skipped with the reason where a tool is missing, required in
CI (``ESOARM_REQUIRE_HIL``).
"""

from __future__ import annotations

import re
import subprocess

from esoarm.scenario import load_scenario

from .chip_helpers import ARM_TOOLS, load_benchmark, on_chip, traced_steps
from .chip_helpers import pil as _pil

_on_chip = on_chip(*ARM_TOOLS)


@_on_chip
def test_test1_on_cortex_m0plus_at_1khz() -> None:
    """float32, soft float: agrees with the float64 reference over the moving part, fits."""
    data = _pil("test-1", "--target", "cortex-m0plus", "--set", "sensor.rate_hz=1000",
                "--steps", "3000")
    assert data["ok"] and data["covers_motion"] and data["steps"] == 3000
    assert data["target"] == "cortex-m0plus" and data["clock_hz"] == 16e6
    assert data["budget_cycles"] == 16000
    assert data["max_rel_du"] <= 1e-4
    # soft float costs: more than the Cortex-M4's ~200 hard-float instructions (docs table)
    assert 1000 < data["cycles"]["median"] < data["budget_cycles"]
    assert "microbit" in data["cycles_are"] and "instructions" in data["cycles_are"]
    assert 0 < data["flash_bytes"] < 256 * 1024 and 0 < data["ram_bytes"] < 16 * 1024


@_on_chip
def test_cortex_m0plus_float64_repeats_python() -> None:
    """libgcc's soft double is IEEE binary64: the same numbers as Python's float64."""
    data = _pil("test-1", "--target", "cortex-m0plus", "--precision", "float64", "--steps",
                "300", "--set", "observer.kind=nonlinear")
    assert data["max_abs_du"] <= 1e-12


@_on_chip
def test_image_is_armv6m_without_fpu() -> None:
    """The PIL image is built for the M0+ (ARMv6-M, soft float), not for the board's M0 or
    an FPU: the ELF's build attributes say so."""
    from esoarm.codegen.cortex_m0 import m0plus_image
    from esoarm.codegen.generate import generate
    from esoarm.codegen.toolchain import tool

    elf = m0plus_image(generate(load_scenario("uno-rig"), "cortex-m0plus", "float32"))
    attrs = subprocess.run([tool("arm-none-eabi-readelf"), "-A", str(elf)], capture_output=True,
                           text=True, check=True).stdout
    assert re.search(r"Tag_CPU_arch: v6S?-M", attrs), attrs
    assert "Tag_FP_arch" not in attrs and "VFP registers" not in attrs


@_on_chip
def test_instruction_proxy_does_not_depend_on_the_icount_shift() -> None:
    """ticks · 62.5 ns / 2^shift is an instruction count only if it is the same for every
    shift."""
    from esoarm.codegen.cortex_m0 import CortexM0PlusChip
    from esoarm.codegen.generate import generate
    from esoarm.codegen.lockstep import lockstep

    scn = load_scenario("test-1", {"duration": 0.3})
    gen = generate(scn, "cortex-m0plus", "float32")
    counts = []
    for shift in (8, 10):
        chip = CortexM0PlusChip(gen, icount_shift=shift)
        try:
            counts.append(lockstep(scn, chip).cycles)
        finally:
            chip.close()
    assert len(counts[0]) == scn.n_samples and counts[0] == counts[1]


@_on_chip
def test_instruction_proxy_matches_qemus_exec_trace(tmp_path) -> None:
    """The proxy ticks · 62.5 / 2^shift against an independent count: QEMU's own trace of
    every executed instruction (one instruction per translation block, ``-d exec,nochain``)
    from esoarm_step's entry to the return into the shell, soft-float calls included.  The
    proxy must exceed it by the same few instructions at every step, whatever the step's
    length: the argument marshalling between the first SysTick read and the call (with the
    soft-float ABI the reals go in core registers and the fifth on the stack), the call and
    the second read (measured 10, against 2 on the Cortex-M4)."""
    from esoarm.codegen.cortex_m0 import CLOCK_HZ, m0plus_image
    from esoarm.codegen.generate import generate

    scn = load_scenario("test-1", {"observer.kind": "nonlinear"})  # fal: steps of two lengths
    elf = m0plus_image(generate(scn, "cortex-m0plus", "float32"))
    proxy, traced = traced_steps(elf, "microbit", CLOCK_HZ, tmp_path / "exec.log")
    assert len(set(traced)) > 1  # steps of different lengths
    assert min(traced) > 500  # the soft-float calls are counted
    extra = {p - t for p, t in zip(proxy, traced, strict=True)}
    assert len(extra) == 1 and 0 < extra.pop() <= 12, (proxy, traced)


def test_bench_replaces_only_the_measured_targets_rows() -> None:
    """``bench_pil.py --targets cortex-m0plus --update``: the M0+ rows are replaced or added
    in the kinds × targets order, every other row is kept word for word."""
    bench = load_benchmark("bench_pil")
    head = "| kind | target | precision | observer sums | run |\n|---|---|---|---|---|"
    kind, other = bench.KINDS[0][0], bench.KINDS[1][0]
    old = "\n".join([
        "Measured on A.", "", head, f"| {kind} | avr | float32 | compensated | 7 |",
        f"| {kind} | cortex-m0plus | float32 | compensated | 1 |",
        f"| {kind} | cortex-m4 | float32 | compensated | 2 |",
        f"| {other} | cortex-m4 | float32 | compensated | 3 |"])
    new = "\n".join([
        "Measured on B.", "", head, f"| {kind} | cortex-m0plus | float32 | compensated | 10 |",
        f"| {other} | cortex-m0plus | float64 | plain | 11 |"])
    merged = bench.merge_rows(old, new)
    lines = merged.splitlines()
    assert lines[:3] == ["Measured on A.", "", "The cortex-m0plus rows: Measured on B."]
    assert lines[4:6] == head.splitlines()
    assert [r.rsplit("|", 2)[1].strip() for r in lines[6:]] == ["7", "10", "2", "11", "3"]
    assert bench.merge_rows(merged, new) == merged  # measuring again replaces its note
