"""Figure of an identification: measured against fitted angle, residual, whiteness.

Kept apart from the numerics (:mod:`esoarm.studies.identification.identify` never imports
matplotlib).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from esoarm.plotting.run import finish_figure

if TYPE_CHECKING:
    from esoarm.studies.identification.identify import IdentResult

__all__ = ["figure_identification"]


def figure_identification(res: IdentResult, path: str | Path | None = None) -> Figure:
    """Three panels: angle (fit part and validation part), residual, residual autocorrelation.

    The fitted angle is the fitted rig simulated from the logged torque over
    segments of ``res.segment_seconds`` [s] (initial state of each estimated).
    """
    fig = Figure(figsize=(9.0, 8.0), layout="constrained")
    ax_y, ax_r, ax_c = fig.subplots(3, 1)
    t, y, yhat = res.curves["fit"]
    # the measured angle as a broad grey band under the thin fitted line: where the fit is
    # good the line runs inside the band, where it is not the band shows beside it
    ax_y.plot(t, y, color="0.72", lw=3.2, solid_capstyle="butt", zorder=1,
              label="measured (fit data)")
    ax_y.plot(t, yhat, color="C0", lw=0.9, zorder=2,
              label=f"fitted twin ({res.fit_percent:.1f} %)")
    ax_r.plot(t, y - yhat, color="C0", lw=0.6, label="fit data")
    val = res.curves.get("validation")
    if val is not None:
        tv, yv, yhv, lags, rho, band = val
        # a validation log of its own starts at its own t = 0: draw it after the fit data
        shift = 0.0 if tv[0] > t[-1] else t[-1] + (t[1] - t[0]) - tv[0]
        ax_y.plot(tv + shift, yv, color="0.55", lw=3.2, solid_capstyle="butt", zorder=1,
                  label="measured (validation)")
        ax_y.plot(tv + shift, yhv, color="C3", lw=0.9, zorder=2,
                  label=f"fitted twin, validation ({res.validation['fit_percent']:.1f} %)")
        ax_r.plot(tv + shift, yv - yhv, color="C3", lw=0.6, label="validation")
        ax_c.axhspan(-band, band, color="0.88", zorder=0, label="95 % band of white noise")
        ax_c.bar(lags, rho, color="C3", width=0.6, zorder=2)
        ax_c.axhline(0.0, color="0.3", lw=0.6, zorder=1)
        ax_c.set_title(f"residual autocorrelation (validation): "
                       f"{res.validation['whiteness']['outside']} of {len(lags)} lags outside")
    from esoarm.kinds import units

    unit = units(res.scenario).position
    ax_y.set_ylabel(f"θ [{unit}]")
    low, high = ax_y.get_ylim()  # room above the traces for the legend
    ax_y.set_ylim(low, high + 0.35 * (high - low))
    ax_y.legend(loc="upper left", fontsize=8, ncol=2, framealpha=0.9)
    ax_y.set_title(f"identification of '{res.scenario.name}' "
                   f"(segments of {res.segment_seconds:g} s)")
    ax_r.set_ylabel(f"residual y − ŷ [{unit}]")
    ax_r.set_xlabel("t [s]")
    ax_r.legend(loc="upper right", fontsize=8)
    ax_c.set_xlabel("lag [samples]")
    ax_c.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_c.set_ylabel("autocorrelation")
    if val is not None:
        ax_c.legend(loc="upper right", fontsize=8)
    for ax in (ax_y, ax_r):
        ax.grid(True, alpha=0.3)
    ax_c.set_xlim(0, max(21, int(np.max(val[3])) + 1) if val is not None else 21)
    return finish_figure(fig, path)
