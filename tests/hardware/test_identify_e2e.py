"""End to end: ``esoarm emulate`` (a twin with known parameters) + ``esoarm excite --port``
+ ``esoarm identify`` + ``esoarm simulate`` on the fitted scenario, as a user runs them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from esoarm.hardware.realtime import LOG_COLUMNS

from .rig_helpers import emulator, esoarm, needs_pty

pytestmark = [needs_pty, pytest.mark.slow]  # end to end: a device and a loop in real time

TRUE = ["rig.inertia_scale=1.25", "rig.coulomb_friction=0.08", "sensor.seed=2"]


def _sets(items):
    return [a for s in items for a in ("--set", s)]


def test_excite_identify_simulate_against_the_emulator(tmp_path):
    log = tmp_path / "excite.csv"
    with emulator("test-1", "--lockstep", "--once", *_sets(TRUE)) as emu:
        res = esoarm("excite", "test-1", "--port", emu.path, "--log", str(log),
                     "--duration", "30", timeout=120)
        assert res.returncode == 0, res.stderr
        assert "stop received" in emu.output()
    lines = log.read_text().splitlines()
    # the probe's header line, the columns, 6 s of probe and 30 s of multisine at 50 Hz
    assert lines[0].startswith("# esoarm excite: probe_s=6.0 ")
    assert lines[1] == ",".join(LOG_COLUMNS) and len(lines) == 2 + 300 + 1500

    fitted = tmp_path / "fitted.toml"
    res = esoarm("identify", str(log), "--scenario", "test-1", "--json", "--out", str(fitted),
                 timeout=180)
    assert res.returncode == 0, res.stderr
    params = json.loads(res.stdout)["parameters"]
    for key, true in (("rig.inertia_scale", 1.25), ("rig.coulomb_friction", 0.08)):
        lo, hi = params[key]["ci95"]
        assert lo <= true <= hi, (key, params[key])
    assert abs(params["rig.inertia_scale"]["value"] / 1.25 - 1) < 0.05

    res = esoarm("simulate", str(fitted), "--json")
    assert res.returncode == 0, res.stderr
    assert np.isfinite(json.loads(res.stdout)["rms_error"])


def test_excite_and_identify_a_motor_rig_over_the_link(tmp_path):
    """With a [motor] table the device takes duties; the fit uses them and finds Kt."""
    true = ["motor.torque_constant=0.025", "motor.deadband=0.05", "rig.inertia_scale=1.2"]
    nominal = ["motor.torque_constant=0.02", "motor.deadband=0.05", "rig.inertia_scale=1.2"]
    log = tmp_path / "excite.csv"
    with emulator("test-1", "--lockstep", "--once", *_sets(true)) as emu:
        res = esoarm("excite", "test-1", "--port", emu.path, "--log", str(log),
                     "--duration", "30", *_sets(nominal), timeout=120)
        assert res.returncode == 0, res.stderr
    res = esoarm("identify", str(log), "--json", *_sets(nominal), timeout=180)
    assert res.returncode == 0, res.stderr
    params = json.loads(res.stdout)["parameters"]
    lo, hi = params["motor.torque_constant"]["ci95"]
    assert lo <= 0.025 <= hi
    assert params["rig.inertia_scale"]["fitted"] is False  # held with a motor (documented)
