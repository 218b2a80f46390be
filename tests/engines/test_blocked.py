"""The blocked exact engine against the one-run-at-a-time loop: the same bits.

``run_metrics`` advances the runs of a grid point together (runs innermost);
``run_metrics(..., blocked=False)`` runs the loop one run at a time, which the
batch tests hold bit-identical to the reference engine.  Blocks must not change
a single bit, whatever the setting, the block size, or a run diverging inside
a block while the others go on.
"""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.engines import batch
from esoarm.scenario import builtin_names, load_scenario

SETTINGS = {
    "default": {},
    "no-noise": {"sensor.noise_deg": 0.0},
    "no-quantization": {"sensor.resolution_deg": 0.0},
    "lag": {"actuator.lag": 0.03},
    "delay": {"actuator.delay_samples": 3},
    "lag+delay": {"actuator.lag": 0.01, "actuator.delay_samples": 1},
    "saturation": {"actuator.torque_limit": 0.05},
    "model-compensation": {"controller.compensation": "model"},
    "theta0": {"rig.theta0": 0.3},
    "stiction": {"rig.stiction": 0.15, "rig.stribeck_velocity": 0.05},
    "stiction+lag": {"rig.stiction": 0.1, "actuator.lag": 0.02},
    "fine-step": {"rig.step": 0.0005, "sensor.rate_hz": 100.0},
    "diverges": {"observer.eps": 0.004},
    "diverges-late": {"observer.discretization": "zoh", "observer.eps": 0.02,
                      "actuator.torque_limit": 1e12, "actuator.delay_samples": 3},
}
# The URDF twin's friction is Coulomb + viscous per joint: rig.stiction is bad input there.
URDF_REFUSES = {"stiction", "stiction+lag"}
# A PID controller (the emps scenario) has no compensation key.
PID_REFUSES = {"model-compensation"}


@pytest.mark.parametrize("name", builtin_names())
@pytest.mark.parametrize("disc", ["euler", "zoh", "current"])
def test_blocks_change_no_bit(name: str, disc: str) -> None:
    scn = load_scenario(name)
    urdf = scn.plant.kind == "urdf"
    pid = scn.controller.kind == "pid"
    pts = [load_scenario(name, {"duration": 2.0, "observer.discretization": disc, **extra})
           for key, extra in SETTINGS.items()
           if not (urdf and key in URDF_REFUSES) and not (pid and key in PID_REFUSES)]
    blocked = batch.run_metrics(pts, seeds=range(5), series=False).values
    single = batch.run_metrics(pts, seeds=range(5), blocked=False).values
    np.testing.assert_array_equal(blocked, single)
    # the small-call path (the time-series kernel, metrics by NumPy): the same bits
    np.testing.assert_array_equal(batch.run_metrics(pts, seeds=range(5), series=True).values,
                                  single)


def test_runs_of_a_block_diverge_at_their_own_sample() -> None:
    # Ts/ε just above 2: every seed diverges, each at its own sample (82 … 92)
    pts = [load_scenario("test-1", {"duration": 3.0, "observer.eps": eps})
           for eps in (0.0095, 0.0105)]
    blocked = batch.run_metrics(pts, seeds=range(8), series=False).values
    single = batch.run_metrics(pts, seeds=range(8), blocked=False).values
    samples = blocked[:8, batch.METRICS.index("samples")]
    assert blocked[:8, -1].all() and len(set(samples)) > 2
    assert not blocked[8:, -1].any()
    np.testing.assert_array_equal(blocked, single)
    np.testing.assert_array_equal(batch.run_metrics(pts, seeds=range(8), series=True).values,
                                  single)


def test_small_blocks_for_long_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    pts = [load_scenario("test-2", {"duration": 2.0, "observer.eps": e}) for e in (0.05, 0.2)]
    whole = batch.run_metrics(pts, seeds=range(7), series=False).values
    budget = batch.BLOCK_BYTES
    monkeypatch.setattr(batch, "BLOCK_BYTES", 1)  # one run per block
    np.testing.assert_array_equal(batch.run_metrics(pts, seeds=range(7), series=False).values,
                                  whole)
    monkeypatch.setattr(batch, "BLOCK_BYTES", budget)
    monkeypatch.setattr(batch, "BLOCK", 3)  # blocks of 3, 3, 1 runs per point
    np.testing.assert_array_equal(batch.run_metrics(pts, seeds=range(7), series=False).values,
                                  whole)
    pairs = batch._blocks(np.repeat([0, 1], 7), np.tile([[100, 20, 0, 0, 1, 3, 0]], (2, 1)))
    assert [list(a) for a in pairs] == [[0, 0, 0, 1, 1, 1], [0, 3, 6, 7, 10, 13],
                                        [3, 3, 1, 3, 3, 1]]
