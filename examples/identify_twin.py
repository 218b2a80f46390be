"""Identify a rig from an experiment: here a twin whose friction and inertia we pretend not
to know: record an experiment, fit the rig, write the fitted scenario and a figure.

Run:  python examples/identify_twin.py [OUTPUT_DIR]
"""

import sys
from pathlib import Path

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import load_scenario
from esoarm.studies.identification.data import read_ident_log
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.identify import identify
from esoarm.studies.identification.plots import figure_identification
from esoarm.studies.identification.report import scenario_toml

out = Path(sys.argv[1] if len(sys.argv) > 1 else "example-output")
out.mkdir(parents=True, exist_ok=True)

# the "real" rig: heavier and stickier than the nominal scenario believes
rig = load_scenario("test-1", {"rig.inertia_scale": 1.3, "rig.coulomb_friction": 0.09})
plan = ExcitationPlan(duration=30.0)  # multisine 0.1-5 Hz around a weak guard loop
excite_twin(rig, plan, out / "excite.csv")  # same columns as `esoarm excite --log`

nominal = load_scenario("test-1")  # what we believe: the starting point of the fit
log = read_ident_log(out / "excite.csv", nominal.actuator.torque_limit)
res = identify(nominal, [log])  # last 25 % of the log kept for validation

for key in ("rig.inertia_scale", "rig.coulomb_friction", "rig.viscous_friction"):
    est = res.estimates[key]
    print(f"{key:22s} {est.value:.4g} {est.unit}  (95 %: {est.ci95[0]:.4g} … {est.ci95[1]:.4g})")
print(f"validation fit {res.validation['fit_percent']:.1f} %, residual "
      f"{'white' if res.validation['whiteness']['white'] else 'not white'}")

fitted = res.fitted_scenario()  # plant.inertia = fitted inertia, the rig = the fit
(out / "fitted.toml").write_text(scenario_toml(res, fitted), encoding="utf-8")
figure_identification(res, out / "identify.png")
print(f"wrote {out / 'fitted.toml'} and {out / 'identify.png'}")
