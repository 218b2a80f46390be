"""On-board mode: the rig firmware runs the generated controller at 1 kHz on the simulated Uno.

``make -C firmware l298n ONBOARD=DIR SAMPLE_PERIOD_US=1000 BAUD=1000000`` with the
code of ``esoarm codegen uno-rig --target avr --set sensor.rate_hz=1000``, run in
simavr with the twin on its pins (:func:`esoarm.codegen.onboard.onboard_run`).
Marked ``hil`` and ``slow`` (skipped where the AVR toolchain is missing; required in CI).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from esoarm.scenario import load_scenario
from hardware.rig_helpers import served

from .chip_helpers import AVR_TOOLS, missing

MISSING = missing(*AVR_TOOLS)

pytestmark = [
    pytest.mark.slow,
    pytest.mark.hil,
    pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}"),
]


def test_uno_rig_at_1khz_on_board() -> None:
    """Every sample of the 20 s run streamed, no OVERRUN or other fault, tracking within
    10 % of `esoarm simulate` (measured: RMS 0.01412 rad on board, 0.01432 rad simulated).

    Plain observer sums: at ε = 0.09 s and 1 kHz float32 holds without compensation
    (max |Δu| 4.3e-6 N·m in PIL), and the compensated sums' extra ~1.9k cycles would not
    leave the firmware room for its frames at 1 kHz (measured: OVERRUN once the first move
    starts).
    """
    from esoarm.codegen.onboard import onboard_firmware, onboard_run
    from esoarm.engines.simulation import simulate
    from esoarm.reference import reference_rows

    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000})
    run = onboard_run(scn, onboard_firmware(scn, compensated=False))
    assert run.every_sample and len(run.k) >= 20000
    assert run.faults == []
    assert (run.t_us - 1000 * run.k).max() < 1000  # never a period late
    ref = reference_rows(scn.reference, run.k / 1000.0, 1)[0]
    rms_chip = float(np.sqrt(np.mean((run.theta - ref) ** 2)))
    rms_sim = simulate(scn).rms_error
    assert abs(rms_chip - rms_sim) <= 0.10 * rms_sim, (rms_chip, rms_sim)


def test_hil_onboard_with_the_python_host() -> None:
    """`esoarm hil uno-rig --onboard` driven by `esoarm run --onboard --log`: the chip's own
    controller tracks like simulate (measured +0.8 % RMS at 50 Hz), every sample is the chip's
    (u and the estimates from CHIP_SAMPLE frames), the log says so in its first line."""
    import json
    import subprocess
    import sys

    from esoarm.hardware.logfile import read_log_columns

    esoarm = [sys.executable, "-m", "esoarm"]
    log = Path(os.environ.get("TMPDIR", "/tmp")) / f"esoarm-onboard-{os.getpid()}.csv"
    try:
        with served("hil", "uno-rig", "--onboard", "--sums", "plain", "--once",
                    "--set", "duration=5") as (hil, device):
            run = subprocess.run([*esoarm, "run", "uno-rig", "--port", device, "--set",
                                  "duration=5", "--onboard", "--log", str(log), "--json",
                                  "--watchdog", "2"],
                                 capture_output=True, text=True, timeout=300)
            assert run.returncode == 0, run.stderr
            hil.wait(60)
            got = json.loads(run.stdout)
            assert log.read_text().startswith("# on board: logging the chip's samples")
            _, data = read_log_columns(log, ("k", "u", "z2"), "test")  # skips the comment line
            latency = np.genfromtxt(log, delimiter=",", names=True, skip_header=1)["latency"]
    finally:
        log.unlink(missing_ok=True)
    sim = json.loads(subprocess.run([*esoarm, "simulate", "uno-rig", "--set", "duration=5",
                                     "--json"], capture_output=True, text=True,
                                    timeout=300).stdout)
    assert got["onboard"] and got["stream_every"] == 1 and got["observer_sums"] == "plain"
    assert got["samples"] == 250 and got["lost_samples"] == 0 and got["stop_acknowledged"]
    assert np.array_equal(data[:, 0], np.arange(250))
    assert np.isnan(latency).all()  # the host answered nothing: no latency
    assert np.abs(data[:, 1]).max() > 0 and np.abs(data[:, 2]).max() > 0  # the chip's u, ẑ2
    assert abs(got["rms_error"] / sim["rms_error"] - 1) < 0.1, (got, sim)


def test_uno_rig_1khz_on_board_with_the_python_host() -> None:
    """The issue's check: `esoarm hil uno-rig --onboard` at 1 kHz (sums chosen by PIL: plain)
    driven by `esoarm run --onboard --log` over the pseudo-terminal: every one of the 20 000
    samples logged is the chip's, in order, none late, no fault, and the tracking is within
    10 % of `esoarm simulate` (measured: RMS 0.014422 rad against 0.014324 rad, +0.7 %)."""
    import json
    import subprocess
    import sys

    esoarm = [sys.executable, "-m", "esoarm"]
    rate = ["--set", "sensor.rate_hz=1000"]
    log = Path(os.environ.get("TMPDIR", "/tmp")) / f"esoarm-onboard-1k-{os.getpid()}.csv"
    try:
        with served("hil", "uno-rig", "--onboard", "--once", *rate) as (hil, device):
            assert hil.stdout is not None
            hil.stdout.readline()
            note = hil.stdout.readline()
            assert note.startswith("on board: uno-rig's controller, float32 plain observer sums, "
                                   "at 1000 Hz (auto: compensated: PIL median"), note
            run = subprocess.run([*esoarm, "run", "uno-rig", "--port", device, *rate, "--onboard",
                                  "--log", str(log), "--json", "--watchdog", "5"],
                                 capture_output=True, text=True, timeout=1800)
            if run.returncode != 0:
                hil.wait(60)
                raise AssertionError(f"{run.stderr}\nhil: {hil.stdout.read()}")
            assert "every sample (1000 Hz)" in run.stderr
            hil.wait(60)
            got = json.loads(run.stdout)
            rows = np.genfromtxt(log, delimiter=",", names=True, skip_header=1)
    finally:
        log.unlink(missing_ok=True)
    sim = json.loads(subprocess.run([*esoarm, "simulate", "uno-rig", *rate, "--json"],
                                    capture_output=True, text=True, timeout=600).stdout)
    assert got["samples"] == 20000 and got["lost_samples"] == 0 and got["lost_frames"] == 0
    assert got["stream_every"] == 1 and got["deadline_misses"] == 0 and got["stop_acknowledged"]
    assert np.array_equal(rows["k"], np.arange(20000))
    assert ((rows["t_device"] - 1e-3 * rows["k"]) < 1e-3).all()  # no sample a period late
    assert np.isfinite(rows["u"]).all() and np.isnan(rows["latency"]).all()
    assert abs(got["rms_error"] / sim["rms_error"] - 1) < 0.1, (got, sim)


def test_host_killed_the_chip_stops_the_motor() -> None:
    """The host quits without a word (SIGKILL) mid-run: the chip's watchdog turns the motor
    off within its 100 ms plus a sample period and reports FAULT(watchdog); the rows the
    host logged stay."""
    import signal
    import subprocess
    import sys
    import time

    esoarm = [sys.executable, "-m", "esoarm"]
    hil = subprocess.Popen([*esoarm, "hil", "uno-rig", "--onboard", "--sums", "plain", "--once"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    log = Path(os.environ.get("TMPDIR", "/tmp")) / f"esoarm-onboard-kill-{os.getpid()}.csv"
    try:
        assert hil.stdout is not None
        # (stderr is merged here: progress lines of the PIL timing may come first)
        first = next(ln for ln in iter(hil.stdout.readline, "") if ln.startswith("device:"))
        device = first.split(": ", 1)[1].strip()
        run = subprocess.Popen([*esoarm, "run", "uno-rig", "--port", device, "--onboard",
                                "--log", str(log), "--watchdog", "5"],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and (
                not log.exists() or len(log.read_text().splitlines()) < 102):
            time.sleep(0.2)
        run.send_signal(signal.SIGKILL)
        run.wait(10)
        rows = len(log.read_text().splitlines()) - 2  # the comment and the header
        out, _ = hil.communicate(timeout=120)
    finally:
        for p in (hil,):
            if p.poll() is None:
                p.terminate()
                p.wait(10)
        log.unlink(missing_ok=True)
    assert rows >= 100
    assert "device fault: watchdog" in out, out
    assert "motor off at" in out, out
    off = [ln for ln in out.splitlines() if ln.startswith("motor off at")][-1]
    ms = float(off.split("(")[1].split(" ms")[0])
    # the chip's 100 ms watchdog, checked at each 20 ms sample tick (AVR time): measured 119 ms
    assert 100 <= ms <= 100 + 20 + 2, off
