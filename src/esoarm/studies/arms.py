"""The paper's study on a URDF arm: Fig. 7 (with and without estimation) and the ε trade-off.

For an arm scenario (``plant.kind = "urdf"``) this runs

* three controllers on the same twin, noise and reference: the ESO-based
  computed torque τ = M̂(α − ẑ3), the same with the nominal n̂ fed forward, and
  computed torque on the nominal model alone τ = M̂α + n̂ (no estimation, the
  Fig. 7 baseline) -- with the per-joint ratio of RMS tracking errors;
* a sweep over ε (the paper's Table II on n joints), with the ε of the lowest
  overall RMS error;

and writes a reproduce-style page (``report.html``, self-contained), the
tables as CSV and JSON, one time-series CSV per run and the figures.  Runs go
to worker processes (the arm's dynamics come from Pinocchio, which the compiled
engine cannot call).
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from esoarm import __version__
from esoarm._io import atomic_path
from esoarm.engines.simulation import SimulationDiverged, prepare, run_reference
from esoarm.result import SimResult
from esoarm.scenario import Scenario

__all__ = ["ArmStudy", "VARIANTS", "run_arm_study", "write_arm_study"]

#: label, file stem, overrides of each compared controller.
VARIANTS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("ESO: τ = M̂(α − ẑ3)", "eso", {"controller.compensation": "eso",
                                    "controller.feedforward": False}),
    ("ESO + n̂ fed forward", "eso-feedforward", {"controller.compensation": "eso",
                                                 "controller.feedforward": True}),
    ("no estimation: τ = M̂α + n̂", "model", {"controller.compensation": "model",
                                            "controller.feedforward": False}),
)


@dataclass(frozen=True)
class ArmStudy:
    """Results of :func:`run_arm_study`.

    Attributes
    ----------
    scenario : Scenario
        The scenario as given (its ε is the one of the compared controllers).
    runs : dict label -> SimResult
        The three controllers of :data:`VARIANTS`.
    eps : ndarray (m,)
        Swept ε [s].
    sweep_error, sweep_u : ndarray (m, n)
        Per-joint RMS error [rad] and torque [N·m] of each ε (NaN: diverged).
    sweep_overall : ndarray (m,)
        RMS error over all joints [rad].
    """

    scenario: Scenario
    runs: dict[str, SimResult]
    eps: np.ndarray
    sweep_error: np.ndarray
    sweep_u: np.ndarray
    sweep_overall: np.ndarray

    @property
    def names(self) -> tuple[str, ...]:
        """Joint names, URDF order."""
        first = next(iter(self.runs.values()))
        return first.joint_names or tuple(f"joint {j + 1}" for j in range(len(first.per_joint)))

    @property
    def ratios(self) -> np.ndarray:
        """Per joint: RMS error without estimation / with the ESO (> 1: the ESO helps)."""
        eso = self.runs[VARIANTS[0][0]]
        model = self.runs[VARIANTS[2][0]]
        return np.array([m.rms_error / e.rms_error
                         for e, m in zip(eso.per_joint, model.per_joint, strict=True)])

    @property
    def best_eps(self) -> float:
        """ε [s] with the lowest overall RMS error in the sweep."""
        return float(self.eps[int(np.nanargmin(self.sweep_overall))])


def _run(scn: Scenario) -> SimResult:
    try:
        return run_reference(scn, prepare(scn))
    except SimulationDiverged as exc:
        return exc.result


def _map(scenarios: list[Scenario], workers: int | None) -> list[SimResult]:
    if workers == 1 or len(scenarios) == 1:
        return [_run(s) for s in scenarios]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(_run, scenarios))


def default_eps(eps: float | list[float]) -> np.ndarray:
    """Nine ε around the scenario's (largest) ε, geometric from ε/4 to 4ε [s].

    Parameters
    ----------
    eps : float or list of float
        The scenario's ``observer.eps`` [s] (one per joint, or one for all).

    Returns
    -------
    ndarray, shape (9,)
        The ε values [s].
    """
    center = max(eps) if isinstance(eps, list) else eps
    return np.geomspace(center / 4.0, center * 4.0, 9)


def run_arm_study(scn: Scenario, eps: Sequence[float] | None = None,
                  workers: int | None = None) -> ArmStudy:
    """Run the comparison and the ε sweep of an arm scenario (module docstring).

    Parameters
    ----------
    scn : Scenario
        An arm scenario (``plant.kind = "urdf"``).
    eps : sequence of float, optional
        ε values [s] to sweep (applied to every joint); default :func:`default_eps`.
    workers : int, optional
        Worker processes (default: all cores).

    Returns
    -------
    ArmStudy
        The controllers' runs, the model-over-ESO ratios and the ε sweep.
    """
    grid = np.asarray(eps if eps is not None else default_eps(scn.observer.eps), dtype=float)
    variants = [scn.with_overrides(over) for _, _, over in VARIANTS]
    sweep = [scn.with_overrides({"observer.eps": float(e), **VARIANTS[0][2]}) for e in grid]
    results = _map(variants + sweep, workers)
    runs = {label: res for (label, _, _), res in zip(VARIANTS, results, strict=False)}
    swept = results[len(VARIANTS):]
    n = len(results[0].per_joint)

    def per_joint(res: SimResult, key: str) -> list[float]:
        if res.diverged:
            return [float("nan")] * n
        return [float(p.metrics[key]) for p in res.per_joint]

    return ArmStudy(
        scenario=scn, runs=runs, eps=grid,
        sweep_error=np.array([per_joint(r, "rms_error") for r in swept]),
        sweep_u=np.array([per_joint(r, "rms_u") for r in swept]),
        sweep_overall=np.array([float("nan") if r.diverged else r.rms_error for r in swept]),
    )


# ---------------------------------------------------------------------------
# outputs


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _table(head: list[str], rows: list[list[str]]) -> str:
    out = ["<table><thead><tr>", *(f"<th>{h}</th>" for h in head), "</tr></thead><tbody>"]
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


_CSS = ("body{font-family:system-ui,sans-serif;max-width:70rem;margin:2rem auto;padding:0 1rem;"
        "color:#222}table{border-collapse:collapse;margin:1rem 0}td,th{border:1px solid #ccc;"
        "padding:.25rem .6rem;text-align:right}th:first-child,td:first-child{text-align:left}"
        "img{max-width:100%}.meta{color:#666}")


def summary(study: ArmStudy) -> dict[str, Any]:
    """The study's tables as JSON-ready data.

    Parameters
    ----------
    study : ArmStudy
        From :func:`run_arm_study`.

    Returns
    -------
    dict
        The scenario, the joints, each controller's metrics, the model-over-ESO error
        ratios and the ε sweep (RMS error [rad] and torque [N·m] per joint).
    """
    names = study.names
    return {
        "scenario": study.scenario.name,
        "joints": list(names),
        "controllers": {label: res.summary() for label, res in study.runs.items()},
        "ratio_model_over_eso": dict(zip(names, map(float, study.ratios), strict=True)),
        "eps_sweep": [{"eps": float(e), "rms_error": float(o),
                       "joints": [{"name": nm, "rms_error": float(er), "rms_u": float(uu)}
                                  for nm, er, uu in zip(names, ers, us, strict=True)]}
                      for e, o, ers, us in zip(study.eps, study.sweep_overall, study.sweep_error,
                                               study.sweep_u, strict=True)],
        "best_eps": study.best_eps,
    }


def render_arm_report(study: ArmStudy, pngs: dict[str, bytes]) -> str:
    """The study as one self-contained HTML page (figures embedded).

    Parameters
    ----------
    study : ArmStudy
        From :func:`run_arm_study`.
    pngs : dict of str to bytes
        The figures, PNG, by name.

    Returns
    -------
    str
        The page.
    """
    names = study.names
    scn = study.scenario
    rows = []
    for label, res in study.runs.items():
        rows.append([_e(label), *(f"{p.rms_error:.4g}" for p in res.per_joint),
                     f"{res.rms_error:.4g}", f"{res.rms_u:.4g}"])
    ctl = _table(["controller", *(f"RMS error {_e(n)} [rad]" for n in names),
                  "RMS error, all joints [rad]", "RMS torque [N·m]"], rows)
    ratio = ", ".join(f"{_e(n)} {r:.2f}×" for n, r in zip(names, study.ratios, strict=True))
    sweep_rows = [[f"{e:.4g}", *(f"{v:.4g}" for v in ers), f"{o:.4g}", *(f"{v:.4g}" for v in us)]
                  for e, o, ers, us in zip(study.eps, study.sweep_overall, study.sweep_error,
                                           study.sweep_u, strict=True)]
    sweep = _table(["ε [s]", *(f"RMS error {_e(n)} [rad]" for n in names), "all joints [rad]",
                    *(f"RMS torque {_e(n)} [N·m]" for n in names)], sweep_rows)

    def img(stem: str, caption: str) -> str:
        if stem not in pngs:
            return ""
        data = base64.b64encode(pngs[stem]).decode("ascii")
        return (f'<figure><img alt="{_e(caption)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{_e(caption)}</figcaption></figure>")

    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        f"<title>esoarm arm study: {_e(scn.name)}</title><style>{_CSS}</style></head><body>"
        f"<h1>One ESO per joint on '{_e(scn.name)}': the paper's study on an arm</h1>"
        f'<p class="meta">esoarm {_e(__version__)} · URDF {_e(Path(scn.plant.file).name)} · '
        f"{len(names)} joints ({_e(', '.join(names))}) · ε = {_e(scn.observer.eps)} s · "
        f"{scn.sensor.rate_hz:g} Hz</p>"
        "<h2>With and without perturbation estimation (Fig. 7 on an arm)</h2>" + ctl +
        f"<p>RMS tracking error without estimation over with the ESO, per joint: {ratio}.</p>"
        + img("ablation", "Tracking error and torque per joint, each controller")
        + img("run", "The ESO controller: angle, error, torque, perturbation and its estimate")
        + "<h2>ε: estimation speed against noise (Table II on an arm)</h2>" + sweep
        + f"<p>Lowest overall RMS error at ε = {study.best_eps:.4g} s.</p>"
        + img("eps", "RMS error and torque per joint against ε")
        + "<h2>Resolved scenario</h2><pre>" + _e(scn.to_toml()) + "</pre></body></html>\n"
    )


def write_arm_study(study: ArmStudy, out: str | Path, fmt: str = "png") -> list[Path]:
    """Write report.html, summary.json, the tables, time series and figures into ``out``.

    Parameters
    ----------
    study : ArmStudy
        From :func:`run_arm_study`.
    out : str or Path
        The folder (created).
    fmt : str
        The figures' format (``png``, ``pdf`` or ``svg``).

    Returns
    -------
    list of Path
        The files written.
    """
    from esoarm.plotting.arms import figure_arm_ablation, figure_arm_eps_sweep, plot_arm_run
    from esoarm.plotting.run import figure_bytes

    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for (_, stem, _), res in zip(VARIANTS, study.runs.values(), strict=True):
        written.append(res.to_csv(out / "runs" / f"{stem}.csv"))
    figures = {
        "ablation": figure_arm_ablation(study.runs, f"{study.scenario.name}: with and without "
                                        "perturbation estimation"),
        "run": plot_arm_run(study.runs[VARIANTS[0][0]]),
        "eps": figure_arm_eps_sweep(list(study.eps), study.sweep_error, study.sweep_u, study.names,
                                    f"{study.scenario.name}: the ε trade-off"),
    }
    pngs = {stem: figure_bytes(fig, "png") for stem, fig in figures.items()}
    for stem, fig in figures.items():
        path = out / f"{stem}.{fmt}"
        with atomic_path(path) as tmp:
            tmp.write_bytes(pngs[stem] if fmt == "png" else figure_bytes(fig, fmt))
        written.append(path)
    data = summary(study)
    for name, text in (("summary.json", json.dumps(data, indent=2)),
                       ("report.html", render_arm_report(study, pngs))):
        with atomic_path(out / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
        written.append(out / name)
    return written
