"""The learned feedforward table (``controller.feedforward_map``) in the generated C and in
``esoarm run``'s host controller (issue 33, item 6): a const table and the Python's
interpolation, the drive checked against the float64 reference in lockstep."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import load_scenario

#: A rig with cogging and a table over the angles test-1 visits (values [rad/s²]).
COG = {"rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6, "duration": 12.0}


def _table(n: int = 72, scale: float = 1.0) -> list[float]:
    """A smooth periodic table: 6 periods per revolution (the cogging's), 8 rad/s²."""
    return [scale * 8.0 * math.cos(6 * 2 * math.pi * i / n) for i in range(n)]


def _scn(table: list[float]):  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {**COG, "controller.feedforward_map": table})


gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")


@gcc
@pytest.mark.parametrize(("precision", "tol"), [("float64", 1e-9), ("float32", 1e-4)])
def test_c_table_drives_like_the_reference(precision: str, tol: float) -> None:
    from esoarm.codegen.generate import generate
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep

    scn = _scn(_table())
    run = lockstep(scn, HostChip(generate(scn, "host", precision)))
    assert run.drive_chip.size == run.steps  # the drive (the table's torque in it) compared
    assert run.max_rel_du <= tol
    assert np.max(np.abs(run.drive_chip - run.u_chip)) > 0.05  # the table moves the drive


@gcc
def test_a_wrong_table_in_c_is_caught() -> None:
    from esoarm.codegen.generate import generate
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep

    run = lockstep(_scn(_table()), HostChip(generate(_scn(_table(scale=1.01)), "host",
                                                     "float64")))
    assert run.max_rel_du > 1e-4


def test_host_controller_applies_the_table() -> None:
    """esoarm run's controller over the emulated rig drives what simulate drives: same u
    and angle, bit for bit, with the table in the drive and not in u."""
    from esoarm.hardware.emulator import Twin
    from esoarm.hardware.host_control import DeploymentController

    scn = _scn(_table())
    ref = run_reference(scn, prepare(scn))
    ctl, twin = DeploymentController(scn), Twin(scn)
    q = math.radians(scn.sensor.resolution_deg)
    u_log, drives = [], []
    for k in range(ctl.n_samples):
        u, _ = ctl.actuate(ctl.step(k, q * twin.count()))
        ctl.commit(u)
        twin.advance(ctl.drive)
        u_log.append(u)
        drives.append(ctl.drive)
    assert np.array_equal(u_log, ref.u)
    assert np.max(np.abs(np.subtract(drives, u_log))) > 0.05
