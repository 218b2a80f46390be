"""Figures: one run, the paper's Fig. 4-7 from a set of runs, and the report's extras.

Plotting is kept apart from the numerics: result objects forward ``.plot()``
here, and nothing in the simulation imports matplotlib.  Figures are built
with the object-oriented :class:`matplotlib.figure.Figure` (no pyplot, no
global state), so they work the same in scripts, notebooks and tests.

Conventions, the same in every figure:

- one colour per ε (:func:`eps_color`; the paper's 0.05, 0.09 and 0.2 s get
  fixed colours from the colour-blind-safe Okabe-Ito palette);
- the reference θd is drawn black and dashed, true (simulated) signals thin
  and black or grey, estimates in the colour of their ε;
- every axis label carries its unit; every figure with more than one line has
  a legend;
- noisier lines (smaller ε) are drawn underneath smoother ones so that no
  line hides another;
- files are PNG by default; PDF or SVG when the path ends in ``.pdf`` or
  ``.svg`` (:func:`save_figure`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from esoarm.plotting.style import (
    DISCRETIZATION_STYLE,
    FIGURE_FORMATS,
    NO_ESTIMATION_COLOR,
    REF_STYLE,
    TRUE_STYLE,
    eps_color,
    figure_bytes,
    finish_figure,
    save_figure,
)

if TYPE_CHECKING:
    from esoarm.result import SimResult

__all__ = [
    "DISCRETIZATION_STYLE",
    "FIGURE_FORMATS",
    "eps_color",
    "figure_replay",
    "figure_ablation",
    "figure_discretizations",
    "figure_estimates",
    "figure_theorem2",
    "figure_tracking",
    "figure_bytes",
    "plot_run",
    "finish_figure",
    "save_figure",
]

def _eps_label(eps: float) -> str:
    return f"ε = {eps:g} s"


def _by_noise(runs: Mapping[float, SimResult]) -> list[tuple[float, SimResult]]:
    """Runs ordered smallest ε first: the noisiest lines are drawn underneath."""
    return sorted(runs.items(), key=lambda item: item[0])


def plot_run(result: SimResult, path: str | Path | None = None) -> Figure:
    """Angle and reference, tracking error, control, and perturbation estimate of one run.

    An arm's run (joint names known) gets one column of panels per joint
    (:func:`esoarm.plotting.arms.plot_arm_run`).
    """
    if result.joint_names:
        from esoarm.plotting.arms import plot_arm_run

        return plot_arm_run(result, path)
    from esoarm.kinds import kind_labels, units

    scn = result.scenario
    u = units(scn)
    fig = Figure(figsize=(8, 9), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    eps = getattr(scn.observer, "eps", None)  # an observer kind may have no ε
    color = eps_color(eps) if isinstance(eps, float) else "C0"
    axes[0].plot(result.t, result.theta_ref, **REF_STYLE)
    axes[0].plot(result.t, result.theta, color=color, label=f"{u.position_word} θ")
    axes[0].set_ylabel(f"{u.position_word} [{u.position}]")
    axes[0].legend(loc="best")
    axes[1].plot(result.t, result.error, color=color, label="θ − θd")
    axes[1].axhline(0.0, color="0.6", linewidth=0.8)
    axes[1].set_ylabel(f"tracking error [{u.position}]")
    axes[2].plot(result.t, result.u, color=color, label="u")
    axes[2].set_ylabel(f"control u [{u.force}]")
    axes[3].plot(result.t, result.f_true, label="true f", **TRUE_STYLE)
    axes[3].plot(result.t, result.z[:, 2], color=color, label="estimate z3")
    axes[3].set_ylabel(f"perturbation [{u.acceleration}]")
    axes[3].set_xlabel("time t [s]")
    axes[3].legend(loc="best")
    for ax in axes:
        ax.grid(alpha=0.3)
    obs_text, ctl_text = kind_labels(scn)
    eps = getattr(scn.observer, "eps", None)
    fig.suptitle(
        f"{scn.name}: " + (f"ε = {eps:g} s, " if eps is not None else "")
        + obs_text
        + f", {ctl_text}\nRMS error {result.rms_error:.4g} {u.position}, "
        f"RMS u {result.rms_u:.4g} {u.force}",
        fontsize=10,
    )
    return finish_figure(fig, path)


def figure_tracking(runs: Mapping[float, SimResult], title: str,
                    path: str | Path | None = None) -> Figure:
    """Paper Fig. 4 / Fig. 6: (a) angle with reference, (b) error, (c) control, one line per ε.

    Parameters
    ----------
    runs : mapping ε [s] -> SimResult
    title : str
    path : str or Path, optional
        Save there (format from the suffix).
    """
    fig = Figure(figsize=(8, 8), layout="constrained")
    ax_a, ax_b, ax_c = fig.subplots(3, 1, sharex=True)
    first = next(iter(runs.values()))
    ax_a.plot(first.t, first.theta_ref, **REF_STYLE)
    for eps, res in _by_noise(runs):
        style = {"color": eps_color(eps), "linewidth": 1.1}
        ax_a.plot(res.t, res.theta, label=_eps_label(eps), **style)
        ax_b.plot(res.t, res.error, label=f"{_eps_label(eps)}: RMS {res.rms_error:.4f} rad",
                  **style)
        ax_c.plot(res.t, res.u, label=f"{_eps_label(eps)}: RMS {res.rms_u:.4f} N·m", **style)
    ax_a.set_ylabel("(a) angle θ [rad]")
    ax_a.legend(loc="best", ncols=2, fontsize=9)
    ax_b.axhline(0.0, color="0.6", linewidth=0.8)
    ax_b.set_ylabel("(b) error θ − θd [rad]")
    ax_b.legend(loc="best", fontsize=8)
    ax_c.set_ylabel("(c) control u [N·m]")
    ax_c.set_xlabel("time t [s]")
    ax_c.legend(loc="best", fontsize=8)
    for ax in (ax_a, ax_b, ax_c):
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=11)
    return finish_figure(fig, path)


def figure_estimates(runs: Mapping[float, SimResult], title: str,
                     path: str | Path | None = None) -> Figure:
    """Paper Fig. 5: (a) estimated vs true rate, then one panel per ε of z3 vs the true f.

    The true perturbation f = θ̈ − b0·u differs between runs (it contains the
    inertia error times the run's own control), so each estimate z3 is drawn
    over the true f of its own run.
    """
    ordered = _by_noise(runs)
    fig = Figure(figsize=(8, 3.0 + 2.0 * len(ordered)), layout="constrained")
    axes = fig.subplots(1 + len(ordered), 1, sharex=True)
    ax_a = axes[0]
    ref_eps, ref_run = min(ordered, key=lambda item: abs(item[0] - 0.09))
    ax_a.plot(ref_run.t, ref_run.omega, label=f"true θ̇ ({_eps_label(ref_eps)} run)",
              zorder=4, **TRUE_STYLE)
    for eps, res in ordered:
        rms = float(np.sqrt(np.mean((res.z[:, 1] - res.omega) ** 2)))
        ax_a.plot(res.t, res.z[:, 1], color=eps_color(eps), linewidth=1.0,
                  label=f"z2, {_eps_label(eps)}: RMS(z2 − θ̇) {rms:.3f} rad/s")
    ax_a.set_ylabel("(a) rate [rad/s]")
    ax_a.legend(loc="best", fontsize=8)
    for i, (ax, (eps, res)) in enumerate(zip(axes[1:], ordered, strict=True)):
        rms = float(np.sqrt(np.mean((res.z[:, 2] - res.f_true) ** 2)))
        ax.plot(res.t, res.f_true, label="true f of this run", **TRUE_STYLE)
        ax.plot(res.t, res.z[:, 2], color=eps_color(eps), linewidth=1.2,
                label=f"z3, {_eps_label(eps)}: RMS(z3 − f) {rms:.3f} rad/s²")
        ax.set_ylabel(f"({chr(ord('b') + i)}) perturbation [rad/s²]")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=11)
    return finish_figure(fig, path)


def figure_ablation(with_eso: SimResult, without: SimResult, title: str,
                    path: str | Path | None = None) -> Figure:
    """Paper Fig. 7: with (β̂ = z3) and without (β̂ = −G(ẑ1)/I0) perturbation estimation."""
    fig = Figure(figsize=(8, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    axes[0].plot(with_eso.t, with_eso.theta_ref, **REF_STYLE)
    pairs = (
        (without, "without estimation (initial model)", NO_ESTIMATION_COLOR),
        (with_eso, f"with estimation (ESO, ε = {with_eso.scenario.observer.eps:g} s)",
         eps_color(with_eso.scenario.observer.eps)),
    )
    for res, label, color in pairs:
        axes[0].plot(res.t, res.theta, color=color, label=label)
        axes[1].plot(res.t, res.error, color=color,
                     label=f"{label}: RMS {res.rms_error:.4f} rad")
        axes[2].plot(res.t, res.u, color=color, linewidth=1.0,
                     label=f"{label}: RMS {res.rms_u:.4f} N·m")
    axes[0].set_ylabel("(a) angle θ [rad]")
    axes[0].legend(loc="best", fontsize=9)
    axes[1].axhline(0.0, color="0.6", linewidth=0.8)
    axes[1].set_ylabel("(b) error θ − θd [rad]")
    axes[1].legend(loc="best", fontsize=8)
    axes[2].set_ylabel("(c) control u [N·m]")
    axes[2].set_xlabel("time t [s]")
    axes[2].legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=11)
    return finish_figure(fig, path)


def figure_discretizations(sweep: Mapping[str, Mapping[float, Mapping[str, float]]],
                           ts: float, title: str, path: str | Path | None = None) -> Figure:
    """RMS tracking error and control roughness against ε, one line per ESO discretization.

    Parameters
    ----------
    sweep : mapping discretization -> ε [s] -> metrics
        Metrics with ``rms_error`` [rad] and ``du_rms`` [N·m] (see
        :func:`esoarm.studies.reproduction.run.table_metrics`).
    ts : float
        Sample period Ts [s]; the Euler limits ε = Ts (poles at 0, below it
        negative) and ε = Ts/2 (unstable below) are marked.
    """
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    ax_e, ax_d = fig.subplots(2, 1, sharex=True)
    all_eps = [e for by_eps in sweep.values() for e in by_eps]
    lo = min(min(all_eps), ts) / 1.3
    hi = max(all_eps) * 1.3
    for disc, by_eps in sweep.items():
        eps = np.array(sorted(by_eps))
        style = dict(DISCRETIZATION_STYLE.get(disc, {"label": disc}))
        style.setdefault("label", disc)
        err = np.array([by_eps[e]["rms_error"] for e in eps])
        rough = np.array([by_eps[e]["du_rms"] for e in eps])
        ax_e.plot(eps, err, markersize=5, **style)  # type: ignore[arg-type]
        style["label"] = f"_{style['label']}"  # one legend (upper panel) for both panels
        ax_d.plot(eps, rough, markersize=5, **style)  # type: ignore[arg-type]
    for ax in (ax_e, ax_d):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(lo, hi)
        ticks = sorted(set(all_eps))
        ax.set_xticks(ticks, [f"{e:g}" for e in ticks])
        ax.set_xticks([], minor=True)
        ax.axvline(ts, color="0.4", linestyle="-.", linewidth=1.0)
        ax.axvspan(lo, ts, color="0.85", alpha=0.5, zorder=0)
        ax.grid(alpha=0.3, which="both")
    ax_e.text(ts * 1.03, 0.97, f" ε = Ts = {ts:g} s: Euler poles at 0;\n below: Euler poles < 0",
              transform=ax_e.get_xaxis_transform(), va="top", fontsize=8)
    ax_e.set_ylabel("RMS tracking error [rad]")
    ax_d.set_ylabel("control noise RMS(Δu) [N·m]\nΔu = uₖ − uₖ₋₁")
    ax_d.set_xlabel("ESO free parameter ε [s] (log scale)")
    ax_d.tick_params(axis="x", labelrotation=0, labelsize=8)
    ax_e.legend(loc="best", fontsize=9)
    fig.suptitle(title, fontsize=11)
    return finish_figure(fig, path)


def figure_theorem2(runs: Mapping[float, SimResult], bounds: Mapping[float, float],
                    t_from: float, title: str, path: str | Path | None = None) -> Figure:
    """|e(t)| against the Theorem 2 bound μ‖h‖₁ (= μ/k2 for k1² ≥ 4 k2), one colour per ε.

    Parameters
    ----------
    runs : mapping ε [s] -> SimResult
    bounds : mapping ε [s] -> bound on |e| [rad]
    t_from : float
        Start of the window the bound was evaluated on [s] (shaded before).
    """
    fig = Figure(figsize=(8, 4.8), layout="constrained")
    ax = fig.subplots()
    top = 0.0
    for eps, res in _by_noise(runs):
        color = eps_color(eps)
        ax.plot(res.t, np.abs(res.error), color=color, linewidth=1.0,
                label=f"|e|, {_eps_label(eps)}")
        ax.axhline(bounds[eps], color=color, linestyle="--", linewidth=1.4,
                   label=f"bound, {_eps_label(eps)}: {bounds[eps]:.3f} rad")
        top = max(top, bounds[eps], float(np.max(np.abs(res.error))))
    ax.axvspan(0.0, t_from, color="0.85", alpha=0.6, zorder=0, label="transient (not checked)")
    ax.set_ylim(0.0, 1.08 * top)
    ax.set_xlim(0.0, max(float(r.t[-1]) for r in runs.values()))
    ax.set_ylabel("|tracking error e| [rad]")
    ax.set_xlabel("time t [s]")
    ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncols=4, fontsize=8)
    fig.suptitle(title, fontsize=11)
    return finish_figure(fig, path)


def figure_replay(result: Any, path: str | Path | None = None) -> Figure:
    """An offline ESO replay: measured angle with ẑ1, rate ẑ2, perturbation ẑ3 and u.

    ``result`` is an :class:`esoarm.hardware.replay.ReplayResult` (arrays
    ``t``, ``theta``, ``u``, ``z``; its ``scenario`` names the units: m and N on a
    prismatic axis).
    """
    from esoarm.kinds import units

    u = units(getattr(result, "scenario", None))
    fig = Figure(figsize=(8, 8), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    axes[0].plot(result.t, result.theta, ".", ms=2, color="0.4", label="θ measured")
    axes[0].plot(result.t, result.z[:, 0], color="#0072B2", label="ẑ1")
    axes[0].set_ylabel(f"{u.position_word} [{u.position}]")
    axes[0].legend(loc="best")
    axes[1].plot(result.t, result.z[:, 1], color="#0072B2")
    axes[1].set_ylabel(f"ẑ2 rate [{u.velocity}]")
    axes[2].plot(result.t, result.z[:, 2], color="#0072B2")
    axes[2].set_ylabel(f"ẑ3 perturbation [{u.acceleration}]")
    axes[3].step(result.t, result.u, where="post", color="#D55E00")
    axes[3].set_ylabel(f"u [{u.force}]")
    axes[3].set_xlabel("time t [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return finish_figure(fig, path)
