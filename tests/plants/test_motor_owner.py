"""The motor has one owner: the actuator supplies the drive and its back-EMF damping.

A plant kind declaring ``MOTOR = True`` (lever arm, axis) is driven by the duty's
rate-independent torque S·d (S = N·Kt·Vs/R) and takes the damping D = (N·Kt)²/R from
:func:`esoarm.plants.actuator.back_emf_damping` into its viscous friction; a kind that
does not (the URDF arm: one ``[motor]`` table cannot describe each joint's drive)
refuses a ``[motor]`` table in one line naming the key, exit status 2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from esoarm.cli import cli
from esoarm.engines.sample import Sampling, advance_plant, hold, new_work
from esoarm.kinds import PLANTS, kinds_of
from esoarm.plants.actuator import back_emf_damping, motor_of
from esoarm.scenario import ScenarioError, load_scenario

MOTOR = ["motor.supply_voltage=12", "motor.resistance=2", "motor.torque_constant=0.02",
         "motor.gear_ratio=5", "motor.pwm_max=1000", "motor.deadband=0"]
# free motion: no gravity, no Coulomb friction, no disturbance, no lag; viscous b only
FREE = {
    "lever-arm": ["plant.g=0", "rig.coulomb_friction=0", "rig.viscous_friction=0.003",
                  "rig.disturbance.amplitude=0", "actuator.lag=0"],
    "axis": ["plant.kind=axis", "plant.coulomb_friction=0", "plant.viscous_friction=0.003",
             "plant.mass=0.02", "actuator.lag=0"],
}


def test_the_plant_kinds_say_whether_they_take_a_motor() -> None:
    declared = {m.KIND: getattr(m, "MOTOR", False) for m in PLANTS}
    assert all(isinstance(value, bool) for value in declared.values())
    assert {k: declared[k] for k in ("lever-arm", "urdf", "axis")} == {
        "lever-arm": True, "urdf": False, "axis": True}


def test_a_kind_without_motor_support_is_refused_by_the_engine(monkeypatch) -> None:
    """A plant kind declaring no MOTOR and no check of its own: prepare() refuses [motor]."""
    from esoarm.engines.simulation import prepare
    from esoarm.plants import lever_arm

    scn = load_scenario("test-1", MOTOR)
    monkeypatch.delattr(lever_arm, "MOTOR")
    with pytest.raises(ScenarioError, match=r"key 'motor': plant.kind = 'lever-arm'"):
        prepare(scn)


def test_the_damping_is_the_closed_form() -> None:
    scn = load_scenario("test-1", MOTOR)
    assert back_emf_damping(scn) == pytest.approx((5 * 0.02) ** 2 / 2, rel=1e-15)
    assert back_emf_damping(load_scenario("test-1")) is None
    assert motor_of(load_scenario("test-1")) is None


@pytest.mark.parametrize("kind", sorted(FREE))
def test_a_motor_driven_plant_follows_the_motor_law(kind: str) -> None:
    """Constant duty d from rest: ω(t) = S·d/(b + D) · (1 − exp(−(b + D)·t/J)), closed form.

    The plant half of the sample (hold, advance_plant) with the drive the actuator gives
    for the duty (S·d, the emulated device's) and the plant kind's design.
    """
    scn = load_scenario("test-1", [*MOTOR, *FREE[kind], "duration=2"])
    motor = motor_of(scn)
    assert motor is not None
    plant = kinds_of(scn).plant
    design = plant.design(scn)
    duty = 400
    drive = motor.source_torque(duty)
    assert drive == pytest.approx(5 * 0.02 * 12 / 2 * 0.4, rel=1e-15)
    sg = Sampling(scn.n_samples, scn.sample_time, scn.rig.step, scn.substeps, 0, 0.0, 0.0)
    w = new_work(scn.n_samples, 1, 0, 0)
    x = np.array(design.x0)
    b, damping = 0.003, (5 * 0.02) ** 2 / 2
    inertia = 0.02 if kind == "axis" else scn.rig.inertia_scale * scn.plant.inertia
    for k in range(scn.n_samples):
        w.drive[0] = drive
        hold(w, k, 0)
        advance_plant(x, w, k, sg, design.vector, plant.advance)
        t = (k + 1) * scn.sample_time
        want = drive / (b + damping) * (1.0 - math.exp(-(b + damping) * t / inertia))
        assert x[1] == pytest.approx(want, rel=1e-9, abs=1e-12)
    # without the damping the rate would be far off: the check can fail
    no_damping = drive / b * (1.0 - math.exp(-b * 2.0 / inertia))
    assert abs(x[1] - no_damping) > 0.1 * abs(no_damping)


@pytest.mark.parametrize("name", ["two-link", "test-1-urdf"])
def test_a_plant_without_a_motor_refuses_the_motor_table(name: str) -> None:
    pytest.importorskip("pinocchio")
    with pytest.raises(ScenarioError, match=r"key 'motor': plant.kind = 'urdf'"):
        load_scenario(name, ["motor.supply_voltage=12"])
    res = CliRunner().invoke(cli, ["simulate", name, "--set", "motor.supply_voltage=12"])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "key 'motor'" in lines[0] and "Traceback" not in res.output
