"""The reproduction's data: the paper's numbers, run ids, and what a reproduction holds.

Everything that reads a reproduction -- the report (:mod:`esoarm.studies.reproduction.report`),
the outputs, the docs -- depends on this module only.  The paper's values below
are quoted from its Tables II and III (hardware); everything in a
:class:`Reproduction` is computed (:mod:`esoarm.studies.reproduction.run`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from esoarm import __version__
from esoarm.result import SimResult
from esoarm.scenario import Scenario

__all__ = [
    "ABLATION_EPS",
    "BASELINE_CONTROLLER",
    "CHECK_FROM",
    "EPS_SET",
    "PAPER_TABLES",
    "SWEEP_EPS",
    "SWEEP_TEST",
    "TABLE_NAMES",
    "BoundCheck",
    "Claim",
    "ObserverCheck",
    "Reproduction",
    "run_id",
    "table_metrics",
]

#: ε values [s] of the discretization sweep on :data:`SWEEP_TEST` (includes :data:`EPS_SET`).
SWEEP_EPS: tuple[float, ...] = (0.015, 0.02, 0.03, 0.05, 0.07, 0.09, 0.12, 0.15, 0.2)
SWEEP_TEST = "test-1"
#: Theorem checks use the samples with t ≥ CHECK_FROM [s] (after the initial transients).
CHECK_FROM = 2.0

#: The paper's free-parameter values ε [s].
EPS_SET: tuple[float, ...] = (0.05, 0.09, 0.2)

#: The paper's published RMS values (hardware), {test: {ε: (rms_error [rad], rms_u [N·m])}}.
#: Table II is test-1, Table III is test-2.  Quoted, not computed.
PAPER_TABLES: dict[str, dict[float, tuple[float, float]]] = {
    "test-1": {0.05: (0.0259, 0.8096), 0.09: (0.0182, 0.4141), 0.2: (0.1582, 0.5135)},
    "test-2": {0.05: (0.0294, 0.8563), 0.09: (0.0119, 0.2244), 0.2: (0.0751, 0.2733)},
}
TABLE_NAMES = {"test-1": "Table II", "test-2": "Table III"}
#: Baseline controller beside the paper's: ``controller.kind`` of the baseline runs.
BASELINE_CONTROLLER = "pid"
ABLATION_EPS = 0.09


def run_id(test: str, eps: float, compensation: str = "eso") -> str:
    """File-name-safe identifier of one experiment, e.g. ``test-1_eps0.09``.

    Parameters
    ----------
    test : str
        The experiment's scenario (``test-1``, ``test-2``).
    eps : float
        ε [s].
    compensation : str
        ``controller.compensation`` ("eso", or "model" for the ablation).

    Returns
    -------
    str
    """
    suffix = "" if compensation == "eso" else f"_{compensation}"
    return f"{test}_eps{eps:g}{suffix}"


#: Metrics of each run in the reproduction's tables:
#: (column name, :data:`esoarm.engines.metrics.METRICS` name).
RUN_COLUMNS: tuple[tuple[str, str], ...] = (
    ("rms_error", "rms_error"), ("rms_u", "rms_u"), ("max_abs_error", "max_abs_error"),
    ("du_rms", "rms_du"), ("rate_est_rms", "rms_rate_error"), ("pert_est_rms", "rms_f_error"),
)


def table_metrics(res: SimResult) -> dict[str, float]:
    """The metrics of a run shown in the reproduction's tables (see :data:`RUN_COLUMNS`).

    ``du_rms`` is the control roughness RMS(u_k − u_{k−1}) [N·m], the measure of
    the paper's "noisy control" claim; ``rate_est_rms`` and ``pert_est_rms`` the
    RMS errors of the rate and perturbation estimates (:mod:`esoarm.engines.metrics`).

    Parameters
    ----------
    res : SimResult
        One run.

    Returns
    -------
    dict of str to float
        The table's columns by name.
    """
    return {column: res.metrics[name] for column, name in RUN_COLUMNS}


@dataclass(frozen=True)
class Claim:
    """One qualitative claim of the paper, checked on the twin."""

    source: str
    statement: str
    reproduced: bool
    evidence: str


@dataclass(frozen=True)
class ObserverCheck:
    """Theorem 1, first part: the observer's error poles for one ε.

    ``charpoly_deviation`` is the largest relative deviation of the
    characteristic polynomial of A − βC (eq. 10), computed from the matrix,
    from (s + 1/ε)³; ``discrete`` holds, per discretization at Ts, the design
    pole (z-plane), its magnitude, whether it is stable, and the largest
    deviation of the discrete error matrix's characteristic polynomial from
    (z − pole)³.
    """

    eps: float
    continuous_pole: float
    charpoly_deviation: float
    ts: float
    discrete: dict[str, dict[str, float | bool]]


@dataclass(frozen=True)
class BoundCheck:
    """A measured steady-state error against a theorem's bound, on one run.

    Theorem 1: ``measured`` and ``bound`` are (|θ − z1| [rad], |θ̇ − z2|
    [rad/s], |f − z3| [rad/s²]) with ``driver`` = sup|γ| = sup|ḟ| [rad/s³].
    Theorem 2: one value each, |e| [rad], with ``driver`` = μ = sup|κ|
    [rad/s²].  Everything over the samples with t ≥ ``t_from``.
    """

    theorem: str
    run: str
    eps: float
    t_from: float
    driver: float
    measured: tuple[float, ...]
    bound: tuple[float, ...]
    holds: bool
    note: str = ""


@dataclass
class Reproduction:
    """Runs, tables, claims and checks of one reproduction.

    Attributes
    ----------
    scenarios, runs : dict
        The paper's experiment set (:func:`experiment_set`), keyed by :func:`run_id`.
    comparison : dict
        discretization -> run id -> SimResult: the paper's set repeated with
        every ESO discretization.
    sweep : dict
        discretization -> ε -> SimResult: :data:`SWEEP_TEST` over :data:`SWEEP_EPS`.
    sweep_scenarios : dict
        discretization -> ε -> Scenario of the sweep (the comparison set's
        scenarios are those of ``scenarios`` with another discretization).
    baselines : dict
        test -> SimResult of the baseline controller (:data:`BASELINE_CONTROLLER`,
        its default gains) on that test, everything else as in the paper's set.
    rows, claims, observer_checks, bound_checks, findings : list
        The tables, the paper's claims checked, Theorem 1 and 2 checks, and what
        the discretization comparison means for choosing ε (sentences).
    n_simulated : int
        Runs simulated for this set (identical scenarios run once).
    n_simulated_all : int
        Runs the whole command simulated, the other twins and the noise scan compared
        included (0: not counted; ``esoarm reproduce`` sets it, as its progress counts).
    """

    scenarios: dict[str, Scenario]
    runs: dict[str, SimResult]
    rows: list[dict[str, Any]] = field(default_factory=list)
    claims: list[Claim] = field(default_factory=list)
    comparison: dict[str, dict[str, SimResult]] = field(default_factory=dict)
    sweep: dict[str, dict[float, SimResult]] = field(default_factory=dict)
    sweep_scenarios: dict[str, dict[float, Scenario]] = field(default_factory=dict)
    observer_checks: list[ObserverCheck] = field(default_factory=list)
    bound_checks: list[BoundCheck] = field(default_factory=list)
    findings: list[str] = field(default_factory=list)
    baselines: dict[str, SimResult] = field(default_factory=dict)
    n_simulated: int = 0
    n_simulated_all: int = 0

    def runs_text(self) -> str:
        """"N simulated runs", with the command's total when it ran more (the twins compared).

        Returns
        -------
        str
        """
        text = f"{self.n_simulated} simulated runs"
        if self.n_simulated_all > self.n_simulated:
            text += (f" for these tables and claims ({self.n_simulated_all} in all, with the "
                     "other twins and the noise scan compared)")
        return text

    def metric(self, test: str, eps: float, key: str, compensation: str = "eso") -> float:
        """One metric of one experiment.

        Parameters
        ----------
        test : str
            The experiment's scenario.
        eps : float
            ε [s].
        key : str
            A column of :data:`RUN_COLUMNS`.
        compensation : str
            ``controller.compensation`` of the run.

        Returns
        -------
        float
            In the column's unit.
        """
        return float(table_metrics(self.runs[run_id(test, eps, compensation)])[key])

    @property
    def sample_time(self) -> float:
        """Sample period Ts [s] of the experiment set."""
        return next(iter(self.scenarios.values())).sample_time

    def comparison_rows(self) -> list[dict[str, Any]]:
        """One row per (discretization, experiment): metrics of the comparison set.

        Returns
        -------
        list of dict
            The discretization, the run, its test, ε [s], compensation and metrics.
        """
        rows = []
        for disc, runs in self.comparison.items():
            for key, res in runs.items():
                scn = res.scenario
                rows.append({"discretization": disc, "run": key, "test": scn.name,
                             "eps": scn.observer.eps,
                             "compensation": scn.controller.compensation, **table_metrics(res)})
        return rows

    def sweep_rows(self) -> list[dict[str, Any]]:
        """One row per (discretization, ε) of the sweep.

        Returns
        -------
        list of dict
            The discretization, the test, ε [s] and the metrics.
        """
        return [{"discretization": disc, "test": SWEEP_TEST, "eps": eps, **table_metrics(res)}
                for disc, runs in self.sweep.items() for eps, res in sorted(runs.items())]

    def to_json(self) -> dict[str, Any]:
        """Tables, claims, checks, version and resolved scenarios, JSON-ready.

        Returns
        -------
        dict
        """
        return {
            "esoarm_version": __version__,
            "tables": self.rows,
            "claims": [asdict(c) for c in self.claims],
            "discretizations": self.comparison_rows(),
            "eps_sweep": self.sweep_rows(),
            "observer_checks": [asdict(c) for c in self.observer_checks],
            "bound_checks": [asdict(c) for c in self.bound_checks],
            "findings": self.findings,
            "scenarios": {k: s.to_dict() for k, s in self.scenarios.items()},
        }


TABLE_COLUMNS = ("run", "table", "test", "eps", "compensation", "discretization", "rms_error",
                 "rms_u", "max_abs_error", "du_rms", "rate_est_rms", "pert_est_rms",
                 "paper_rms_error", "paper_rms_u")
METRIC_COLUMNS = ("rms_error", "rms_u", "max_abs_error", "du_rms", "rate_est_rms",
                  "pert_est_rms")
