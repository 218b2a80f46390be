"""The twin behind the pins (no simulator needed): physics, encoder edges, quadrature order.

The quadrature table is read from the sketch itself, so the twin's idea of "counting up"
is checked against the firmware's decoder, not against a copy of it.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from esoarm.hardware.emulator import Twin
from esoarm.hardware.hil.twin import GRAY, PinTwin
from esoarm.scenario import ScenarioError, load_scenario

SKETCH = Path(__file__).resolve().parents[2] / "firmware" / "esoarm_rig" / "esoarm_rig.ino"
F_CPU = 16_000_000


def _quad_table() -> list[int]:
    text = SKETCH.read_text()
    body = re.search(r"QUAD_TABLE\[16\]\s*=\s*\{([^}]*)\}", text, re.S)
    assert body is not None
    bad = int(re.search(r"#define QUAD_BAD (\d+)", text).group(1))  # type: ignore[union-attr]
    return [bad if v.strip() == "QUAD_BAD" else int(v) for v in body.group(1).split(",")]


def _decode(levels, start_ab: int) -> tuple[int, int]:
    """The firmware's x4 decoder over a sequence of levels: (count, invalid transitions)."""
    table = _quad_table()
    count, bad, state = 0, 0, start_ab
    for ab in levels:
        step = table[(state << 2) | int(ab)]
        if step == 2:
            bad += 1
        else:
            count += step
        state = int(ab)
    return count, bad


def test_gray_code_counts_up_in_the_firmwares_table():
    table = _quad_table()
    for p in range(8):
        assert table[(GRAY[p % 4] << 2) | GRAY[(p + 1) % 4]] == +1
        assert table[(GRAY[(p + 1) % 4] << 2) | GRAY[p % 4]] == -1


@pytest.mark.parametrize("duty", [-255, -120, 0, 37, 200])
def test_physics_is_the_emulators(duty):
    """One sample of PinTwin steps equals the emulator's Twin over the same sample."""
    scn = load_scenario("uno-rig", {"rig.theta0": 0.2})
    pin, twin = PinTwin(scn, F_CPU), Twin(scn)
    pin.start()
    nsub = scn.substeps
    for k in range(5):
        for _ in range(nsub):
            pin.step(duty, 0)
        twin.advance(twin.torque_of_duty(duty))
        np.testing.assert_allclose(pin.x, twin.x,
                                   rtol=1e-12, atol=1e-15)
        assert pin.t == pytest.approx((k + 1) * scn.sample_time, abs=1e-12)


def test_edges_land_where_the_angle_crosses_each_count():
    scn = load_scenario("uno-rig", {"rig.step": 0.02})  # one long step: many edges in it
    pin = PinTwin(scn, F_CPU)
    pin.start()
    start_ab = pin.levels
    theta0 = pin.theta
    cycles, levels = pin.step(255, 1000)
    n = len(cycles)
    assert n > 3
    assert np.all(np.diff(cycles.astype(np.int64)) >= 0)
    assert cycles[0] >= 1000 and cycles[-1] < 1000 + pin.step_cycles
    count, bad = _decode(levels, start_ab)
    assert bad == 0 and count == math.floor(pin.theta / pin.q + 0.5) == n
    # edge j sits where the linear interpolation of θ crosses (j + 1/2)·q
    frac = (np.arange(1, n + 1) - 0.5) * pin.q / (pin.theta - theta0)
    expected = 1000 + np.floor(frac * pin.step_cycles)
    np.testing.assert_array_equal(cycles, expected.astype(np.uint64))


def test_start_keeps_the_lines_and_zeroes_the_count():
    scn = load_scenario("uno-rig")
    pin = PinTwin(scn, F_CPU)
    pin.start()
    for _ in range(30):
        pin.step(255, 0)
    before = pin.levels
    pin.start()
    assert pin.levels == before and pin.theta == scn.rig.theta0 and pin.t == 0.0
    cycles, levels = pin.step(-255, 0)
    for _ in range(20):
        c, lv = pin.step(-255, 0)
        levels = np.concatenate([levels, lv])
    count, bad = _decode(levels, before)
    assert bad == 0 and count == pin.position - pin.start_position < 0


def test_needs_a_motor_and_a_whole_number_of_counts():
    with pytest.raises(ScenarioError, match=r"\[motor\] table"):
        PinTwin(load_scenario("test-1"), F_CPU)
    with pytest.raises(ScenarioError, match="resolution_deg"):
        PinTwin(load_scenario("uno-rig", {"sensor.resolution_deg": 0.07}), F_CPU)


@pytest.mark.parametrize("over, key", [({"sensor.noise_ar": [0.5]}, "sensor.noise_ar"),
                                       ({"sensor.vibration_deg": 0.1}, "sensor.vibration_deg")])
def test_refuses_coloured_noise_in_one_line(over, key):
    with pytest.raises(ScenarioError, match=f"key '{key}': the hil engine") as err:
        PinTwin(load_scenario("uno-rig", over), F_CPU)
    assert "\n" not in str(err.value)
