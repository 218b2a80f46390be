"""esoarm reproduce: the experiment plan, claims that can fail, checks, outputs and the CLI."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from esoarm.engines.metrics import LOG_ROWS
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.result import SimResult
from esoarm.studies.reproduction.run import (
    EPS_SET,
    SWEEP_EPS,
    Reproduction,
    bound_checks,
    check_claims,
    discretization_findings,
    experiment_set,
    observer_checks,
    plan_runs,
    run_id,
    run_reproduction,
    table_metrics,
)

# -- the plan ------------------------------------------------------------------


def test_plan_runs_every_scenario_once():
    plan = plan_runs()
    texts = [s.to_toml() for s in plan.values()]
    assert len(set(texts)) == len(texts)
    # paper's set (7) + zoh and current copies (2 × 7) + sweep ε not in EPS_SET (3 × 6)
    n_new_eps = len([e for e in SWEEP_EPS if e not in EPS_SET])
    assert len(plan) == 7 + 2 + 2 * 7 + 3 * n_new_eps  # + the PID baseline on both tests
    discs = {s.observer.discretization for s in plan.values()}
    assert discs == set(DISCRETIZATIONS)
    assert len(plan_runs(compare=False)) == 7 + 2


def test_overrides_reach_every_run():
    plan = plan_runs(["sensor.noise_deg=0.1"])
    assert all(s.sensor.noise_deg == 0.1 for s in plan.values())


# -- claims: synthetic runs so that each verdict can go both ways ---------------


def _fake(scn, error_rms: float, u_rms: float, rough: float = 0.0) -> SimResult:
    """A SimResult with a constant error and a control with chosen RMS and roughness."""
    n = 100
    t = np.arange(n) * scn.sample_time
    u = np.full(n, u_rms)
    if rough:
        # alternating ±rough/2 around u_rms keeps RMS(Δu) = rough
        u = u_rms + 0.5 * rough * (-1.0) ** np.arange(n)
    log = np.zeros((len(LOG_ROWS), n))
    log[LOG_ROWS.index("error")] = error_rms
    log[LOG_ROWS.index("u")] = u
    return SimResult.from_log(scn, t, log)


def _fake_rep(best_eps: float, eso_better: bool) -> Reproduction:
    scenarios = experiment_set()
    runs = {}
    for key, scn in scenarios.items():
        eps = scn.observer.eps
        err = 0.01 if eps == best_eps else 0.02 + eps
        rough = 1e-4 / eps  # smaller ε: rougher control, as in the paper
        if scn.controller.compensation == "model":
            err = 0.5 if eso_better else 0.001
        runs[key] = _fake(scn, err, err, rough)
    rep = Reproduction(scenarios=scenarios, runs=runs)
    return rep


def test_claims_reproduced_when_the_numbers_say_so():
    claims = check_claims(_fake_rep(0.09, eso_better=True))
    lowest = [c for c in claims if "0.09 gives the lowest" in c.statement]
    assert len(lowest) == 4 and all(c.reproduced for c in lowest)
    by = {c.statement: c for c in claims}
    assert by["the controller with perturbation estimation tracks better than without"].reproduced
    assert by["too small ε (0.05) makes the control noisy (more high-frequency content than "
              "ε = 0.09)"].reproduced


def test_claims_not_reproduced_when_the_numbers_say_otherwise():
    claims = check_claims(_fake_rep(0.05, eso_better=False))
    lowest = [c for c in claims if "0.09 gives the lowest" in c.statement]
    assert len(lowest) == 4 and not any(c.reproduced for c in lowest)
    by = {c.statement: c for c in claims}
    assert not by["the controller with perturbation estimation tracks better than without"
                  ].reproduced
    assert "ratio" in by["the controller with perturbation estimation tracks better than without"
                         ].evidence


# -- checks ----------------------------------------------------------------------


def test_observer_checks_match_closed_forms():
    ts = 0.02
    for check in observer_checks(EPS_SET, ts):
        eps = check.eps
        assert check.continuous_pole == pytest.approx(-1.0 / eps, rel=1e-15)
        assert check.charpoly_deviation < 1e-9
        assert check.discrete["euler"]["pole"] == pytest.approx(1.0 - ts / eps, rel=1e-12)
        for disc in ("zoh", "current"):
            assert check.discrete[disc]["pole"] == pytest.approx(math.exp(-ts / eps), rel=1e-12)
            assert check.discrete[disc]["charpoly_deviation"] < 1e-9
        assert all(d["stable"] for d in check.discrete.values())
    # Euler goes unstable once Ts/ε ≥ 2; the check says so
    (bad,) = observer_checks((0.009,), ts)
    assert not bad.discrete["euler"]["stable"] and bad.discrete["zoh"]["stable"]


@pytest.fixture(scope="module")
def paper_runs():
    return run_reproduction(compare=False)


def test_reproduction_without_comparisons_is_deterministic(paper_runs):
    again = run_reproduction(compare=False)
    assert again.rows == paper_runs.rows
    for key, res in paper_runs.runs.items():
        assert np.array_equal(res.table(), again.runs[key].table())


def test_bound_checks_follow_the_theorems(paper_runs):
    checks = bound_checks(paper_runs.runs, t_from=2.0)
    t2 = [c for c in checks if c.theorem == "Theorem 2"]
    assert len(t2) == 6  # the "model" run is not an ESO run
    for c in t2:
        res = paper_runs.runs[c.run]
        scn = res.scenario
        win = res.t >= 2.0
        # κ of eq. 17 written out independently of esoarm.observers.stability
        kappa = (res.f_true - res.z[:, 2]) + scn.controller.k1 * (res.omega - res.z[:, 1]) \
            + scn.controller.k2 * (res.theta - res.z[:, 0])
        mu = np.max(np.abs(kappa[win & (np.abs(res.u) < scn.actuator.torque_limit)]))
        assert c.driver == pytest.approx(mu, rel=1e-12)
        # k1² = 4 k2 for the defaults: the bound is exactly μ/k2
        assert c.bound[0] == pytest.approx(mu / scn.controller.k2, rel=1e-12)
        assert c.measured[0] == pytest.approx(np.max(np.abs(res.error[win])), rel=1e-15)
        assert c.holds == (c.measured[0] <= c.bound[0])
    for c in (c for c in checks if c.theorem == "Theorem 1"):
        assert c.bound == pytest.approx((c.driver * c.eps**3, 3 * c.driver * c.eps**2,
                                         3 * c.driver * c.eps))
        assert c.holds == all(m <= b for m, b in zip(c.measured, c.bound, strict=True))


def test_discretization_findings_quote_the_sweep():
    rep = run_reproduction()
    assert rep.n_simulated == len(plan_runs())
    assert set(rep.comparison) == set(DISCRETIZATIONS)
    # the euler comparison is the paper's set itself (run once)
    for key, res in rep.runs.items():
        assert rep.comparison["euler"][key] is res
    text = " ".join(discretization_findings(rep))
    for disc, by_eps in rep.sweep.items():
        best = min(by_eps, key=lambda e: by_eps[e].rms_error)
        assert f"ε = {best:g} s for {disc} ({by_eps[best].rms_error:.4f} rad)" in text
    rows = rep.sweep_rows()
    assert len(rows) == 3 * len(SWEEP_EPS)
    assert rows[0]["rms_error"] == table_metrics(rep.sweep[rows[0]["discretization"]][
        rows[0]["eps"]])["rms_error"]


# -- the command line ------------------------------------------------------------


@pytest.mark.slow
def test_cli_reproduce_writes_everything(run_cli, tmp_path):
    out = tmp_path / "res"
    res = run_cli("reproduce", "--out", str(out), "--format", "svg")
    assert res.exit_code == 0, res.stderr
    assert "report.html" in res.stdout
    for name in ("tables.csv", "tables.json", "discretizations.csv", "eps_sweep.csv",
                 "report.html", "fig4.svg", "fig5.svg", "fig6.svg", "fig7.svg",
                 "theorem2.svg", "discretizations.svg"):
        assert (out / name).is_file(), name
    assert (out / "fig4.svg").read_text()[:200].lstrip().startswith("<?xml")
    assert not list(out.glob("*.png")) and not list(out.glob(".*tmp"))
    assert len(list((out / "runs").glob("*.csv"))) == 7 + 2  # + the PID baseline runs
    data = json.loads((out / "tables.json").read_text())
    for key in ("tables", "claims", "discretizations", "eps_sweep", "observer_checks",
                "bound_checks", "findings", "scenarios", "esoarm_version"):
        assert data[key], key
    with open(out / "tables.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["run"] for r in rows} == set(experiment_set()) | {"test-1_pid", "test-2_pid"}
    assert float(rows[0]["rms_error"]) == pytest.approx(data["tables"][0]["rms_error"])
    html = (out / "report.html").read_text()
    assert '<img src="data:image/png;base64,' in html
    # both twins in the report, whichever one ran
    assert 'id="twins"' in html and "paper twin" in html and "nominal twin" in html
    assert "What stands in the way" in html


def test_cli_reproduce_bad_out_is_exit_2(run_cli, tmp_path):
    target = tmp_path / "file.txt"
    target.write_text("x")
    res = run_cli("reproduce", "--out", str(target))
    assert res.exit_code == 2
    assert "not a directory" in res.stderr and "Traceback" not in res.stderr
    res = run_cli("reproduce", "--twin", "hardware")
    assert res.exit_code == 2 and "--twin" in res.stderr
    res = run_cli("reproduce", "--format", "jpg")
    assert res.exit_code == 2


def test_run_ids():
    assert run_id("test-1", 0.09) == "test-1_eps0.09"
    assert run_id("test-2", 0.09, "model") == "test-2_eps0.09_model"


def test_cli_reproduce_diverged_run_is_exit_1_and_writes_nothing(run_cli, tmp_path, monkeypatch):
    from esoarm.engines.simulation import SimulationDiverged
    from esoarm.studies.reproduction import run as reproduce

    def diverge(scenarios, progress):
        raise SimulationDiverged("simulation of 'test-1' diverged at t = 0.1 s", None)

    monkeypatch.setattr(reproduce, "_run_all", diverge)
    out = tmp_path / "res"
    res = run_cli("reproduce", "--out", str(out))
    assert res.exit_code == 1
    assert "diverged" in res.stderr and "Traceback" not in res.stderr
    assert not out.exists() or not any(out.iterdir())


def test_pid_baseline_rows() -> None:
    """The PID baseline: a row per test, the runs of controller.kind = "pid"."""
    from esoarm.engines.simulation import simulate

    rep = run_reproduction(["duration=4"], compare=False)
    rows = [r for r in rep.rows if r["table"] == "baseline"]
    assert [r["test"] for r in rows] == ["test-1", "test-2"]
    for row in rows:
        res = simulate(row["test"], {"duration": 4.0, "controller.kind": "pid"}, warn=False)
        assert row["rms_error"] == res.metrics["rms_error"] and row["compensation"] == "pid"


def _short_reproductions(monkeypatch):  # type: ignore[no-untyped-def]
    """Every reproduction of the command at duration = 4 s without the comparisons (fast)."""
    from esoarm.studies.reproduction import run as reproduce
    from esoarm.studies.reproduction import twins as twins_report

    real = reproduce.run_reproduction

    def short(overrides=None, progress=None, compare=True):  # type: ignore[no-untyped-def]
        return real([*(overrides or []), "duration=4"], progress=progress, compare=False)

    monkeypatch.setattr(reproduce, "run_reproduction", short)
    monkeypatch.setattr(twins_report, "run_reproduction", short)


@pytest.mark.slow
@pytest.mark.parametrize("earlier", [False, True], ids=["new DIR", "DIR with earlier results"])
def test_cli_reproduce_failing_halfway_leaves_dir_as_it_was(tmp_path, monkeypatch, capsys,
                                                            earlier):
    """A full disk while writing the figures: one line, exit 1, DIR as before the command."""
    import errno

    from esoarm.cli import main
    from esoarm.studies.reproduction import outputs as reproduce_outputs

    _short_reproductions(monkeypatch)
    out = tmp_path / "res"
    if earlier:
        (out / "runs").mkdir(parents=True)
        (out / "tables.csv").write_text("earlier\n")
        (out / "runs" / "test-1_eps0.09.csv").write_text("earlier\n")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    real, calls = reproduce_outputs._write_bytes, []

    def full_disk(path, data):  # type: ignore[no-untyped-def]
        calls.append(path.name)
        if path.name == "fig5.png":  # the runs, tables and fig4 are written by then
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(path, data)

    monkeypatch.setattr(reproduce_outputs, "_write_bytes", full_disk)
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "--out", str(out)])
    assert exit_info.value.code == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert calls[-2:] == ["fig4.png", "fig5.png"] and "tables.json" in calls
    assert err[0] == (f"esoarm: failed: cannot write '{out / 'fig5.png'}': no space left on "
                      "the device (no partial file left behind)")
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
    if earlier:
        assert (out / "tables.csv").read_text() == "earlier\n"
