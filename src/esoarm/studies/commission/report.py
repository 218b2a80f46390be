"""The commissioning report: one HTML page (figures inline) beside ``commission.json``.

The page is for the person at the rig: what was done, in order, with the numbers that
decided each step, and at the end the measured tracking beside the predicted one.  The
figures are drawn with matplotlib (imported here only) from the step files.
"""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["write_report"]

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1080px;margin:24px auto;
padding:0 20px;color:#1d232a;line-height:1.45}
h1{font-size:1.6em;margin-bottom:0.1em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid
#d7dde3;padding-bottom:4px}.sub{color:#5b6670;margin-top:0}
table{border-collapse:collapse;margin:8px 0 12px 0;font-size:0.94em}
td,th{border:1px solid #d7dde3;padding:4px 10px;text-align:left}th{background:#f2f5f8}
td.num{text-align:right;font-variant-numeric:tabular-nums}
.verdict{padding:10px 14px;border-radius:6px;margin:12px 0;font-weight:600}
.ok{background:#e6f4ea;border:1px solid #9fd3ad}.bad{background:#fdecea;border:1px solid #f1a7a0}
.note{color:#5b6670;font-size:0.92em}img{max-width:100%;border:1px solid #e3e7eb}
code{background:#f2f5f8;padding:1px 4px;border-radius:3px}
"""


def _f(x: Any, spec: str = ".4g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "—"
    return format(x, spec) if isinstance(x, (int, float)) else html.escape(str(x))


def _table(head: list[str], rows: list[list[Any]]) -> str:
    out = ["<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for row in rows:
        cells = []
        for v in row:
            cls = ' class="num"' if isinstance(v, (int, float)) else ""
            cells.append(f"<td{cls}>{_f(v) if not isinstance(v, str) else html.escape(v)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    return "\n".join(out) + "</table>"


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return ('<img alt="figure" src="data:image/png;base64,'
            + base64.b64encode(buf.getvalue()).decode() + '">')


def _read(path: Path) -> np.ndarray | None:
    if not path.exists():
        return None
    skip = 1 if path.read_text(encoding="utf-8").startswith("#") else 0
    return np.genfromtxt(path, delimiter=",", names=True, skip_header=skip)


def _figures(workdir: Path) -> dict[str, str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out: dict[str, str] = {}
    exc = _read(workdir / "01-excite.csv")
    if exc is not None:
        fig, ax = plt.subplots(2, 1, figsize=(10, 4.2), sharex=True)
        ax[0].plot(exc["t"], exc["theta"], lw=0.8)
        ax[0].set_ylabel("θ measured [rad]")
        ax[1].plot(exc["t"], exc["u"], lw=0.6, color="tab:orange")
        ax[1].set_ylabel("u [N·m]")
        ax[1].set_xlabel("t [s]")
        fig.suptitle("Excitation", fontsize=11)
        out["excite"] = _png(fig)
        plt.close(fig)
    run, pred = _read(workdir / "06-run.csv"), _read(workdir / "03-predicted.csv")
    if run is not None:
        fig, ax = plt.subplots(3, 1, figsize=(10, 7.0), sharex=True)
        ax[0].plot(run["t"], run["theta_ref"], color="0.5", lw=1.0, label="reference θd")
        ax[0].plot(run["t"], run["theta"], lw=1.0, label="measured θ (on board)")
        if pred is not None:
            ax[0].plot(pred["t"], pred["theta"], "--", lw=1.0, label="predicted θ")
        ax[0].set_ylabel("θ [rad]")
        ax[0].legend(loc="best", fontsize=8)
        ax[1].plot(run["t"], run["error"], lw=0.9, label="measured")
        if pred is not None:
            ax[1].plot(pred["t"], pred["theta"] - pred["theta_ref"], "--", lw=0.9,
                       label="predicted")
        ax[1].set_ylabel("θ − θd [rad]")
        ax[1].legend(loc="best", fontsize=8)
        ax[2].plot(run["t"], run["u"], lw=0.8, label="measured (the chip's)")
        if pred is not None:
            ax[2].plot(pred["t"], pred["u"], "--", lw=0.8, label="predicted")
        ax[2].set_ylabel("u [N·m]")
        ax[2].set_xlabel("t [s]")
        ax[2].legend(loc="best", fontsize=8)
        fig.suptitle("On-board run of the reference trajectory", fontsize=11)
        out["run"] = _png(fig)
        plt.close(fig)
    return out


def write_report(summary: dict[str, Any], path: Path, refused: dict[str, str] | None = None
                 ) -> Path:
    """Write the HTML page of a commissioning (finished or stopped) to ``path``.

    Parameters
    ----------
    summary : dict
        :meth:`esoarm.studies.commission.Commission.summary`.
    path : Path
        The page (its figures are inline).
    refused : dict, optional
        ``{"step", "reason", "advice"}`` when a step refused.

    Returns
    -------
    Path
    """
    workdir = Path(summary["workdir"])
    figs = _figures(workdir)
    p: list[str] = [f"<!doctype html><html><head><meta charset='utf-8'><title>Commissioning "
                    f"{html.escape(summary['scenario'])}</title><style>{_CSS}</style></head><body>",
                    f"<h1>Commissioning of {html.escape(summary['scenario'])}</h1>",
                    f"<p class='sub'>Rig: {html.escape(summary['rig'])} · work directory "
                    f"<code>{html.escape(str(workdir))}</code></p>"]
    agreement = summary.get("agreement")
    if refused:
        p.append(f"<div class='verdict bad'>Stopped at <b>{html.escape(refused['step'])}</b>: "
                 f"{html.escape(refused['reason'])}<br>To go on: "
                 f"{html.escape(refused['advice'])}</div>")
    elif agreement:
        good = agreement["rms_error_ok"] and agreement["rms_du_ok"]
        rel = agreement["relative"]
        p.append(f"<div class='verdict {'ok' if good else 'bad'}'>"
                 + ("Commissioned: the controller runs on the board and tracks as predicted"
                    if good else "The controller runs on the board, but not as predicted")
                 + f" (RMS error {_f(100 * rel['rms_error'], '+.1f')} %, RMS Δu "
                 f"{_f(100 * rel['rms_du'], '+.1f') if rel['rms_du'] is not None else '—'} % "
                 f"against the prediction; within ±{100 * agreement['limit']:.0f} % is "
                 "expected)</div>")
    steps = summary.get("steps", {})
    p.append("<h2>Steps</h2>")
    p.append(_table(["step", "status", "time [s]", "file"],
                    [[name, s["status"], _f(s.get("elapsed_s"), ".1f"), s["file"]]
                     for name, s in steps.items()]))

    ex = summary.get("excitation")
    if ex:
        p.append("<h2>1. Excitation</h2>")
        p.append(f"<p>A multisine of {ex['amplitude']:g} N·m RMS ({ex['tones']} tones, "
                 f"{ex['f_min']:g}–{ex['f_max']:g} Hz) for {ex['seconds']:g} s under a weak "
                 "guard loop, through the safety layer of <code>esoarm run</code>.</p>")
        p.append(_table(["", "reached", "limit"], [
            ["|u| [N·m]", ex["max_abs_u"], ex["torque_limit"]],
            ["|θ| [rad]", ex["max_abs_theta"], ex["angle_limit"]],
            ["samples", ex["samples"], "—"], ["lost samples", ex["lost_samples"], "—"]]))
        if "excite" in figs:
            p.append(figs["excite"])

    ident = summary.get("identified")
    if ident:
        p.append("<h2>2. Identification</h2>")
        p.append(f"<p>Output-error fit {ident['fit_percent']:.2f} %, validation "
                 f"{_f(ident['validation_fit_percent'], '.2f')} % on data not used for the "
                 f"fit; validation residual {'white' if ident['residual_white'] else 'NOT white'}"
                 f". Noise: {html.escape(ident['noise'])}.</p>")
        rows = [[k, v["value"], "withheld" if v["ci95"] is None
                 else f"[{_f(v['ci95'][0])}, {_f(v['ci95'][1])}]", v["unit"],
                 "fitted" if v["fitted"] else "held"] for k, v in ident["parameters"].items()]
        p.append(_table(["key", "value", "95 % interval", "unit", ""], rows))
        for k, v in ident["parameters"].items():
            for why in (v.get("withheld"), v.get("advice")):
                if why:
                    p.append(f"<p class='note'>{html.escape(k)}: {html.escape(why)}.</p>")
        if ident["poorly_identifiable"] or ident["at_bound"]:
            p.append(f"<p class='note'>Poorly determined: "
                     f"{html.escape(', '.join(ident['poorly_identifiable']) or 'none')}; at a "
                     f"bound: {html.escape(', '.join(ident['at_bound']) or 'none')}.</p>")
        p.append(f"<p class='note'>The identified scenario: <code>{ident['scenario']}</code>.</p>")

    d = summary.get("design")
    if d:
        p.append("<h2>3. Noise budget and observer</h2>")
        p.append(f"<p>Perturbation-estimate bandwidth {d['bandwidth']:.4g} rad/s "
                 f"({html.escape(d['bandwidth_source'])}; Nyquist π/Ts = {d['nyquist']:.4g} "
                 f"rad/s). Chosen: <b>observer.kind = {d['observer_kind']}, observer.eps = "
                 f"{d['eps']:.4g} s</b>: the least noise-driven control chatter at that "
                 "bandwidth among the kinds whose disturbance → error peak is within 1.5× of "
                 "the smallest.</p>")
        p.append(_table(["kind", "ε [s]", "bandwidth [rad/s]", "noise RMS u [N·m]",
                         "noise RMS Δu [N·m]", "disturbance → error peak [rad/(N·m)]"],
                        [[r["kind"], r["eps"], r["bandwidth"], r["rms_u"], r["rms_du"],
                          r["disturbance_peak"]] for r in d["recommendations"]]))
        for note in d["notes"]:
            p.append(f"<p class='note'>Note: {html.escape(note)}.</p>")
    cg, fl = summary.get("codegen"), summary.get("flash")
    if cg:
        p.append("<h2>4. Generated code</h2>")
        p.append(f"<p>C99 for the {cg['target'].upper()}, {cg['precision']}, "
                 f"{cg['observer_sums']} observer sums (scenario hash {cg['sha256']}): "
                 + ", ".join(f"<code>{html.escape(f)}</code>" for f in cg["files"]) + ".</p>")
        p.append(f"<p class='note'>Why these sums: {html.escape(cg['why'])}.</p>")
    if fl:
        p.append("<h2>5. Flashing</h2>")
        p.append(f"<p>On-board firmware: {fl['flash_bytes']} bytes of flash, {fl['ram_bytes']} "
                 f"bytes of static RAM, {fl['baud']} bit/s. Board: "
                 f"{html.escape(fl['board'])}.</p>")
    pr, me = summary.get("predicted"), summary.get("measured")
    if me or pr:
        p.append("<h2>6. On board: measured against predicted</h2>")
        p.append("<p>The reference trajectory, run by the chip's controller; the prediction is "
                 "<code>esoarm simulate</code> of the design on the identified rig.</p>")
        rows = []
        for key, label, unit in (("rms_error", "RMS tracking error", "rad"),
                                 ("rms_du", "RMS Δu (u_k − u_k−1)", "N·m"),
                                 ("rms_u", "RMS u", "N·m"),
                                 ("max_abs_error", "max |error|", "rad")):
            pv = pr.get(key) if pr else None
            mv = me.get(key) if me else None
            rel = (f"{100 * (mv / pv - 1):+.1f} %" if pv and mv is not None else "—")
            rows.append([label, pv, mv, rel, unit])
        p.append(_table(["", "predicted", "measured", "measured vs predicted", "unit"], rows))
        if me:
            p.append(f"<p class='note'>{me['samples']} samples logged, {me['lost_samples']} "
                     f"lost, {me['deadline_misses']} late; observer sums "
                     f"{html.escape(str(me['observer_sums']))}.</p>")
        if "run" in figs:
            p.append(figs["run"])
    p.append("<p class='note'>Every step's result is in its file in the work directory; "
             "<code>--resume</code> continues from them.</p></body></html>")
    tmp = path.with_suffix(".html.tmp")
    tmp.write_text("\n".join(p), encoding="utf-8")
    tmp.replace(path)
    return path
