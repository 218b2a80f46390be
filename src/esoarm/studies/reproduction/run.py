"""The paper's experiment set on the digital twin, beside the paper's numbers.

The experiment set (the scenario format): test-1 and test-2 at ε ∈ {0.05, 0.09, 0.2}
(Tables II and III, Fig. 4-6), plus the Fig. 7 ablation: test-2 at ε = 0.09
with ``compensation = "model"`` against ``"eso"``.  The paper's values below
are quoted from its Tables II and III (hardware); everything else is computed.
Each qualitative claim of the paper is checked on the twin's numbers and
marked reproduced or not, with the numbers behind it.

Besides the paper's set, a reproduction repeats the set with every ESO
discretization (the sampled-data loop, step 5: the paper's "euler" against the exact "zoh"
and "current" forms), sweeps ε on test-1 for each discretization, and checks
Theorem 1 (observer poles, estimation-error bound) and Theorem 2 (tracking
bound μ/k2) on the runs.  All runs go through :func:`_run_all`, the single
place that simulates; identical scenarios are run once.

The reproduction is split in four modules: this one plans and runs it
(:func:`plan_runs`, :func:`run_reproduction`); :mod:`esoarm.studies.reproduction.data`
holds its data (the paper's numbers, :class:`Reproduction`);
:mod:`esoarm.studies.reproduction.checks` checks claims and theorems; and
:mod:`esoarm.studies.reproduction.outputs` writes tables, figures and the report.
The names of all four are available here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.result import SimResult
from esoarm.scenario import Scenario, load_scenario
from esoarm.studies.reproduction.checks import (
    bound_checks,
    check_claims,
    discretization_findings,
    observer_checks,
)
from esoarm.studies.reproduction.data import (
    ABLATION_EPS,
    BASELINE_CONTROLLER,
    CHECK_FROM,
    EPS_SET,
    METRIC_COLUMNS,
    PAPER_TABLES,
    SWEEP_EPS,
    SWEEP_TEST,
    TABLE_COLUMNS,
    TABLE_NAMES,
    BoundCheck,
    Claim,
    ObserverCheck,
    Reproduction,
    run_id,
    table_metrics,
)
from esoarm.studies.reproduction.outputs import figure_specs, write_outputs

__all__ = [
    "ABLATION_EPS",
    "BASELINE_CONTROLLER",
    "CHECK_FROM",
    "EPS_SET",
    "METRIC_COLUMNS",
    "PAPER_TABLES",
    "SWEEP_EPS",
    "SWEEP_TEST",
    "TABLE_COLUMNS",
    "TABLE_NAMES",
    "BoundCheck",
    "Claim",
    "ObserverCheck",
    "Reproduction",
    "baseline_set",
    "bound_checks",
    "check_claims",
    "discretization_findings",
    "experiment_set",
    "figure_specs",
    "observer_checks",
    "plan_runs",
    "run_id",
    "run_reproduction",
    "table_metrics",
    "write_outputs",
]


def experiment_set(overrides: list[str] | None = None) -> dict[str, Scenario]:
    """The paper's experiments as resolved scenarios, keyed by :func:`run_id`.

    ``overrides`` (``KEY=VALUE`` strings) apply to every experiment, e.g.
    ``["observer.discretization=zoh"]`` to repeat the set with another ESO.

    Parameters
    ----------
    overrides : list of str, optional
        ``KEY=VALUE`` applied to every experiment.

    Returns
    -------
    dict of str to Scenario
    """
    out: dict[str, Scenario] = {}
    extra = list(overrides or [])
    for test in PAPER_TABLES:
        for eps in EPS_SET:
            out[run_id(test, eps)] = load_scenario(test, extra + [f"observer.eps={eps!r}"])
    out[run_id("test-2", ABLATION_EPS, "model")] = load_scenario(
        "test-2", extra + [f"observer.eps={ABLATION_EPS!r}", "controller.compensation=model"]
    )
    return out


def baseline_set(overrides: list[str] | None = None) -> dict[str, Scenario]:
    """The baseline controller's runs: each test with ``controller.kind`` = the baseline.

    Keyed ``baseline/<test>``; the controller table takes the baseline kind's
    defaults (for the PID: gains tuned on test-1).

    Parameters
    ----------
    overrides : list of str, optional
        ``KEY=VALUE`` applied to every run.

    Returns
    -------
    dict of str to Scenario
    """
    extra = list(overrides or [])
    return {f"baseline/{test}": load_scenario(
        test, extra + [f"controller.kind={BASELINE_CONTROLLER}"]) for test in PAPER_TABLES}


def _run_all(scenarios: dict[str, Scenario],
             progress: Callable[[str], None] | None) -> dict[str, SimResult]:
    """Simulate every scenario (the single place a reproduction runs simulations).

    Runs go through the compiled batch engine (:func:`esoarm.engines.batch.simulate_many`,
    the same numbers as the reference engine) a few at a time, so progress is
    reported as they finish; a diverged run raises
    :class:`~esoarm.engines.simulation.SimulationDiverged` as before.
    """
    from esoarm.engines.batch import simulate_many

    keys = list(scenarios)
    runs: dict[str, SimResult] = {}
    step = 8
    for start in range(0, len(keys), step):
        part = keys[start : start + step]
        for key, result in zip(part, simulate_many([scenarios[k] for k in part]), strict=True):
            runs[key] = result
            if progress is not None:
                progress(key)
    return runs


def plan_runs(overrides: list[str] | None = None, compare: bool = True
              ) -> dict[str, Scenario]:
    """Every run of a reproduction, keyed; identical scenarios appear once.

    Keys: the :func:`run_id` of the paper's set; ``"<disc>/<run id>"`` for the
    discretization comparison; ``"sweep/<disc>/<test>_eps<ε>"`` for the sweep.
    A run that repeats an earlier scenario exactly is left out (see
    :func:`_aliases`).

    Parameters
    ----------
    overrides : list of str, optional
        ``KEY=VALUE`` applied to every run.
    compare : bool
        Include the discretization comparison and the ε sweep.

    Returns
    -------
    dict of str to Scenario
    """
    unique, _ = _aliases(_all_runs(overrides, compare))
    return unique


def _all_runs(overrides: list[str] | None, compare: bool) -> dict[str, Scenario]:
    extra = list(overrides or [])
    out = dict(experiment_set(extra))
    out.update(baseline_set(extra))
    if not compare:
        return out
    for disc in DISCRETIZATIONS:
        for key, scn in experiment_set(extra + [f"observer.discretization={disc}"]).items():
            out[f"{disc}/{key}"] = scn
        for eps in SWEEP_EPS:
            out[f"sweep/{disc}/{SWEEP_TEST}_eps{eps:g}"] = load_scenario(
                SWEEP_TEST, extra + [f"observer.discretization={disc}", f"observer.eps={eps!r}"])
    return out


def _aliases(scenarios: dict[str, Scenario]) -> tuple[dict[str, Scenario], dict[str, str]]:
    """Unique scenarios (first key wins) and, for every key, the key that is run."""
    seen: dict[str, str] = {}
    unique: dict[str, Scenario] = {}
    alias: dict[str, str] = {}
    for key, scn in scenarios.items():
        text = scn.to_toml()
        if text not in seen:
            seen[text] = key
            unique[key] = scn
        alias[key] = seen[text]
    return unique, alias


def _rows(rep: Reproduction) -> list[dict[str, Any]]:
    rows = []
    for key, res in rep.runs.items():
        scn = rep.scenarios[key]
        test = scn.name
        eps = scn.observer.eps
        comp = scn.controller.compensation
        paper = PAPER_TABLES.get(test, {}).get(eps) if comp == "eso" else None
        rows.append(
            {
                "run": key,
                "table": TABLE_NAMES.get(test, "") if comp == "eso" else "Fig. 7",
                "test": test,
                "eps": eps,
                "compensation": comp,
                "discretization": scn.observer.discretization,
                **table_metrics(res),
                "paper_rms_error": paper[0] if paper else None,
                "paper_rms_u": paper[1] if paper else None,
            }
        )
    return rows


def _baseline_rows(rep: Reproduction) -> list[dict[str, Any]]:
    return [{"run": f"{test}_{BASELINE_CONTROLLER}", "table": "baseline", "test": test,
             "eps": None, "compensation": BASELINE_CONTROLLER,
             "discretization": None, **table_metrics(res),
             "paper_rms_error": None, "paper_rms_u": None}
            for test, res in rep.baselines.items()]


def run_reproduction(
    overrides: list[str] | None = None,
    progress: Callable[[str], None] | None = None,
    compare: bool = True,
) -> Reproduction:
    """Run the experiment set (and the comparisons) and check claims and theorems.

    Parameters
    ----------
    overrides : list of str, optional
        ``KEY=VALUE`` applied to every experiment.
    progress : callable, optional
        Called with the run key after each simulated run.
    compare : bool
        Also run the discretization comparison and the ε sweep.

    Returns
    -------
    Reproduction
        The runs, the tables, the claims and the theorems' checks.
    """
    planned = _all_runs(overrides, compare)
    unique, alias = _aliases(planned)
    simulated = _run_all(unique, progress)
    runs = {key: simulated[alias[key]] for key in planned}
    scenarios = experiment_set(overrides)
    rep = Reproduction(scenarios=scenarios, runs={k: runs[k] for k in scenarios},
                       n_simulated=len(simulated))
    if compare:
        for disc in DISCRETIZATIONS:
            rep.comparison[disc] = {k: runs[f"{disc}/{k}"] for k in scenarios}
            rep.sweep[disc] = {e: runs[f"sweep/{disc}/{SWEEP_TEST}_eps{e:g}"] for e in SWEEP_EPS}
            rep.sweep_scenarios[disc] = {e: planned[f"sweep/{disc}/{SWEEP_TEST}_eps{e:g}"]
                                         for e in SWEEP_EPS}
    rep.baselines = {key.split("/", 1)[1]: runs[key] for key in baseline_set(overrides)}
    rep.rows = _rows(rep) + _baseline_rows(rep)
    rep.claims = check_claims(rep)
    rep.observer_checks = observer_checks(EPS_SET, rep.sample_time)
    rep.bound_checks = bound_checks(rep.runs)
    rep.findings = discretization_findings(rep) if rep.sweep else []
    return rep
