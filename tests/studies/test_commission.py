"""``esoarm commission``: the steps from a new rig to a measured on-board run.

Fast: bad input (exit 2), the resume mechanism, and the design step on its own (its
prediction is `esoarm simulate` of the design it writes; a bandwidth above Nyquist is
refused).  Slow and hil: the whole commissioning of uno-rig on the simulated Uno, and a
refusal at the excitation that a resumed run gets past.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from codegen.chip_helpers import AVR_TOOLS, on_chip
from esoarm.cli import cli
from esoarm.scenario import load_scenario
from esoarm.studies.commission import Commission, CommissionOptions, CommissionRefused

ESOARM = [sys.executable, "-m", "esoarm"]


needs_hil = on_chip(*AVR_TOOLS)  # slow, hil: the AVR toolchain and simavr


@pytest.mark.parametrize("args, words", [
    ([], "exactly one of --port PATH"),
    (["--hil", "--port", "/dev/null"], "exactly one of --port PATH"),
    (["--hil", "--bandwidth", "-3"], "--bandwidth -3"),
    (["--hil", "--amplitude", "0"], "--amplitude 0"),
    (["--hil", "--set", "observer.nope=1"], "observer.nope"),
])
def test_bad_input(tmp_path: Path, args: list[str], words: str) -> None:
    res = CliRunner().invoke(cli, ["commission", "uno-rig", "--workdir", str(tmp_path / "w"),
                                   *args])
    assert res.exit_code == 2, res.output
    assert words in res.output
    assert not (tmp_path / "w" / "01-excite.json").exists()


def test_earlier_steps_need_resume(tmp_path: Path) -> None:
    (tmp_path / "w").mkdir()
    (tmp_path / "w" / "01-excite.json").write_text("{}")
    res = CliRunner().invoke(cli, ["commission", "uno-rig", "--hil", "--workdir",
                                   str(tmp_path / "w")])
    assert res.exit_code == 2 and "add --resume" in res.output


def _opts(tmp_path: Path, **kw: object) -> CommissionOptions:
    return CommissionOptions("uno-rig", (), tmp_path, hil=True, **kw)  # type: ignore[arg-type]


def test_a_step_is_taken_from_its_file_only_when_its_inputs_match(tmp_path: Path) -> None:
    calls: list[int] = []

    def work() -> dict:
        calls.append(1)
        return {"value": float(len(calls))}

    first = Commission(_opts(tmp_path), say=lambda s: None)
    assert first._step("excite", {"a": 1}, work) == {"value": 1.0}
    again = Commission(_opts(tmp_path, resume=True), say=lambda s: None)
    assert again._step("excite", {"a": 1}, work) == {"value": 1.0}  # from the file
    assert again.status["excite"]["status"] == "resumed" and len(calls) == 1
    changed = Commission(_opts(tmp_path, resume=True), say=lambda s: None)
    assert changed._step("excite", {"a": 2}, work) == {"value": 2.0}  # inputs changed: redone
    fresh = Commission(_opts(tmp_path), say=lambda s: None)  # no --resume: redone
    assert fresh._step("excite", {"a": 2}, work) == {"value": 3.0}
    saved = json.loads((tmp_path / "01-excite.json").read_text())
    assert saved["step"] == "excite" and saved["result"] == {"value": 3.0}


def _fitted(tmp_path: Path) -> None:
    """uno-rig itself as the identified scenario (as if the fit were exact)."""
    (tmp_path / "02-fitted.toml").write_text(load_scenario("uno-rig").to_toml())


def test_design_predicts_with_simulate(tmp_path: Path) -> None:
    from esoarm.engines.simulation import simulate

    _fitted(tmp_path)
    job = Commission(_opts(tmp_path), say=lambda s: None)
    d = job._design()
    assert d["bandwidth_proposed"] and abs(d["bandwidth"] - 6.406) < 0.01  # uno-rig's ESO
    assert {r["kind"] for r in d["recommendations"]} == {"linear", "cascade"}
    design = load_scenario(tmp_path / "03-design.toml")
    assert design.observer.kind == d["observer_kind"] and design.observer.eps == d["eps"]
    sim = simulate(design).metrics
    assert d["predicted"]["rms_error"] == sim["rms_error"]
    assert d["predicted"]["rms_du"] == sim["rms_du"]
    assert any("torque loop" in n for n in d["notes"])  # the motor left out of the budget, said
    linear = Commission(_opts(tmp_path / "l", observer_kind="linear"), say=lambda s: None)
    (tmp_path / "l").mkdir()
    _fitted(tmp_path / "l")
    assert linear._design()["observer_kind"] == "linear"


def test_design_refuses_a_bandwidth_above_nyquist(tmp_path: Path) -> None:
    _fitted(tmp_path)
    job = Commission(_opts(tmp_path, bandwidth=1000.0), say=lambda s: None)
    with pytest.raises(CommissionRefused) as exc:
        job._design()
    assert exc.value.step == "design" and "Nyquist" in exc.value.reason
    assert "lower --bandwidth" in exc.value.advice
    assert not (tmp_path / "03-design.json").exists()


@needs_hil
def test_uno_rig_commissioned_on_the_simulated_uno(tmp_path: Path) -> None:
    """The issue's check, with a 30 s excitation to keep CI short (the default is 60 s):
    identified, design, predicted and measured in the JSON, the measured RMS error within
    25 % of the predicted one, and a report page.  Measured (load ~13 on 2 cores, 40 s
    excitation): 206 s in all; RMS error 0.0437 rad against 0.0394 predicted (+10.9 %),
    RMS Δu −2.9 %."""
    work = tmp_path / "w"
    run = subprocess.run([*ESOARM, "commission", "uno-rig", "--hil", "--json", "--workdir",
                          str(work), "--excite-seconds", "30"],
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    for key in ("identified", "design", "predicted", "measured"):
        assert out[key], key
    assert out["measured"]["samples"] == 1000 and out["measured"]["lost_samples"] == 0
    assert abs(out["measured"]["rms_error"] / out["predicted"]["rms_error"] - 1) <= 0.25
    assert out["agreement"]["rms_error_ok"] and out["agreement"]["rms_du_ok"]
    assert out["excitation"]["max_abs_u"] <= out["excitation"]["torque_limit"]
    assert out["excitation"]["max_abs_theta"] <= out["excitation"]["angle_limit"]
    page = Path(out["report"]).read_text(encoding="utf-8")
    for words in ("1. Excitation", "2. Identification", "3. Noise budget and observer",
                  "4. Generated code", "5. Flashing", "6. On board: measured against predicted",
                  "data:image/png;base64,"):
        assert words in page, words
    assert json.loads((work / "commission.json").read_text())["measured"] == out["measured"]
    again = subprocess.run([*ESOARM, "commission", "uno-rig", "--hil", "--json", "--workdir",
                            str(work), "--excite-seconds", "30", "--resume"],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert again.stderr.count("resumed from") == 6
    assert json.loads(again.stdout)["measured"] == out["measured"]


@needs_hil
def test_a_refusal_stops_with_what_to_change(tmp_path: Path) -> None:
    work = tmp_path / "w"
    run = subprocess.run([*ESOARM, "commission", "uno-rig", "--hil", "--json", "--workdir",
                          str(work), "--excite-seconds", "30", "--angle-limit", "0.05"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    assert "esoarm: failed: excite: angle limit" in run.stderr
    assert "to go on: lower --amplitude, or raise --angle-limit" in run.stderr
    out = json.loads(run.stdout)
    assert out["refused"]["step"] == "excite" and out["measured"] is None
    assert "Stopped at <b>excite</b>" in (work / "report.html").read_text(encoding="utf-8")
    assert not (work / "01-excite.json").exists()


@needs_hil  # the AVR toolchain and simavr: the PIL timing and the firmware build
def test_on_a_port_flashing_is_checked_by_the_boards_hash(tmp_path: Path) -> None:
    """--port: the excitation through the serial link (the emulated rig in lockstep), the
    identification, design and code; then the port answers neither with the design's hash
    nor as an Uno bootloader (avrdude's probe), so the flash step stops with the make command
    to flash it by hand and --resume.  (Writing through the bootloader is esoarm flash's,
    tested in tests/hardware/test_flash.py.)"""
    emu = subprocess.Popen([*ESOARM, "emulate", "uno-rig", "--lockstep"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    work = tmp_path / "w"
    try:
        assert emu.stdout is not None
        device = emu.stdout.readline().split(": ", 1)[1].strip()
        run = subprocess.run([*ESOARM, "commission", "uno-rig", "--port", device, "--json",
                              "--workdir", str(work), "--excite-seconds", "20"],
                             capture_output=True, text=True, timeout=600)
    finally:
        emu.terminate()
        emu.wait(10)
    assert run.returncode == 1, run.stderr
    out = json.loads(run.stdout)
    assert out["refused"]["step"] == "flash"
    assert "does not answer as an Uno bootloader" in out["refused"]["reason"]  # avrdude's probe
    assert "make -C firmware upload ONBOARD=" in out["refused"]["advice"]
    assert "--resume" in out["refused"]["advice"]
    assert out["identified"] and out["design"] and out["codegen"] and out["measured"] is None
    assert (work / "04-codegen" / "esoarm_controller.c").exists()


def test_report_of_a_refused_run_with_a_withheld_interval(tmp_path: Path) -> None:
    """The page is written for a commissioning stopped early, and says an interval the
    identification withheld in words (its JSON has ci95 null then)."""
    from esoarm.studies.commission.report import write_report

    summary = {
        "scenario": "uno-rig", "workdir": str(tmp_path), "rig": "simulated Uno (--hil)",
        "steps": {"excite": {"status": "done", "file": "01-excite.json", "elapsed_s": 1.0},
                  "identify": {"status": "done", "file": "02-identify.json", "elapsed_s": 2.0}},
        "identified": {"parameters": {
            "rig.stiction": {"value": 0.007, "ci95": None, "unit": "N·m", "fitted": True,
                             "withheld": "the residual is not white"},
            "plant.m2": {"value": 0.55, "ci95": [0.54, 0.56], "unit": "kg", "fitted": True}},
            "fit_percent": 99.0, "validation_fit_percent": 98.0, "residual_white": False,
            "poorly_identifiable": [], "at_bound": [], "noise": "not written",
            "scenario": "02-fitted.toml"},
        "design": None, "predicted": None, "measured": None, "agreement": None}
    page = write_report(summary, tmp_path / "report.html",
                        {"step": "design", "reason": "no kind reaches it", "advice": "lower it"})
    text = page.read_text(encoding="utf-8")
    assert "Stopped at <b>design</b>: no kind reaches it" in text and "To go on: lower it" in text
    assert "withheld" in text and "rig.stiction: the residual is not white" in text
    assert "[0.54, 0.56]" in text


def test_a_watchdog_on_the_simulated_board_is_tried_again(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """On --hil a run a watchdog ended (a busy machine) is tried again, with a fresh
    controller, and said; a limit is not; on a port nothing is tried again."""
    said: list[str] = []
    made: list[int] = []
    outcomes = [CommissionRefused("excite", "the device reported a fault: command watchdog "
                                  "(detail 626): stop sent, motor off", "x"), "done"]

    def once(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        out = outcomes.pop(0)
        if isinstance(out, Exception):
            raise out
        return out

    monkeypatch.setattr(Commission, "_drive_once", once)
    job = Commission(_opts(tmp_path), say=said.append)
    assert job._drive(None, None, tmp_path / "l.csv", "excite", None, "advice",  # type: ignore[arg-type]
                      controller=lambda: made.append(1)) == "done"
    assert len(made) == 2 and "attempt 2 of 3" in said[0] and "command watchdog" in said[0]
    outcomes[:] = [CommissionRefused("excite", "angle limit: θ = 0.06 rad", "x")]
    with pytest.raises(CommissionRefused, match="angle limit"):
        job._drive(None, None, tmp_path / "l.csv", "excite", None, "advice")  # type: ignore[arg-type]
    outcomes[:] = [CommissionRefused("run", "watchdog: no sample", "x"), "done"]
    port = Commission(CommissionOptions("uno-rig", (), tmp_path, port="/dev/null"),
                      say=said.append)
    with pytest.raises(CommissionRefused, match="watchdog"):
        port._drive(None, None, tmp_path / "l.csv", "run", None, "advice")  # type: ignore[arg-type]
