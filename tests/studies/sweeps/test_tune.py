"""Tuning: objective expressions, bounds, the optimizer against brute force, the CLI."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from esoarm.cli import cli
from esoarm.engines import batch
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.sweeps.plots import pareto_mask
from esoarm.studies.sweeps.tune import (
    DIVERGED_PENALTY,
    Bound,
    Objective,
    describe_baseline,
    describe_nonfinite,
    parse_bound,
    tune,
)

FAST = {"maxiter": 8, "popsize": 6}


@pytest.fixture()
def base():  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {"duration": 4.0})


def test_objective_default_and_functions() -> None:
    m = {"rms_error": np.array([0.02, 0.01]), "rms_u": np.array([0.1, 0.5]),
         "max_abs_error": np.array([0.1, 0.2]), "max_abs_u": np.array([1.0, 2.0]),
         "rms_f_error": np.array([0.3, 0.4])}
    np.testing.assert_allclose(Objective("rms_error + w*rms_u", 0.5)(m), [0.07, 0.26])
    np.testing.assert_allclose(Objective("max(rms_error, 0.015) + sqrt(rms_u)**2 - -1")(m),
                               [1.12, 1.515])


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("rms_error + foo", "unknown name 'foo'"),
        ("__import__('os')", "only numbers"),
        ("rms_error.real", "only numbers"),
        ("rms_error +", "not a valid expression"),
        ("rms_error if rms_u else 1", "only numbers"),
        ("1/0", "not a finite number (gives inf)"),
        ("rms_error/0 - rms_u/0", "not a finite number (gives nan)"),
        ("log(-rms_error)", "not a finite number"),
        ("9**9**9 * rms_u", "not a finite number"),  # a float: no bignum, no hang
        ("min(rms_error)", "min() takes 2 arguments, got 1"),
        ("1" + "0" * 400 + " * rms_u", "is not a finite number"),
        ("1e999 + rms_u", "inf is not a finite number"),
        ("sqrt(rms_u, 2)", "sqrt() takes 1 argument, got 2"),
    ],
)
def test_objective_rejects(text: str, needle: str) -> None:
    with pytest.raises(ScenarioError) as exc:
        Objective(text)
    assert needle in str(exc.value) and str(exc.value).startswith("objective")


def test_bounds(base) -> None:  # type: ignore[no-untyped-def]
    eps = parse_bound("observer.eps=0.02:0.3", base)
    assert eps.log and eps.from_unit(eps.to_unit(0.09)) == pytest.approx(0.09, rel=1e-15)
    k1 = parse_bound("controller.k1=5:15", base)
    assert not k1.log and k1.search_bounds == (5.0, 15.0)
    delay = parse_bound("actuator.delay_samples=0:3", base)
    assert delay.integer and delay.from_unit(1.6) == 2
    for item, needle in [("observer.eps=0.3:0.1", "LOW < HIGH"), ("observer.eps", "KEY=LOW:HIGH"),
                         ("observer.eps=0:0.1", "observer.eps"), ("observer.epz=0.1:0.2",
                                                                   "unknown key"),
                         ("observer.discretization=0:1", "observer.discretization")]:
        with pytest.raises(ScenarioError) as exc:
            parse_bound(item, base)
        assert needle in str(exc.value), str(exc.value)


def test_tune_matches_brute_force_and_is_deterministic(base) -> None:  # type: ignore[no-untyped-def]
    bounds = [parse_bound("observer.eps=0.03:0.3", base)]
    res = tune(base, bounds, seeds=2, seed=1, **FAST)
    again = tune(base, bounds, seeds=2, seed=1, **FAST)
    assert res.best == again.best and res.best_metrics == again.best_metrics
    # brute force on a fine grid with the same seeds and objective
    grid = np.geomspace(0.03, 0.3, 60)
    pts = [base.with_overrides({"observer.eps": float(e)}) for e in grid]
    vals = batch.run_metrics(pts, seeds=[0, 1]).values.reshape(60, 2, -1).mean(axis=1)
    objective = vals[:, 0] + 1.0 * vals[:, 1]
    assert res.best_metrics["objective"] <= objective.min() * (1 + 2e-3)
    eps_best = res.best["observer.eps"]
    assert abs(np.log(eps_best / grid[np.argmin(objective)])) < np.log(1.3)
    # the reported metrics are those of a direct run at the optimum
    direct = batch.run_metrics([base.with_overrides({"observer.eps": eps_best})], seeds=[0, 1])
    assert res.best_metrics["rms_error"] == pytest.approx(direct.column("rms_error").mean(),
                                                          rel=1e-12)
    assert res.baseline["observer.eps"] == 0.09
    assert len(res.evaluations) >= FAST["popsize"]


def test_robust_samples_are_seeded_and_within_bounds(base) -> None:  # type: ignore[no-untyped-def]
    bounds = [parse_bound("controller.k2=10:40", base)]
    robust = [parse_bound("rig.inertia_scale=0.8:1.2", base, "--robust"),
              Bound("rig.coulomb_friction", 0.0, 0.1)]
    res = tune(base, bounds, robust=robust, samples=4, seed=3, maxiter=3, popsize=4)
    assert len(res.robust_samples) == 4
    for s in res.robust_samples:
        assert 0.8 <= s["rig.inertia_scale"] <= 1.2 and 0.0 <= s["rig.coulomb_friction"] <= 0.1
    other = tune(base, bounds, robust=robust, samples=4, seed=3, maxiter=3, popsize=4)
    assert other.robust_samples == res.robust_samples and other.best == res.best
    assert res.runs == len(res.evaluations) * 4 + 2 * 4  # × samples (seeds = 1), + best, baseline


def test_diverging_candidates_are_penalised(base) -> None:  # type: ignore[no-untyped-def]
    res = tune(base, [parse_bound("observer.eps=0.003:0.3", base)], seed=0, **FAST)
    bad = [e for e in res.evaluations if e["diverged_runs"]]
    assert bad and all(e["objective"] == DIVERGED_PENALTY for e in bad)
    assert res.best_metrics["diverged_runs"] == 0


def test_best_found_is_never_worse_than_the_scenario_within_bounds(base) -> None:  # type: ignore[no-untyped-def]
    # one generation of two members: without the scenario's values in the population the
    # best found scored 0.0591 against the scenario's 0.0569
    bounds = [parse_bound("observer.eps=0.02:0.3", base), parse_bound("controller.k1=1:100", base)]
    res = tune(base, bounds, maxiter=1, popsize=1)
    assert res.best_metrics["objective"] <= res.baseline["objective"]
    assert describe_baseline(res) is None


def test_scenario_better_than_bounds_is_said(base) -> None:  # type: ignore[no-untyped-def]
    bounds = [parse_bound("observer.eps=0.1:0.3", base), parse_bound("controller.k1=1:100", base)]
    res = tune(base, bounds, maxiter=1, popsize=1)
    assert res.baseline["objective"] < res.best_metrics["objective"]
    line = describe_baseline(res)
    assert line is not None and "outside the bounds" in line and "observer.eps = 0.09" in line


def test_objective_weight_must_be_a_price() -> None:
    for w in (-1.0, math.nan, math.inf):
        with pytest.raises(ScenarioError, match=r"weight .*: must be a finite number >= 0"):
            Objective("rms_error + w*rms_u", w)
    assert Objective("rms_error + w*rms_u", 0.0).weight == 0.0


def test_objective_finite_somewhere_is_accepted() -> None:
    # finite only where rms_u > 0.1 (or rms_error > rms_u): fine until a run says otherwise
    for text in ("log(rms_u - 0.1)", "log(rms_error - rms_u)", "1"):
        assert Objective(text).text == text


def test_nonfinite_objective_is_scored_as_diverged_and_counted(base) -> None:  # type: ignore[no-untyped-def]
    bounds = [parse_bound("observer.eps=0.03:0.3", base)]
    grid = [base.with_overrides({"observer.eps": e}) for e in (0.03, 0.1, 0.3)]
    rms_u = batch.run_metrics(grid, seeds=[0]).values[:, 1]
    cut = float(np.median(rms_u))  # the objective is nan below, -inf at, finite above
    objective = Objective(f"log(rms_u - {cut!r})")
    res = tune(base, bounds, objective=objective, seeds=1, seed=0, **FAST)
    ok = [e for e in res.evaluations if not e["diverged_runs"]]
    below = [e for e in ok if e["rms_u"] <= cut]
    assert 0 < res.nonfinite == len(below) < len(ok)
    assert all(e["objective"] == DIVERGED_PENALTY for e in below)
    assert res.nonfinite_example == below[0] and res.best_metrics["rms_u"] > cut
    line = describe_nonfinite(res, objective)
    assert line is not None and f"at {res.nonfinite} of {len(res.evaluations)} candidates" in line
    assert f"rms_u = {below[0]['rms_u']:.4g}" in line and "rms_error" not in line


def test_objective_finite_at_no_candidate_is_bad_input(tmp_path: Path) -> None:
    out, fig = tmp_path / "never.csv", tmp_path / "never.png"
    res = CliRunner().invoke(cli, ["tune", "test-1", "--vary", "observer.eps=0.03:0.3",
                                   "--set", "duration=2.0", "--seeds", "1", "--maxiter", "2",
                                   "--popsize", "3", "--objective", "log(rms_u - 500)",
                                   "--out", str(out), "--plot", str(fig)])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "--objective 'log(rms_u - 500)': not a finite number at any" \
        in lines[0], res.stderr
    assert "observer.eps = " in lines[0] and "rms_u = " in lines[0]
    assert not out.exists() and not fig.exists()


def test_cli_tune(tmp_path: Path) -> None:
    out, fig = tmp_path / "cands.csv", tmp_path / "pareto.png"
    res = CliRunner().invoke(cli, ["tune", "test-1", "--vary", "observer.eps=0.03:0.3",
                                   "--set", "duration=3.0", "--seeds", "1", "--maxiter", "4",
                                   "--popsize", "5", "--out", str(out), "--plot", str(fig),
                                   "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert 0.03 <= summary["best"]["observer.eps"] <= 0.3
    assert summary["objective"] == "rms_error + w*rms_u" and summary["w"] == 1.0
    assert summary["metrics"]["objective"] <= summary["baseline"]["objective"] + 1e-12
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows and {"observer.eps", "rms_error", "rms_u", "objective"} <= set(rows[0])
    assert fig.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--vary", "observer.eps=0.3:0.1"], "LOW < HIGH"),
        (["--vary", "observer.eps=0.03:0.3", "--objective", "rms_error + bogus"], "bogus"),
        (["--vary", "observer.eps=0.03:0.3", "--robust", "rig.inertia_scale=-1:1"],
         "rig.inertia_scale"),
        (["--set", "duration=1"], "--vary"),
        (["--vary", "observer.eps=0.03:0.3", "--seeds", "0"], "--seeds"),
        (["--vary", "observer.eps=0.03:0.3", "--objective", "1/0"],
         "--objective '1/0': not a finite number"),
        # a negative price of control effort rewarded it (the tune ran, best ε at the bound)
        (["--vary", "observer.eps=0.03:0.3", "--weight", "-1"],
         "--weight -1.0: must be a finite number >= 0"),
    ],
)
def test_cli_tune_bad_input(tmp_path: Path, args: list[str], needle: str) -> None:
    fig = tmp_path / "never.png"
    res = CliRunner().invoke(cli, ["tune", "test-1", *args, "--plot", str(fig)])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], res.stderr
    assert not fig.exists()


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10)), min_size=1, max_size=40))
def test_pareto_mask_is_the_non_dominated_set(points: list[tuple[float, float]]) -> None:
    a = np.array([p[0] for p in points])
    b = np.array([p[1] for p in points])
    mask = pareto_mask(a, b)
    for i in range(len(a)):
        dominated = any((a[j] <= a[i] and b[j] <= b[i]) and (a[j] < a[i] or b[j] < b[i])
                        for j in range(len(a)))
        if dominated:
            assert not mask[i]
        else:  # non-dominated: kept unless an identical point is kept instead
            assert mask[i] or any(mask[j] and a[j] == a[i] and b[j] == b[i]
                                  for j in range(len(a)))
