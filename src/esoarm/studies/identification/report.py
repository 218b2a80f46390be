"""Text and TOML output of an identification (``esoarm identify``)."""

from __future__ import annotations

import math

from esoarm import __version__
from esoarm.scenario import Scenario
from esoarm.studies.identification.identify import IdentResult

__all__ = ["result_text", "scenario_toml"]


def _num(x: float) -> str:
    if not math.isfinite(x):
        return "—"
    return f"{x:.4g}"


def result_text(res: IdentResult) -> str:
    """The parameters with their 95 % intervals, what is poorly determined, fit and validation."""
    lines = [f"identification of '{res.scenario.name}' from {', '.join(res.fit_logs)} "
             f"({res.n_fit} samples fitted, segments of {res.segment_seconds:g} s, "
             f"{res.iterations} iterations, {res.elapsed:.2g} s)", ""]
    rows = [("parameter", "value", "95 % interval", "unit", "")]
    for key, est in res.estimates.items():
        if not est.fitted:
            note = "held"
        elif est.at_bound:
            note = f"AT THE {est.bound.upper()} BOUND"
        elif not est.identifiable:
            note = "POORLY DETERMINED"
        else:
            note = "interval clipped to the bounds" if est.ci_clipped else ""
        rows.append((key, _num(est.value), f"[{_num(est.ci95[0])}, {_num(est.ci95[1])}]",
                     est.unit, note))
    g = res.gravity
    rows.append(("  = gravity coefficient", _num(g.value),
                 f"[{_num(g.ci95[0])}, {_num(g.ci95[1])}]", g.unit, ""))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for r in rows:
        lines.append("  ".join(c.ljust(w) for c, w in zip(r[:4], widths, strict=True))
                     + ("  " + r[4] if r[4] else ""))
    held = [e for e in res.estimates.values() if not e.fitted and e.advice.startswith("held:")]
    for e in held:
        lines.append(f"{e.key} {e.advice}")
    pinned = [e for e in res.estimates.values() if e.at_bound]
    if pinned:
        lines.append("")
        lines.append("at a bound of the fit (the log pulls the value beyond it: the value is a "
                     "limit, not an optimum, and its interval is clipped to the bounds):")
        for e in pinned:
            lines.append(f"  {e.key} = {_num(e.value)} {e.unit}, the {e.bound} bound"
                         + (f" ({e.bound_why})" if e.bound_why else "")
                         + (f"; {e.advice}" if e.advice else ""))
    poor = [e for e in res.estimates.values()
            if e.fitted and not e.identifiable and not e.at_bound]
    if poor:
        lines.append("")
        lines.append("poorly determined by this log (the interval is wider than ±25 % or the "
                     "parameter trades off with another):")
        for e in poor:
            lines.append(f"  {e.key}: {e.advice}")
    lines.append("")
    lines.append(f"fit: {res.fit_percent:.2f} % of the measured angle's variation explained, "
                 f"residual RMS {res.residual_rms:.3g} rad")
    v = res.validation
    if v:
        w = v["whiteness"]
        verdict = "white" if w["white"] else "NOT white: sensor noise by its spectrum below " \
            "(the intervals are from its covariance)" if res.coloured_noise() is not None \
            else "NOT white (model error or colored noise: the intervals are too optimistic)"
        lines.append(f"validation on {', '.join(res.validation_logs)} (not used for fitting): "
                     f"fit {v['fit_percent']:.2f} %, residual RMS {v['residual_rms_rad']:.3g} "
                     f"rad")
        lines.append(f"residual whiteness: {w['outside']} of {w['lags']} autocorrelation lags "
                     f"outside ±{w['band']:.3g} (max |ρ| {w['max_abs_autocorrelation']:.3g}): "
                     f"{verdict}")
        spec = v.get("noise_spectrum")
        if spec:
            coloured = res.coloured_noise()
            what = ("sensor noise (white), written to the fitted scenario" if coloured == []
                    else "sensor noise, written to the fitted scenario" if coloured
                    else "sensor noise (white)" if w["white"]
                    else "model error: the validation residual is well above the fit's"
                    if spec["sensor_noise"]
                    else spec["meaning"])
            cis = spec.get("noise_ar_ci95", [])
            nan, wkey = float("nan"), "innovation_autocorrelation_chi2"
            coef = ", ".join(f"{c:.3f} [{lo:.3f}, {hi:.3f}]" for c, (lo, hi)
                             in zip(spec["noise_ar"], cis, strict=False)) or "white"
            lines.append(f"residual spectrum (fit and validation segments): AR({spec['order']}) "
                         f"by BIC, φ = {coef} (95 %), σ = {spec.get('noise_std_deg', 0.0):.3g}° "
                         f"[{', '.join(f'{v:.3g}' for v in spec.get('noise_std_ci95_deg', []))}]; "
                         f"innovation whiteness χ² {spec.get(wkey, nan):.3g} "
                         f"(95 %: {spec.get('innovation_chi2_95', nan):.3g}), past-input χ² "
                         f"{spec['input_cross_correlation_chi2']:.3g} (95 %: "
                         f"{spec['chi2_95']:.3g}): {what}")
    else:
        lines.append("validation: none (--validate-fraction 0 and a single log)")
    return "\n".join(lines)


def scenario_toml(res: IdentResult, fitted: Scenario) -> str:
    """The fitted scenario as TOML, with where it came from and the intervals as comments."""
    head = [f"# Fitted by esoarm {__version__} identify from: {', '.join(res.fit_logs)}",
            f"# fit {res.fit_percent:.2f} %"
            + (f", validation fit {res.validation['fit_percent']:.2f} %" if res.validation
               else ""),
            "# The fitted rig is the twin (plant.inertia = fitted inertia, "
            "rig.inertia_scale = 1) and the plant model is updated to the fit.",
            "# 95 % intervals:"]
    for key, est in res.estimates.items():
        if est.fitted:
            head.append(f"#   {key} = {est.value:.6g} [{est.ci95[0]:.6g}, {est.ci95[1]:.6g}] "
                        f"{est.unit}" + (f"  (at the {est.bound} bound of the fit)"
                                         if est.at_bound else "" if est.identifiable
                                         else "  (poorly determined)"))
    return "\n".join(head) + "\n\n" + fitted.to_toml()
