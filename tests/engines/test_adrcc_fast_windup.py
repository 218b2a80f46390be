"""The fast engine runs issue 33's rig and actuator settings like the reference engine.

``actuator.observer_sees = "commanded"`` (the paper's ESO, fed the command before
saturation), hard end stops (``rig.end_stops``), the ESO's gate at a stop
(``actuator.stop_gate``), a cogging torque (``rig.cogging``) and a learned feedforward table
(``controller.feedforward_map``) used to be refused by the fast C kernel.  Here each runs on
it and its metrics agree with the reference engine (plain Python, bit-identical to the exact
engine) to the fast engine's documented tolerance, relative 1e-9, with the encoder's
quantization off (a quantization boundary may otherwise be crossed differently).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.engines import batch, fast
from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import load_scenario

pytestmark = pytest.mark.skipif(not fast.available(),
                                reason="the fast engine's C kernel does not build here")

RTOL = 1e-9
STOPS = {"rig.end_stops": [-0.5, 0.8]}
COG = {"rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6, "rig.cogging.phase": 0.3}
#: A table over the cogging's six periods [rad/s²], and a short odd one.
TABLE = [4.0 * math.cos(6 * 2 * math.pi * i / 72) for i in range(72)]
TABLE5 = [1.0, -2.0, 0.5, 3.0, 0.0]
CASES = {
    "commanded": {"actuator.observer_sees": "commanded", "actuator.torque_limit": 0.08},
    "commanded+pwm+delay": {"actuator.observer_sees": "commanded",
                            "actuator.torque_limit": 0.1, "actuator.pwm_bits": 6,
                            "actuator.delay_samples": 2},
    "stops": STOPS,
    "stops+gate": {**STOPS, "actuator.stop_gate": 0.01},
    "stops+gate+lag+commanded": {**STOPS, "actuator.stop_gate": 0.01, "actuator.lag": 0.01,
                                 "actuator.observer_sees": "commanded"},
    "cogging": COG,
    "cogging+lag": {**COG, "actuator.lag": 0.01},
    "cogging+backlash": {**COG, "rig.backlash_deg": 1.0},
    "table": {"controller.feedforward_map": TABLE},
    "cogging+table+pwm+delay+saturation": {**COG, "controller.feedforward_map": TABLE,
                                           "actuator.pwm_bits": 7,
                                           "actuator.delay_samples": 1,
                                           "actuator.torque_limit": 0.12},
    "table5+commanded+stops": {"controller.feedforward_map": TABLE5, **STOPS,
                               "actuator.stop_gate": 0.01, "actuator.torque_limit": 0.1,
                               "actuator.observer_sees": "commanded"},
}
FLOATS = [i for i, m in enumerate(batch.METRICS) if m not in ("samples", "diverged")]


def _scn(case: str, disc: str, eps: float = 0.05):  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {"duration": 12.0, "sensor.resolution_deg": 0.0,
                                    "observer.discretization": disc, "observer.eps": eps,
                                    **CASES[case]})


def _reference_row(scn) -> np.ndarray:  # type: ignore[no-untyped-def]
    res = run_reference(scn, prepare(scn))
    return np.array([float(res.metrics[m]) for m in batch.METRICS])


@pytest.mark.parametrize("disc", ["euler", "zoh", "current"])
@pytest.mark.parametrize("case", list(CASES))
def test_fast_engine_agrees_with_the_reference(case: str, disc: str) -> None:
    scn = _scn(case, disc)
    assert fast.unsupported(scn) is None
    quick = fast.run_metrics([scn]).values[0]
    ref = _reference_row(scn)
    assert quick[batch.METRICS.index("diverged")] == ref[batch.METRICS.index("diverged")] == 0
    assert quick[batch.METRICS.index("samples")] == ref[batch.METRICS.index("samples")]
    np.testing.assert_allclose(quick[FLOATS], ref[FLOATS], rtol=RTOL, atol=0)


def test_each_setting_changes_the_fast_engines_numbers() -> None:
    """The kernel does not ignore the keys: each moves the metrics as the reference does."""
    rms = batch.METRICS.index("rms_error")
    base = {"duration": 12.0, "sensor.resolution_deg": 0.0}
    pairs = [({"actuator.torque_limit": 0.08},
              {"actuator.torque_limit": 0.08, "actuator.observer_sees": "commanded"}),
             ({}, STOPS),
             (STOPS, {**STOPS, "actuator.stop_gate": 0.01}),
             ({}, COG),
             (COG, {**COG, "controller.feedforward_map": TABLE})]
    for before, after in pairs:
        a, b = (load_scenario("test-1", {**base, **o}) for o in (before, after))
        qa, qb = fast.run_metrics([a, b]).values[:, rms]
        assert abs(qb - qa) > 1e-3 * qa, (before, after)
        assert qb == pytest.approx(_reference_row(b)[rms], rel=RTOL)


def test_seeds_and_mixed_blocks() -> None:
    """Runs with and without stops, cogging and tables of 72 and 5 bins in one call (kernel
    blocks of each structure; lanes of one block with different tables), several seeds."""
    pts = [_scn("stops+gate", "zoh"), _scn("commanded", "zoh"), _scn("cogging", "zoh"),
           _scn("table", "zoh"), _scn("table", "zoh").with_overrides(
               {"controller.feedforward_map": TABLE5}),
           load_scenario("test-1", {"duration": 12.0, "sensor.resolution_deg": 0.0})]
    quick = fast.run_metrics(pts, seeds=[0, 1]).values
    for i, scn in enumerate(pts):
        for j, seed in enumerate((0, 1)):
            ref = _reference_row(scn.with_overrides({"sensor.seed": seed}))
            np.testing.assert_allclose(quick[2 * i + j, FLOATS], ref[FLOATS], rtol=RTOL,
                                       atol=0)


def test_what_it_does_not_model_is_still_refused_by_name() -> None:
    scn = load_scenario("test-1", {"rig.stiction": 0.05})
    assert "rig.stiction" in (fast.unsupported(scn) or "")
    with pytest.raises(ValueError, match="rig.stiction"):
        fast.run_metrics([scn])
