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
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from esoarm import __version__
from esoarm._io import atomic_path, make_dir
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.result import SimResult
from esoarm.scenario import Scenario, load_scenario

__all__ = [
    "EPS_SET",
    "PAPER_TABLES",
    "Claim",
    "Reproduction",
    "experiment_set",
    "run_reproduction",
    "write_outputs",
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
ABLATION_EPS = 0.09


def run_id(test: str, eps: float, compensation: str = "eso") -> str:
    """File-name-safe identifier of one experiment, e.g. ``test-1_eps0.09``."""
    suffix = "" if compensation == "eso" else f"_{compensation}"
    return f"{test}_eps{eps:g}{suffix}"


def experiment_set(overrides: list[str] | None = None) -> dict[str, Scenario]:
    """The paper's experiments as resolved scenarios, keyed by :func:`run_id`.

    ``overrides`` (``KEY=VALUE`` strings) apply to every experiment, e.g.
    ``["observer.discretization=zoh"]`` to repeat the set with another ESO.
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
    n_simulated: int = 0

    def metric(self, test: str, eps: float, key: str, compensation: str = "eso") -> float:
        """One metric of one experiment."""
        return float(table_metrics(self.runs[run_id(test, eps, compensation)])[key])

    @property
    def sample_time(self) -> float:
        """Sample period Ts [s] of the experiment set."""
        return next(iter(self.scenarios.values())).sample_time

    def comparison_rows(self) -> list[dict[str, Any]]:
        """One row per (discretization, experiment): metrics of the comparison set."""
        rows = []
        for disc, runs in self.comparison.items():
            for key, res in runs.items():
                scn = res.scenario
                rows.append({"discretization": disc, "run": key, "test": scn.name,
                             "eps": scn.observer.eps,
                             "compensation": scn.controller.compensation, **table_metrics(res)})
        return rows

    def sweep_rows(self) -> list[dict[str, Any]]:
        """One row per (discretization, ε) of the sweep."""
        return [{"discretization": disc, "test": SWEEP_TEST, "eps": eps, **table_metrics(res)}
                for disc, runs in self.sweep.items() for eps, res in sorted(runs.items())]

    def to_json(self) -> dict[str, Any]:
        """Tables, claims, checks, version and resolved scenarios, JSON-ready."""
        return {
            "esoarm_version": __version__,
            "tables": self.rows,
            "claims": [asdict(c) for c in self.claims],
            "discretizations": self.comparison_rows(),
            "eps_sweep": self.sweep_rows(),
            "observer_checks": [asdict(c) for c in self.observer_checks],
            "bound_checks": [asdict(c) for c in self.bound_checks],
            "findings": discretization_findings(self) if self.sweep else [],
            "scenarios": {k: s.to_dict() for k, s in self.scenarios.items()},
        }


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
    """
    unique, _ = _aliases(_all_runs(overrides, compare))
    return unique


def _all_runs(overrides: list[str] | None, compare: bool) -> dict[str, Scenario]:
    extra = list(overrides or [])
    out = dict(experiment_set(extra))
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


def _fmt(values: dict[float, float]) -> str:
    return ", ".join(f"ε={e:g}: {v:.4g}" for e, v in values.items())


def check_claims(rep: Reproduction) -> list[Claim]:
    """Check the paper's qualitative claims on the twin's runs."""
    claims: list[Claim] = []
    for test, table in TABLE_NAMES.items():
        err = {e: rep.metric(test, e, "rms_error") for e in EPS_SET}
        ctl = {e: rep.metric(test, e, "rms_u") for e in EPS_SET}
        claims.append(Claim(
            f"{table} ({test})", "ε = 0.09 gives the lowest RMS tracking error of the three",
            min(err, key=err.__getitem__) == 0.09, f"RMS error [rad]: {_fmt(err)}"))
        claims.append(Claim(
            f"{table} ({test})", "ε = 0.09 gives the lowest RMS control input of the three",
            min(ctl, key=ctl.__getitem__) == 0.09, f"RMS u [N·m]: {_fmt(ctl)}"))
    big = {t: {e: rep.metric(t, e, "rms_error") for e in EPS_SET} for t in TABLE_NAMES}
    claims.append(Claim(
        "Sec. V, Fig. 4, 6",
        "too large ε (0.2) gives a large tracking error (largest of the three)",
        all(max(v, key=v.__getitem__) == 0.2 for v in big.values()),
        "; ".join(f"{t} RMS error [rad]: {_fmt(v)}" for t, v in big.items())))
    rough = {t: {e: rep.metric(t, e, "du_rms") for e in EPS_SET} for t in TABLE_NAMES}
    claims.append(Claim(
        "Sec. V, Fig. 4(c)",
        "too small ε (0.05) makes the control noisy (more high-frequency content than ε = 0.09)",
        all(v[0.05] > v[0.09] for v in rough.values()),
        "; ".join(f"{t} RMS(Δu) [N·m]: {_fmt(v)}" for t, v in rough.items())))
    rate = {e: rep.metric("test-1", e, "rate_est_rms") for e in EPS_SET}
    pert = {e: rep.metric("test-1", e, "pert_est_rms") for e in EPS_SET}
    claims.append(Claim(
        "Fig. 5 (test-1)", "ε = 0.09 estimates the rate and the perturbation most accurately",
        min(rate, key=rate.__getitem__) == 0.09 and min(pert, key=pert.__getitem__) == 0.09,
        f"RMS(z2 − θ̇) [rad/s]: {_fmt(rate)}; RMS(z3 − f) [rad/s²]: {_fmt(pert)}"))
    with_eso = rep.metric("test-2", ABLATION_EPS, "rms_error")
    without = rep.metric("test-2", ABLATION_EPS, "rms_error", "model")
    claims.append(Claim(
        "Fig. 7 (test-2, ε = 0.09)",
        "the controller with perturbation estimation tracks better than without",
        with_eso < without,
        f"RMS error [rad]: with ESO {with_eso:.4g}, without {without:.4g} "
        f"(ratio {without / with_eso:.3g})"))
    return claims


def observer_checks(eps_values: tuple[float, ...], ts: float) -> list[ObserverCheck]:
    """Theorem 1's pole placement, checked from the matrices the simulators use.

    Parameters
    ----------
    eps_values : tuple of float
        ε values [s].
    ts : float
        Sample period Ts [s].
    """
    from esoarm.studies.analysis import (
        analyze_observer,
        characteristic_polynomial,
        error_matrix,
    )

    def deviation(matrix: np.ndarray, pole: float) -> float:
        got = characteristic_polynomial(matrix)
        want = np.poly(np.full(3, pole))
        scale = np.maximum(np.abs(want), 1.0)
        return float(np.max(np.abs(got - want) / scale))

    out = []
    for eps in eps_values:
        cont = analyze_observer(eps)
        discrete: dict[str, dict[str, float | bool]] = {}
        for disc in DISCRETIZATIONS:
            a = analyze_observer(eps, ts, disc)
            pole = float(a.poles[0])
            discrete[disc] = {"pole": pole, "radius": a.spectral_radius, "stable": a.stable,
                              "damping": a.damping,
                              "charpoly_deviation": deviation(error_matrix(eps, ts, disc), pole)}
        out.append(ObserverCheck(eps, float(cont.poles[0]),
                                 deviation(error_matrix(eps), float(cont.poles[0])), ts,
                                 discrete))
    return out


def bound_checks(runs: dict[str, SimResult], t_from: float = CHECK_FROM) -> list[BoundCheck]:
    """Theorem 1 and Theorem 2 bounds against the errors measured on each ESO run.

    Theorem 1 (eq. 11-12): |z̃_i| ≤ sup|γ| · (ε³, 3ε², 3ε) for the continuous
    observer (:func:`esoarm.studies.analysis.theorem1_bound`), γ = ḟ estimated by the
    difference quotient of the true perturbation f over one sample.
    Theorem 2 (eq. 17-20): |e| ≤ μ · ‖h‖₁ (= μ/k2 for k1² ≥ 4 k2), μ = sup|κ|
    with κ from :func:`esoarm.studies.analysis.estimation_error`, over the samples
    where u is not saturated.  The theorems are stated for the continuous
    loop with exact measurements; the runs are sampled at 50 Hz with
    quantization and noise, so a violation is possible and is reported as
    such.
    """
    from esoarm.studies.analysis import estimation_error, theorem1_bound, tracking_l1_gain

    out: list[BoundCheck] = []
    for key, res in runs.items():
        scn = res.scenario
        if scn.controller.compensation != "eso":
            continue
        eps, ts = scn.observer.eps, scn.sample_time
        win = res.t >= t_from
        gamma = np.abs(np.diff(res.f_true)) / ts
        gamma_max = float(np.max(gamma[win[1:]]))
        measured = (float(np.max(np.abs(res.theta - res.z[:, 0])[win])),
                    float(np.max(np.abs(res.omega - res.z[:, 1])[win])),
                    float(np.max(np.abs(res.f_true - res.z[:, 2])[win])))
        bound = tuple(float(b) for b in theorem1_bound(eps, gamma_max))
        ratio = max(m / b for m, b in zip(measured, bound, strict=True))
        out.append(BoundCheck(
            "Theorem 1", key, eps, t_from, gamma_max, measured, bound,
            all(m <= b for m, b in zip(measured, bound, strict=True)),
            f"largest measured/bound ratio {ratio:.2g}"))
        unsat = win & (np.abs(res.u) < scn.actuator.torque_limit)
        kappa = estimation_error(res)
        mu = float(np.max(np.abs(kappa[unsat]))) if unsat.any() else float("nan")
        gain = tracking_l1_gain(scn.controller.k1, scn.controller.k2)
        e_max = float(np.max(np.abs(res.error[win])))
        n_sat = int(np.sum(win & ~unsat))
        out.append(BoundCheck(
            "Theorem 2", key, eps, t_from, mu, (e_max,), (mu * gain,), e_max <= mu * gain,
            f"‖h‖₁ = {gain:.4g} s² (1/k2 = {1 / scn.controller.k2:.4g} s²); "
            f"{n_sat} saturated samples left out; measured/bound {e_max / (mu * gain):.2g}"))
    return out


def _best(by_eps: dict[float, SimResult], key: str) -> tuple[float, float]:
    metrics = {e: table_metrics(r)[key] for e, r in by_eps.items()}
    eps = min(metrics, key=metrics.__getitem__)
    return eps, metrics[eps]


def discretization_findings(rep: Reproduction) -> list[str]:
    """What the discretization comparison means for choosing ε at the sample rate.

    Every sentence is built from the runs and the observer designs; nothing
    here is typed in by hand except the wording.
    """
    ts = rep.sample_time
    rate = 1.0 / ts
    out: list[str] = []
    poles = ", ".join(
        f"ε = {e:g} s: Euler {1 - ts / e:.3g} vs exact {np.exp(-ts / e):.3g}" for e in EPS_SET)
    out.append(
        f"At {rate:g} Hz (Ts = {ts:g} s) the paper's Euler ESO puts its error poles at "
        f"1 − Ts/ε instead of the exact image e^(−Ts/ε) of −1/ε ({poles}). The difference grows "
        f"as ε approaches Ts: Euler's poles reach 0 at ε = Ts = {ts:g} s, become negative "
        f"(oscillating estimates) below it, and leave the unit circle at ε = Ts/2 = {ts / 2:g} s; "
        f"the exact forms stay stable for every ε > 0.")
    if rep.comparison:
        base = rep.comparison.get("euler", {})
        spreads = []
        for key, res in base.items():
            if res.scenario.controller.compensation != "eso":
                continue
            vals = [rep.comparison[d][key].rms_error for d in rep.comparison]
            spreads.append((max(vals) - min(vals)) / min(vals))
        if spreads:
            out.append(
                f"At the paper's ε values (0.05, 0.09, 0.2 s) the discretization changes the RMS "
                f"tracking error by at most {100 * max(spreads):.0f} % (median "
                f"{100 * float(np.median(spreads)):.0f} %) over the six runs: at those ε the "
                f"choice hardly matters, and the paper's conclusions about ε do not hinge on it.")
    if rep.sweep:
        bests = {d: _best(r, "rms_error") for d, r in rep.sweep.items()}
        out.append(
            f"Sweeping ε on {SWEEP_TEST} ({', '.join(f'{e:g}' for e in SWEEP_EPS)} s), the lowest "
            "RMS tracking error is reached at " + "; ".join(
                f"ε = {e:g} s for {d} ({v:.4f} rad)" for d, (e, v) in bests.items()) + ".")
        small = [e for e in SWEEP_EPS if e <= ts + 1e-12]
        if small and "euler" in rep.sweep:
            e0 = max(small)
            eu = rep.sweep["euler"][e0]
            others = {d: r[e0] for d, r in rep.sweep.items() if d != "euler"}
            limit = eu.scenario.actuator.torque_limit
            sat = float(np.mean(np.abs(eu.u) >= limit - 1e-12))
            out.append(
                f"At ε = {e0:g} s (= Ts) Euler gives an RMS error of {eu.rms_error:.3g} rad and "
                f"RMS u = {eu.rms_u:.3g} N·m ({100 * sat:.0f} % of samples at the ±{limit:g} N·m "
                "limit), against " + ", ".join(
                    f"{d}: {r.rms_error:.3g} rad and {r.rms_u:.3g} N·m"
                    for d, r in others.items()) + ".")
        if "zoh" in rep.sweep and "current" in rep.sweep:
            lower = [e for e in SWEEP_EPS
                     if rep.sweep["current"][e].rms_error < rep.sweep["zoh"][e].rms_error]
            out.append(
                f"'current' (which feeds y_k to the controller one sample earlier) tracks better "
                f"than 'zoh' at {len(lower)} of {len(SWEEP_EPS)} ε values"
                + (f" (all but {', '.join(f'{e:g}' for e in SWEEP_EPS if e not in lower)} s)"
                   if 0 < len(lower) < len(SWEEP_EPS) else "") + ".")
        rough = {d: table_metrics(r[0.05])["du_rms"] for d, r in rep.sweep.items() if 0.05 in r}
        monotone = [d for d, r in rep.sweep.items()
                    if all(r[a].rms_error < r[b].rms_error
                           for a, b in zip(SWEEP_EPS, SWEEP_EPS[1:], strict=False))]
        if rough:
            trend = (f"for {', '.join(monotone)} a smaller ε gives a lower tracking error at "
                     "every step of the sweep, paid for with a noisier control"
                     if monotone else "no discretization improves monotonically with smaller ε")
            out.append(
                "The control noise RMS(Δu) at ε = 0.05 s is " + ", ".join(
                    f"{v:.3g} N·m for {d}" for d, v in rough.items())
                + f"; {trend}. Where to stop depends on how much torque ripple the motor and "
                "gearbox tolerate, which the paper does not give.")
        out.append(
            "For someone choosing ε at this sample rate: with the paper's Euler form keep ε well "
            f"above Ts = {ts:g} s (the runs above show what happens at ε ≤ Ts); with 'zoh' or "
            "'current' (--set observer.discretization=current) the observer's poles stay "
            "stable and real for any ε, and ε is then limited mainly by the measurement noise "
            "passed on to the control (lower panel of the figure).")
    return out


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
    rep.rows = _rows(rep)
    rep.claims = check_claims(rep)
    rep.observer_checks = observer_checks(EPS_SET, rep.sample_time)
    rep.bound_checks = bound_checks(rep.runs)
    return rep


TABLE_COLUMNS = ("run", "table", "test", "eps", "compensation", "discretization", "rms_error",
                 "rms_u", "max_abs_error", "du_rms", "rate_est_rms", "pert_est_rms",
                 "paper_rms_error", "paper_rms_u")
METRIC_COLUMNS = ("rms_error", "rms_u", "max_abs_error", "du_rms", "rate_est_rms",
                  "pert_est_rms")


def figure_specs(rep: Reproduction) -> list[tuple[str, str, Callable[[], Any]]]:
    """(file stem, caption, draw) for every figure of a reproduction.

    ``draw()`` returns a :class:`matplotlib.figure.Figure`.
    """
    from esoarm import plotting

    by_eps = {t: {e: rep.runs[run_id(t, e)] for e in EPS_SET} for t in TABLE_NAMES}
    disc = next(iter(rep.scenarios.values())).observer.discretization
    specs: list[tuple[str, str, Callable[[], Any]]] = [
        ("fig4", "Fig. 4 — test-1: (a) angle, (b) tracking error, (c) control for three ε",
         lambda: plotting.figure_tracking(
             by_eps["test-1"], f"Fig. 4 — test-1, ESO-based FLC for three ε ({disc} ESO, "
             "digital twin)")),
        ("fig5", "Fig. 5 — test-1: (a) rate estimate z2, (b-d) perturbation estimate z3 against "
         "the true perturbation of the same run",
         lambda: plotting.figure_estimates(
             by_eps["test-1"], "Fig. 5 — test-1, rate and perturbation estimates (digital twin)")),
        ("fig6", "Fig. 6 — test-2: (a) angle, (b) tracking error, (c) control for three ε",
         lambda: plotting.figure_tracking(
             by_eps["test-2"], f"Fig. 6 — test-2, ESO-based FLC for three ε ({disc} ESO, "
             "digital twin)")),
        ("fig7", "Fig. 7 — test-2, ε = 0.09 s: with and without perturbation estimation",
         lambda: plotting.figure_ablation(
             rep.runs[run_id("test-2", ABLATION_EPS)],
             rep.runs[run_id("test-2", ABLATION_EPS, "model")],
             "Fig. 7 — test-2, ε = 0.09 s, with and without perturbation estimation "
             "(digital twin)")),
    ]
    t2 = [c for c in rep.bound_checks if c.theorem == "Theorem 2" and c.run in {
        run_id("test-1", e) for e in EPS_SET}]
    if t2:
        bounds = {c.eps: c.bound[0] for c in t2}
        specs.append((
            "theorem2", "Theorem 2 on test-1: |e(t)| against the bound μ/k2 for each ε",
            lambda: plotting.figure_theorem2(
                by_eps["test-1"], bounds, CHECK_FROM,
                "Theorem 2 — test-1: tracking error against μ/k2 (digital twin)")))
    if rep.sweep:
        specs.append((
            "discretizations",
            f"ESO discretizations on {SWEEP_TEST}: RMS tracking error and control noise "
            "against ε",
            lambda: plotting.figure_discretizations(
                {d: {e: table_metrics(r) for e, r in runs.items()}
                 for d, runs in rep.sweep.items()},
                rep.sample_time,
                f"ESO discretizations at {1 / rep.sample_time:g} Hz — {SWEEP_TEST} "
                "(digital twin)")))
    return specs


def write_outputs(rep: Reproduction, out_dir: str | Path,
                  progress: Callable[[str], None] | None = None,
                  fmt: str = "png", report: bool = True,
                  extra_sections: Sequence[tuple[str, str, str]] = ()) -> list[Path]:
    """Write tables (CSV, JSON), one time-series CSV per run, the figures and report.html.

    Parameters
    ----------
    rep : Reproduction
    out_dir : str or Path
        Output directory (created).
    progress : callable, optional
        Called with the name of each written item.
    fmt : {"png", "pdf", "svg"}
        File format of the figures; the report always embeds PNG.
    report : bool
        Write ``report.html`` (see :mod:`esoarm.studies.report`).
    extra_sections : sequence of (id, title, HTML)
        Further report sections (see :func:`esoarm.studies.report.render_report`).

    Returns the written paths.
    """
    from esoarm import plotting

    if fmt not in plotting.FIGURE_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(plotting.FIGURE_FORMATS)}, got {fmt!r}")
    out = Path(out_dir)
    make_dir(out / "runs")
    written: list[Path] = []
    for key, res in rep.runs.items():
        written.append(res.to_csv(out / "runs" / f"{key}.csv"))
    written.append(_write_table_csv(out / "tables.csv", rep.rows, TABLE_COLUMNS))
    if rep.comparison:
        written.append(_write_table_csv(
            out / "discretizations.csv", rep.comparison_rows(),
            ("discretization", "run", "test", "eps", "compensation", *METRIC_COLUMNS)))
        written.append(_write_table_csv(
            out / "eps_sweep.csv", rep.sweep_rows(),
            ("discretization", "test", "eps", *METRIC_COLUMNS)))
    json_path = out / "tables.json"
    _write_text(json_path, json.dumps(rep.to_json(), indent=2) + "\n")
    written.append(json_path)
    if progress:
        progress("tables")
    pngs: dict[str, bytes] = {}
    for stem, _caption, draw in figure_specs(rep):
        fig = draw()
        path = out / f"{stem}.{fmt}"
        if fmt == "png":  # render once: the same PNG goes into the file and the report
            pngs[stem] = plotting.figure_bytes(fig, "png")
            _write_bytes(path, pngs[stem])
        else:
            pngs[stem] = plotting.figure_bytes(fig, "png", dpi=110)
            plotting.save_figure(fig, path)
        written.append(path)
        if progress:
            progress(path.name)
    if report:
        from esoarm.studies.report import render_report

        html_path = out / "report.html"
        _write_text(html_path, render_report(rep, pngs, extra_sections))
        written.append(html_path)
        if progress:
            progress("report.html")
    return written


def _write_text(path: Path, text: str) -> None:
    _write_bytes(path, text.encode("utf-8"))


def _write_bytes(path: Path, data: bytes) -> None:
    """Write a file that appears only once complete."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _write_table_csv(path: Path, rows: list[dict[str, Any]],
                     columns: tuple[str, ...] = TABLE_COLUMNS) -> Path:
    import csv
    import io

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row[k] is None else row[k]) for k in columns})
    _write_text(path, buf.getvalue())
    return path


__all__ += ["BoundCheck", "ObserverCheck", "bound_checks", "check_claims",
            "discretization_findings", "figure_specs", "observer_checks", "plan_runs", "run_id",
            "table_metrics"]
