"""``esoarm codegen SCENARIO --arduino-library DIR``: the layout, and the example built with
arduino-mk and run in simavr against the twin (the check of ``hil --onboard``)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from esoarm.scenario import load_scenario

from .chip_helpers import AVR_TOOLS, missing

MISSING = missing(*AVR_TOOLS, ("make", shutil.which("make")),
    ("arduino-core-avr", Path("/usr/share/arduino/hardware/arduino/avr/cores").is_dir()))


def _codegen(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "esoarm", "codegen", *args],
                          capture_output=True, text=True, timeout=600)


def test_library_layout(tmp_path: Path) -> None:
    lib = tmp_path / "EsoarmUno"
    res = _codegen("uno-rig", "--arduino-library", str(lib), "--no-check")
    assert res.returncode == 0, res.stderr
    files = sorted(str(p.relative_to(lib)) for p in lib.rglob("*") if p.is_file())
    assert files == ["examples/OnBoard/Makefile", "examples/OnBoard/OnBoard.ino",
                     "examples/OnBoard/esoarm_protocol.h", "library.properties",
                     "src/esoarm_controller.c", "src/esoarm_controller.h",
                     "src/esoarm_reference.c", "src/esoarm_reference.h"]
    props = dict(line.split("=", 1) for line in
                 (lib / "library.properties").read_text().splitlines() if "=" in line)
    assert props["name"] == "esoarm-uno-rig" and props["architectures"] == "avr"
    assert props["includes"] == "esoarm_controller.h"
    sketch = (lib / "examples/OnBoard/OnBoard.ino").read_text()
    assert "#include <esoarm_controller.h>" in sketch and '.c"' not in sketch
    assert "#define SAMPLE_PERIOD_US 20000UL" in sketch and "#define ENCODER_PPR 600UL" in sketch
    for piece in ("ISR(TIMER2_COMPA_vect)", "esoarm_reference_next", "ESO_HEARTBEAT",
                  "motor_write"):
        assert piece in sketch, piece
    make = (lib / "examples/OnBoard/Makefile").read_text()
    assert "ARDUINO_LIBS = EsoarmUno" in make and "Arduino.mk" in make


def test_library_refusals(tmp_path: Path) -> None:
    res = _codegen("test-1", "--arduino-library", str(tmp_path / "a"))
    assert res.returncode == 2 and "[motor]" in res.stderr
    assert not (tmp_path / "a" / "src").exists()
    res = _codegen("uno-rig", "--arduino-library", str(tmp_path / "b"), "--target", "host")
    assert res.returncode == 2 and "--target avr" in res.stderr
    res = _codegen("uno-rig", "--arduino-library", str(tmp_path / "c"), "--out",
                   str(tmp_path / "d"))
    assert res.returncode == 2


@pytest.mark.slow
@pytest.mark.hil
@pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}")
def test_example_builds_with_arduino_mk_and_tracks_in_simavr(tmp_path: Path) -> None:
    """`make` in the example folder builds OnBoard.hex; the ELF runs in simavr with the twin
    on its pins and a scripted `run --onboard` host: every sample streamed, no fault, RMS
    tracking error within 10 % of `esoarm simulate` (as tests/codegen/test_onboard.py)."""
    from esoarm.codegen.onboard import onboard_run
    from esoarm.engines.simulation import simulate
    from esoarm.reference import reference_rows

    lib = tmp_path / "lib"
    res = _codegen("uno-rig", "--arduino-library", str(lib), "--no-check")
    assert res.returncode == 0, res.stderr
    ex = lib / "examples" / "OnBoard"
    res = subprocess.run(["make", "-s"], cwd=ex, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (ex / "build-uno" / "OnBoard.hex").stat().st_size > 1000
    scn = load_scenario("uno-rig")
    run = onboard_run(scn, ex / "build-uno" / "OnBoard.elf")
    assert run.every_sample and run.faults == []
    rate = scn.sensor.rate_hz
    ref = reference_rows(scn.reference, run.k / rate, 1)[0]
    rms_chip = float(np.sqrt(np.mean((run.theta - ref) ** 2)))
    rms_sim = simulate(scn).rms_error
    assert abs(rms_chip - rms_sim) <= 0.10 * rms_sim, (rms_chip, rms_sim)
