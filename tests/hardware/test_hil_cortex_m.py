"""On board on a Cortex-M4: ``esoarm hil SCENARIO --onboard --target cortex-m4`` (QEMU's
mps2-an386, the twin in lockstep on the chip's pin link) driven by ``esoarm run --onboard``.

The end-to-end runs are marked ``hil`` and ``slow`` (skipped where arm-none-eabi-gcc or
qemu-system-arm is missing); the refusals of bad input run in the fast tier.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from codegen.chip_helpers import ARM_TOOLS, on_chip
from esoarm.cli import cli

ESOARM = [sys.executable, "-m", "esoarm"]
RATE = ["--set", "sensor.rate_hz=1000", "--set", "duration=5"]


needs_qemu = on_chip(*ARM_TOOLS)  # slow, hil: the ARM toolchain and QEMU


@pytest.mark.parametrize("args, words", [
    ([], "add --onboard"),
    (["--onboard", "--fault", "unplug@1"], "--fault is for --target avr"),
    (["--onboard", "--realtime"], "--realtime is for --target avr"),
])
def test_bad_input_is_refused(args: list[str], words: str) -> None:
    res = CliRunner().invoke(cli, ["hil", "test-1", "--target", "cortex-m4", *args])
    assert res.exit_code == 2, res.output
    assert words in res.output


def _start_hil(scenario: str, extra: list[str]) -> tuple[subprocess.Popen[str], str]:
    hil = subprocess.Popen([*ESOARM, "hil", scenario, "--onboard", "--target", "cortex-m4",
                            "--once", *extra], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True)
    assert hil.stdout is not None
    while True:
        line = hil.stdout.readline()
        assert line, "hil ended before printing its device"
        if line.startswith("device: "):
            return hil, line.split(": ", 1)[1].strip()


def _stop(hil: subprocess.Popen[str]) -> None:
    if hil.poll() is None:
        hil.terminate()
        hil.wait(10)


@needs_qemu
def test_test1_1khz_on_the_cortex_m4(tmp_path: Path) -> None:
    """The issue's check: every one of the 5000 samples logged is the chip's, in order, no
    fault, and the RMS tracking error is within 10 % of `esoarm simulate` (measured:
    0.019197 rad against 0.018810 rad, +2.1 %: the run's error is on the measured angle, with
    the encoder noise of 0.2°, simulate's on the true one).  The chip's u is the simulator's
    to float32: RMS u agrees to 1e-4 relative."""
    log = tmp_path / "run.csv"
    hil, device = _start_hil("test-1", RATE)
    try:
        run = subprocess.run([*ESOARM, "run", "test-1", "--port", device, *RATE, "--onboard",
                              "--log", str(log), "--json", "--watchdog", "5"],
                             capture_output=True, text=True, timeout=600)
        out, _ = hil.communicate(timeout=60)
    finally:
        _stop(hil)
    assert run.returncode == 0, run.stderr
    assert "every sample (1000 Hz)" in run.stderr
    got = json.loads(run.stdout)
    sim = json.loads(subprocess.run([*ESOARM, "simulate", "test-1", *RATE, "--json"],
                                    capture_output=True, text=True, timeout=300).stdout)
    rows = np.genfromtxt(log, delimiter=",", names=True, skip_header=1)
    assert got["samples"] == 5000 and got["lost_samples"] == 0 and got["lost_frames"] == 0
    assert got["bad_frames"] == 0 and got["stop_acknowledged"]
    assert np.array_equal(rows["k"], np.arange(5000))
    assert np.allclose(rows["t_device"], 1e-3 * rows["k"])  # the chip's clock: the sample tick
    assert np.isnan(rows["duty"]).all()  # an ideal torque source (test-1 has no [motor])
    assert abs(got["rms_error"] / sim["rms_error"] - 1) < 0.1, (got, sim)
    assert abs(got["rms_u"] / sim["rms_u"] - 1) < 1e-4, (got, sim)
    served = int(out.split("twin: ")[1].split(" samples")[0])
    assert 5000 <= served <= 5010, out  # the chip steps on until STOP reaches it


@needs_qemu
def test_another_scenario_is_refused_before_start(tmp_path: Path) -> None:
    """The chip's CHIP_INFO hash names its scenario: other --set values exit 2 before START."""
    hil, device = _start_hil("test-1", RATE)
    try:
        run = subprocess.run([*ESOARM, "run", "test-1", "--port", device, *RATE,
                              "--set", "observer.eps=0.05", "--onboard"],
                             capture_output=True, text=True, timeout=120)
    finally:
        _stop(hil)
    assert run.returncode == 2, run.stderr
    assert "generated from another scenario" in run.stderr


@needs_qemu
def test_host_killed_the_chip_stops_the_motor(tmp_path: Path) -> None:
    """The host quits without a word (SIGKILL): the chip's watchdog (100 samples at 1 kHz)
    turns the motor off and reports FAULT(watchdog); the rows the host logged stay."""
    log = tmp_path / "run.csv"
    hil, device = _start_hil("uno-rig", ["--set", "sensor.rate_hz=1000"])
    try:
        run = subprocess.Popen([*ESOARM, "run", "uno-rig", "--port", device, "--onboard",
                                "--set", "sensor.rate_hz=1000", "--log", str(log),
                                "--watchdog", "5"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and (
                not log.exists() or len(log.read_text().splitlines()) < 502):
            time.sleep(0.1)
        run.send_signal(signal.SIGKILL)
        run.wait(10)
        rows = len(log.read_text().splitlines()) - 2
        out, _ = hil.communicate(timeout=60)
    finally:
        _stop(hil)
    assert rows >= 500
    assert "device fault: watchdog" in out, out
    off = [ln for ln in out.splitlines() if ln.startswith("motor off at")][-1]
    ms = float(off.split("(")[1].split(" ms")[0])
    # the chip's watchdog: more than 100 samples (1 ms each) after the last heartbeat reached
    # it (the twin's count when it passed the frame on may be one sample off the chip's)
    assert 100 <= ms <= 103, off
