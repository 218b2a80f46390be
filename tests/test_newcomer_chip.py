"""What a newcomer trips on along the chip path (issues 32 and 34): each case failed before.

Fast tier unless marked: the CLI refuses or says what it does before anything is built.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ESOARM = [sys.executable, "-m", "esoarm"]
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="not installed: gcc")
HIL_MISSING = [t for t, ok in (("avr-gcc", shutil.which("avr-gcc")),
                               ("libsimavr-dev", Path("/usr/include/simavr/sim_avr.h").exists()),
                               ("arduino-mk", Path("/usr/share/arduino/Arduino.mk").exists()))
               if not ok]
needs_hil = pytest.mark.skipif(bool(HIL_MISSING), reason=f"not installed: {HIL_MISSING}")


def _esoarm(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*ESOARM, *args], capture_output=True, text=True, timeout=timeout)


def test_hil_sums_without_onboard_refused() -> None:
    res = _esoarm("hil", "uno-rig", "--sums", "plain")
    assert res.returncode == 2 and "--onboard" in res.stderr and "Traceback" not in res.stderr


def test_codegen_plain_sums_with_float64_refused(tmp_path: Path) -> None:
    res = _esoarm("codegen", "test-1", "--target", "host", "--precision", "float64",
                  "--plain-sums", "--out", str(tmp_path / "g"))
    assert res.returncode == 2 and "--plain-sums" in res.stderr
    assert not (tmp_path / "g").exists()


@needs_gcc
def test_codegen_unstable_observer_named_as_such(tmp_path: Path) -> None:
    res = _esoarm("codegen", "test-1", "--target", "host", "--set", "observer.eps=0.001",
                  "--out", str(tmp_path / "g"))
    assert res.returncode == 1, res.stderr
    assert "unstable" in res.stderr and "use --precision float64" not in res.stderr
    assert "kept" in res.stderr and (tmp_path / "g" / "esoarm_controller.c").exists()


@pytest.mark.parametrize("args", [["codegen", "two-link", "--target", "host", "--out", "x"],
                                  ["pil", "two-link", "--target", "avr"]])
def test_no_internal_names_for_a_kind_without_c(args: list[str], tmp_path: Path) -> None:
    args = [str(tmp_path / a) if a == "x" else a for a in args]
    res = _esoarm(*args)
    assert res.returncode == 2 and "C_SOURCE" not in res.stderr
    assert "lever-arm" in res.stderr  # what does run


def test_hil_elf_that_is_not_an_avr_elf(tmp_path: Path) -> None:
    text = tmp_path / "firmware.elf"
    text.write_text("not an elf\n")
    res = _esoarm("hil", "uno-rig", "--elf", str(text))
    assert res.returncode == 2 and "not an AVR ELF" in res.stderr
    host_elf = Path(sys.executable).resolve()  # an ELF, for the wrong machine
    if host_elf.read_bytes()[:4] == b"\x7fELF":
        res = _esoarm("hil", "uno-rig", "--elf", str(host_elf))
        assert res.returncode == 2 and "not an AVR ELF" in res.stderr


def test_pil_steps_beyond_the_run_refused() -> None:
    res = _esoarm("pil", "test-1", "--target", "avr", "--steps", "99999999")
    assert res.returncode == 2 and "samples" in res.stderr and "duration" in res.stderr


@needs_gcc
def test_codegen_says_what_its_check_does(tmp_path: Path) -> None:
    res = _esoarm("codegen", "test-1", "--target", "host", "--out", str(tmp_path / "g"))
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    wrote = next(i for i, ln in enumerate(lines) if "wrote" in ln)
    assert "checking float32" in lines[wrote + 1] and "--no-check" in lines[wrote + 1]


@needs_gcc
def test_ctrl_c_during_codegen_check_says_what_was_kept(tmp_path: Path) -> None:
    out = tmp_path / "g"
    proc = subprocess.Popen([*ESOARM, "codegen", "test-1", "--target", "host", "--set",
                             "duration=20000", "--out", str(out)], stderr=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, text=True)
    assert proc.stderr is not None
    seen = ""
    deadline = time.monotonic() + 120
    while "checking float32" not in seen and time.monotonic() < deadline:
        seen += proc.stderr.readline()
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    rest = proc.stderr.read()
    proc.wait(timeout=60)
    assert proc.returncode == 130, seen + rest
    assert "kept" in rest and str(out) in rest, rest
    assert (out / "esoarm_controller.h").exists()


def test_run_onboard_json_prints_the_fault(monkeypatch: pytest.MonkeyPatch) -> None:
    """A fault still gives one JSON object on stdout (with the fault), exit 1."""
    import json

    from click.testing import CliRunner

    import esoarm.hardware.link as link
    import esoarm.hardware.realtime as realtime
    from esoarm.cli import cli

    class FakeLink:
        def __init__(self, *a: object, **k: object) -> None:
            pass

        def close(self) -> None:
            pass

        def stop(self) -> None:
            pass

    def fault(*a: object, **k: object) -> None:
        raise realtime.RigFault("the device reported a fault: WATCHDOG at sample 12",
                                realtime.RunSummary(samples=12, onboard=True))

    monkeypatch.setattr(link, "SerialLink", FakeLink)
    monkeypatch.setattr(realtime, "run_rig", fault)
    res = CliRunner().invoke(cli, ["run", "uno-rig", "--port", "/dev/null", "--onboard",
                                   "--json"])
    assert res.exit_code == 1
    first = res.stdout.strip().splitlines()[0]
    got = json.loads(first)
    assert got["samples"] == 12 and "WATCHDOG" in got["fault"]


@pytest.mark.slow
@pytest.mark.hil
@needs_hil
def test_pil_at_rest_is_not_ok() -> None:
    """100 samples at 100 kHz end long before the first move: not 'ok'."""
    res = _esoarm("pil", "test-1", "--target", "avr", "--set", "sensor.rate_hz=100000",
                  "--set", "rig.step=1e-5", "--steps", "100", "--json", timeout=600)
    assert res.returncode == 1 and "at rest" in res.stderr, res.stderr
    import json

    assert json.loads(res.stdout)["covers_motion"] is False


@pytest.mark.slow
@pytest.mark.hil
@needs_hil
def test_onboard_at_100khz_refused_at_the_first_step_over_budget() -> None:
    """Was 528 s of silent PIL; now the first step over the 160-cycle period ends it."""
    start = time.monotonic()
    res = _esoarm("hil", "uno-rig", "--onboard", "--set", "sensor.rate_hz=100000", "--set",
                  "rig.step=1e-5", timeout=600)
    took = time.monotonic() - start
    assert res.returncode == 2 and "neither observer sum fits" in res.stderr, res.stderr
    assert "PIL stopped there" in res.stderr
    assert "timing the compensated observer sums" in res.stderr or took < 60


@pytest.mark.slow
@pytest.mark.hil
@needs_hil
def test_forced_sums_that_do_not_fit_are_warned() -> None:
    proc = subprocess.Popen([*ESOARM, "hil", "uno-rig", "--onboard", "--sums", "plain",
                             "--set", "sensor.rate_hz=2000", "--set", "rig.step=1e-4"],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 500
        line = ""
        while "device:" not in line and time.monotonic() < deadline and proc.poll() is None:
            line = proc.stdout.readline()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert "does not fit" in err and "OVERRUN" in err, err

