"""Figures of URDF-arm runs: one column of panels per joint.

Plotting only: the numbers come from :class:`~esoarm.result.SimResult` (its
``joints``) and from :mod:`esoarm.studies.arms`.  Object-oriented
Matplotlib (no global backend switch), saved atomically by
:func:`esoarm.plotting.run.finish_figure`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from esoarm.plotting.style import REF_STYLE, TRUE_STYLE, finish_figure

if TYPE_CHECKING:
    from esoarm.result import SimResult

__all__ = ["figure_arm_ablation", "figure_arm_eps_sweep", "figure_arm_replay", "plot_arm_run"]

_COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e")


def _names(result: SimResult) -> list[str]:
    parts = result.per_joint
    names = list(result.joint_names) or [f"joint {j + 1}" for j in range(len(parts))]
    return names[:len(parts)]


def _width(n: int) -> float:
    return min(3.6 * n + 1.0, 24.0)


def plot_arm_run(result: SimResult, path: str | Path | None = None) -> Figure:
    """Angle with reference, tracking error, torque and perturbation estimate, per joint."""
    parts = result.per_joint
    names = _names(result)
    fig = Figure(figsize=(_width(len(parts)), 9), layout="constrained")
    axes = np.atleast_2d(fig.subplots(4, len(parts), sharex=True, squeeze=False))
    for j, (part, name) in enumerate(zip(parts, names, strict=True)):
        col = axes[:, j]
        col[0].plot(part.t, part.theta_ref, **REF_STYLE)
        col[0].plot(part.t, part.theta, color=_COLORS[0], label="q")
        col[0].set_title(f"{name}: RMS error {part.rms_error:.4f} rad", fontsize=10)
        col[1].plot(part.t, part.error, color=_COLORS[0])
        col[1].axhline(0.0, color="0.6", linewidth=0.8)
        col[2].plot(part.t, part.u, color=_COLORS[0])
        col[3].plot(part.t, part.f_true, label="true f", **TRUE_STYLE)
        col[3].plot(part.t, part.z[:, 2], color=_COLORS[0], label="estimate ẑ3")
        col[3].set_xlabel("time t [s]")
        for ax in col:
            ax.grid(alpha=0.3)
    for ax, label in zip(axes[:, 0], ("angle [rad]", "tracking error [rad]", "torque u [N·m]",
                                      "perturbation [rad/s²]"), strict=True):
        ax.set_ylabel(label)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[3, 0].legend(loc="best", fontsize=8)
    scn = result.scenario
    fig.suptitle(f"{scn.name}: {scn.controller.compensation} compensation, RMS error "
                 f"{result.rms_error:.4f} rad over all joints, RMS u {result.rms_u:.4f} N·m",
                 fontsize=10)
    return finish_figure(fig, path)


def figure_arm_ablation(runs: Mapping[str, SimResult], title: str,
                        path: str | Path | None = None) -> Figure:
    """Fig. 7 on an arm: tracking error and torque of each variant, one column per joint.

    The tracking errors of the variants share the top row; each variant's torque has a row
    of its own (same torque scale within a joint), so that the noisy traces do not hide
    each other.

    Parameters
    ----------
    runs : mapping label -> SimResult
        The variants (e.g. with the ESO, with feed-forward, the computed-torque baseline).
    title : str
        The figure's title.
    path : str or Path, optional
        Where to save the figure (suffix: format).

    Returns
    -------
    Figure
        Rows: tracking error [rad] of every variant, then torque u [N·m] of each.
    """
    first = next(iter(runs.values()))
    names = _names(first)
    n = len(first.per_joint)
    m = len(runs)
    fig = Figure(figsize=(_width(n), 3.2 + 1.7 * m), layout="constrained")
    axes = fig.subplots(1 + m, n, sharex=True, squeeze=False,
                        gridspec_kw={"height_ratios": [1.8] + [1.0] * m})
    for i, ((label, res), color) in enumerate(zip(runs.items(), _COLORS, strict=False)):
        for j, part in enumerate(res.per_joint):
            axes[0, j].plot(part.t, part.error, color=color, linewidth=1.0,
                            label=f"{label}: RMS {part.rms_error:.4f} rad")
            ax_u = axes[1 + i, j]
            ax_u.plot(part.t, part.u, color=color, linewidth=0.8)
            rms_u = float(np.sqrt(np.mean(np.square(part.u)))) if len(part.u) else float("nan")
            ax_u.set_title(f"{label}: RMS u {rms_u:.3f} N·m", fontsize=8, loc="left",
                           color=color)
    for j in range(n):
        axes[0, j].set_title(names[j], fontsize=10)
        axes[0, j].axhline(0.0, color="0.6", linewidth=0.8)
        axes[0, j].legend(loc="best", fontsize=8)
        axes[-1, j].set_xlabel("time t [s]")
        low = min(ax.get_ylim()[0] for ax in axes[1:, j])  # one torque scale per joint
        high = max(ax.get_ylim()[1] for ax in axes[1:, j])
        for ax in axes[1:, j]:
            ax.set_ylim(low, high)
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("tracking error [rad]")
    for ax in axes[1:, 0]:
        ax.set_ylabel("u [N·m]")
    fig.suptitle(title, fontsize=10)
    return finish_figure(fig, path)


def figure_arm_eps_sweep(eps: Sequence[float], rms_error: np.ndarray, rms_u: np.ndarray,
                         names: Sequence[str], title: str,
                         path: str | Path | None = None) -> Figure:
    """RMS tracking error and torque against ε per joint (the paper's Table II trade-off).

    Parameters
    ----------
    eps : sequence of float
        ε [s] of each run.
    rms_error, rms_u : ndarray, shape (len(eps), n_joints)
        Per-joint RMS error [rad] and torque [N·m].
    """
    fig = Figure(figsize=(8, 6), layout="constrained")
    ax_e, ax_u = fig.subplots(2, 1, sharex=True)
    for j, name in enumerate(names):
        color = _COLORS[j % len(_COLORS)]
        ax_e.plot(eps, rms_error[:, j], "o-", color=color, label=name)
        ax_u.plot(eps, rms_u[:, j], "o-", color=color, label=name)
    for ax in (ax_e, ax_u):
        ax.set_xscale("log")
        ax.grid(alpha=0.3, which="both")
        ax.legend(loc="best", fontsize=8)
    ax_e.set_yscale("log")
    ax_e.set_ylabel("RMS tracking error [rad]")
    ax_u.set_ylabel("RMS torque [N·m]")
    ax_u.set_xlabel("ε [s]")
    fig.suptitle(title, fontsize=10)
    return finish_figure(fig, path)


def figure_arm_replay(result: object, names: Sequence[str],
                      path: str | Path | None = None) -> Figure:
    """Measured angle with the estimates ẑ1, ẑ2, ẑ3 of each joint (``esoarm replay`` on an arm).

    ``result`` is an :class:`esoarm.hardware.replay.ArmReplay`.
    """
    t, theta, z = result.t, result.theta, result.z  # type: ignore[attr-defined]
    n = theta.shape[1]
    fig = Figure(figsize=(_width(n), 7), layout="constrained")
    axes = fig.subplots(3, n, sharex=True, squeeze=False)
    for j in range(n):
        axes[0, j].plot(t, theta[:, j], ".", color="0.4", markersize=2, label="measured")
        axes[0, j].plot(t, z[:, j, 0], color=_COLORS[0], label="ẑ1")
        axes[0, j].set_title(names[j] if j < len(names) else f"joint {j + 1}", fontsize=10)
        axes[1, j].plot(t, z[:, j, 1], color=_COLORS[0])
        axes[2, j].plot(t, z[:, j, 2], color=_COLORS[0])
        axes[2, j].set_xlabel("time t [s]")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("angle [rad]")
    axes[1, 0].set_ylabel("rate ẑ2 [rad/s]")
    axes[2, 0].set_ylabel("perturbation ẑ3 [rad/s²]")
    axes[0, 0].legend(loc="best", fontsize=8)
    return finish_figure(fig, path)
