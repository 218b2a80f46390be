"""Text and TOML output of an identification (``esoarm identify``)."""

from __future__ import annotations

import math

from esoarm import __version__
from esoarm.scenario import Scenario
from esoarm.studies.identification.identify import IdentResult

__all__ = ["result_text", "scenario_toml", "spectrum_line"]


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
        elif est.withheld:
            note = "INTERVAL WITHHELD"
        elif est.at_bound:
            note = f"AT THE {est.bound.upper()} BOUND"
        elif not est.identifiable:
            note = "POORLY DETERMINED"
        else:
            note = "interval clipped to the bounds" if est.ci_clipped else ""
        rows.append((key, _num(est.value), "withheld" if est.withheld else
                     f"[{_num(est.ci95[0])}, {_num(est.ci95[1])}]", est.unit, note))
    g = res.gravity
    rows.append(("  = gravity coefficient", _num(g.value), "withheld" if g.withheld else
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
    if res.model_error:
        lines.append("")
        lines.append("the evidence rejects the model (" + "; ".join(res.model_error) + "): "
                     f"the intervals are {res.interval_method}")
        for e in res.estimates.values():
            if e.withheld:
                lines.append(f"  {e.key}: interval withheld: {e.withheld}")
    elif "segment-cluster" in res.interval_method:  # the floor widened some intervals
        lines.append("")
        lines.append(f"intervals: {res.interval_method} (never narrower than the spread of "
                     "the segments allows)")
    poor = [e for e in res.estimates.values()
            if e.fitted and not e.identifiable and not e.at_bound and not e.withheld]
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
            else "NOT white (model error: see the intervals above)"
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
            lines.append(spectrum_line(spec, what))
    else:
        lines.append("validation: none (--validate-fraction 0 and a single log)")
    return "\n".join(lines)


def spectrum_line(spec: dict, what: str) -> str:
    """The "residual spectrum" line from the keys ``spec`` has: the segments' restricted
    likelihood (coefficients with 95 % intervals, σ with its interval, the innovation's χ²)
    or the plain Yule-Walker verdict of long segments (coefficients, AIC, the residual's σ,
    the innovation's lags outside)."""
    phi = [float(c) for c in spec.get("noise_ar", [])]
    cis = spec.get("noise_ar_ci95") or []
    if cis:
        coef = ", ".join(f"{c:.3f} [{lo:.3f}, {hi:.3f}]" for c, (lo, hi)
                         in zip(phi, cis, strict=True)) + " (95 %)"
    else:
        coef = ", ".join(f"{c:.3f}" for c in phi)
    coef = coef or "white"
    crit = "BIC" if "bic" in spec else "AIC"
    where = "fit and validation segments" if "bic" in spec else "validation residual"
    parts = [f"residual spectrum ({where}): AR({spec.get('order', len(phi))}) by {crit}, "
             f"φ = {coef}"]
    if "noise_std_deg" in spec:
        ci = spec.get("noise_std_ci95_deg") or []
        parts.append(f"σ = {spec['noise_std_deg']:.3g}°"
                     + (f" [{ci[0]:.3g}, {ci[1]:.3g}]" if len(ci) == 2 else ""))
    elif "residual_std_deg" in spec:
        parts.append(f"σ = {spec['residual_std_deg']:.3g}°")
    if "innovation_autocorrelation_chi2" in spec:
        parts.append(f"innovation whiteness χ² {spec['innovation_autocorrelation_chi2']:.3g} "
                     f"(95 %: {spec.get('innovation_chi2_95', float('nan')):.3g})")
    elif "innovation_autocorrelation_outside" in spec:
        parts.append(f"innovation: {spec['innovation_autocorrelation_outside']} of "
                     f"{spec.get('lags', 20)} lags outside ±1.96")
    if "input_cross_correlation_chi2" in spec:
        parts.append(f"past-input χ² {spec['input_cross_correlation_chi2']:.3g} (95 %: "
                     f"{spec.get('chi2_95', float('nan')):.3g})")
    return "; ".join(parts) + f": {what}"


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
        if est.fitted and est.withheld:
            head.append(f"#   {key} = {est.value:.6g} (interval withheld: {est.withheld}) "
                        f"{est.unit}")
        elif est.fitted:
            head.append(f"#   {key} = {est.value:.6g} [{est.ci95[0]:.6g}, {est.ci95[1]:.6g}] "
                        f"{est.unit}" + (f"  (at the {est.bound} bound of the fit)"
                                         if est.at_bound else "" if est.identifiable
                                         else "  (poorly determined)"))
    return "\n".join(head) + "\n\n" + fitted.to_toml()
