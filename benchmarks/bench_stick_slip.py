"""Identification on stick-slip twins: recovered, refused, or confidently wrong?

A grid of 20 emulated rigs (test-1's twin): Coulomb friction 0.02 … 0.10 N·m (up to
half the excitation's 0.2 N·m RMS torque), inertia scale 0.8 or 1.25, with and without
Stribeck stiction (0.05 N·m above Coulomb; the fit frees ``rig.stiction`` and keeps it by a
likelihood-ratio test).
Each is excited with the default plan of ``esoarm excite`` (60 s at 50 Hz) and fitted
by :func:`esoarm.studies.identification.identify.identify` from test-1's values.

A rig is *recovered* when the truth of the inertia scale, the Coulomb friction and the
stiction lie inside the fit's 95 % intervals (or within 5 %: intervals of a few 1e-3 on an exact
twin), *refused* when the fit raises (one line naming why), and *wrong* otherwise --
accepted, with the truth outside both.  The goal is no *wrong*.

Run: ``python benchmarks/bench_stick_slip.py`` (writes docs/benchmarks-stick-slip.md).
"""

from __future__ import annotations

import datetime
import os
import tempfile
import time
from pathlib import Path

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.identification.data import read_ident_log
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.identify import FitFailed, identify

ROOT = Path(__file__).resolve().parents[1]
COULOMB = (0.02, 0.04, 0.06, 0.08, 0.10)
INERTIA = (0.8, 1.25)
STICTION = (0.0, 0.05)


def _inside(est, truth: float) -> bool:
    lo, hi = est.ci95
    return lo <= truth <= hi or abs(est.value - truth) <= 0.05 * abs(truth)


def main() -> None:
    rows = []
    counts = {"recovered": 0, "refused": 0, "wrong": 0}
    nominal = load_scenario("test-1")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for k, (fc, scale, fst) in enumerate((c, i, s) for s in STICTION for i in INERTIA
                                             for c in COULOMB):
            truth = load_scenario("test-1", [f"rig.coulomb_friction={fc}",
                                             f"rig.inertia_scale={scale}",
                                             f"rig.stiction={fst}", f"sensor.seed={k}"])
            path = Path(tmp) / f"rig{k}.csv"
            excite_twin(truth, ExcitationPlan(seed=k), path)
            try:
                res = identify(nominal, [read_ident_log(path, 2.0)])
            except (FitFailed, ScenarioError) as exc:
                counts["refused"] += 1
                rows.append((fc, scale, fst, "refused", "–", "–", "–", str(exc)[:160]))
                continue
            ei, ec = res.estimates["rig.inertia_scale"], res.estimates["rig.coulomb_friction"]
            es = res.estimates["rig.stiction"]
            ok = _inside(ei, scale) and _inside(ec, fc) and (
                es.ci95[0] <= fst <= es.ci95[1] or abs(es.value - fst) <= 0.05 * max(fst, 0.01))
            verdict = "recovered" if ok else "wrong"
            counts[verdict] += 1
            rows.append((fc, scale, fst, verdict,
                         f"{ei.value:.3f} [{ei.ci95[0]:.3f}, {ei.ci95[1]:.3f}]",
                         f"{ec.value:.4f} [{ec.ci95[0]:.4f}, {ec.ci95[1]:.4f}]",
                         f"{es.value:.4f} [{es.ci95[0]:.4f}, {es.ci95[1]:.4f}]",
                         f"delay {int(res.value('actuator.delay_samples'))}, validation "
                         f"{res.validation.get('fit_percent', float('nan')):.1f} %"))
    elapsed = time.perf_counter() - t0
    lines = ["# Stick-slip identification benchmark", "",
             f"Measured with `python benchmarks/bench_stick_slip.py` on "
             f"{datetime.date.today().isoformat()} ({elapsed:.0f} s, load average "
             f"{os.getloadavg()[0]:.2f}).", "",
             (__doc__ or "").split("\n\n")[1].replace("\n", " "), "",
             f"**{counts['recovered']} recovered, {counts['refused']} refused, "
             f"{counts['wrong']} wrong** of {len(rows)}.", "",
             "| Fc [N·m] | inertia scale | stiction [N·m] | verdict | inertia scale fit | "
             "Fc fit [N·m] | stiction fit [N·m] | notes |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {fc:g} | {sc:g} | {st:g} | {v} | {a} | {b} | {s} | {c.replace('|', '/')} |"
              for fc, sc, st, v, a, b, s, c in rows]
    out = ROOT / "docs" / "benchmarks-stick-slip.md"
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
