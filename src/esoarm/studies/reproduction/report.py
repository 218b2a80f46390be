"""The reproduction report: one self-contained HTML page (``report.html``).

:func:`render_report` turns a :class:`esoarm.studies.reproduction.data.Reproduction` and its
figures (PNG bytes) into a single HTML document with inline CSS and figures
embedded as base64 ``data:`` URIs: no scripts, no network, no other files.
It shows

- the paper's Tables II and III beside the twin's numbers;
- each qualitative claim, reproduced or not, with the numbers behind it;
- the figures corresponding to the paper's Fig. 4-7;
- the twin's assumptions where the paper is silent, each value read from the
  resolved scenarios that ran (nothing typed in by hand);
- the Theorem 1 and Theorem 2 checks;
- the three ESO discretizations compared on the same experiments and what
  that means for choosing ε at the sample rate;
- the esoarm version and the resolved scenarios.

Every number on the page comes from the :class:`Reproduction` (the paper's
values from :data:`esoarm.studies.reproduction.data.PAPER_TABLES`, quoted).
"""

from __future__ import annotations

import base64
import html
import platform
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from esoarm import __version__

if TYPE_CHECKING:
    from esoarm.scenario import Scenario
    from esoarm.studies.reproduction.data import Reproduction

__all__ = ["ASSUMPTIONS", "assumption_rows", "render_report", "summary_text"]

#: Scenario keys the paper does not give, with why the twin needs them.  The
#: values shown in the report are read from the resolved scenarios.
ASSUMPTIONS: tuple[tuple[str, str], ...] = (
    ("reference", "Reference trajectory: the paper shows it only in Fig. 4 and 6."),
    ("duration", "Run length: not stated (the figures span about 20 s)."),
    ("controller.k1", "FLC error-rate gain k1 (eq. 16): not given."),
    ("controller.k2", "FLC error gain k2 (eq. 16): not given."),
    ("rig.coulomb_friction", "Coulomb friction of the rig: not given (unmodelled dynamics)."),
    ("rig.friction_velocity", "Smoothing velocity of the Coulomb friction: modelling choice."),
    ("rig.viscous_friction", "Viscous friction of the rig: not given."),
    ("rig.inertia_scale", "The paper states a 10 % inertia uncertainty, not its sign."),
    ("sensor.noise_deg", "Encoder noise: not given (only the 0.05° resolution)."),
    ("sensor.seed", "Seed of the simulated noise (the twin is deterministic)."),
    ("actuator.torque_limit", "Torque saturation of the 12 V motor and driver: not given."),
    ("actuator.lag", "Actuator lag: not given."),
    ("actuator.delay_samples", "Transport delay: not given."),
    ("observer.discretization", "How eq. 8 was discretized in Simulink: not stated "
                                "(a fixed-step Euler solver is assumed)."),
    ("rig.step", "Integration step of the twin (RK4)."),
    ("rig.theta0", "Initial angle: not given."),
)

_CSS = """
:root { --ok: #1a7f37; --bad: #b42318; --muted: #57606a; --line: #d0d7de; }
* { box-sizing: border-box; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
       color: #1f2328; margin: 0; background: #f6f8fa; }
main { max-width: 1080px; margin: 0 auto; padding: 24px 32px 64px; background: #fff; }
h1 { font-size: 1.7em; margin: 0.2em 0; }
h2 { font-size: 1.3em; border-bottom: 1px solid var(--line); padding-bottom: 4px;
     margin-top: 2em; }
h3 { font-size: 1.05em; margin-top: 1.4em; }
p.meta, .muted { color: var(--muted); }
nav ol { columns: 2; padding-left: 1.4em; }
table { border-collapse: collapse; margin: 0.6em 0 1em; font-size: 0.92em; }
th, td { border: 1px solid var(--line); padding: 4px 8px; text-align: right;
         vertical-align: top; }
th { background: #f0f3f6; }
td.l, th.l { text-align: left; }
td.nw { white-space: nowrap; }
tr.sep td { border-top: 2px solid #8c959f; }
.pair { display: flex; flex-wrap: wrap; gap: 24px; }
.badge { display: inline-block; padding: 1px 8px; border-radius: 10px; color: #fff;
         font-weight: 600; font-size: 0.85em; white-space: nowrap; }
.ok { background: var(--ok); } .bad { background: var(--bad); }
figure { margin: 1.2em 0; text-align: center; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--line); }
figcaption { color: var(--muted); font-size: 0.9em; margin-top: 4px; }
pre { background: #f6f8fa; border: 1px solid var(--line); padding: 8px; overflow-x: auto;
      font-size: 0.85em; text-align: left; }
details { margin: 4px 0; } summary { cursor: pointer; }
code { font-size: 0.92em; background: #f0f3f6; padding: 0 3px; border-radius: 3px; }
.summary { font-size: 1.05em; padding: 10px 14px; border-left: 4px solid #0072B2;
           background: #f0f6fc; }
"""


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _num(value: float | None, digits: int = 4) -> str:
    if value is None:
        return "—"
    return f"{value:.{digits}g}"


def _badge(ok: bool, yes: str = "reproduced", no: str = "not reproduced") -> str:
    return f'<span class="badge {"ok" if ok else "bad"}">{_e(yes if ok else no)}</span>'


def _table(head: list[str], rows: list[list[str]], left: int = 1,
           sep_every: int = 0, text_cols: tuple[int, ...] = ()) -> str:
    """An HTML table; cells are already-escaped HTML.

    The first ``left`` columns and the ``text_cols`` are left-aligned, the
    rest (numbers) right-aligned; the first column does not wrap.
    """
    def cls(i: int) -> str:
        names = (["l"] if i < left or i in text_cols else []) + (["nw"] if i == 0 else [])
        return " ".join(names)

    out = ["<table><thead><tr>"]
    out += [f'<th class="{cls(i)}">{h}</th>' for i, h in enumerate(head)]
    out.append("</tr></thead><tbody>")
    for n, row in enumerate(rows):
        sep = ' class="sep"' if sep_every and n and n % sep_every == 0 else ""
        out.append(f"<tr{sep}>")
        out += [f'<td class="{cls(i)}">{c}</td>' for i, c in enumerate(row)]
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _get(data: Mapping[str, Any], dotted: str) -> Any:
    value: Any = data
    for part in dotted.split("."):
        value = value[part]
    return value


def _units() -> dict[str, str]:
    from esoarm.scenario.keys_doc import scenario_keys

    return {key: unit for key, _default, unit, _desc in scenario_keys()}


def _fmt_value(value: Any) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{k} = {_fmt_value(v)}" for k, v in value.items())
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


def assumption_rows(scenarios: Mapping[str, Scenario]) -> list[tuple[str, str, str, str]]:
    """(key, value, unit, why) for every :data:`ASSUMPTIONS` key, values from ``scenarios``.

    Where the experiments differ in a key (the reference: test-1 against
    test-2), one row per distinct value names the scenarios that use it;
    ε and the compensation, which the experiments vary on purpose, are not
    assumptions and are not listed.

    Parameters
    ----------
    scenarios : mapping of str to Scenario
        The experiments' scenarios by run key.

    Returns
    -------
    list of tuple of str
        (key, value, unit, why), one row per key and distinct value.
    """
    units = _units()
    rows: list[tuple[str, str, str, str]] = []
    for key, why in ASSUMPTIONS:
        by_value: dict[str, list[str]] = {}
        for name, scn in scenarios.items():
            by_value.setdefault(_fmt_value(_get(scn.to_dict(), key)), []).append(
                scn.name if key == "reference" else name)
        for value, names in by_value.items():
            where = ""
            if len(by_value) > 1:
                where = f" ({', '.join(sorted(set(names)))})"
            rows.append((key + where, value, units.get(key, ""), why))
    return rows


def summary_text(rep: Reproduction) -> str:
    """What the twin reproduces, in a few sentences built from the runs.

    The ratio of the paper's RMS control to the twin's, the ε with the lowest
    RMS tracking error per test, and the claims reproduced and not.

    Parameters
    ----------
    rep : Reproduction
        A finished reproduction (:func:`~esoarm.studies.reproduction.run.run_reproduction`).

    Returns
    -------
    str
        The sentences, plain text (the caller escapes it for HTML).
    """
    from esoarm.studies.reproduction.data import EPS_SET, PAPER_TABLES, TABLE_NAMES

    ratios = [PAPER_TABLES[t][e][1] / rep.metric(t, e, "rms_u")
              for t in TABLE_NAMES for e in EPS_SET]
    def error_at(test: str) -> Callable[[float], float]:
        return lambda eps: rep.metric(test, eps, "rms_error")

    best = {t: min(EPS_SET, key=error_at(t)) for t in TABLE_NAMES}
    ok = [f"{c.statement} ({c.source})" for c in rep.claims if c.reproduced]
    not_ok = [f"{c.statement} ({c.source})" for c in rep.claims if not c.reproduced]
    return (
        "A twin is not the paper's hardware. The twin's RMS control is "
        f"{min(ratios):.1f} to {max(ratios):.1f} times smaller than the paper's (its friction "
        "and the rest of its unmodelled dynamics are assumptions, not measured values). On the "
        "twin the lowest RMS tracking error is at "
        + " and ".join(f"ε = {e:g} s in {t}" for t, e in best.items())
        + " (paper: ε = 0.09 s in both). Reproduced: " + ("; ".join(ok) or "none")
        + ". Not reproduced: " + ("; ".join(not_ok) or "none") + ".")


def _img(pngs: Mapping[str, bytes], stem: str, caption: str) -> str:
    if stem not in pngs:
        return ""
    data = base64.b64encode(pngs[stem]).decode("ascii")
    return (f'<figure id="{_e(stem)}"><img src="data:image/png;base64,{data}" '
            f'alt="{_e(caption)}"><figcaption>{_e(caption)}</figcaption></figure>')


def _tables_section(rep: Reproduction) -> str:
    from esoarm.studies.reproduction.data import EPS_SET, PAPER_TABLES, TABLE_NAMES

    parts = ['<div class="pair">']
    for test, name in TABLE_NAMES.items():
        rows = []
        for eps in EPS_SET:
            p_err, p_u = PAPER_TABLES[test][eps]
            rows.append([f"{eps:g}", f"{p_err:.4f}", f"{rep.metric(test, eps, 'rms_error'):.4f}",
                         f"{p_u:.4f}", f"{rep.metric(test, eps, 'rms_u'):.4f}",
                         f"{rep.metric(test, eps, 'du_rms'):.4f}"])
        parts.append(f"<div><h3>{_e(name)} — {_e(test)}</h3>" + _table(
            ["ε [s]", "error [rad]<br>paper", "error [rad]<br>twin", "control [N·m]<br>paper",
             "control [N·m]<br>twin", "Δu [N·m]<br>twin"], rows) + "</div>")
    parts.append("</div>")
    parts.append(
        '<p class="muted">RMS over the run. Paper: hardware (quoted from its Tables II and III). '
        "Twin: the built-in digital twin with the assumptions listed below; Δu: RMS of "
        "u_k − u_k−1 (control chatter; the paper gives none). A twin does not "
        "reproduce hardware numbers; compare the trends, which the claims below check.</p>")
    if rep.baselines:
        rows = [[_e(test), f"{res.metrics['rms_error']:.4f}", f"{res.metrics['rms_u']:.4f}",
                 f"{rep.metric(test, 0.09, 'rms_error'):.4f}",
                 f"{rep.metric(test, 0.09, 'rms_u'):.4f}"]
                for test, res in rep.baselines.items()]
        parts.append(
            "<h3>Baseline: a discrete PID on the measured angle (not in the paper)</h3>"
            "<p>The same twin and tests with <code>controller.kind = \"pid\"</code> at its "
            "default gains (tuned on test-1; derivative filter, anti-windup), beside the "
            "paper's ESO + FLC at ε = 0.09 s.</p>" + _table(
                ["test", "error [rad]<br>PID", "control [N·m]<br>PID",
                 "error [rad]<br>ESO + FLC", "control [N·m]<br>ESO + FLC"], rows))
    return "".join(parts)


def _claims_section(rep: Reproduction) -> str:
    rows = [[_badge(c.reproduced), _e(c.source), _e(c.statement), _e(c.evidence)]
            for c in rep.claims]
    n_ok = sum(c.reproduced for c in rep.claims)
    return (f"<p>{n_ok} of {len(rep.claims)} claims reproduced on the twin.</p>"
            + _table(["on the twin", "paper", "claim", "numbers behind it"], rows, left=4)
            + f"<p>{_e(summary_text(rep))}</p>")


def _theorem_section(rep: Reproduction, pngs: Mapping[str, bytes]) -> str:
    parts = [
        "<h3>Theorem 1 — observer poles</h3>",
        "<p>With β = (3/ε, 3/ε², 1/ε³) the error matrix A − βC of eq. 10 has the characteristic "
        "polynomial (s + 1/ε)³. The check computes the polynomial from the matrix the "
        "simulator uses and compares it with (s + 1/ε)³; for each discretization at Ts the "
        "same is done with the discrete error matrix and its design pole (Euler: 1 − Ts/ε; "
        "zoh, current: e<sup>−Ts/ε</sup>).</p>",
    ]
    rows = []
    for c in rep.observer_checks:
        cells = [f"{c.eps:g}", f"{c.continuous_pole:.4g}", f"{c.charpoly_deviation:.1e}"]
        for disc, d in c.discrete.items():
            cells.append(f"{d['pole']:.4f} ({_e(disc)}) "
                         + _badge(bool(d["stable"]), "stable", "unstable")
                         + f" <span class='muted'>dev {float(d['charpoly_deviation']):.0e}</span>")
        rows.append(cells)
    if rep.observer_checks:
        discs = list(rep.observer_checks[0].discrete)
        ts = rep.observer_checks[0].ts
        parts.append(_table(
            ["ε [s]", "continuous pole −1/ε [1/s]", "char. poly deviation"]
            + [f"{_e(d)}: z-pole at Ts = {ts:g} s" for d in discs], rows))
    t1 = [c for c in rep.bound_checks if c.theorem == "Theorem 1"]
    t2 = [c for c in rep.bound_checks if c.theorem == "Theorem 2"]
    if t1:
        parts.append(
            "<h3>Theorem 1 — estimation-error bound</h3><p>For the continuous observer, "
            "|z̃<sub>i</sub>| ≤ sup|γ|·(ε³, 3ε², 3ε) once the initial error has decayed "
            "(eq. 11-12; the L1 norms of the error responses to γ = ḟ). Measured on each run "
            f"over t ≥ {t1[0].t_from:g} s, with sup|γ| from the difference quotient of the true "
            "perturbation. The runs are sampled at 50 Hz with noise, which the theorem does not "
            "cover; the noise also enters γ through the control, so the bound is loose.</p>")
        rows = [[_e(c.run), f"{c.driver:.4g}",
                 " / ".join(f"{m:.3g}" for m in c.measured),
                 " / ".join(f"{b:.3g}" for b in c.bound), _badge(c.holds, "holds", "violated"),
                 _e(c.note)] for c in t1]
        parts.append(_table(["run", "sup|γ| [rad/s³]",
                             "measured max |θ−z1| / |θ̇−z2| / |f−z3|",
                             "bound [rad / rad/s / rad/s²]", "verdict", "note"], rows, left=1,
                            text_cols=(5,)))
    if t2:
        parts.append(
            "<h3>Theorem 2 — tracking-error bound</h3><p>The tracking error obeys "
            "ë + k1 ė + k2 e = κ (eq. 17) with κ the estimation error of the control law. "
            "With |κ| ≤ μ the steady-state error is bounded by μ/k2 (eq. 20) when "
            "k1² ≥ 4k2, in general by μ‖h‖₁ (h the impulse response of 1/(s² + k1 s + k2)). "
            f"μ is measured on each run over t ≥ {t2[0].t_from:g} s from κ = (f − β̂) + "
            "k1(θ̇ − ẑ2) + k2(θ − ẑ1), leaving out saturated samples.</p>")
        rows = [[_e(c.run), f"{c.driver:.4g}", f"{c.measured[0]:.4g}", f"{c.bound[0]:.4g}",
                 _badge(c.holds, "holds", "violated"), _e(c.note)] for c in t2]
        parts.append(_table(["run", "μ = max|κ| [rad/s²]", "max |e| [rad]",
                             "bound μ‖h‖₁ [rad]", "verdict", "note"], rows, left=1,
                            text_cols=(5,)))
        parts.append(_img(pngs, "theorem2",
                          "Theorem 2 on test-1: |e(t)| (solid) against μ/k2 (dashed), one "
                          "colour per ε"))
    return "".join(parts)


def _discretization_section(rep: Reproduction, pngs: Mapping[str, bytes]) -> str:
    from esoarm.studies.reproduction.data import table_metrics

    if not rep.comparison:
        return "<p>Not run (reproduction without comparisons).</p>"
    discs = list(rep.comparison)
    parts = [
        "<p>The paper's experiments repeated with each ESO discretization of the loop: "
        "<b>euler</b> (the paper's fixed-step form, z⁺ = z + Ts·eq. 8), <b>zoh</b> (exact "
        "discrete model of the extended plant, predictive form) and <b>current</b> (exact "
        "model, corrected with y<sub>k</sub> before the control is computed). Everything else "
        "is identical, including the noise sequence.</p>"]
    rows = []
    for key in rep.comparison[discs[0]]:
        cells = [_e(key)]
        for metric in ("rms_error", "rms_u", "du_rms"):
            cells += [f"{table_metrics(rep.comparison[d][key])[metric]:.4f}" for d in discs]
        rows.append(cells)
    head = ["run"]
    for label in ("RMS error [rad]", "RMS u [N·m]", "RMS(Δu) [N·m]"):
        head += [f"{label}<br>{_e(d)}" for d in discs]
    parts.append(_table(head, rows))
    parts.append(_img(pngs, "discretizations",
                      "RMS tracking error and control noise RMS(Δu) against ε on test-1, one "
                      "line per discretization; grey: ε ≤ Ts"))
    parts.append("<h3>What this means for choosing ε at 50 Hz</h3><ul>")
    parts += [f"<li>{_e(s)}</li>" for s in rep.findings]
    parts.append("</ul>")
    sweep_rows = [[_e(r["discretization"]), f"{r['eps']:g}", f"{r['rms_error']:.4f}",
                   f"{r['rms_u']:.4f}", f"{r['du_rms']:.4f}", f"{r['pert_est_rms']:.3g}"]
                  for r in rep.sweep_rows()]
    parts.append("<details><summary>All sweep runs (table)</summary>" + _table(
        ["discretization", "ε [s]", "RMS error [rad]", "RMS u [N·m]", "RMS(Δu) [N·m]",
         "RMS(z3 − f) [rad/s²]"], sweep_rows, sep_every=len(rep.sweep[discs[0]]))
        + "</details>")
    return "".join(parts)


def _assumptions_section(rep: Reproduction) -> str:
    rows = [[f"<code>{_e(k)}</code>", f"<code>{_e(v)}</code>", _e(u), _e(w)]
            for k, v, u, w in assumption_rows(rep.scenarios)]
    return ("<p>The paper gives the model (Table I), the disturbance (eq. 6), the 10 % inertia "
            "uncertainty, the 50 Hz encoder with 0.05° resolution and the ESO/FLC structure. "
            "The twin needs more; these values come from the resolved scenarios that produced "
            "this report. The ESO starts at (y<sub>0</sub>, 0, 0) (the sampled-data loop).</p>"
            + _table(["key", "value", "unit", "why it is an assumption"], rows, left=4))


def _scenarios_section(rep: Reproduction) -> str:
    parts = [f"<p>esoarm {_e(__version__)}, Python {_e(platform.python_version())}, "
             f"{rep.runs_text()}. The paper's set below; the discretization "
             "comparison and the ε sweep use the same scenarios with "
             "<code>observer.discretization</code> and <code>observer.eps</code> changed. "
             "Run one again with <code>esoarm simulate test-1 --set observer.eps=0.05</code> "
             "or from the TOML text.</p>"]
    for key, scn in rep.scenarios.items():
        parts.append(f"<details><summary><code>{_e(key)}</code></summary>"
                     f"<pre>{_e(scn.to_toml())}</pre></details>")
    return "".join(parts)


def render_report(rep: Reproduction, pngs: Mapping[str, bytes],
                  extra_sections: Sequence[tuple[str, str, str]] = (),
                  captions: Mapping[str, str] | None = None) -> str:
    """The reproduction report as one self-contained HTML document.

    Parameters
    ----------
    rep : Reproduction
        From :func:`esoarm.studies.reproduction.run.run_reproduction`.
    pngs : mapping stem -> PNG bytes
        Figures from :func:`esoarm.studies.reproduction.run.figure_specs` (``fig4`` … ``fig7``,
        ``theorem2``, ``discretizations``); missing ones are left out.
    extra_sections : sequence of (id, title, HTML)
        Further sections, placed after the claims (e.g. the two twins of
        :func:`esoarm.studies.reproduction.twins.twins_section`).
    captions : mapping stem -> str, optional
        Figure captions (:func:`esoarm.studies.reproduction.outputs.captions`); a
        figure without one is shown with its stem.

    Returns
    -------
    str
        HTML5 text (UTF-8), no external resources.
    """
    captions = dict(captions or {})
    n_ok = sum(c.reproduced for c in rep.claims)
    sections = [
        ("tables", "Tables II and III: paper beside twin", _tables_section(rep)),
        ("claims", "The paper's claims, checked on the twin", _claims_section(rep)),
        *extra_sections,
        ("figures", "Fig. 4-7 on the twin", "".join(
            _img(pngs, s, captions.get(s, s)) for s in ("fig4", "fig5", "fig6", "fig7")
            if s in pngs)),
        ("theorems", "Theorem 1 and Theorem 2", _theorem_section(rep, pngs)),
        ("discretizations", "ESO discretizations compared", _discretization_section(rep, pngs)),
        ("assumptions", "Assumptions where the paper is silent", _assumptions_section(rep)),
        ("provenance", "Version and resolved scenarios", _scenarios_section(rep)),
    ]
    toc = "".join(f'<li><a href="#{sid}">{_e(title)}</a></li>' for sid, title, _ in sections)
    body = "".join(f'<section id="{sid}"><h2>{_e(title)}</h2>{content}</section>'
                   for sid, title, content in sections)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
        f"<title>esoarm reproduction report (esoarm {_e(__version__)})</title>"
        f"<style>{_CSS}</style></head><body><main>"
        "<h1>ESO-based feedback linearization of a lever arm: reproduction on the digital twin"
        "</h1>"
        f'<p class="meta">esoarm {_e(__version__)} · paper\'s experiment set '
        f"(test-1 and test-2 at ε = 0.05, 0.09, 0.2 s, and the Fig. 7 ablation) · "
        f"{rep.runs_text()}</p>"
        f'<p class="summary">{n_ok} of {len(rep.claims)} of the paper\'s qualitative claims '
        "are reproduced on the twin. The twin's numbers are not the paper's hardware numbers; "
        "see the assumptions below.</p>"
        f"<nav><ol>{toc}</ol></nav>{body}</main></body></html>\n"
    )
