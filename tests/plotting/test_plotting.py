"""Figures: units on every axis, legends, one colour per ε, reference distinct, formats."""

from __future__ import annotations

import matplotlib.colors as mcolors
import pytest

from esoarm.engines.simulation import simulate
from esoarm.plotting import run as plotting
from esoarm.studies.reproduction.run import EPS_SET


@pytest.fixture(scope="module")
def runs():
    """Short runs (2 s) of test-1 at the paper's three ε, and the model-compensation run."""
    out = {eps: simulate("test-1", {"observer.eps": eps, "duration": 2.0}, warn=False)
           for eps in EPS_SET}
    model = simulate("test-1", {"observer.eps": 0.09, "duration": 2.0,
                                "controller.compensation": "model"}, warn=False)
    return out, model


def _all_figures(runs):
    by_eps, model = runs
    sweep = {d: {e: {"rms_error": 0.01 * e, "du_rms": 0.1 / e} for e in EPS_SET}
             for d in ("euler", "zoh", "current")}
    return {
        "tracking": plotting.figure_tracking(by_eps, "t"),
        "estimates": plotting.figure_estimates(by_eps, "t"),
        "ablation": plotting.figure_ablation(by_eps[0.09], model, "t"),
        "theorem2": plotting.figure_theorem2(by_eps, {e: 0.1 for e in EPS_SET}, 0.5, "t"),
        "discretizations": plotting.figure_discretizations(sweep, 0.02, "t"),
        "run": plotting.plot_run(by_eps[0.05]),
    }


def test_every_axis_has_a_unit_and_every_multi_line_axis_a_legend(runs):
    for name, fig in _all_figures(runs).items():
        for ax in fig.axes:
            assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), (name, ax.get_ylabel())
            if ax.get_xlabel():
                assert "[" in ax.get_xlabel(), (name, ax.get_xlabel())
            labelled = [ln for ln in ax.get_lines() if not ln.get_label().startswith("_")]
            if len(labelled) > 1:
                assert ax.get_legend() is not None or fig.legends, (name, ax.get_ylabel())
        assert any(ax.get_xlabel() for ax in fig.axes), name


def test_one_colour_per_eps_in_every_figure(runs):
    figs = _all_figures(runs)
    colours = {plotting.eps_color(e) for e in EPS_SET}
    assert len(colours) == 3
    for eps in EPS_SET:
        want = {plotting.eps_color(eps).lower()}
        label = f"ε = {eps:g} s"
        for name in ("tracking", "estimates", "theorem2"):
            found = {mcolors.to_hex(ln.get_color()) for ax in figs[name].axes
                     for ln in ax.get_lines() if label in ln.get_label()
                     and not ln.get_label().startswith("true")}
            assert found == want, (name, eps, found)
    # the ESO run in Fig. 7 has the colour of its ε
    abl = figs["ablation"]
    found = {mcolors.to_hex(ln.get_color()) for ln in abl.axes[0].get_lines()
             if "with estimation" in ln.get_label()}
    assert found == {plotting.eps_color(0.09).lower()}


def test_reference_is_black_dashed_and_not_an_eps_colour(runs):
    figs = _all_figures(runs)
    for name in ("tracking", "ablation", "run"):
        refs = [ln for ln in figs[name].axes[0].get_lines() if ln.get_label() == "reference θd"]
        assert len(refs) == 1, name
        assert mcolors.to_hex(refs[0].get_color()) == "#000000"
        assert refs[0].get_linestyle() == "--"
    assert "#000000" not in {plotting.eps_color(e).lower() for e in EPS_SET}


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".pdf", b"%PDF"),
                                           (".svg", b"<?xml")])
def test_save_figure_formats(runs, tmp_path, suffix, magic):
    fig = plotting.figure_tracking(runs[0], "t")
    path = plotting.save_figure(fig, tmp_path / f"f{suffix}")
    assert path.read_bytes()[:len(magic)] == magic
    assert [p.name for p in tmp_path.iterdir()] == [f"f{suffix}"]  # no temporary left


def test_save_figure_rejects_other_suffixes(runs, tmp_path):
    fig = plotting.figure_tracking(runs[0], "t")
    with pytest.raises(ValueError, match=r"\.png, \.pdf, \.svg"):
        plotting.save_figure(fig, tmp_path / "f.jpg")
    assert not list(tmp_path.iterdir())


def test_result_plot_forwards_here(runs, tmp_path):
    path = tmp_path / "run.svg"
    runs[0][0.09].plot(path)
    assert path.read_text().lstrip().startswith("<?xml")


def test_figure_bytes_png(runs):
    data = plotting.figure_bytes(plotting.figure_ablation(runs[0][0.09], runs[1], "t"))
    assert data[:4] == b"\x89PNG"
