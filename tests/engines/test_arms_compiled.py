"""URDF arms on the compiled batch engine against the reference engine (Pinocchio).

The compiled engine runs the arm's twin, observer input and computed-torque law
on :mod:`esoarm.plants.arms.rigid_body`; the reference engine on Pinocchio.  They
agree to rounding, not bit for bit: every metric of every run within
:data:`esoarm.plants.arms.compiled.ENGINE_TOLERANCE` (relative to the metric,
absolute below 1e-12), the number of samples and the divergence flag exactly.
Within the compiled engine, blocks and single runs give the same bits, and a
rerun the same bits.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from esoarm.engines import batch  # noqa: E402
from esoarm.engines.metrics import METRICS  # noqa: E402
from esoarm.engines.simulation import reference_metrics  # noqa: E402
from esoarm.kinds import kinds_of  # noqa: E402
from esoarm.plants.arms.compiled import ENGINE_TOLERANCE  # noqa: E402
from esoarm.scenario import load_scenario  # noqa: E402

pytestmark = pytest.mark.slow  # compiles the kernels for the arms' vectors

EXACT = [METRICS.index("samples"), METRICS.index("diverged")]


def _points(name: str, **over: object) -> list:
    base = {"duration": 2.0, **over}
    return [load_scenario(name, {**base, "observer.eps": eps}) for eps in (0.02, 0.04)]


def _assert_close(compiled: np.ndarray, reference: np.ndarray) -> None:
    np.testing.assert_array_equal(compiled[:, EXACT], reference[:, EXACT])
    scale = np.maximum(np.abs(reference), 1e-12 / ENGINE_TOLERANCE)
    worst = float(np.max(np.abs(compiled - reference) / scale))
    assert worst <= ENGINE_TOLERANCE, worst


def test_urdf_kinds_compile():
    assert kinds_of(load_scenario("two-link")).jit
    assert kinds_of(load_scenario("test-1-urdf")).jit


@pytest.mark.parametrize(("name", "over"), [
    ("two-link", {}),
    ("two-link", {"controller.compensation": "model"}),
    ("two-link", {"controller.feedforward": True, "actuator.lag": 0.005}),
    ("test-1-urdf", {}),
    ("two-link", {"observer.kind": "nonlinear"}),
    ("two-link", {"observer.kind": "cascade"}),
])
def test_compiled_rows_match_the_reference_engine(name, over):
    points = _points(name, **over)
    seeds = [1, 2]
    compiled = batch.run_metrics(points, seeds).values
    reference = reference_metrics(points, seeds).values
    _assert_close(compiled, reference)
    again = batch.run_metrics(points, seeds).values
    np.testing.assert_array_equal(again, compiled)  # deterministic: the same bits


def test_blocks_and_single_runs_are_the_same_bits():
    points = _points("two-link")
    blocked = batch.run_metrics(points, [3, 4, 5]).values
    single = batch.run_metrics(points, [3, 4, 5], blocked=False).values
    np.testing.assert_array_equal(blocked, single)


def test_series_match_the_reference_engine():
    from esoarm.engines.simulation import simulate

    scn = load_scenario("two-link", {"duration": 2.0})
    compiled = batch.simulate_many([scn])[0]
    reference = simulate(scn, warn=False)
    for mine, ref in zip(compiled.per_joint, reference.per_joint, strict=True):
        np.testing.assert_allclose(mine.theta, ref.theta, rtol=0, atol=1e-9)
        np.testing.assert_allclose(mine.u, ref.u, rtol=0, atol=1e-7)
