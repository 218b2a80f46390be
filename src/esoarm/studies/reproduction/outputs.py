"""The reproduction's outputs: tables (CSV, JSON), time series, figures, report.html.

Reads a :class:`~esoarm.studies.reproduction.data.Reproduction`; plotting and the
report are imported only here.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from esoarm._io import atomic_path, make_dir
from esoarm.studies.reproduction.data import (
    ABLATION_EPS,
    BASELINE_CONTROLLER,
    CHECK_FROM,
    EPS_SET,
    METRIC_COLUMNS,
    SWEEP_TEST,
    TABLE_COLUMNS,
    TABLE_NAMES,
    Reproduction,
    run_id,
    table_metrics,
)

__all__ = ["captions", "figure_specs", "write_outputs"]


def figure_specs(rep: Reproduction) -> list[tuple[str, str, Callable[[], Any]]]:
    """(file stem, caption, draw) for every figure of a reproduction.

    Parameters
    ----------
    rep : Reproduction
        A finished reproduction (:func:`~esoarm.studies.reproduction.run.run_reproduction`).

    Returns
    -------
    list of tuple
        (file stem, caption, draw); ``draw()`` returns a :class:`matplotlib.figure.Figure`.
    """
    from esoarm.plotting import run as plotting

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


def captions(rep: Reproduction) -> dict[str, str]:
    """Caption of every figure of :func:`figure_specs`, by file stem.

    Parameters
    ----------
    rep : Reproduction
        A finished reproduction (:func:`~esoarm.studies.reproduction.run.run_reproduction`).

    Returns
    -------
    dict of str to str
    """
    return {stem: caption for stem, caption, _ in figure_specs(rep)}


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
        Write ``report.html`` (see :mod:`esoarm.studies.reproduction.report`).
    extra_sections : sequence of (id, title, HTML)
        Further report sections (see :func:`esoarm.studies.reproduction.report.render_report`).

    Returns
    -------
    list of Path
        The files written.
    """
    from esoarm.plotting import run as plotting

    if fmt not in plotting.FIGURE_FORMATS:
        raise ValueError(f"fmt must be one of {', '.join(plotting.FIGURE_FORMATS)}, got {fmt!r}")
    out = Path(out_dir)
    make_dir(out / "runs")
    written: list[Path] = []
    for key, res in rep.runs.items():
        written.append(res.to_csv(out / "runs" / f"{key}.csv"))
    for test, res in rep.baselines.items():
        written.append(res.to_csv(out / "runs" / f"{test}_{BASELINE_CONTROLLER}.csv"))
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
        from esoarm.studies.frequency.report import frequency_section
        from esoarm.studies.reproduction.report import render_report

        # the loop in the frequency domain (margins and gains at the paper's three ε)
        extra_sections = [*extra_sections, ("frequency", "The loop in the frequency domain",
                                            frequency_section(rep))]

        html_path = out / "report.html"
        _write_text(html_path, render_report(rep, pngs, extra_sections, captions(rep)))
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
