"""``esoarm flash``: end to end on a simulated Uno (simavr running the Uno's bootloader
behind a pseudo-terminal), and the refusal of a port that is not one.

Covered here: the firmware build, avrdude's probe, write and verify over the bootloader's
STK500 protocol (the flash written by the bootloader's own SPM code), the application's
start and the scenario hash read back, a second write over the first.  Not covered (no
board): the USB-serial chip and its DTR auto-reset (emulated), real flash timing and wear,
fuses, a bootloader other than Debian's optiboot.
"""

from __future__ import annotations

import json
import os
import pty
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from codegen.chip_helpers import AVR_TOOLS, missing

ESOARM = [sys.executable, "-m", "esoarm"]
MISSING = missing(*AVR_TOOLS, ("avrdude", shutil.which("avrdude")),
    ("arduino-core-avr", Path("/usr/share/arduino/hardware/arduino/avr/bootloaders").is_dir()))
needs_tools = pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}")


def _flash(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*ESOARM, "flash", *args], capture_output=True, text=True,
                          timeout=900)


def test_missing_port_refused() -> None:
    res = _flash("uno-rig", "--port", "/dev/esoarm-no-such-port")
    assert res.returncode == 2 and "no such device" in res.stderr


def test_scenario_without_motor_refused() -> None:
    res = _flash("test-1", "--port", "/dev/null")
    assert res.returncode == 2 and "[motor]" in res.stderr


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("avrdude") is None, reason="not installed: avrdude")
def test_a_port_that_does_not_answer_is_refused_before_anything_is_built() -> None:
    master, slave = pty.openpty()
    try:
        res = _flash("uno-rig", "--port", os.ttyname(slave))
    finally:
        os.close(master)
        os.close(slave)
    assert res.returncode == 2, res.stderr
    assert "does not answer as an Uno bootloader" in res.stderr
    assert "firmware:" not in res.stderr  # nothing built, nothing written


@pytest.mark.slow
@pytest.mark.hil
@needs_tools
def test_flash_a_simulated_uno_and_read_the_hash_back() -> None:
    from esoarm.codegen.generate import scenario_hash
    from esoarm.hardware.flash import SimulatedUno, read_hash
    from esoarm.scenario import load_scenario

    with SimulatedUno() as uno:
        res = _flash("uno-rig", "--port", uno.port, "--json")
        assert res.returncode == 0, res.stderr
        got = json.loads(res.stdout)
        want = scenario_hash(load_scenario("uno-rig"))
        assert got["ok"] and got["hash_read"] == want[:8] and got["signature"] == "0x1e950f"
        assert got["flash_bytes"] > 4000
        # a second design over the first: the bootloader is entered again, the hash changes
        res = _flash("uno-rig", "--port", uno.port, "--set", "observer.eps=0.05", "--json")
        assert res.returncode == 0, res.stderr
        other = scenario_hash(load_scenario("uno-rig", {"observer.eps": 0.05}))
        assert json.loads(res.stdout)["hash_read"] == other[:8] != want[:8]
        assert read_hash(uno.port, 1_000_000) == other[:8]
