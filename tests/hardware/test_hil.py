"""The firmware built for the ATmega328P and run cycle-accurately in simavr.

``make -C firmware`` builds the Uno binary with the Debian AVR toolchain;
``esoarm hil`` runs it on simavr with the twin on its pins.  These tests drive
it with the unchanged host (``esoarm run``) and check the closed loop against
``esoarm simulate`` and the emulator.  Marked ``hil`` (skipped with the reason
shown where the toolchain is not installed; CI installs it).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from codegen.chip_helpers import AVR_TOOLS, missing

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware"
MISSING = missing(*AVR_TOOLS)  # raises in CI (ESOARM_REQUIRE_HIL): the firmware tests must run

pytestmark = [
    pytest.mark.slow,  # end to end: the firmware built and run in simavr
    pytest.mark.hil,
    pytest.mark.skipif(bool(MISSING), reason=f"not installed: {', '.join(MISSING)}"),
]

ESOARM = [sys.executable, "-m", "esoarm"]


@pytest.fixture(scope="module")
def elf() -> Path:
    from esoarm.hardware.hil.build import firmware_elf

    return firmware_elf("l298n", FIRMWARE)


def _json(args: list[str], **kw) -> dict:
    res = subprocess.run([*ESOARM, *args], capture_output=True, text=True, timeout=300, **kw)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout)


class Hil:
    """``esoarm hil`` in a subprocess; ``device`` is its pseudo-terminal."""

    def __init__(self, args: list[str]) -> None:
        self.proc = subprocess.Popen([*ESOARM, "hil", *args], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        first = self.proc.stdout.readline()
        assert first.startswith("device: "), first + self.proc.stderr.read()  # type: ignore[union-attr]
        self.device = first.split(": ", 1)[1].strip()
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def finish(self, timeout: float = 30.0) -> int:
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.terminate()
            rc = self.proc.wait(10)
        self._reader.join(5)
        return rc


def test_build_both_drivers_prints_sizes(tmp_path):
    res = subprocess.run(["make", "-C", str(FIRMWARE), f"BUILD={tmp_path}"],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    sizes = [ln for ln in res.stdout.splitlines() if ": flash " in ln]
    assert len(sizes) == 2, res.stdout
    for line, driver in zip(sizes, ("l298n", "bts7960"), strict=True):
        assert f"uno-{driver}/esoarm_rig.elf" in line
        flash = int(line.split("flash ")[1].split()[0])
        ram = int(line.split("RAM ")[1].split()[0])
        assert 1000 < flash < 32256 and 100 < ram < 2048, line
    assert (tmp_path / "uno-l298n" / "esoarm_rig.hex").exists()
    assert (tmp_path / "uno-bts7960" / "esoarm_rig.hex").exists()


def test_build_names_the_missing_package(tmp_path):
    # a PATH with make but no avr-gcc: the build stops with one line naming the package
    (tmp_path / "bin").mkdir()
    os.symlink(shutil.which("make"), tmp_path / "bin" / "make")
    res = subprocess.run([str(tmp_path / "bin" / "make"), "-C", str(FIRMWARE)],
                         capture_output=True, text=True, env={"PATH": str(tmp_path / "bin")})
    assert res.returncode != 0
    assert "apt-get install gcc-avr" in res.stderr


def test_sketch_warnings_are_errors(tmp_path):
    sketch = tmp_path / "esoarm_rig"
    shutil.copytree(FIRMWARE / "esoarm_rig", sketch)
    shutil.copy(FIRMWARE / "Makefile", tmp_path / "Makefile")
    shutil.copy(FIRMWARE / "sketch.mk", tmp_path / "sketch.mk")
    ino = sketch / "esoarm_rig.ino"
    ino.write_text(ino.read_text() + "\nstatic int esoarm_unused_for_test;\n")
    res = subprocess.run(["make", "-C", str(tmp_path), "l298n"], capture_output=True, text=True,
                         timeout=600)
    assert res.returncode != 0
    assert "esoarm_unused_for_test" in res.stderr and "error" in res.stderr


def test_run_against_hil_tracks_like_simulate(elf, tmp_path):
    """10 s of simulated time: esoarm run on the unchanged host against the Uno binary."""
    hil = Hil(["uno-rig", "--once", "--elf", str(elf)])
    log = tmp_path / "run.csv"
    # --watchdog 2: a loaded test machine can starve the simulator for a few hundred ms
    run = _json(["run", "uno-rig", "--port", hil.device, "--set", "duration=10",
                 "--json", "--log", str(log), "--watchdog", "2"])
    assert hil.finish() == 0, hil.lines
    sim = _json(["simulate", "uno-rig", "--set", "duration=10", "--json"])
    assert run["samples"] == 500 and run["lost_samples"] == 0
    assert run["bad_frames"] == 0 and run["lost_frames"] == 0
    assert run["stop_acknowledged"]
    # the timing inside a sample (the count latched by the firmware's clock, the duty
    # reaching the pins milliseconds after the tick) is what simulate does not have;
    # measured: +0.1 % (docs/hardware.md)
    assert abs(run["rms_error"] / sim["rms_error"] - 1) < 0.2, (run, sim)
    assert any(line.startswith("motor off at t = ") for line in hil.lines), hil.lines
    isr = [ln for ln in hil.lines if ln.startswith("encoder interrupts:")]
    assert isr and int(isr[0].split()[2].rstrip(",")) > 100


def _run_cli(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([*ESOARM, *args], capture_output=True, text=True, timeout=300)


def _motor_off_delays(lines: list[str]) -> list[float]:
    """Milliseconds from the host's last byte to each 'motor off' the harness saw."""
    return [float(ln.split("(")[1].split(" ms")[0]) for ln in lines
            if ln.startswith("motor off at t = ")]


# fault -> (what ends the run on the host, the host's --watchdog [s])
FAULTS = {
    "driver@1.5": ("following error", "2"),
    "encoder-break@1.5": ("following error", "2"),
    "encoder-noise@0.5": ("device reported a fault: encoder", "2"),
    "brownout@1.5": ("watchdog: no sample from the device", "0.5"),
    "unplug@1.5": ("went away", "2"),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_fault_ends_safe_on_both_sides(elf, tmp_path, fault):
    cause, watchdog = FAULTS[fault]
    hil = Hil(["uno-rig", "--once", "--elf", str(elf), "--fault", fault])
    log = tmp_path / "run.csv"
    res = _run_cli(["run", "uno-rig", "--port", hil.device, "--set", "duration=4",
                    "--log", str(log), "--watchdog", watchdog])
    assert hil.finish() == 0, hil.lines
    # host: exit 1, one line naming the cause, every row kept
    assert res.returncode == 1, res.stderr
    # (a 4 s run warns that the scenario's second move, at 10 s, is never reached)
    lines = [ln for ln in res.stderr.strip().splitlines()
             if not ln.startswith("esoarm: warning:")]
    assert len(lines) == 1 and cause in lines[0], res.stderr
    rows = len(log.read_text().splitlines()) - 1
    at = float(fault.split("@")[1])
    assert f"{rows} rows in" in lines[0]
    assert at * 50 - 2 <= rows < 200
    # device: the motor pins go off, at the latest one watchdog (100 ms) after the host
    # stopped talking (the check runs every 1 ms step; the last frame takes ~1 ms to arrive)
    assert f"fault injected: {fault.split('@')[0]} at t = {at:g} s" in hil.lines
    delays = _motor_off_delays(hil.lines)
    assert delays and delays[-1] <= 105, hil.lines
    if fault.startswith("unplug"):
        assert delays[-1] >= 100  # nobody left to send STOP: the firmware's watchdog did it
        assert any(ln.startswith("device fault: watchdog") for ln in hil.lines)
    if fault.startswith("encoder-noise"):  # the firmware caught it before the count drifted
        assert "encoder: device count − arm position at the last sample: +0 counts" in \
            "\n".join(hil.lines)


def test_hil_bad_input(elf, tmp_path):
    res = _run_cli(["hil", "test-1", "--elf", str(elf)])
    assert res.returncode == 2 and "[motor] table" in res.stderr
    res = _run_cli(["hil", "two-link", "--elf", str(elf)])  # an arm: the plant is the reason
    assert res.returncode == 2 and "'hil' works on the lever-arm rig" in res.stderr
    res = _run_cli(["hil", "uno-rig", "--elf", str(tmp_path / "missing.elf")])
    assert res.returncode == 2 and "missing.elf" in res.stderr
    res = _run_cli(["hil", "uno-rig", "--elf", str(elf), "--fault", "meteor@1"])
    assert res.returncode == 2 and "encoder-break" in res.stderr


def test_realtime_and_bts7960(tmp_path):
    """The BTS7960 build, paced to the wall clock: a short run completes cleanly."""
    from esoarm.hardware.hil.build import firmware_elf

    bts = firmware_elf("bts7960", FIRMWARE)
    hil = Hil(["uno-rig", "--once", "--realtime", "--elf", str(bts)])
    run = _json(["run", "uno-rig", "--port", hil.device, "--set", "duration=1.5", "--json",
                 "--watchdog", "2"])
    assert hil.finish() == 0, hil.lines
    assert run["samples"] == 75 and run["lost_samples"] == 0 and run["bad_frames"] == 0
    assert run["mode"] == "real time" and run["stop_acknowledged"]
    assert run["rms_error"] < 0.05


def test_realtime_slip_is_counted_not_repaid(elf):
    """Behind the wall clock, the real-time pacing carries on from now (no burst of frames)."""
    import time

    from esoarm.hardware.hil.server import F_CPU, HilServer
    from esoarm.scenario import load_scenario

    server = HilServer(load_scenario("uno-rig"), elf, realtime=True, echo=lambda _: None)
    try:
        server._wall0, server._cycle0 = time.perf_counter() - 0.5, 0  # 0.5 s behind
        t0 = time.perf_counter()
        server._pace(F_CPU // 1000)  # 1 ms of AVR time: due 0.499 s ago
        assert server.slips == 1 and server.worst_slip == pytest.approx(0.499, abs=0.05)
        server._pace(F_CPU // 1000 + F_CPU // 100)  # 10 ms after the new anchor: waits for it
        elapsed = time.perf_counter() - t0
        assert server.slips == 1 and 0.009 < elapsed < 0.2
    finally:
        server.close()


def test_host_paced_lag_behind_the_wall_clock_is_counted(elf):
    """Host-paced: samples sent later than the AVR's time says are counted, running ahead is not."""
    import time

    from esoarm.hardware import protocol as P
    from esoarm.hardware.hil.server import F_CPU, FrameRecord, HilServer
    from esoarm.scenario import load_scenario

    server = HilServer(load_scenario("uno-rig"), elf, echo=lambda _: None)
    try:
        ts = round(0.02 * F_CPU)  # cycles per sample at 50 Hz
        # the AVR 3x faster than the wall clock: always ahead, never behind
        for k in range(50):
            server._track_lag(100.0 + k * 0.02 / 3, k * ts)
        assert server.lags == 0 and server.samples_tracked == 50
        # then 2x slower: sample j is j * 20 ms behind the most-ahead one
        base = 100.0 + 49 * 0.02 / 3
        for j in range(1, 11):
            server._track_lag(base + j * 0.04, (49 + j) * ts)
        assert server.lags == 10 and server.worst_lag == pytest.approx(0.2, abs=1e-9)

        # wired to the SAMPLE frames of a run (and not outside one)
        def sample(k: int, cycle: int) -> None:
            payload = P.encode(P.SAMPLE, 0, k, cycle // 16, 0)[5:-2]
            server._on_device_frame(FrameRecord(P.Frame(P.SAMPLE, 0, payload), cycle, cycle))

        server.lags, server.samples_tracked, server.worst_lag = 0, 0, 0.0
        sample(0, 0)
        assert server.samples_tracked == 0  # no run in progress
        server.run_active, server._drift_min = True, float("inf")  # as START does
        sample(0, 0)
        time.sleep(0.03)
        sample(1, F_CPU // 1000)  # 1 ms of AVR time after at least 30 ms of wall time
        assert server.samples_tracked == 2 and server.lags == 1 and server.worst_lag > 0.028
    finally:
        server.close()
