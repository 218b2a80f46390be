"""Figures of sweeps and tuning: metric curves, heat maps, the Pareto front.

Object-oriented :class:`matplotlib.figure.Figure` only (no pyplot, no global
state); files are written with :func:`esoarm.plotting.run.save_figure` (PNG, PDF
or SVG by suffix, atomic).

* :func:`figure_sweep` -- one varied key: RMS tracking error [rad] and RMS
  control [N·m] (m and N on a prismatic axis, :func:`esoarm.kinds.units`) against
  it, the seed mean as a line and the spread over seeds
  (min…max) as a band; two varied keys: a heat map of each (seed mean).
* :func:`figure_pareto` -- tuning: every evaluated candidate as (RMS control,
  RMS error), the non-dominated ones joined as the Pareto front, the optimum
  and any reference points (e.g. the paper's ε = 0.09) marked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from esoarm.contract import ROTARY_UNITS, Units
from esoarm.kinds import units as units_of_scenario
from esoarm.plotting.run import finish_figure

if TYPE_CHECKING:
    from esoarm.studies.sweeps.sweep import SweepResult

__all__ = ["figure_pareto", "figure_sweep", "pareto_mask"]

_METRICS = (("rms_error", "RMS tracking error", "position"), ("rms_u", "RMS control", "force"))
_UNITS = {
    "observer.eps": "s", "controller.k1": "1/s", "controller.k2": "1/s²",
    "actuator.lag": "s", "actuator.torque_limit": "N·m", "rig.step": "s", "duration": "s",
    "sensor.rate_hz": "Hz", "sensor.noise_deg": "deg", "sensor.resolution_deg": "deg",
    "rig.coulomb_friction": "N·m", "rig.viscous_friction": "N·m·s/rad",
    "rig.friction_velocity": "rad/s", "rig.theta0": "rad", "actuator.delay_samples": "samples",
    "rig.disturbance.amplitude": "rad/s²", "rig.disturbance.frequency": "rad/s",
}
#: Keys whose unit is the plant's (:class:`esoarm.contract.Units` field): a prismatic axis's
#: force limit is in N, its friction in N·s/m and N.
_PLANT_UNITS = {
    "actuator.torque_limit": "force", "plant.mass": "inertia",
    "plant.viscous_friction": "damping", "plant.viscous_asymmetry": "damping",
    "plant.coulomb_friction": "force", "plant.coulomb_asymmetry": "force",
    "plant.offset": "force", "plant.friction_velocity": "velocity", "plant.q0": "position",
}
MAX_KEYS = 2


def _label(key: str, units: Units = ROTARY_UNITS) -> str:
    quantity = _PLANT_UNITS.get(key)
    unit = getattr(units, quantity) if quantity else _UNITS.get(key)
    return f"{key} [{unit}]" if unit else key


def _metric_label(name: str, quantity: str, units: Units) -> str:
    return f"{name} [{getattr(units, quantity)}]"


def figure_sweep(result: SweepResult, path: str | Path | None = None) -> Figure:
    """Draw a sweep of one or two varied keys (see the module docstring).

    Parameters
    ----------
    result : SweepResult
        The sweep's rows (unfinished runs are left out).
    path : str or Path, optional
        Write the figure there too (PNG, PDF or SVG by suffix).

    Returns
    -------
    Figure
        Curves with the spread over seeds for one key, heat maps for two.

    Raises
    ------
    ValueError
        More than two varied keys.
    """
    grid = result.grid
    if len(grid.vary) > MAX_KEYS:
        raise ValueError(f"a sweep figure draws one or two varied keys, got {len(grid.vary)}")
    n_seeds = max(len(grid.seeds), 1)
    title = f"{grid.base.name}: {grid.n_runs} runs ({n_seeds} seed{'s' if n_seeds > 1 else ''} " \
            "per point)"
    units = units_of_scenario(grid.base)
    if len(grid.vary) == 1:
        fig = _curves(result, units)
    else:
        fig = _heatmaps(result, units)
    fig.suptitle(title)
    return finish_figure(fig, path)


def _stats(result: SweepResult, metric: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = result.point_metric(metric)
    with np.errstate(all="ignore"):
        finite = np.where(np.isfinite(a), a, np.nan)
        ok = np.isfinite(finite).any(axis=1)
        mean = np.full(a.shape[0], np.nan)
        lo = np.full(a.shape[0], np.nan)
        hi = np.full(a.shape[0], np.nan)
        mean[ok] = np.nanmean(finite[ok], axis=1)
        lo[ok] = np.nanmin(finite[ok], axis=1)
        hi[ok] = np.nanmax(finite[ok], axis=1)
    return mean, lo, hi


def _curves(result: SweepResult, units: Units) -> Figure:
    spec = result.grid.vary[0]
    fig = Figure(figsize=(7.0, 5.6), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    numeric = spec.numeric
    x = np.array(spec.values, dtype=float) if numeric else np.arange(len(spec.values))
    diverged = result.point_metric("diverged")
    bad = np.nan_to_num(diverged, nan=0.0).max(axis=1) > 0
    for ax, (metric, name, quantity) in zip(axes, _METRICS, strict=True):
        label = _metric_label(name, quantity, units)
        mean, lo, hi = _stats(result, metric)
        if len(result.grid.seeds) > 1:
            ax.fill_between(x, lo, hi, color="#56B4E9", alpha=0.35, linewidth=0,
                            label="min…max over seeds")
        ax.plot(x, mean, color="#0072B2", marker="o" if len(x) <= 30 else None,
                markersize=3, linewidth=1.4, label="mean over seeds")
        if bad.any():
            ax.plot(x[bad], np.where(np.isfinite(mean[bad]), mean[bad], np.nan), "x",
                    color="#D55E00", label="diverged run(s)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        finite = mean[np.isfinite(mean)]
        if finite.size and finite.min() > 0 and finite.max() / finite.min() > 30:
            ax.set_yscale("log")
        ax.legend(loc="best", fontsize="small")
    if numeric and spec.spacing == "geom":
        axes[-1].set_xscale("log")
    if not numeric:
        axes[-1].set_xticks(x, [str(v) for v in spec.values])
    axes[-1].set_xlabel(_label(spec.key, units))
    return fig


def _heatmaps(result: SweepResult, units: Units) -> Figure:
    sa, sb = result.grid.vary
    fig = Figure(figsize=(11.0, 4.6), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, (metric, name, quantity) in zip(axes, _METRICS, strict=True):
        label = _metric_label(name, quantity, units)
        mean, _, _ = _stats(result, metric)
        img = mean.reshape(len(sa.values), len(sb.values))
        mesh = ax.imshow(img, origin="lower", aspect="auto", cmap="viridis",
                         interpolation="nearest")
        fig.colorbar(mesh, ax=ax, label=f"{label} (mean over seeds)")
        for spec, setter, most in ((sa, ax.set_yticks, 16), (sb, ax.set_xticks, 10)):
            idx = _tick_index(len(spec.values), most)
            setter(idx, [_fmt(spec.values[i]) for i in idx])
        ax.set_ylabel(_label(sa.key, units))
        ax.set_xlabel(_label(sb.key, units))
        best = np.nanargmin(img) if np.isfinite(img).any() else None
        # the marker is named in the title: a legend inside would cover cells
        ax.set_title(f"{label} (★ lowest)" if best is not None else label)
        if best is not None:
            i, j = np.unravel_index(best, img.shape)
            ax.plot(j, i, marker="*", color="white", markersize=12, markeredgecolor="black")
    return fig


def _tick_index(n: int, most: int = 10) -> list[int]:
    """Which of n cells get a tick label: all up to ``most``, else every k-th from the first.

    A regular stride: labels at uneven steps would read as missing rows.
    """
    if n <= most:
        return list(range(n))
    step = -(-n // most)
    return list(range(0, n, step))


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def pareto_mask(cost_a: np.ndarray, cost_b: np.ndarray) -> np.ndarray:
    """Points not dominated in (a, b), both minimized (ties kept once).

    Parameters
    ----------
    cost_a, cost_b : ndarray
        The two costs of each point (e.g. RMS control [N·m] and RMS error [rad]); points
        where either is not finite are never on the front.

    Returns
    -------
    ndarray of bool
        True for the points on the Pareto front.
    """
    a = np.asarray(cost_a, dtype=float)
    b = np.asarray(cost_b, dtype=float)
    mask = np.zeros(len(a), dtype=bool)
    ok = np.isfinite(a) & np.isfinite(b)
    order = [i for i in np.lexsort((b, a)) if ok[i]]
    best_b = np.inf
    for i in order:
        if b[i] < best_b:
            mask[i] = True
            best_b = b[i]
    return mask


def figure_pareto(
    rms_u: Sequence[float],
    rms_error: Sequence[float],
    *,
    best: tuple[float, float] | None = None,
    marks: Mapping[str, tuple[float, float]] | None = None,
    color: Sequence[float] | None = None,
    color_label: str = "",
    title: str = "",
    path: str | Path | None = None,
    units: Units = ROTARY_UNITS,
) -> Figure:
    """Trade-off of tracking error against control effort (tuning).

    Parameters
    ----------
    rms_u, rms_error : sequence of float
        Objective metrics of every evaluated candidate: RMS control [N·m] and
        RMS tracking error [rad] (means over seeds and robust samples).
    best : (rms_u, rms_error), optional
        The optimum found, marked with a star.
    marks : mapping label -> (rms_u, rms_error), optional
        Further labelled points (e.g. the paper's setting).
    color : sequence of float, optional
        A value per candidate to colour the points by (e.g. ε [s]).
    color_label : str, optional
        The colour bar's label.
    title : str, optional
        The axes' title.
    path : str or Path, optional
        Save the figure there (.png, .pdf or .svg).
    units : Units, optional
        The plant's units for the axis labels (default rotary: N·m and rad).

    Returns
    -------
    Figure
        The figure.
    """
    u = np.asarray(rms_u, dtype=float)
    e = np.asarray(rms_error, dtype=float)
    fig = Figure(figsize=(7.0, 5.0), layout="constrained")
    ax = fig.subplots()
    if color is not None:
        sc = ax.scatter(u, e, c=np.asarray(color, dtype=float), s=10, cmap="viridis",
                        alpha=0.7, label="evaluated candidates")
        fig.colorbar(sc, ax=ax, label=color_label)
    else:
        ax.scatter(u, e, s=10, color="0.6", alpha=0.7, label="evaluated candidates")
    mask = pareto_mask(u, e)
    order = np.argsort(u[mask])
    ax.plot(u[mask][order], e[mask][order], "-o", color="#D55E00", markersize=3,
            linewidth=1.4, label="Pareto front")
    if best is not None:
        ax.plot(*best, marker="*", markersize=16, color="#0072B2", markeredgecolor="black",
                linestyle="none", label="optimum of the objective")
    for (label, (mu, me)), mk in zip((marks or {}).items(), "DsP^v", strict=False):
        ax.plot(mu, me, marker=mk, markersize=8, color="#009E73", markeredgecolor="black",
                linestyle="none", label=label)
    finite = np.isfinite(u) & np.isfinite(e)
    for values, setter, axis in ((u, ax.set_xscale, ax.xaxis), (e, ax.set_yscale, ax.yaxis)):
        v = values[finite]
        if v.size and v.min() > 0 and v.max() / v.min() > 10:
            setter("log")  # the knee of the front stays readable
            # ticks at 1, 2, 5 × 10^n in plain numbers: default minor labels collide
            axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
            axis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(f"RMS control [{units.force}]")
    ax.set_ylabel(f"RMS tracking error [{units.position}]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        ax.set_title(title)
    return finish_figure(fig, path)
