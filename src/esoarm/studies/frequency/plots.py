"""Figures of the frequency-domain analysis (:mod:`esoarm.studies.frequency.margins`).

Kept apart from the numerics, like :mod:`esoarm.plotting.run` (whose colour per ε
and file handling they share): a Bode diagram of the loop transfer with its
margins, the sensitivity functions, and the margins against a varied key.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FormatStrFormatter, NullFormatter

from esoarm.plotting.run import eps_color, finish_figure
from esoarm.studies.frequency.margins import eso_label

if TYPE_CHECKING:
    from esoarm.studies.frequency.margins import FrequencyAnalysis

__all__ = ["figure_frequency", "figure_vary"]


def _db(x: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(np.abs(x))


def _nyquist(ax: Any, wn: float) -> None:
    ax.axvline(wn, color="0.5", linestyle=":", linewidth=1.0)


#: The box behind a margin's label (readable over grid lines and curves).
_LABEL_BOX = {"facecolor": "white", "edgecolor": "0.8", "boxstyle": "round,pad=0.3",
              "alpha": 0.9}


def _draw(axes: Any, a: FrequencyAnalysis, color: str, label: str, marks: bool) -> None:
    c = a.curves
    keep = slice(0, -1)  # drop ω = π/Ts itself, where the phase of a real L is ambiguous
    c = {k: v[keep] for k, v in c.items()}
    w = c["w"]
    ax_m, ax_p, ax_s, ax_d = axes
    ax_m.semilogx(w, _db(c["loop"]), color=color, label=label)
    phase = np.degrees(np.unwrap(np.angle(c["loop"])))
    # show the phase on the branch that passes through −180° at the crossover
    if math.isfinite(a.gain_crossover):
        i = int(np.searchsorted(w, a.gain_crossover))
        i = min(i, len(w) - 1)
        target = -180.0 + a.phase_margin
        phase += 360.0 * round((target - phase[i]) / 360.0)
    ax_p.semilogx(w, phase, color=color, label=label)
    ax_s.semilogx(w, _db(c["sensitivity"]), color=color, label=f"|S| {label}".strip())
    ax_s.semilogx(w, _db(c["complementary"]), color=color, linestyle="--",
                  label=f"|T| {label}".strip())
    ax_d.semilogx(w, _db(c["disturbance"]), color=color, label=label)
    if marks:
        if math.isfinite(a.gain_crossover):
            ax_m.plot([a.gain_crossover], [0.0], "o", color=color)
            ax_p.plot([a.gain_crossover], [-180.0 + a.phase_margin], "o", color=color)
            # the margins' labels in the axes' lower-left corner (inside the axes, on a white
            # box: a label beside the marker ran off the axes when the marker sat at an edge)
            ax_p.text(0.02, 0.03, f"● PM {a.phase_margin:.1f}° at {a.gain_crossover:.3g} "
                      f"rad/s\nDM {a.delay_margin * 1e3:.1f} ms", transform=ax_p.transAxes,
                      fontsize=8, ha="left", va="bottom", color=color, bbox=_LABEL_BOX)
        if math.isfinite(a.gain_margin) and math.isfinite(a.phase_crossover):
            ax_m.plot([a.phase_crossover], [-20.0 * math.log10(a.gain_margin)], "s",
                      color=color)
            ax_m.text(0.02, 0.03, f"■ GM {a.gain_margin:.2f} "
                      f"({20 * math.log10(a.gain_margin):.1f} dB) at {a.phase_crossover:.3g} "
                      "rad/s", transform=ax_m.transAxes, fontsize=8, ha="left", va="bottom",
                      color=color, bbox=_LABEL_BOX)
        ax_s.plot([a.ms_frequency], [20 * math.log10(a.ms)], "v", color=color)
        ax_s.text(0.02, 0.03, f"▼ Ms {a.ms:.2f} at {a.ms_frequency:.3g} rad/s",
                  transform=ax_s.transAxes, fontsize=8, ha="left", va="bottom", color=color,
                  bbox=_LABEL_BOX)


def _finish_axes(axes: Any, wn: float) -> None:
    ax_m, ax_p, ax_s, ax_d = axes
    ax_m.axhline(0.0, color="0.6", linewidth=0.8)
    ax_p.axhline(-180.0, color="0.6", linewidth=0.8)
    ax_s.axhline(0.0, color="0.6", linewidth=0.8)
    ax_m.set_ylabel("|L| [dB]")
    ax_p.set_ylabel("∠L [deg]")
    ax_s.set_ylabel("|S|, |T| [dB]")
    ax_d.set_ylabel("|e / w| [dB rad/(N·m)]")
    ax_m.set_title("loop transfer L = K P (plant input)", fontsize=9)
    ax_p.set_title("phase of L", fontsize=9)
    ax_s.set_title("sensitivity S (solid) and T (dashed)", fontsize=9)
    ax_d.set_title("input torque disturbance w → tracking error e", fontsize=9)
    for ax in axes:
        _nyquist(ax, wn)
        ax.grid(alpha=0.3, which="both")
        ax.set_xlabel("frequency ω [rad/s] (dotted: Nyquist π/Ts)")
    ax_s.set_ylim(bottom=max(ax_s.get_ylim()[0], -60.0))


def figure_frequency(a: FrequencyAnalysis, path: str | Path | None = None) -> Figure:
    """Bode diagram of L with its margins, |S| and |T|, and the disturbance transfer.

    Parameters
    ----------
    a : FrequencyAnalysis
        An analysis with its curves (:func:`~esoarm.studies.frequency.margins.analyze`).
    path : str or Path, optional
        Write the figure there too (PNG, PDF or SVG by suffix).

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(10, 7), layout="constrained")
    axes = fig.subplots(2, 2).ravel()
    _draw(axes, a, eps_color(a.eps), "", marks=True)
    _finish_axes(axes, a.nyquist)
    fig.suptitle(
        f"{a.scenario}: ε = {a.eps:g} s, {a.discretization} {eso_label(a)}, linearized at θ0 = "
        f"{a.theta0:g} rad, friction '{a.friction}', Ts = {a.ts:g} s"
        + (", motor's linear part" if a.motor else ""), fontsize=10)
    return finish_figure(fig, path)


def figure_vary(key: str, values: Sequence[Any], results: Sequence[FrequencyAnalysis],
                path: str | Path | None = None) -> Figure:
    """Bode of L and |S| for each value of ``key``, and the margins against it.

    Parameters
    ----------
    key : str
        The dotted scenario key varied.
    values : sequence
        Its values, one per analysis.
    results : sequence of FrequencyAnalysis
        The analyses, in the order of ``values``.
    path : str or Path, optional
        Write the figure there too (PNG, PDF or SVG by suffix).

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(11, 9), layout="constrained")
    grid = fig.subplots(3, 2)
    axes = grid[:2].ravel()
    palette = ["#D55E00", "#0072B2", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"]
    pick = np.unique(np.linspace(0, len(results) - 1, min(len(results), 5)).round().astype(int))
    for n, i in enumerate(pick):
        _draw(axes, results[i], palette[n % len(palette)], f"{values[i]:.3g}"
              if isinstance(values[i], float) else str(values[i]), marks=False)
    _finish_axes(axes, results[0].nyquist)
    axes[0].legend(title=key, fontsize=8)
    numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
    x = np.asarray(values, dtype=float) if numeric else np.arange(len(values))
    ax_g, ax_d = grid[2]

    def col(name: str) -> np.ndarray:
        return np.array([getattr(r, name) for r in results], dtype=float)

    ax_g.plot(x, col("gain_margin"), "o-", color="#0072B2", label="gain margin [ratio]")
    ax_g.plot(x, col("ms"), "s--", color="#D55E00", label="Ms")
    ax_g.plot(x, col("mt"), "^:", color="#009E73", label="Mt")
    ax_g.axhline(1.0, color="0.6", linewidth=0.8)
    ax_g.set_ylabel("ratio [1]")
    ax_g.legend(fontsize=8, loc="upper left")
    ax_p = ax_g.twinx()
    ax_p.plot(x, col("phase_margin"), "d-", color="#CC79A7", label="phase margin [deg]")
    ax_p.set_ylabel("phase margin [deg]", color="#CC79A7")
    ax_d.plot(x, col("delay_margin") * 1e3, "o-", color="#0072B2", label="delay margin")
    ax_d.axhline(results[0].ts * 1e3, color="0.6", linestyle=":", linewidth=1.0,
                 label="one sample Ts")
    ax_d.set_ylabel("delay margin [ms]")
    ax_d.legend(fontsize=8, loc="upper left")
    ax_b = ax_d.twinx()
    ax_b.plot(x, col("closed_loop_bandwidth"), "s--", color="#E69F00",
              label="closed-loop bandwidth")
    ax_b.plot(x, col("observer_bandwidth"), "^:", color="#009E73",
              label="observer bandwidth")
    ax_b.axhline(results[0].nyquist, color="0.5", linestyle=":", linewidth=1.0)
    ax_b.set_ylabel("bandwidth [rad/s]")
    ax_b.legend(fontsize=8, loc="lower right")
    for ax in (ax_g, ax_d):
        ax.set_xlabel(key)
        ax.grid(alpha=0.3)
        if numeric and np.all(x > 0) and x.max() / x.min() > 5:
            ax.set_xscale("log")
            ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.xaxis.set_minor_formatter(NullFormatter())
        if not numeric:
            ax.set_xticks(x, [str(v) for v in values])
    a = results[0]
    fig.suptitle(f"{a.scenario}: margins against {key} (linearized at θ0 = {a.theta0:g} rad, "
                 f"friction '{a.friction}', Ts = {a.ts:g} s"
                 + (", motor's linear part" if a.motor else "") + ")", fontsize=10)
    return finish_figure(fig, path)
