"""The report's frequency-domain section: the paper's ε values seen through margins and bandwidths.

Computed from the resolved test-1 scenarios of a reproduction with
:func:`esoarm.studies.frequency.margins.analyze` (NumPy/SciPy only), beside the
time-domain numbers of the same runs, so the ε trade-off of Tables II and III
is read twice: as RMS values and as loop gains.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from esoarm.scenario import Scenario
    from esoarm.studies.frequency.margins import FrequencyAnalysis
    from esoarm.studies.reproduction.data import Reproduction

__all__ = ["frequency_rows", "frequency_section"]

#: ε values of the margins-against-ε figure [s].
FIGURE_EPS = tuple(float(e) for e in np.geomspace(0.03, 0.3, 9))


def _e(text: Any) -> str:
    return html.escape(str(text))


def _base(rep: Reproduction) -> Scenario:
    for scn in rep.scenarios.values():
        if scn.name == "test-1" and scn.controller.compensation == "eso":
            return scn
    return next(iter(rep.scenarios.values()))


def frequency_rows(base: Scenario, eps_values: Sequence[float]) -> list[FrequencyAnalysis]:
    """The loop of ``base`` analyzed at each ε (linearized at rig.theta0, viscous friction).

    Parameters
    ----------
    base : Scenario
        The lever-arm scenario.
    eps_values : sequence of float
        ε values [s].

    Returns
    -------
    list of FrequencyAnalysis
        One per ε, in order.
    """
    from esoarm.studies.frequency.margins import analyze

    return [analyze(base.with_overrides({"observer.eps": float(e)}), over_range=False,
                    n_freq=800) for e in eps_values]


def frequency_section(rep: Reproduction, eps_values: Sequence[float] = (0.05, 0.09, 0.2)
                      ) -> str:
    """HTML of the report's section (table, figure, and the trade-off in numbers).

    Parameters
    ----------
    rep : Reproduction
        The reproduction the report is of.
    eps_values : sequence of float
        ε values [s] analyzed.

    Returns
    -------
    str
        The section's HTML.
    """
    from esoarm.plotting.run import figure_bytes
    from esoarm.studies.frequency.plots import figure_vary

    base = _base(rep)
    rows = frequency_rows(base, eps_values)
    head = ["ε [s]", "gain margin", "phase margin [deg]", "delay margin [ms]", "Ms", "Mt",
            "closed-loop bw [rad/s]", "ESO bw [rad/s]", "w → e peak [rad/(N·m)]",
            "noise → u peak [N·m/rad]", "RMS u on the twin [N·m]",
            "RMS Δu on the twin [N·m]"]
    body = []
    for a in rows:
        try:
            rms_u = f"{rep.metric(base.name, a.eps, 'rms_u'):.4f}"
            rms_du = f"{rep.metric(base.name, a.eps, 'du_rms'):.4f}"
        except (KeyError, StopIteration, ValueError):
            rms_u = rms_du = "—"
        body.append([f"{a.eps:g}", f"{a.gain_margin:.2f}", f"{a.phase_margin:.1f}",
                     f"{a.delay_margin * 1e3:.1f}", f"{a.ms:.2f}", f"{a.mt:.2f}",
                     f"{a.closed_loop_bandwidth:.3g}", f"{a.observer_bandwidth:.3g}",
                     f"{a.disturbance_peak:.3g}", f"{a.noise_to_control_peak:.3g}", rms_u, rms_du])
    table = ("<table><thead><tr>" + "".join(f"<th>{_e(h)}</th>" for h in head)
             + "</tr></thead><tbody>"
             + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in body)
             + "</tbody></table>")
    lo, hi = rows[0], rows[-1]
    text = (
        f"<p>The loop of {_e(base.name)} ({_e(base.observer.discretization)} ESO at "
        f"{base.sensor.rate_hz:g} Hz), linearized at θ0 = {base.rig.theta0:g} rad with viscous "
        "friction (Coulomb friction is a disturbance the ESO estimates) and sampled with the "
        "zero-order hold; margins at the plant input. From ε = "
        f"{lo.eps:g} s to {hi.eps:g} s the peak gain from encoder noise to the torque falls "
        f"from {lo.noise_to_control_peak:.3g} to {hi.noise_to_control_peak:.3g} N·m/rad, "
        "while the peak gain from a torque disturbance to the tracking error grows from "
        f"{lo.disturbance_peak:.3g} to {hi.disturbance_peak:.3g} rad/(N·m) and the delay "
        f"margin from {lo.delay_margin * 1e3:.0f} to {hi.delay_margin * 1e3:.0f} ms: the "
        "paper's trade-off between disturbance rejection and noise, in loop gains. The "
        f"Nyquist frequency is {lo.nyquist:.4g} rad/s. Regenerate with <code>esoarm analyze "
        f"{_e(base.name)} --vary observer.eps=0.05,0.09,0.2</code>.</p>")
    sweep = frequency_rows(base, FIGURE_EPS)
    fig = figure_vary("observer.eps", list(FIGURE_EPS), sweep)
    data = base64.b64encode(figure_bytes(fig, "png", dpi=100)).decode("ascii")
    caption = ("Bode diagram of the loop, sensitivities and disturbance transfer for five ε, "
               "and the margins, Ms, Mt and bandwidths against ε")
    figure = (f'<figure id="frequency-figure"><img src="data:image/png;base64,{data}" '
              f'alt="{_e(caption)}"><figcaption>{_e(caption)}</figcaption></figure>')
    return text + table + figure
