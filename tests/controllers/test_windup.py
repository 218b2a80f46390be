"""What the ESO is fed under saturation: ``actuator.observer_sees`` (issue 33, item 4).

"applied" (the default) feeds every observer the saturated command; "commanded" the
controller's command before saturation (the paper's ESO).  Every engine and consumer
follows: the reference loop, the host controller of ``esoarm run``, the TF form's and the
error form's own ESOs, and the generated C (lockstep on the host).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from esoarm.engines.simulation import simulate
from esoarm.hardware.host_control import DeploymentController
from esoarm.scenario import load_scenario

TIGHT = {"actuator.torque_limit": 0.08}


def _run(**keys):  # type: ignore[no-untyped-def]
    return simulate("test-1", {**TIGHT, **keys}, warn=False)


def test_applied_is_the_default_and_unchanged() -> None:
    a, b = _run(), _run(**{"actuator.observer_sees": "applied"})
    assert np.array_equal(a.table(), b.table(), equal_nan=True)
    tab = a.table()
    assert np.all(np.abs(tab[:, 4]) <= 0.08)  # the logged u is the applied command
    assert tab[:, 10].mean() > 0.02  # the limit bites


def test_commanded_feeds_the_unsaturated_command_and_winds_up() -> None:
    a = _run()
    c = _run(**{"actuator.observer_sees": "commanded"})
    tab = c.table()
    assert np.max(np.abs(tab[:, 4])) > 0.08  # the logged u is what the ESO saw: the command
    # the paper's ESO misreads the saturated loop: worse tracking than the anti-windup
    assert c.metrics["rms_error"] > 1.2 * a.metrics["rms_error"]
    # the estimate ẑ3 of a run whose commands are never clipped does not depend on it
    lo = simulate("test-1", {"duration": 3.0, "actuator.observer_sees": "commanded"},
                  warn=False)
    hi = simulate("test-1", {"duration": 3.0}, warn=False)
    assert not hi.table()[:, 10].any()
    assert np.array_equal(lo.table(), hi.table(), equal_nan=True)


@pytest.mark.parametrize("sees", ["applied", "commanded"])
def test_tf_form_is_the_state_space_form_both_ways(sees: str) -> None:
    ss = _run(**{"actuator.observer_sees": sees})
    tf = _run(**{"actuator.observer_sees": sees, "controller.kind": "adrc-tf"})
    assert np.max(np.abs(ss.table()[:, 4] - tf.table()[:, 4])) < 1e-9


def test_error_form_follows_the_key() -> None:
    a = _run(**{"controller.kind": "adrc-error"})
    c = _run(**{"controller.kind": "adrc-error", "actuator.observer_sees": "commanded"})
    assert c.metrics["rms_error"] > 1.2 * a.metrics["rms_error"]


@pytest.mark.parametrize("sees", ["applied", "commanded"])
def test_host_controller_matches_simulate(sees: str) -> None:
    """esoarm run's controller, fed the simulator's measurements, commands what it did."""
    scn = load_scenario("test-1", {**TIGHT, "actuator.observer_sees": sees,
                                   "sensor.noise_deg": 0.0})
    res = simulate(scn, warn=False)
    tab = res.table()
    ctl = DeploymentController(scn)
    for k in range(len(tab)):
        u = ctl.step(k, float(tab[k, 9]))
        host, _ = ctl.actuate(u)
        ctl.commit(host)
        assert u == min(max(tab[k, 4], -0.08), 0.08)
        assert ctl.zhat == (tab[k, 5], tab[k, 6], tab[k, 7])


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
@pytest.mark.parametrize("kind", ["flc", "adrc-tf", "adrc-error"])
def test_generated_c_follows_the_key(kind: str) -> None:
    """The C on the host in lockstep: agrees with its own setting, not with the other."""
    from esoarm.codegen.generate import generate
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep

    keys = {**TIGHT, "controller.kind": kind}
    cmd = load_scenario("test-1", {**keys, "actuator.observer_sees": "commanded"})
    app = load_scenario("test-1", keys)
    run = lockstep(cmd, HostChip(generate(cmd, "host", "float64")))
    assert run.max_rel_du < 1e-9
    wrong = lockstep(cmd, HostChip(generate(app, "host", "float64")))
    assert wrong.max_rel_du > 1e-3


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["flc", "adrc-tf", "pid"])
def test_compiled_engine_agrees(kind: str) -> None:
    """The batch engine (compiled) logs what the reference loop does, in both settings."""
    from esoarm.engines import batch
    from esoarm.engines.simulation import prepare, run_reference

    for sees in ("applied", "commanded"):
        scn = load_scenario("test-1", {**TIGHT, "controller.kind": kind,
                                       "actuator.observer_sees": sees})
        (fast,) = batch.simulate_many([scn])
        assert np.array_equal(fast.table(), run_reference(scn, prepare(scn)).table())
