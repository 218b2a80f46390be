"""The on-board build's stream from the CLI, and the learned table on board (issue 33).

``esoarm hil --onboard`` and ``esoarm codegen --arduino-library`` take ``--stream-every N``,
``--baud BITS/S`` and ``--stream-polled``: the decimated stream that leaves the Uno 35 % of
its 1 kHz period free at p99 (``benchmarks/bench_onboard.py``, docs/on-the-chip.md).  The
learned feedforward table (``controller.feedforward_map``) is generated into flash on the AVR
(``PROGMEM``), not RAM, and runs on board like ``esoarm simulate``.

The fast tests check the options and the generated C; the ``slow``/``hil`` ones build the
firmware and run it in simavr with the twin on its pins.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from esoarm.scenario import load_scenario
from hardware.rig_helpers import served

from .chip_helpers import AVR_TOOLS, on_chip

ESOARM = [sys.executable, "-m", "esoarm"]
CHEAP = ["--stream-every", "10", "--baud", "115200", "--stream-polled"]
KHZ = ["--set", "sensor.rate_hz=1000"]


def _one_line(res, *words: str) -> str:  # type: ignore[no-untyped-def]
    assert res.exit_code == 2, (res.exit_code, res.stdout, res.stderr)
    assert res.exception is None and "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1, lines
    for word in words:
        assert word in lines[0], lines[0]
    return str(lines[0])


# --------------------------------------------------------------------------- fast tier


def test_check_stream_numbers() -> None:
    from esoarm.codegen import CodegenError
    from esoarm.codegen.onboard import check_stream

    assert check_stream(1000.0, 1_000_000) == 1  # 370 bits per ms fit 1 Mbit/s
    assert check_stream(1000.0, 115_200) == 4  # ceil(370 / (0.9 · 115.2))
    assert check_stream(1000.0, 115_200, 10) == 10
    assert check_stream(50.0, 115_200) == 1
    with pytest.raises(CodegenError, match="give N >= 4"):
        check_stream(1000.0, 115_200, 3)
    with pytest.raises(CodegenError, match=r"--baud 230400: .* 222222 bit/s"):
        check_stream(1000.0, 230_400)  # the UART's divisor makes it 3.5 % slow
    with pytest.raises(CodegenError, match="--baud 4000000"):
        check_stream(1000.0, 4_000_000)


@pytest.mark.parametrize(("args", "words"), [
    (["--stream-every", "10"], ["--stream-every", "--onboard"]),
    (["--stream-polled"], ["--stream-polled", "--onboard"]),
    (["--baud", "115200"], ["--baud", "--onboard"]),
    (["--onboard", "--stream-every", "3", "--baud", "115200", *KHZ],
     ["--stream-every 3", "N >= 4"]),
    (["--onboard", "--baud", "230400"], ["--baud 230400", "3.5 %"]),
    (["--onboard", "--stream-every", "10", "--target", "cortex-m4"],
     ["--stream-every", "--target avr"]),
])
def test_hil_stream_options_are_checked(run_cli, args: list[str],  # type: ignore[no-untyped-def]
                                        words: list[str]) -> None:
    """Refused in one line, exit 2, before anything is built or timed."""
    _one_line(run_cli("hil", "uno-rig", *args), *words)


def test_stream_every_zero_is_a_usage_error(run_esoarm) -> None:  # type: ignore[no-untyped-def]
    """The console entry point: one line naming the option and its range."""
    _one_line(run_esoarm("hil", "uno-rig", "--onboard", "--stream-every", "0"),
              "--stream-every", "1<=x<=65535")


def test_codegen_stream_options(run_cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    _one_line(run_cli("codegen", "uno-rig", "--target", "avr", "--out", str(tmp_path / "c"),
                      "--stream-every", "10"), "--stream-every", "--arduino-library")
    _one_line(run_cli("codegen", "uno-rig", "--arduino-library", str(tmp_path / "bad"),
                      "--stream-every", "2", "--baud", "115200", *KHZ, "--no-check"),
              "--stream-every 2", "N >= 4")
    assert not (tmp_path / "bad").exists()  # nothing half-written
    plain = tmp_path / "Plain"
    res = run_cli("codegen", "uno-rig", "--arduino-library", str(plain), "--no-check")
    assert res.exit_code == 0, res.stderr
    text = (plain / "examples/OnBoard/OnBoard.ino").read_text()
    head = text[: text.index("#define ESOARM_ONBOARD")]
    assert "#define BAUD 1000000UL" in text and "#define STREAM_EVERY" not in head
    cheap = tmp_path / "Cheap"
    res = run_cli("codegen", "uno-rig", "--arduino-library", str(cheap), *CHEAP, *KHZ,
                  "--no-check", "--plain-sums")
    assert res.exit_code == 0, res.stderr
    text = (cheap / "examples/OnBoard/OnBoard.ino").read_text()
    assert "#define BAUD 115200UL" in text and "#define STREAM_EVERY 10u" in text
    assert "#define ESOARM_STREAM_POLLED" in text
    assert ("--baud 115200 --stream-every 10 --stream-polled" in text
            and "--onboard --baud 115200" in text)  # the command lines in its header


def _mapped_table(n: int = 72) -> list[float]:
    return [4.0 * math.cos(6 * 2 * math.pi * i / n) for i in range(n)]


def test_generated_table_is_in_flash_on_the_avr() -> None:
    """The table is its own array, PROGMEM under __AVR__; ACT_P stops at the bin count."""
    from esoarm.codegen.generate import generate
    from esoarm.plants.actuator import FF_BINS

    scn = load_scenario("uno-rig", {"controller.feedforward_map": _mapped_table()})
    src = generate(scn, "avr", "float32").source
    assert f"static const esoarm_real ACT_P[{FF_BINS + 1}]" in src
    assert "static const esoarm_real ACT_FF[72] PROGMEM" in src
    assert "pgm_read_float(&ACT_FF[(i)])" in src and "#include <avr/pgmspace.h>" in src
    bare = generate(load_scenario("uno-rig"), "avr", "float32").source
    assert "static const esoarm_real ACT_FF" not in bare and "pgmspace" not in bare  # as before


# --------------------------------------------------------------------------- slow, on the chip

onchip = on_chip(*AVR_TOOLS)


def _sizes(elf: Path) -> dict[str, int]:
    out = subprocess.run(["avr-size", "-A", str(elf)], capture_output=True, text=True,
                         check=True).stdout
    return {ln.split()[0]: int(ln.split()[1]) for ln in out.splitlines()
            if ln.startswith(".")}


@onchip
def test_table_costs_no_ram_on_the_uno() -> None:
    """The on-board firmware with a 72-bin table has the RAM (.data, .bss) of the one
    without: measured 770 B both (1106 B with the table in RAM before); flash +1046 B."""
    from esoarm.codegen.onboard import onboard_firmware

    with_table = load_scenario("uno-rig", {"controller.feedforward_map": _mapped_table()})
    without = load_scenario("uno-rig")
    a = _sizes(onboard_firmware(with_table, compensated=False))
    b = _sizes(onboard_firmware(without, compensated=False))
    assert a[".data"] == b[".data"] and a[".bss"] == b[".bss"], (a, b)
    assert a[".text"] > b[".text"] + 72 * 4  # the table's 288 bytes are in flash


def _hil_run(tmp_path: Path, label: str, hil_args: list[str],
             run_args: list[str]) -> tuple[dict, str]:  # type: ignore[type-arg]
    """``esoarm run --onboard`` against ``esoarm hil --onboard --once``: (metrics, hil's stdout)."""
    log = tmp_path / f"{label}.csv"
    with served("hil", *hil_args, "--onboard", "--once") as (dev, port):
        res = subprocess.run([*ESOARM, "run", *run_args, "--port", port, "--onboard", "--json",
                              "--log", str(log), "--watchdog", "5"], capture_output=True,
                             text=True, timeout=600)
        dev.wait(120)
        out = dev.stdout.read()  # type: ignore[union-attr]
    assert res.returncode == 0, res.stderr
    return dict(json.loads(res.stdout)), f"device: {port}\n" + out


def _simulated_rms(*args: str) -> float:
    res = subprocess.run([*ESOARM, "-q", "simulate", *args, "--json"], capture_output=True,
                         text=True, timeout=600, check=True)
    return float(json.loads(res.stdout)["rms_error"])


@onchip
def test_hil_onboard_streams_every_10th_at_1khz(tmp_path: Path) -> None:
    """`esoarm hil uno-rig --onboard --stream-every 10 --baud 115200 --stream-polled` at
    1 kHz: the host logs every 10th of the 3000 samples, none lost, no fault, and the chip
    tracks like simulate (measured RMS 0.02027 rad; the chip controls at every sample)."""
    short = [*KHZ, "--set", "duration=3"]
    got, hil_out = _hil_run(tmp_path, "k1", ["uno-rig", "--sums", "plain", *CHEAP, *short],
                            ["uno-rig", *short, "--baud", "115200"])
    assert "streams every 10th sample at 115200 bit/s, polled from loop()" in hil_out
    # the firmware benchmarks/bench_onboard.py measures with the same options
    from esoarm.codegen.onboard import onboard_firmware

    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000, "duration": 3})
    bench_elf = onboard_firmware(scn, compensated=False, baud=115200, every=10, polled=True)
    assert f"firmware {bench_elf}," in hil_out
    assert got["stream_every"] == 10 and got["samples"] == 300
    assert got["lost_samples"] == 0 and got["lost_frames"] == 0 and got["stop_acknowledged"]
    sim = _simulated_rms("uno-rig", *short)
    assert abs(got["rms_error"] / sim - 1) < 0.1, (got["rms_error"], sim)


@onchip
def test_learned_table_on_board_agrees_with_simulate(tmp_path: Path) -> None:
    """uno-rig with cogging, the table learned by `learn-map` from a simulated run: on board
    (`hil --onboard`, the table in flash) the RMS error is simulate's within 3 % with and
    without the table (measured 0.03789 vs 0.03753 rad with, 0.07763 vs 0.07772 without,
    6 s at 50 Hz), and the table lowers it as in simulate."""
    cog = ["--set", "rig.cogging.amplitude=0.08", "--set", "rig.cogging.periods=6"]
    learn = tmp_path / "cog.csv"
    subprocess.run([*ESOARM, "-q", "simulate", "uno-rig", *cog, "--set", "duration=40",
                    "--out", str(learn)], check=True, capture_output=True, timeout=600)
    mapped = str(tmp_path / "mapped.toml")
    subprocess.run([*ESOARM, "learn-map", str(learn), "uno-rig", *cog, "--bins", "72",
                    "--out", mapped], check=True, capture_output=True, timeout=600)
    short = ["--set", "duration=6"]
    off = ["--set", "controller.feedforward_map=[]"]
    on_chip, _ = _hil_run(tmp_path, "on", [mapped, "--sums", "plain", *short],
                          [mapped, *short])
    off_chip, _ = _hil_run(tmp_path, "off", [mapped, "--sums", "plain", *short, *off],
                           [mapped, *short, *off])
    on_sim, off_sim = _simulated_rms(mapped, *short), _simulated_rms(mapped, *short, *off)
    assert on_chip["samples"] == off_chip["samples"] == 300
    assert on_chip["lost_samples"] == 0 and off_chip["lost_samples"] == 0
    assert abs(on_chip["rms_error"] / on_sim - 1) < 0.03, (on_chip["rms_error"], on_sim)
    assert abs(off_chip["rms_error"] / off_sim - 1) < 0.03, (off_chip["rms_error"], off_sim)
    assert on_chip["rms_error"] < 0.6 * off_chip["rms_error"]


@onchip
def test_arduino_example_with_the_cheap_stream_runs_at_1khz(tmp_path: Path) -> None:
    """`esoarm codegen uno-rig --arduino-library DIR --stream-every 10 --baud 115200
    --stream-polled --set sensor.rate_hz=1000`: `make` builds the example, which in simavr
    streams samples 0, 10, 20, ... without a fault over 3 s (the chip controls at every one)."""
    import shutil

    import numpy as np

    from esoarm.codegen.onboard import onboard_run

    if not Path("/usr/share/arduino/hardware/arduino/avr/cores").is_dir() or not shutil.which(
            "make"):
        pytest.skip("arduino-core-avr or make not installed")
    lib = tmp_path / "Cheap"
    res = subprocess.run([*ESOARM, "codegen", "uno-rig", "--arduino-library", str(lib), *CHEAP,
                          *KHZ, "--plain-sums", "--no-check"], capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr
    ex = lib / "examples" / "OnBoard"
    res = subprocess.run(["make", "-s"], cwd=ex, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000})
    run = onboard_run(scn, ex / "build-uno" / "OnBoard.elf", seconds=3.0)
    assert run.faults == []
    assert len(run.k) >= 295 and np.array_equal(run.k, 10 * np.arange(len(run.k)))


def test_flash_stream_options_are_checked_before_the_port(run_cli) -> None:  # type: ignore[no-untyped-def]
    """A bad stream is refused in one line before the port is asked (it does not exist)."""
    _one_line(run_cli("flash", "uno-rig", "--port", "/dev/esoarm-no-such-port", "--stream-every",
                      "2", "--baud", "115200", *KHZ), "--stream-every 2", "N >= 4")
    _one_line(run_cli("flash", "uno-rig", "--port", "/dev/esoarm-no-such-port", "--baud",
                      "230400"), "--baud 230400")


@onchip
def test_flash_the_cheap_stream_and_read_the_hash_at_its_baud() -> None:
    """`esoarm flash uno-rig ... --stream-every 10 --baud 115200 --stream-polled` on the
    simulated Uno (its bootloader in simavr): written, verified, and the firmware answers
    with the scenario's hash at 115200 bit/s, the build's line rate."""
    import shutil

    from esoarm.codegen.generate import scenario_hash
    from esoarm.hardware.flash import SimulatedUno, read_hash

    if not shutil.which("avrdude") or not Path(
            "/usr/share/arduino/hardware/arduino/avr/bootloaders").is_dir():
        pytest.skip("avrdude or the Uno's bootloader (arduino-core-avr) not installed")
    with SimulatedUno() as uno:
        res = subprocess.run([*ESOARM, "flash", "uno-rig", "--port", uno.port, *KHZ, "--sums",
                              "plain", *CHEAP, "--json"], capture_output=True, text=True,
                             timeout=900)
        assert res.returncode == 0, res.stderr
        got = json.loads(res.stdout)
        want = scenario_hash(load_scenario("uno-rig", {"sensor.rate_hz": 1000}))[:8]
        assert got["ok"] and got["baud"] == 115200 and got["hash_read"] == want
        assert read_hash(uno.port, 115_200) == want


@onchip
def test_pil_with_the_table_in_flash() -> None:
    """`esoarm pil` on the ATmega328P with a 72-bin table: agrees with the float64 reference
    (drive compared; measured 1.5e-7 of the torque limit on test-1's learned table) and uses
    the static RAM of the run without a table (318 B; 654 B with the table in RAM before)."""
    from .chip_helpers import pil

    table = json.dumps(_mapped_table())
    with_table = pil("test-1", "--target", "avr", "--set", "duration=12", "--set",
                     f"controller.feedforward_map={table}")
    without = pil("test-1", "--target", "avr", "--set", "duration=12")
    assert with_table["ok"] and with_table["max_rel_du"] <= 1e-4
    assert with_table["ram_bytes"] == without["ram_bytes"]
    assert with_table["flash_bytes"] > without["flash_bytes"] + 72 * 4
