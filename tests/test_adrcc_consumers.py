"""Issue 33's new kinds and options through every consumer (the gaps found and closed).

Each new option (adrc-error, adrc-tf, half-gain, input_delay, pid + ESO compensation, the
switch, the learned table, the ESO fed the command, end stops with the gate, the model
delay form) is run by
simulate, the fast engine (or refused naming the key), analyze (or refused naming the key,
or its "left out" lines naming what the linear model does not hold), the Gymnasium
environment driven by the scenario's own controller (bit for bit with simulate) and replay
(the logged estimates again, bit for bit).  Three of these failed before this file:
the gym policy with ``controller.kind = "switch"`` (it called the kind with k = 1 at every
sample, so the switch never came: |Δθ| up to 2 rad), replay of a run with
``actuator.stop_gate`` (the gate was not applied: ẑ3 off by 9.6 rad/s²), and analyze with
a learned table, cogging or end stops (no word that the margins leave them out).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import esoarm
from esoarm.engines import fast
from esoarm.engines.simulation import simulate
from esoarm.scenario import ScenarioError, load_scenario

gym = pytest.importorskip("gymnasium")
envs = pytest.importorskip("esoarm.envs")

TABLE = [4.0 * math.cos(6 * 2 * math.pi * i / 72) for i in range(72)]
COG = {"rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6}
STOPS = {"rig.end_stops": [-0.5, 0.8], "actuator.stop_gate": 0.01}
OPTIONS = {
    "adrc-error": {"controller.kind": "adrc-error"},
    "adrc-tf": {"controller.kind": "adrc-tf"},
    "half-gain": {"observer.tuning": "half-gain"},
    "input_delay": {"observer.input_delay": 2},
    "pid+eso": {"controller.kind": "pid", "controller.compensation": "eso"},
    "switch": {"controller.kind": "switch"},
    "table": {"controller.feedforward_map": TABLE, **COG},
    "commanded": {"actuator.observer_sees": "commanded", "actuator.torque_limit": 0.1},
    "stops+gate": STOPS,
    "delay-model": {"observer.discretization": "current", "observer.delay_form": "model",
                    "observer.model_coulomb": 0.05, "observer.model_viscous": 0.01,
                    "observer.input_delay": 3, "actuator.delay_samples": 3},
}
#: What the fast engine refuses, by the key its one line names (None: it runs the option).
FAST_REFUSES = {"adrc-error": "controller.kind", "adrc-tf": "controller.kind",
                "input_delay": "observer.input_delay", "pid+eso": "controller.kind",
                "switch": "controller.kind", "delay-model": "observer.input_delay"}
#: What analyze refuses (its linearization models the FLC law), by key.
ANALYZE_REFUSES = {"pid+eso": "controller.kind", "switch": "controller.kind",
                   "delay-model": "observer.delay_form"}
#: (adrc-error and adrc-tf are analyzed as their FLC equivalent: test_flc_equivalent.py)
#: Words of analyze's "left out" lines.
ANALYZE_LEFT_OUT = {"table": ["controller.feedforward_map", "rig.cogging"],
                    "stops+gate": ["rig.end_stops", "actuator.stop_gate"]}


def _scn(name: str):  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {**OPTIONS[name], "duration": 12.0})


@pytest.mark.parametrize("name", list(OPTIONS))
def test_fast_engine_runs_or_names_the_key(name: str) -> None:
    scn = _scn(name)
    why = fast.unsupported(scn)
    if name in FAST_REFUSES:
        assert why is not None and FAST_REFUSES[name] in why
        with pytest.raises(ValueError, match=FAST_REFUSES[name].replace(".", r"\.")):
            fast.run_metrics([scn])
    else:
        assert why is None
        quick = fast.run_metrics([scn.with_overrides({"sensor.resolution_deg": 0.0})])
        ref = simulate(scn.with_overrides({"sensor.resolution_deg": 0.0}), warn=False)
        assert quick.column("rms_error")[0] == pytest.approx(ref.rms_error, rel=1e-9)


@pytest.mark.parametrize("name", list(OPTIONS))
def test_analyze_runs_refuses_or_says_what_it_leaves_out(run_cli, name: str  # type: ignore[no-untyped-def]
                                                         ) -> None:
    sets = [a for key, value in OPTIONS[name].items()
            for a in ("--set", f"{key}={json.dumps(value)}")]
    res = run_cli("analyze", "test-1", *sets, "--json")
    if name in ANALYZE_REFUSES:
        assert res.exit_code == 2 and ANALYZE_REFUSES[name] in res.stderr, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1
        return
    assert res.exit_code == 0, res.stderr
    left_out = " ".join(json.loads(res.stdout).get("left_out", []))
    for word in ANALYZE_LEFT_OUT.get(name, []):
        assert word in left_out, left_out
    if name not in ANALYZE_LEFT_OUT:
        assert left_out == ""


def test_analyze_table_note_gives_the_tables_slope(run_cli) -> None:  # type: ignore[no-untyped-def]
    """The note quotes the feedback the table adds: I0 · max |Δm| · N / (2π) [N·m/rad]."""
    from esoarm.studies.frequency.margins import left_out_notes

    scn = load_scenario("test-1", {"controller.feedforward_map": [0.0, 1.0, 0.0, -1.0]})
    (line,) = left_out_notes(scn)
    slope = 1.0 * 4 / (2 * math.pi)
    assert f"I0·{slope:.3g} = {scn.plant.inertia * slope:.3g} N·m/rad" in line


@pytest.mark.parametrize("name", list(OPTIONS))
def test_gym_policy_is_simulate_bit_for_bit(name: str) -> None:
    over = {**OPTIONS[name], "duration": 12.0}
    env = gym.make("esoarm/LeverArm-v0", scenario="test-1", overrides=over,
                   action_mode="torque", observe_estimates=True)
    policy = envs.EsoFlcPolicy(env)
    obs, _ = env.reset()
    rows = []
    while True:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        rows.append([info[k] for k in esoarm.result.CSV_COLUMNS])
        if terminated or truncated:
            break
    np.testing.assert_array_equal(np.array(rows), simulate("test-1", over, warn=False).table())


def test_policy_past_its_episode_says_so() -> None:
    """The policy keeps one column per sample: called past the episode, it says so."""
    over = {"controller.kind": "switch", "duration": 12.0}
    env = gym.make("esoarm/LeverArm-v0", scenario="test-1", overrides=over,
                   action_mode="torque", observe_estimates=True)
    policy = envs.EsoFlcPolicy(env)
    obs, _ = env.reset()
    for _ in range(10):
        obs, *_ = env.step(policy(obs))
    with pytest.raises(RuntimeError, match="episode is over"):
        for _ in range(env.unwrapped.n_steps):
            policy(obs)


@pytest.mark.parametrize("name", list(OPTIONS))
def test_replay_recovers_the_logged_estimates(run_cli, tmp_path: Path, name: str  # type: ignore[no-untyped-def]
                                              ) -> None:
    sets = [a for key, value in {**OPTIONS[name], "duration": 12.0}.items()
            for a in ("--set", f"{key}={json.dumps(value)}")]
    log, out = tmp_path / "run.csv", tmp_path / "replayed.csv"
    res = run_cli("-q", "simulate", "test-1", *sets, "--out", str(log))
    assert res.exit_code == 0, res.stderr
    res = run_cli("-q", "replay", str(log), "--scenario", "test-1", *sets, "--out", str(out))
    assert res.exit_code == 0, res.stderr
    a = np.genfromtxt(log, delimiter=",", names=True)
    b = np.genfromtxt(out, delimiter=",", names=True)
    for col in ("z1", "z2", "z3"):
        np.testing.assert_array_equal(b[col], a[col])


def test_stop_gate_without_stops_is_still_refused() -> None:
    with pytest.raises(ScenarioError, match="actuator.stop_gate"):
        load_scenario("test-1", {"actuator.stop_gate": 0.01})


@pytest.mark.parametrize("name", [n for n in OPTIONS if n not in ("table", "commanded")])
def test_host_controller_commands_what_simulate_does(name: str) -> None:
    """`esoarm run`'s host controller over the emulated twin (noise off): u bit for bit.
    (The table and "commanded", whose drive differs from u: tests/codegen/test_map_c.py and
    tests/controllers/test_windup.py.)"""
    from controllers.lockstep import host_commands

    scn = load_scenario("test-1", {**OPTIONS[name], "duration": 12.0, "sensor.noise_deg": 0.0})
    np.testing.assert_array_equal(host_commands(scn), simulate(scn, warn=False).u)
