"""The issue's real-log cases on the lever arm: degrees, a disturbance the log lacks, noise.

Each test fails on the code before IDIM-LS was computed beside the output-error fit
(that code fitted a log in degrees with exit 0, blamed the delay bound for a template's
disturbance, and wrote the residual of a model error into sensor.noise_deg).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.identification.data import read_ident_log
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.identify import FitFailed, identify
from esoarm.studies.identification.lever_checks import lever_idim


@pytest.fixture(scope="module")
def twin_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("twin") / "ex.csv"
    excite_twin(load_scenario("test-1"), ExcitationPlan(duration=30.0), path)
    return path


def _rewrite(src, dst, column, factor):
    lines = src.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    cols = [header.index(c) for c in column]
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for j in cols:
            cells[j] = repr(float(cells[j]) * factor)
        out.append(",".join(cells))
    dst.write_text("\n".join(out) + "\n", encoding="utf-8")
    return dst


def test_idim_ls_of_the_twin_finds_its_inertia_and_disturbance(twin_log):
    scn = load_scenario("test-1")
    est = lever_idim(scn, [read_ident_log(twin_log, 2.0)])
    assert est is not None
    true_inertia = scn.rig.inertia_scale * scn.plant.inertia
    assert est.value("inertia") == pytest.approx(true_inertia, rel=0.1)
    assert -est.value("disturbance") / est.value("inertia") == pytest.approx(0.2, rel=0.25)


def test_a_log_in_degrees_is_refused_as_bad_input(twin_log, tmp_path):
    """Issue 20, case 9: angles in degrees (was exit 0, fit 35 %, a scenario written)."""
    deg = _rewrite(twin_log, tmp_path / "deg.csv", ("y", "theta"), 180.0 / math.pi)
    scn = load_scenario("test-1")
    with pytest.raises(ScenarioError, match=r"units look wrong: .* 0\.0[12]\d+× .*degrees"):
        identify(scn, [read_ident_log(deg, 2.0)])


def test_cli_degrees_exit_2_nothing_written(twin_log, tmp_path, run_cli):
    deg = _rewrite(twin_log, tmp_path / "deg.csv", ("y", "theta"), 180.0 / math.pi)
    out = tmp_path / "fitted.toml"
    res = run_cli("identify", str(deg), "--out", str(out))
    assert res.exit_code == 2 and "units look wrong" in res.stderr and not out.exists()


def test_a_template_disturbance_the_log_lacks_is_named(tmp_path):
    """Issue 20, case 6, on a log of two periods and more (IDIM-LS decides)."""
    path = tmp_path / "nod.csv"
    excite_twin(load_scenario("test-1", ["rig.disturbance.amplitude=0"]),
                ExcitationPlan(duration=60.0), path)
    with pytest.raises(FitFailed, match=r"rig\.disturbance\.amplitude"):
        identify(load_scenario("test-1"), [read_ident_log(path, 2.0)])


@pytest.mark.slow
def test_case_6_a_template_disturbance_is_named_on_a_log_shorter_than_two_periods(tmp_path):
    """Issue 20, case 6, on a 15 s log (two periods of the template's 0.5 rad/s sine take
    25 s, so IDIM-LS cannot tell): the fit without d(t) wins the likelihood-ratio test and
    the refusal names the key.  The code before accepted this log (exit 0) with a stiction
    that is not there and 4× the sensor noise; and a log that has the disturbance is not
    refused."""
    path = tmp_path / "nod.csv"
    excite_twin(load_scenario("test-1", ["rig.disturbance.amplitude=0"]),
                ExcitationPlan(duration=15.0), path)
    with pytest.raises(FitFailed, match=r"rig\.disturbance\.amplitude") as err:
        identify(load_scenario("test-1"), [read_ident_log(path, 2.0)])
    assert "shorter than two of its periods" in str(err.value)
    assert "delay" not in str(err.value) and "blocked" not in str(err.value)
    has = tmp_path / "has.csv"
    excite_twin(load_scenario("test-1"), ExcitationPlan(duration=15.0), has)
    res = identify(load_scenario("test-1"), [read_ident_log(has, 2.0)])
    assert res.estimates["rig.inertia_scale"].value == pytest.approx(1.1, rel=0.1)


@pytest.mark.slow
def test_noise_is_written_only_when_the_residual_is_white(twin_log):
    """Issue 20, case 5: sensor.noise_deg is written only when the residual is white, or
    sensor noise by its spectrum (the model error of a fit is not sensor noise)."""
    scn = load_scenario("test-1")
    res = identify(scn, [read_ident_log(twin_log, 2.0)])
    white = res.validation["whiteness"]["white"]
    fitted = res.fitted_scenario()
    coloured = res.coloured_noise()  # sensor noise by its spectrum (white: [])
    if white or coloured is not None:
        assert fitted.sensor.noise_deg == pytest.approx(res.value("sensor.noise_deg"))
        assert fitted.sensor.noise_ar == (coloured or [])
    else:
        assert fitted.sensor.noise_deg == scn.sensor.noise_deg
    assert res.noise_is_sensor() is bool(white)
    data = res.to_json()
    assert np.isfinite(data["idim_ls"]["force_error_percent"])
    phys = data["physical"]
    assert {"inertia", "viscous_friction", "coulomb_friction", "offset"} <= set(phys)
    assert phys["inertia"]["unit"] == "kg·m²" and phys["coulomb_friction"]["unit"] == "N·m"
    assert phys["inertia"]["value"] == pytest.approx(
        res.value("rig.inertia_scale") * scn.plant.inertia)


@pytest.mark.slow
def test_stick_slip_is_recovered(tmp_path):
    """Issue 20, case 8: Coulomb friction half the excitation's RMS torque plus breakaway
    friction (the fit used to settle on a wrong delay and exclude the truth)."""
    truth = load_scenario("test-1", ["rig.coulomb_friction=0.1", "rig.stiction=0.05",
                                     "rig.inertia_scale=1.25", "sensor.seed=19"])
    path = tmp_path / "stick.csv"
    excite_twin(truth, ExcitationPlan(seed=19), path)
    res = identify(load_scenario("test-1"), [read_ident_log(path, 2.0)])
    assert res.value("actuator.delay_samples") == 0
    for key, true in (("rig.inertia_scale", 1.25), ("rig.coulomb_friction", 0.1),
                      ("rig.stiction", 0.05)):
        lo, hi = res.estimates[key].ci95
        assert lo <= true <= hi or res.value(key) == pytest.approx(true, rel=0.03), key
