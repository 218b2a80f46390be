"""Identification: a parameter that ends at a bound of the fit.

It is reported as at the bound (text and JSON), its interval is clipped to the
bounds and that is said; with a validation residual that is not white as well,
the fit is not trustworthy: exit status 1 and nothing written.
"""

from __future__ import annotations

import json

import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import load_scenario
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.fit import PARAMS


@pytest.fixture(scope="module")
def frictionless_log(tmp_path_factory):
    """A twin without viscous friction (truth at the lower bound 0 of the fit)."""
    path = tmp_path_factory.mktemp("bounds") / "b0.csv"
    excite_twin(load_scenario("test-1", ["rig.viscous_friction=0", "sensor.seed=2"]),
                ExcitationPlan(duration=12.0, seed=2), path)
    return path


def test_value_at_a_bound_is_reported_and_its_interval_clipped(run_cli, frictionless_log):
    args = (str(frictionless_log), "--max-delay", "0", "--fix", "actuator.lag")
    res = run_cli("identify", *args, "--json")
    assert res.exit_code == 0, res.stderr
    data = json.loads(res.stdout)
    visc = data["parameters"]["rig.viscous_friction"]
    low = PARAMS["rig.viscous_friction"][3][0]
    assert visc["value"] == low and visc["at_bound"] is True and visc["bound"] == "lower"
    assert visc["ci95"][0] == low < visc["ci95"][1] and visc["ci95_clipped"] is True
    assert data["at_bound"] == ["rig.viscous_friction"]
    assert data["validation"]["whiteness"]["white"]  # so the fit stands (exit 0)
    inside = data["parameters"]["rig.inertia_scale"]
    assert inside["at_bound"] is False and inside["ci95_clipped"] is False
    text = run_cli("identify", *args)
    assert text.exit_code == 0, text.stderr
    row = next(line for line in text.stdout.splitlines()
               if line.startswith("rig.viscous_friction"))
    assert "AT THE LOWER BOUND" in row
    assert "interval is clipped to the bounds" in text.stdout


def test_a_physical_zero_alone_does_not_make_the_fit_untrustworthy(frictionless_log) -> None:
    import dataclasses

    from esoarm.studies.identification.data import read_ident_log
    from esoarm.studies.identification.identify import identify

    scn = load_scenario("test-1")
    log = read_ident_log(frictionless_log, scn.actuator.torque_limit)
    res = identify(scn, [log], max_delay=0, fix=("actuator.lag",))
    visc = res.estimates["rig.viscous_friction"]
    assert visc.bound == "lower" and visc.value == 0.0
    res.validation["whiteness"] = {**res.validation["whiteness"], "white": False}
    assert res.untrustworthy() == ""  # "no viscous friction" is an answer
    res.estimates["rig.viscous_friction"] = dataclasses.replace(visc, bound="upper")
    assert "rig.viscous_friction at the upper bound" in res.untrustworthy()


@pytest.mark.slow
def test_at_a_bound_and_not_white_is_not_trustworthy(run_cli, tmp_path):
    """Friction far above the model's range (the arm creeps, sticks and slips): the fit runs
    the viscous friction into its upper bound and cannot whiten the residual."""
    log = tmp_path / "stuck.csv"
    excite_twin(load_scenario("test-1", ["rig.coulomb_friction=5"]),
                ExcitationPlan(duration=20.0), log)
    out, fig = tmp_path / "fit.toml", tmp_path / "fit.png"
    res = run_cli("identify", str(log), "--out", str(out), "--plot", str(fig))
    assert res.exit_code == 1, res.stdout + res.stderr
    # (progress lines first when stderr is not a terminal; the refusal is the last, one line)
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith("esoarm: failed") and "not trustworthy" in line
    assert "rig.viscous_friction at the upper bound" in line and "not white" in line
    # the bound comes from the data (no absolute number), and says how
    assert "(10× inertia × sample rate)" in line
    assert not out.exists() and not fig.exists() and list(tmp_path.iterdir()) == [log]


@pytest.mark.slow
def test_case_2_a_log_in_scaled_units_fits_the_same_physics(tmp_path):
    """Issue 20, case 2: no absolute bounds.  The same twin log with the torque in units
    1000 times smaller (and the scenario's masses and friction in them) fits the same
    physical values, ×1000.  With the old bounds (Coulomb and viscous friction ≤ 10) the
    scaled Coulomb friction, 55, was pinned at 10."""
    from esoarm.studies.identification.data import read_ident_log
    from esoarm.studies.identification.identify import identify

    k = 1000.0
    sets = ["sensor.seed=4"]
    path = tmp_path / "si.csv"
    excite_twin(load_scenario("test-1", sets), ExcitationPlan(duration=12.0, seed=4), path)
    lines = path.read_text(encoding="utf-8").splitlines()
    j = lines[0].split(",").index("u")
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[j] = repr(float(cells[j]) * k)
        out.append(",".join(cells))
    scaled = tmp_path / "scaled.csv"
    scaled.write_text("\n".join(out) + "\n", encoding="utf-8")
    scn = load_scenario("test-1", sets)
    p, r = scn.plant, scn.rig
    big = load_scenario("test-1", [*sets, f"plant.inertia={p.inertia * k!r}",
                                   f"plant.m1={p.m1 * k!r}", f"plant.m2={p.m2 * k!r}",
                                   f"rig.coulomb_friction={r.coulomb_friction * k!r}",
                                   f"rig.viscous_friction={r.viscous_friction * k!r}",
                                   f"actuator.torque_limit={scn.actuator.torque_limit * k!r}"])
    args = {"max_delay": 0, "fix": ("actuator.lag", "rig.stiction")}
    ref = identify(scn, [read_ident_log(path, scn.actuator.torque_limit)], **args)
    res = identify(big, [read_ident_log(scaled, big.actuator.torque_limit)], **args)
    assert not any(e.at_bound for e in res.estimates.values() if e.key != "rig.stiction")
    a, b = ref.physical(), res.physical()
    for name in ("inertia", "viscous_friction", "coulomb_friction", "gravity"):
        assert b[name]["value"] == pytest.approx(k * a[name]["value"], rel=1e-3), name
    assert res.estimates["rig.inertia_scale"].value == pytest.approx(
        ref.estimates["rig.inertia_scale"].value, rel=1e-3)
