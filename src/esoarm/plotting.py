"""Figures: one run, and the paper's Fig. 4-7 from a set of runs.

Plotting is kept apart from the numerics: result objects forward ``.plot()``
here, and nothing in the simulation imports matplotlib.  Figures are built
with the object-oriented :class:`matplotlib.figure.Figure` (no pyplot, no
global state), so they work the same in scripts, notebooks and tests.

Conventions: one colour per ε, used in every figure (:func:`eps_color`); the
reference is drawn black and dashed; labels carry units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from matplotlib.figure import Figure

if TYPE_CHECKING:
    from esoarm.result import SimResult

__all__ = ["eps_color", "figure_ablation", "figure_estimates", "figure_tracking", "plot_run",
           "save_figure"]

_EPS_COLORS = {0.05: "#d62728", 0.09: "#1f77b4", 0.2: "#2ca02c"}
_OTHER = ["#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]
REF_STYLE = {"color": "black", "linestyle": "--", "linewidth": 1.2, "label": "reference θd"}
TRUE_STYLE = {"color": "black", "linewidth": 1.0, "alpha": 0.8}


def eps_color(eps: float) -> str:
    """The colour used for ε in every figure (fixed for the paper's 0.05, 0.09, 0.2)."""
    for key, color in _EPS_COLORS.items():
        if abs(key - eps) < 1e-12:
            return color
    return _OTHER[int(round(eps * 1e4)) % len(_OTHER)]


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save as PNG (default), PDF or SVG, chosen by the file suffix."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    return path


def _finish(fig: Figure, path: str | Path | None) -> Figure:
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_run(result: SimResult, path: str | Path | None = None) -> Figure:
    """Angle and reference, tracking error, control, and perturbation estimate of one run."""
    scn = result.scenario
    fig = Figure(figsize=(8, 9), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    color = eps_color(scn.observer.eps)
    axes[0].plot(result.t, result.theta_ref, **REF_STYLE)
    axes[0].plot(result.t, result.theta, color=color, label="angle θ")
    axes[0].set_ylabel("angle [rad]")
    axes[0].legend(loc="best")
    axes[1].plot(result.t, result.error, color=color)
    axes[1].axhline(0.0, color="0.6", linewidth=0.8)
    axes[1].set_ylabel("error θ − θd [rad]")
    axes[2].plot(result.t, result.u, color=color)
    axes[2].set_ylabel("control u [N·m]")
    axes[3].plot(result.t, result.f_true, label="true f", **TRUE_STYLE)
    axes[3].plot(result.t, result.z[:, 2], color=color, label="estimate z3")
    axes[3].set_ylabel("perturbation [rad/s²]")
    axes[3].set_xlabel("time t [s]")
    axes[3].legend(loc="best")
    fig.suptitle(
        f"{scn.name}: ε = {scn.observer.eps:g} s, {scn.observer.discretization}, "
        f"{scn.controller.compensation} compensation — RMS error {result.rms_error:.4f} rad, "
        f"RMS u {result.rms_u:.4f} N·m",
        fontsize=10,
    )
    return _finish(fig, path)


def figure_tracking(runs: Mapping[float, SimResult], title: str,
                    path: str | Path | None = None) -> Figure:
    """Paper Fig. 4 / Fig. 6: (a) angle with reference, (b) error, (c) control, one line per ε."""
    fig = Figure(figsize=(8, 8), layout="constrained")
    ax_a, ax_b, ax_c = fig.subplots(3, 1, sharex=True)
    first = next(iter(runs.values()))
    ax_a.plot(first.t, first.theta_ref, **REF_STYLE)
    for eps, res in runs.items():
        style = {"color": eps_color(eps), "linewidth": 1.1}
        ax_a.plot(res.t, res.theta, label=f"ε = {eps:g}", **style)
        ax_b.plot(res.t, res.error, **style)
        ax_c.plot(res.t, res.u, label=f"ε = {eps:g}", **style)
    ax_a.set_ylabel("(a) angle [rad]")
    ax_a.legend(loc="best", ncols=2)
    ax_b.axhline(0.0, color="0.6", linewidth=0.8)
    ax_b.set_ylabel("(b) error θ − θd [rad]")
    ax_c.set_ylabel("(c) control u [N·m]")
    ax_c.set_xlabel("time t [s]")
    fig.suptitle(title, fontsize=11)
    return _finish(fig, path)


def figure_estimates(runs: Mapping[float, SimResult], title: str,
                     path: str | Path | None = None) -> Figure:
    """Paper Fig. 5: (a) estimated vs true rate, (b) estimated perturbation z3 vs true f."""
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    ax_a, ax_b = fig.subplots(2, 1, sharex=True)
    first = next(iter(runs.values()))
    ax_a.plot(first.t, first.omega, label="true θ̇ (ε = %g run)" % first.scenario.observer.eps,
              **TRUE_STYLE)
    ax_b.plot(first.t, first.f_true, label="true f (ε = %g run)" % first.scenario.observer.eps,
              **TRUE_STYLE)
    for eps, res in runs.items():
        style = {"color": eps_color(eps), "linewidth": 1.0, "alpha": 0.9}
        ax_a.plot(res.t, res.z[:, 1], label=f"z2, ε = {eps:g}", **style)
        ax_b.plot(res.t, res.z[:, 2], label=f"z3, ε = {eps:g}", **style)
    ax_a.set_ylabel("(a) angular velocity [rad/s]")
    ax_b.set_ylabel("(b) perturbation [rad/s²]")
    ax_b.set_xlabel("time t [s]")
    for ax in (ax_a, ax_b):
        ax.legend(loc="best", ncols=2, fontsize=8)
    fig.suptitle(title, fontsize=11)
    return _finish(fig, path)


def figure_ablation(with_eso: SimResult, without: SimResult, title: str,
                    path: str | Path | None = None) -> Figure:
    """Paper Fig. 7: with (β̂ = z3) and without (β̂ = −G(ẑ1)/I0) perturbation estimation."""
    fig = Figure(figsize=(8, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    axes[0].plot(with_eso.t, with_eso.theta_ref, **REF_STYLE)
    pairs: Sequence[tuple[SimResult, str, str]] = (
        (with_eso, "with estimation (ESO)", "#1f77b4"),
        (without, "without estimation (initial model)", "#ff7f0e"),
    )
    for res, label, color in pairs:
        axes[0].plot(res.t, res.theta, color=color, label=label)
        axes[1].plot(res.t, res.error, color=color,
                     label=f"{label}: RMS {res.rms_error:.4f} rad")
        axes[2].plot(res.t, res.u, color=color, label=label)
    axes[0].set_ylabel("(a) angle [rad]")
    axes[0].legend(loc="best")
    axes[1].axhline(0.0, color="0.6", linewidth=0.8)
    axes[1].set_ylabel("(b) error θ − θd [rad]")
    axes[1].legend(loc="best", fontsize=8)
    axes[2].set_ylabel("(c) control u [N·m]")
    axes[2].set_xlabel("time t [s]")
    fig.suptitle(title, fontsize=11)
    return _finish(fig, path)

