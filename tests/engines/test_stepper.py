"""The one stepper (esoarm.engines.stepper) and the consumers that take one sample at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.kinds import kinds_of
from esoarm.scenario import load_scenario


def _read(path):
    data = np.genfromtxt(path, delimiter=",", names=True, skip_header=_comments(path))
    return data


def _observer_by_hand(scn, y, u):
    """The observer kind's own step functions over (y, u): what every engine runs for it."""
    kinds = kinds_of(scn)
    plant = kinds.plant.design(scn)
    d = kinds.observer.design(scn, plant, scn.sample_time)
    z = np.zeros(d.n_state)
    zhat = np.zeros(3)
    yk, vk, uk = np.zeros(1), np.zeros(1), np.zeros(1)
    out = np.empty((len(y), 3))
    yk[0] = y[0]
    kinds.observer.initialize(z, yk, d.vector)
    for k in range(len(y)):
        yk[0] = y[k]
        kinds.observer.estimate(z, yk, d.vector, zhat)
        out[k] = zhat
        uk[0] = u[k]
        kinds.plant.observer_input(zhat, uk, plant.vector, vk)
        kinds.observer.advance(z, zhat, yk, vk, d.vector)
    return out


@pytest.mark.parametrize("kind", ["nonlinear", "cascade"])
def test_excite_runs_the_scenarios_own_observer(run_cli, tmp_path, kind):
    """``excite --twin --set observer.kind=K`` logs K's estimates, not the linear ESO's.

    The logged z1..z3 are the kind's own step functions over the logged (y, u), bit for
    bit; the linear ESO over the same drive gives other rates (the former back door).
    """
    log = tmp_path / "ex.csv"
    res = run_cli("excite", "test-1", "--twin", "--set", f"observer.kind={kind}",
                  "--duration", "6", "--log", str(log))
    assert res.exit_code == 0, res.stdout + res.stderr
    data = _read(log)
    y, u = data["y"], data["u"]
    logged = np.column_stack([data["z1"], data["z2"], data["z3"]])
    scn = load_scenario("test-1", {"observer.kind": kind})
    want = _observer_by_hand(scn, y, u)
    np.testing.assert_allclose(logged, want, rtol=1e-12, atol=1e-12)
    linear = _observer_by_hand(load_scenario("test-1"), y, u)
    assert np.max(np.abs(linear[:, 1] - logged[:, 1])) > 1e-3  # not the linear ESO


def test_excite_estimates_match_simulate_for_the_same_observer():
    """The guard loop's observer equals the reference engine's on the same drive.

    The reference engine (simulate) logs y and u of a closed-loop run; stepping the
    excitation controller's observer with that y and u gives simulate's z columns.
    """
    from esoarm.engines.simulation import simulate
    from esoarm.studies.identification.experiment.excitation import (
        ExcitationController,
        ExcitationPlan,
    )

    for kind in ("nonlinear", "cascade"):
        scn = load_scenario("test-1", {"observer.kind": kind, "duration": 3.0})
        res = simulate(scn, warn=False)
        ctl = ExcitationController(scn, ExcitationPlan(duration=3.0))
        got = np.empty((len(res.t), 3))
        for k in range(len(res.t)):
            ctl.step(k, float(res.y[k]))
            got[k] = ctl.zhat
            ctl.commit(float(res.u[k]))
        want = np.asarray(res.z).reshape(len(res.t), -1)[:, :3]
        np.testing.assert_array_equal(got, want)


def test_excite_lost_sample_uses_the_kinds_predict():
    """A lost sample in the guard loop is bridged by the observer kind (finite, bounded)."""
    from esoarm.studies.identification.experiment.excitation import (
        ExcitationController,
        ExcitationPlan,
    )

    scn = load_scenario("test-1", {"observer.kind": "cascade"})
    ctl = ExcitationController(scn, ExcitationPlan(duration=2.0))
    ctl.step(0, 0.1)
    ctl.commit(0.0)
    zhat = ctl.predict(0.0)
    assert all(math.isfinite(v) for v in zhat)
    assert abs(zhat[0] - 0.1) < 1e-6



@pytest.mark.parametrize("over", [{}, {"observer.kind": "cascade", "controller.kind": "pid"},
                                  {"observer.kind": "nonlinear", "actuator.delay_samples": 2}])
def test_a_run_stepped_by_hand_is_the_reference_engine(over) -> None:
    """sense → command → hold → record → update → advance with the Stepper: run_reference's
    log bit for bit (the compiled loops run the same sample functions)."""
    from esoarm.engines.metrics import NROW, TH, Z1, Z2, Z3, U
    from esoarm.engines.simulation import prepare, run_reference
    from esoarm.engines.stepper import Stepper

    scn = load_scenario("test-1", {**over, "duration": 2.0})
    inp = prepare(scn)
    st = Stepper.of(scn)
    x = np.array(inp.plant.x0)
    log = np.full((NROW, len(inp.t)), np.nan)
    st.sense(x, inp.noise, 0)
    st.start()
    for k in range(len(inp.t)):
        st.sense(x, inp.noise, k)
        st.estimate()
        st.control(k)
        st.limit()
        st.hold(k)
        assert st.record(log, x, k)
        st.update()
        st.advance_plant(x, k)
    ref = run_reference(scn, prepare(scn))
    assert np.array_equal(log[U], ref.u) and np.array_equal(log[TH], ref.theta)
    assert np.array_equal(log[[Z1, Z2, Z3]].T, ref.z)


def test_the_policy_runs_the_scenarios_controller_not_the_flc() -> None:
    """EsoFlcPolicy recognised the FLC by its vector's length and ran the FLC law on a
    PID's parameters; it asks the registry now: the PID's run, bit for bit."""
    from esoarm import envs
    from esoarm.engines.simulation import prepare, run_reference

    scn = load_scenario("test-1", {"controller.kind": "pid", "duration": 2.0})
    env = envs.LeverArmEnv(scn, observe_estimates=True)
    policy = envs.EsoFlcPolicy(env)
    obs, _ = env.reset()
    u = []
    for _ in range(env.n_steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        u.append(info["u"])
        if terminated or truncated:
            break
    assert np.array_equal(u, run_reference(scn, prepare(scn)).u)


def _comments(path) -> int:  # type: ignore[no-untyped-def]
    """Lines starting with '#' before a log's header (excite writes its probe's result)."""
    lines = open(path).read().splitlines()
    return next(i for i, line in enumerate(lines) if not line.startswith("#"))
