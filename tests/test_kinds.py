"""Every registered kind through every engine; the nonlinear ESO and the PID on their own."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from controllers.lockstep import host_commands
from esoarm import kinds
from esoarm.cli import cli
from esoarm.controllers.pid import pid_command
from esoarm.engines import batch
from esoarm.engines.simulation import prepare, run_reference
from esoarm.hardware.replay import replay
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.observers.nonlinear import fal
from esoarm.scenario import ScenarioError, load_scenario

SHORT = {"duration": 2.0}


def _kind_sets() -> dict[str, dict[str, str]]:
    """Every registered observer × controller kind the lever arm (test-1) takes."""
    sets = {}
    for obs in kinds.OBSERVERS:
        for ctl in kinds.CONTROLLERS:
            over = {**({"observer.kind": obs.KIND} if obs is not kinds.OBSERVERS[0] else {}),
                    **({"controller.kind": ctl.KIND} if ctl is not kinds.CONTROLLERS[0] else {})}
            try:
                load_scenario("test-1", {**SHORT, **over})
            except ScenarioError:  # e.g. computed torque needs a URDF plant
                continue
            sets[f"{obs.KIND}+{ctl.KIND}"] = over
    return sets


KIND_SETS = _kind_sets()
if "cascade+flc" in KIND_SETS:  # also a non-default setting of a kind with a free size
    KIND_SETS["cascade-3-levels+flc"] = {**KIND_SETS["cascade+flc"], "observer.levels": 3}


def _discretizations(kind_set: str) -> list[str | None]:
    """The ESO discretizations if the set's observer kind has the key, else [None]."""
    obs = kinds.by_name(kinds.OBSERVERS, KIND_SETS[kind_set].get("observer.kind",
                                                                kinds.OBSERVERS[0].KIND))
    return list(DISCRETIZATIONS) if "discretization" in obs.Params.model_fields else [None]


KIND_DISC = [(k, d) for k in sorted(KIND_SETS) for d in _discretizations(k)]


def _scn(kind_set: str, disc: str | None = "euler", **extra: object):  # type: ignore[no-untyped-def]
    with_disc = {"observer.discretization": disc} if disc in _discretizations(kind_set) else {}
    return load_scenario("test-1", {**SHORT, **KIND_SETS[kind_set], **with_disc, **extra})


def test_kind_sets_cover_the_registry() -> None:
    """The parametrized engine tests below run every registered observer and controller kind
    that the lever arm takes (and the four sets they ran before the registry made them)."""
    assert {"linear+flc", "nonlinear+flc", "linear+pid", "nonlinear+pid"} <= set(KIND_SETS)
    for obs in kinds.OBSERVERS:
        assert any(k.startswith(f"{obs.KIND}+") for k in KIND_SETS), obs.KIND


def test_registry_is_consistent() -> None:
    for component in (kinds.PLANTS, kinds.OBSERVERS, kinds.CONTROLLERS):
        assert len({m.CODE for m in component}) == len(component)
        for module in component:
            assert module.Params().kind == module.KIND
            for name in ("design", "JIT"):
                assert hasattr(module, name), (module.__name__, name)
    for name, component in zip(("plant", "observer", "controller"),
                               (kinds.PLANTS, kinds.OBSERVERS, kinds.CONTROLLERS), strict=True):
        for i, module in enumerate(component):
            kinds.check_kind(name, module, component[:i])  # the contract, as at import


def test_switching_kind_starts_from_its_defaults() -> None:
    scn = load_scenario("test-1", {"observer.eps": 0.05, "observer.kind": "nonlinear"})
    assert scn.observer.kind == "nonlinear" and scn.observer.eps == 0.05  # a shared key kept
    assert scn.observer.alpha == [0.5, 0.25]  # the new kind's defaults
    pid = load_scenario("test-1", {"controller.k1": 5.0, "controller.kind": "pid"})
    assert pid.controller == load_scenario("test-1", {"controller.kind": "pid"}).controller
    with pytest.raises(ScenarioError, match="not apply to observer kind 'linear'.*eps"):
        load_scenario("test-1", {"observer.alpha": [0.5, 0.5]})
    with pytest.raises(ScenarioError, match="observer.kind.*'linear', 'nonlinear'"):
        load_scenario("test-1", {"observer.kind": "kalman"})
    with pytest.raises(ScenarioError, match="observer.alpha"):
        load_scenario("test-1", {"observer.kind": "nonlinear", "observer.alpha": [0.5, 1.5]})


# -- fal and the nonlinear ESO ---------------------------------------------------


@pytest.mark.parametrize("alpha", [0.25, 0.5, 0.8, 1.0])
def test_fal_definition(alpha: float) -> None:
    delta = 0.1
    for e in np.linspace(-0.5, 0.5, 101):
        expected = e / delta ** (1 - alpha) if abs(e) <= delta else abs(e) ** alpha * np.sign(e)
        assert fal(e, alpha, delta) == pytest.approx(expected, rel=1e-15, abs=1e-300)
    # continuous at the edge of the linear zone, odd, and the identity for α = 1
    assert fal(delta, alpha, delta) == pytest.approx(delta**alpha, rel=1e-14)
    assert fal(-0.3, alpha, delta) == -fal(0.3, alpha, delta)
    if alpha == 1.0:
        assert all(fal(e, 1.0, delta) == e for e in (-0.3, -1e-9, 0.0, 0.05, 2.0))


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_nonlinear_eso_with_alpha_one_is_the_linear_eso(disc: str) -> None:
    lin = load_scenario("test-2", {"observer.discretization": disc})
    nl = lin.with_overrides({"observer.kind": "nonlinear", "observer.discretization": disc,
                             "observer.alpha": [1.0, 1.0], "observer.delta": 0.02})
    a, b = run_reference(lin, prepare(lin)), run_reference(nl, prepare(nl))
    assert np.array_equal(a.table(), b.table())
    assert a.metrics == b.metrics
    (fast,) = batch.simulate_many([nl])
    assert np.array_equal(fast.table(), a.table())


def test_nonlinear_eso_changes_the_estimate() -> None:
    lin, nl = _scn("linear+flc"), _scn("nonlinear+flc")
    a, b = run_reference(lin, prepare(lin)), run_reference(nl, prepare(nl))
    assert not np.array_equal(a.z, b.z)
    assert b.metrics["rms_error"] < 0.05  # still tracks


# -- PID -------------------------------------------------------------------------


def _pid_reference(errors, kp, ki, kd, tf, limit, ts):  # type: ignore[no-untyped-def]
    """The PID written out again, independently, on a given error sequence."""
    out, integ, der, e_prev = [], 0.0, 0.0, None
    a = tf / (tf + ts)
    for e in errors:
        e_prev = e if e_prev is None else e_prev
        der = a * der + kd * (1 - a) * (e - e_prev) / ts
        u = kp * e + integ + der
        if not ((u > limit and e > 0) or (u < -limit and e < 0)):
            integ += ki * ts * e
        out.append(u)
        e_prev = e
    return np.array(out)


@pytest.mark.parametrize("limit", [10.0, 0.3])
def test_pid_law(limit: float) -> None:
    rng = np.random.default_rng(1)
    errors = np.cumsum(rng.normal(0, 0.05, 200))
    vec = (0.9, 1.5, 0.12, 0.02, limit, 0.02)
    c = np.zeros(3)
    got = np.array([pid_command(e, k, c, vec) for k, e in enumerate(errors)])
    np.testing.assert_allclose(got, _pid_reference(errors, *vec), rtol=1e-13, atol=1e-15)


def test_pid_anti_windup_bounds_the_integrator() -> None:
    c = np.zeros(3)
    vec = (1.0, 5.0, 0.0, 0.0, 0.5, 0.02)
    for k in range(500):  # a large error that saturates the command
        pid_command(2.0, k, c, vec)
    assert c[0] < 0.5  # stopped integrating once saturated (about 0.2 when it stops)
    c2 = np.zeros(3)
    for k in range(500):
        pid_command(2.0, k, c2, (1.0, 5.0, 0.0, 0.0, 1e9, 0.02))
    assert c2[0] == pytest.approx(500 * 5.0 * 0.02 * 2.0)


def test_pid_tracks_test1() -> None:
    res = run_reference(*[(s, prepare(s)) for s in [load_scenario("test-1",
                                                                  {"controller.kind": "pid"})]][0])
    assert res.metrics["rms_error"] < 0.05 and res.metrics["diverged"] == 0.0


# -- every kind through every engine -----------------------------------------------


@pytest.mark.parametrize(("kind_set", "disc"), KIND_DISC)
def test_batch_engine_is_the_reference_engine(kind_set: str, disc: str | None) -> None:
    scns = [_scn(kind_set, disc), _scn(kind_set, disc, **{"actuator.lag": 0.02,
                                                          "actuator.delay_samples": 1,
                                                          "motor.pwm_max": 1023})]
    for scn, fast in zip(scns, batch.simulate_many(scns), strict=True):
        ref = run_reference(scn, prepare(scn))
        assert np.array_equal(fast.table(), ref.table())
        assert fast.metrics == ref.metrics
    table = batch.run_metrics(scns)
    for i, scn in enumerate(scns):
        ref = run_reference(scn, prepare(scn))
        assert table.row(i) == ref.metrics


@pytest.mark.parametrize("kind_set", sorted(KIND_SETS))
def test_deployment_controller_and_replay_agree(kind_set: str) -> None:
    """The rig loop's controller over the emulated device, and replay, give simulate's numbers."""
    scn = _scn(kind_set, "current")
    ref = run_reference(scn, prepare(scn))
    assert np.array_equal(host_commands(scn), ref.u)
    rep = replay(scn, ref.t, ref.y, ref.u, scn.sample_time)
    assert np.array_equal(rep.z, ref.z)


def test_sweep_over_kinds(tmp_path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "kinds.csv"
    sets = {k: v for k, v in KIND_SETS.items()  # the kinds at their defaults
            if set(v) <= {"observer.kind", "controller.kind"}}
    observers = sorted({v.get("observer.kind", kinds.OBSERVERS[0].KIND) for v in sets.values()})
    controllers = sorted({v.get("controller.kind", kinds.CONTROLLERS[0].KIND)
                          for v in sets.values()})
    assert len(observers) * len(controllers) == len(sets)  # a full grid of valid sets
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--set", "duration=2",
                                   "--vary", f"observer.kind={','.join(observers)}",
                                   "--vary", f"controller.kind={','.join(controllers)}",
                                   "--out", str(out)])
    assert res.exit_code == 0, res.output
    rows = np.genfromtxt(out, delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert len(rows) == len(sets)
    for row in rows:
        scn = load_scenario("test-1", {"duration": 2.0, "observer.kind": row["observerkind"],
                                       "controller.kind": row["controllerkind"]})
        assert row["rms_error"] == run_reference(scn, prepare(scn)).metrics["rms_error"]


@pytest.mark.parametrize("kind_set", sorted(KIND_SETS))
def test_simulate_command_names_the_kinds(kind_set: str, tmp_path) -> None:  # type: ignore[no-untyped-def]
    sets = [a for k, v in {**SHORT, **KIND_SETS[kind_set]}.items() for a in ("--set", f"{k}={v}")]
    res = CliRunner().invoke(cli, ["simulate", "test-1", *sets, "--plot",
                                   str(tmp_path / "run.png")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "run.png").is_file()
    if "pid" in kind_set:
        assert "pid" in res.output and "controller" in res.output  # (rich may wrap the title)


def test_compile_only_some_kinds() -> None:
    """The compiled dispatch can be narrowed to the kinds a job uses, and widened again."""
    lever = kinds.kinds_of(load_scenario("test-1"))
    pid = kinds.kinds_of(load_scenario("test-1", {"controller.kind": "pid"}))
    nonlinear = kinds.kinds_of(load_scenario("test-1", {"observer.kind": "nonlinear"}))
    full = kinds.dispatch_source()
    stamp = kinds.registry_stamp()
    try:
        assert kinds.compile_only([lever, pid])
        assert kinds.compiled_selection() == "lever-arm.linear.flc+pid"
        source = kinds.dispatch_source()
        assert "flc=0" in source and "pid=" in source and "nonlinear=" not in source
        assert kinds.covers(lever) and kinds.covers(pid) and not kinds.covers(nonlinear)
        assert not kinds.compile_only([pid, lever])  # the same selection: nothing to redo
        assert kinds.registry_stamp() == stamp  # the registry itself is unchanged
    finally:
        kinds.compile_only(None)
    assert kinds.compiled_selection() == "" and kinds.dispatch_source() == full
    every = [kinds.Kinds(p, o, c) for p in kinds.PLANTS for o in kinds.OBSERVERS
             for c in kinds.CONTROLLERS]
    assert not kinds.compile_only(every)  # every compiled kind is the usual dispatch


@pytest.mark.slow
def test_batch_engine_with_some_kinds_compiled() -> None:
    """Kernels compiled for some kinds give the reference engine's bits; a point of another
    kind widens the selection instead of failing."""
    pts = [load_scenario("test-1", {**SHORT, **over})
           for over in ({}, {"controller.kind": "pid"}, {"observer.eps": 0.004})]
    other = load_scenario("test-1", {**SHORT, "observer.kind": "nonlinear"})
    try:
        kinds.compile_only([kinds.kinds_of(p) for p in pts])
        got = batch.run_metrics(pts, seeds=[0, 1], series=True).values
        assert kinds.compiled_selection() == "lever-arm.linear.flc+pid"
        (res,) = batch.simulate_many([pts[0]])
        widened = batch.run_metrics([other], seeds=[0], series=True).values
        assert kinds.compiled_selection() == ""
    finally:
        kinds.compile_only(None)
    for i, scn in enumerate(pts):
        for j, seed in enumerate((0, 1)):
            one = scn.with_overrides({"sensor.seed": seed})
            try:
                ref = run_reference(one, prepare(one))
            except Exception as exc:  # noqa: BLE001 - a diverged run's partial result
                ref = exc.result  # type: ignore[attr-defined]
            row = dict(zip(batch.METRICS, got[2 * i + j], strict=True))
            assert {k: row[k] for k in ref.metrics} == ref.metrics
    assert res.metrics == run_reference(pts[0], prepare(pts[0])).metrics
    ref = run_reference(other, prepare(other)).metrics
    assert {k: dict(zip(batch.METRICS, widened[0], strict=True))[k] for k in ref} == ref
