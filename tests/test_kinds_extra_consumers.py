"""Two kinds written from docs/contract.md alone, through every consumer (issue 31).

``tests/kinds_extra/reduced.py`` (a reduced-order ESO with 2 states per joint, whose state
holds no angle) and ``tests/kinds_extra/sliding.py`` (a sliding-mode controller), each one
module and one ``register`` line: each command runs them or refuses them in one line.
The passive registration check refuses a kind that writes past its declared state.
"""

from __future__ import annotations

import csv
import math
import types

import numpy as np
import pytest

from controllers.lockstep import lockstep
from esoarm import kinds
from esoarm._jit import jitable
from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import load_scenario
from kinds_extra import reduced, sliding

BOTH = ("--set", "observer.kind=reduced", "--set", "controller.kind=sliding")
OVR = {"observer.kind": "reduced", "controller.kind": "sliding"}
SHORT = ("--set", "duration=2")


@pytest.fixture
def extra():  # type: ignore[no-untyped-def]
    kinds.register("observer", reduced)  # the one registry line of each
    kinds.register("controller", sliding)
    yield
    kinds.unregister("controller", sliding)
    kinds.unregister("observer", reduced)


def _one_line(res, code: int, *words: str) -> str:  # type: ignore[no-untyped-def]
    assert res.exit_code == code, (res.exit_code, res.stdout, res.stderr)
    assert res.exception is None and "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.strip().splitlines()
             if not ln.startswith("esoarm: warning:")]
    assert len(lines) == 1, lines
    for word in words:
        assert word in lines[0], lines[0]
    return str(lines[0])


def _copy(module, name: str, code: int, **names: object):  # type: ignore[no-untyped-def]
    """``module`` as another kind (same Params tag is fine: it is never registered long)."""
    from typing import Literal

    from pydantic import Field, create_model

    out = types.ModuleType(f"kinds_extra.{name}")
    for attr in dir(module):
        if not attr.startswith("__"):
            setattr(out, attr, getattr(module, attr))
    out.KIND, out.CODE = name, code  # type: ignore[attr-defined]
    out.Params = create_model(  # type: ignore[attr-defined]
        "Params", __base__=module.Params, kind=(Literal[name], Field(name)))  # type: ignore[valid-type]

    def design(scn, plant, ts):  # type: ignore[no-untyped-def]
        from esoarm.contract import ComponentDesign, read_only

        d = module.design(scn, plant, ts)
        return ComponentDesign(read_only(np.concatenate([[float(code)], d.vector[1:]])),
                               d.n_state)

    out.design = design  # type: ignore[attr-defined]
    for attr, value in names.items():
        setattr(out, attr, value)
    return out


# -- the registration check --------------------------------------------------------------


@jitable
def _advance_one_past(z, zhat, y, u, p):  # type: ignore[no-untyped-def]
    reduced.advance(z, zhat, y, u, p)
    z[2 * len(y)] = 0.0  # one element past the declared state (2 per joint)


@jitable
def _estimate_leaves_a_hole(z, y, p, zhat):  # type: ignore[no-untyped-def]
    reduced.estimate(z, y, p, zhat)
    zhat[len(zhat) - 1] = math.nan  # the last joint's perturbation never written


@pytest.mark.parametrize(("names", "words"), [
    ({"advance": _advance_one_past},
     ("advance on the 1-joint case", "out of bounds", "z of shape (2,) = state_size 2 × 1")),
    ({"estimate": _estimate_leaves_a_hole},
     ("estimate on the 1-joint case", "zhat[2] of shape (3,)")),
    ({"state_size": lambda params: 3},
     ("n_state 2", "state_size declares 3 per joint")),
])
def test_registration_refuses_a_kind_that_breaks_its_shapes(names, words) -> None:  # type: ignore[no-untyped-def]
    module = _copy(reduced, "reduced-bad", 30, **names)
    with pytest.raises(ImportError) as info:
        kinds.register("observer", module)
    message = str(info.value)
    assert "\n" not in message and "observer kind 'reduced-bad'" in message
    for word in words:
        assert word in message, message
    assert module not in kinds.OBSERVERS


def test_registration_refuses_a_controller_writing_past_its_command() -> None:
    @jitable
    def control(c, zhat, y, refs, k, p, u):  # type: ignore[no-untyped-def]
        sliding.control(c, zhat, y, refs, k, p, u)
        u[len(y)] = 0.0

    module = _copy(sliding, "sliding-bad", 31, control=control)
    with pytest.raises(ImportError, match=r"control on the 1-joint case: index 1 is out of "
                                          r"bounds .* y and u \(1,\)"):
        kinds.register("controller", module)


@pytest.mark.parametrize("component", ["observer", "controller"])
def test_every_registered_kind_passes_the_check(component) -> None:  # type: ignore[no-untyped-def]
    for module in (kinds.OBSERVERS if component == "observer" else kinds.CONTROLLERS):
        kinds.check_steps(component, module)


def test_the_extra_kinds_pass_the_check(extra) -> None:  # type: ignore[no-untyped-def]
    assert reduced in kinds.OBSERVERS and sliding in kinds.CONTROLLERS
    d = reduced.design(load_scenario("test-1", OVR), kinds.PLANTS[0].design(
        load_scenario("test-1")), 0.02)
    assert d.n_state == 2  # 2 states per joint: the engines size z from it, ẑ is 3 per joint


# -- every consumer ------------------------------------------------------------------------


def test_show(extra, run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("show", "test-1", *BOTH)
    assert res.exit_code == 0, res.stderr
    assert 'kind = "reduced"' in res.stdout and 'kind = "sliding"' in res.stdout


def test_simulate_tracks_and_estimates(extra, run_cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """simulate runs both (it crashed with IndexError when ẑ was sized by the state)."""
    out = tmp_path / "run.csv"
    res = run_cli("simulate", "test-1", *BOTH, *SHORT, "--out", str(out))
    assert res.exit_code == 0, res.stderr
    scn = load_scenario("test-1", {**OVR, "duration": 4.0})
    ref = run_reference(scn, prepare(scn))
    assert ref.metrics["rms_error"] < 0.02
    k = len(ref.t) // 2  # after the transient ẑ2 follows the true rate
    assert np.sqrt(np.mean((ref.z[k:, 1] - ref.omega[k:]) ** 2)) < 0.3 * np.std(ref.omega[k:])
    with out.open() as fh:
        assert len(list(csv.DictReader(fh))) == 100


@pytest.mark.slow
def test_sweep_exact_is_the_reference_engine(extra, run_cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The compiled batch engine (generated dispatch, ẑ of 3 per joint, z of 2) bit for bit.

    6 runs: more than the sweep's REFERENCE_RUNS, so the compiled engine runs them."""
    from esoarm.studies.sweeps.sweep import REFERENCE_RUNS

    assert 6 > REFERENCE_RUNS
    out = tmp_path / "sweep.csv"
    res = run_cli("sweep", "test-1", *BOTH, *SHORT, "--vary", "observer.eps=0.05,0.09",
                  "--seeds", "3", "--out", str(out))
    assert res.exit_code == 0, res.stderr
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6
    for row in rows:
        scn = load_scenario("test-1", {**OVR, "duration": 2.0,
                                       "observer.eps": float(row["observer.eps"]),
                                       "sensor.seed": int(row["seed"])})
        ref = run_reference(scn, prepare(scn))
        assert float(row["rms_error"]) == ref.metrics["rms_error"]
        assert float(row["rms_u"]) == ref.metrics["rms_u"]


@pytest.mark.slow
def test_tune(extra, run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("tune", "test-1", *BOTH, *SHORT, "--vary", "observer.eps=0.05:0.2",
                  "--maxiter", "1", "--popsize", "2", "--no-plot", "--json")
    assert res.exit_code == 0, res.stderr
    assert "observer.eps" in res.stdout


def test_analyze_runs_the_observer_and_refuses_the_controller(extra, run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("analyze", "test-1", "--set", "observer.kind=reduced")
    assert res.exit_code == 0, res.stderr
    assert "reduced-order ESO" in " ".join(res.stdout.split())
    _one_line(run_cli("analyze", "test-1", *BOTH), 2, "controller.kind", "'sliding'")


def test_replay_bridges_a_lost_sample_with_the_kinds_predict(extra, run_cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The reduced ESO's state holds no angle: a lost sample bridged as "y = z[0]" made ẑ2
    reach 10⁴ rad/s; through the kind's predict the estimate stays with the no-loss one."""
    from esoarm.hardware.replay import replay

    scn = load_scenario("test-1", {**OVR, "duration": 4.0})
    ref = run_reference(scn, prepare(scn))
    y = ref.y.copy()
    y[100] = math.nan
    rep = replay(scn, ref.t, y, ref.u, scn.sample_time)
    assert np.array_equal(replay(scn, ref.t, ref.y, ref.u, scn.sample_time).z, ref.z)
    assert np.all(np.isfinite(rep.z))
    assert np.max(np.abs(rep.z[:, 1] - ref.z[:, 1])) < 0.5  # rad/s, one sample bridged
    log = tmp_path / "run.csv"
    assert run_cli("simulate", "test-1", *BOTH, *SHORT, "--out", str(log)).exit_code == 0
    rows = log.read_text().splitlines()
    head = rows[0].split(",")
    cells = rows[40].split(",")
    cells[head.index("y")] = "nan"
    rows[40] = ",".join(cells)
    log.write_text("\n".join(rows) + "\n")
    res = run_cli("replay", str(log), "--scenario", "test-1", *BOTH,
                  "--out", str(tmp_path / "rep.csv"))
    assert res.exit_code == 0, res.stderr
    assert "1 of 100 rows" in res.stderr
    z2 = np.genfromtxt(tmp_path / "rep.csv", delimiter=",", names=True)["z2"]
    assert np.all(np.isfinite(z2)) and np.max(np.abs(z2)) < 5.0


def test_excite_twin(extra, run_cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("excite", "test-1", *BOTH, "--twin", "--duration", "2", "--log",
                  str(tmp_path / "ex.csv"))
    assert res.exit_code == 0, res.stderr
    data = np.genfromtxt(tmp_path / "ex.csv", delimiter=",", names=True,
                         skip_header=_comments(tmp_path / "ex.csv"))
    assert np.array_equal(data["z1"], data["y"])  # the reduced ESO's ẑ1 is the measurement
    assert np.all(np.isfinite(data["z2"])) and np.any(data["z2"] != 0.0)


def test_gymnasium_env_with_the_scenarios_controller_is_simulate(extra) -> None:  # type: ignore[no-untyped-def]
    from esoarm import envs

    scn = load_scenario("test-1", {**OVR, "duration": 2.0})
    env = envs.LeverArmEnv(scn, observe_estimates=True)
    policy = envs.EsoFlcPolicy(env)
    obs, _ = env.reset()
    u = []
    for _ in range(env.n_steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        u.append(info["u"])
        if terminated or truncated:
            break
    ref = run_reference(scn, prepare(scn))
    assert np.array_equal(u, ref.u)


def test_host_controller_against_the_emulated_device(extra) -> None:  # type: ignore[no-untyped-def]
    """The rig's host controller over the emulator's twin: simulate's commands bit for bit."""

    scn = load_scenario("test-1", {**OVR, "duration": 2.0})
    ref = run_reference(scn, prepare(scn))
    u_log, ctl = lockstep(scn)
    assert np.array_equal(u_log, ref.u)
    zhat = ctl.predict(0.0)  # a lost sample on the rig: the kind's predict, finite
    assert all(math.isfinite(v) for v in zhat)


@pytest.mark.parametrize("command", [("codegen", "--target", "host"), ("pil", "--target", "avr")])
def test_codegen_and_pil_refuse_in_one_line(extra, run_cli, tmp_path, command) -> None:  # type: ignore[no-untyped-def]
    out = ("--out", str(tmp_path / "gen")) if command[0] == "codegen" else ()
    res = run_cli(command[0], "test-1", *BOTH, *command[1:], *out)
    _one_line(res, 2, "observer.kind = 'reduced'", "codegen")


def _comments(path) -> int:  # type: ignore[no-untyped-def]
    """Lines starting with '#' before a log's header (excite writes its probe's result)."""
    lines = open(path).read().splitlines()
    return next(i for i, line in enumerate(lines) if not line.startswith("#"))
