"""Identification of an axis (plant kind "axis"): IDIM-LS, HAC intervals, refusals, EMPS."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from esoarm.studies.identification.idim import (
    ASYMMETRY_Z,
    cross_test,
    filtered_derivatives,
    hac_covariance,
    idim_ls,
    viscous_asymmetry,
)

ROOT = Path(__file__).resolve().parents[3]
EMPS = ROOT / "examples" / "emps"
#: The data set's published IDIM-LS values (its description, section 3.4).
PUBLISHED = {"mass": 95.1089, "viscous_friction": 203.5034, "coulomb_friction": 20.3935,
             "offset": -3.1648}
TS = 1e-3


def _trajectory(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A smooth back-and-forth position [m] with its exact velocity and acceleration."""
    t = np.arange(n) * TS
    q = np.zeros(n)
    v = np.zeros(n)
    a = np.zeros(n)
    for f, amp in ((0.15, 0.1), (0.4, 0.03), (1.1, 0.01)):
        w = 2 * math.pi * f
        ph = rng.uniform(0, 2 * math.pi)
        q += amp * np.sin(w * t + ph)
        v += amp * w * np.cos(w * t + ph)
        a -= amp * w * w * np.sin(w * t + ph)
    return q, v, a


def _log(theta, n=20000, seed=0, rho=0.995, sigma=2.0, change=None, viscous_asymmetry=0.0):
    """(y, u): position and force of an axis following a smooth trajectory, the force with
    AR(1) noise of correlation ``rho`` per sample (coloured: ripple, model error);
    Fv± = Fv ± ``viscous_asymmetry``/2."""
    rng = np.random.default_rng(seed)
    q, v, a = _trajectory(n, rng)
    m, fv, fc, off = theta
    mass = np.full(n, m)
    if change is not None:
        mass[n // 2:] = change
    fv_dir = np.where(v > 0, fv + 0.5 * viscous_asymmetry, fv - 0.5 * viscous_asymmetry)
    u = mass * a + fv_dir * v + fc * np.sign(v) + off
    e = np.empty(n)
    e[0] = 0.0
    w = rng.normal(0, sigma * math.sqrt(1 - rho**2), n)
    for k in range(1, n):
        e[k] = rho * e[k - 1] + w[k]
    return q + rng.normal(0, 1e-7, n), u + e


TRUE = (10.0, 30.0, 3.0, -0.5)


def test_filtered_derivatives_of_a_sine():
    t = np.arange(5000) * TS
    w = 2 * math.pi * 2.0
    q, dq, ddq = filtered_derivatives(np.sin(w * t), TS, 100.0)
    inner = slice(200, -200)
    np.testing.assert_allclose(dq[inner], w * np.cos(w * t[inner]), atol=2e-3 * w)
    np.testing.assert_allclose(ddq[inner], -w * w * np.sin(w * t[inner]), atol=3e-3 * w * w)


def test_hac_equals_the_classical_covariance_at_lag_0_for_homoscedastic_rows():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(4000, 3))
    r = rng.normal(size=4000)
    hac = hac_covariance(x, r, 0)
    g = x * r[:, None]
    bread = np.linalg.inv(x.T @ x)
    np.testing.assert_allclose(hac, bread @ (g.T @ g) @ bread, rtol=1e-12)


def test_idim_ls_recovers_the_axis_and_does_not_depend_on_units():
    y, u = _log(TRUE, rho=0.0, sigma=0.1)
    est = idim_ls([(y, u)], TS)
    np.testing.assert_allclose(est.values, TRUE, rtol=0.02, atol=0.02)
    # the same log in mm and kN: the same physics, values in the new units (no bound, no scale)
    mm = idim_ls([(y * 1e3, u * 1e-3)], TS)
    np.testing.assert_allclose(mm.values, est.values * np.array([1e-6, 1e-6, 1e-3, 1e-3]),
                               rtol=1e-6)


def test_hac_intervals_cover_with_coloured_noise_where_white_ones_do_not():
    """Issue 20, case 4: intervals that stay valid when the residual is coloured."""
    hac = white = 0
    runs = 40
    for seed in range(runs):
        est = idim_ls([_log(TRUE, n=12000, seed=seed)], TS)
        i = est.names.index("viscous_friction")
        err = abs(est.values[i] - TRUE[1])
        hac += err <= 1.96 * est.se_hac[i]
        white += err <= 1.96 * est.se_white[i]
    assert hac / runs >= 0.85, (hac, white)
    assert white / runs < 0.7, (hac, white)


def test_case_1_float32_stamps_are_imported_and_fitted(tmp_path, run_cli):
    """Issue 20, case 1: a time column stored in float32 (the EMPS files: stamps off the
    1 kHz grid by up to 2e-5 relative) is refused by the log reader (tolerance 1e-6),
    `esoarm log import` accepts it onto the uniform grid, and IDIM-LS fits the result."""
    import scipy.io

    from esoarm.scenario import ScenarioError
    from esoarm.studies.identification.data import read_ident_log

    y, u = _log(TRUE, n=12000, rho=0.0, sigma=0.1)
    t32 = (np.arange(len(y)) * TS).astype(np.float32).astype(float)
    raw = tmp_path / "raw.csv"
    np.savetxt(raw, np.column_stack([t32, y, u]), delimiter=",", header="t,y,u",
               comments="", fmt="%.17g")
    with pytest.raises(ScenarioError, match="uniformly spaced"):
        read_ident_log(raw, 1e3)
    mat = tmp_path / "rec.mat"
    scipy.io.savemat(mat, {"time": t32.reshape(-1, 1), "pos": y.reshape(-1, 1),
                           "force": u.reshape(-1, 1)})
    out = tmp_path / "log.csv"
    res = run_cli("log", "import", str(mat), "--map", "t=time,y=pos,u=force", "--out", str(out))
    assert res.exit_code == 0, res.output
    log = read_ident_log(out, 1e3)
    est = idim_ls([(log.y, log.u)], log.ts)
    np.testing.assert_allclose(est.values, TRUE, rtol=0.02, atol=0.02)


def test_cli_refuses_an_axis_that_changed_half_way(tmp_path, run_cli):
    y, u = _log(TRUE, seed=3, rho=0.0, sigma=0.1, change=14.0)
    path = tmp_path / "log.csv"
    t = np.arange(len(y)) * TS
    np.savetxt(path, np.column_stack([t, y, u]), delimiter=",", header="t,y,u", comments="")
    out = tmp_path / "fitted.toml"
    res = run_cli("identify", str(path), "--scenario", "emps", "--set", "plant.mass=10",
                  "--out", str(out), "--validate-fraction", "0")
    assert res.exit_code == 1, res.output
    assert "not consistent: mass is" in res.stderr and "first half" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and not out.exists()


def _emps(name: str) -> tuple[np.ndarray, np.ndarray]:
    d = np.loadtxt(EMPS / name, delimiter=",", skiprows=1)
    return d[:, 1], d[:, 2]


def test_emps_idim_ls_reproduces_the_published_values_and_force_error():
    # the scripts' own filter: cut-off fs/10 and nd = fs/cutoff (a decimated rate of 1×
    # the cut-off; esoarm's default keeps 4× and reads the cut-off from the motion's band)
    est = idim_ls([_emps("estimation.csv")], TS, 0.1 / TS, rate=1.0, moving_only=False)
    for name in ("mass", "viscous_friction", "coulomb_friction"):
        assert est.value(name) == pytest.approx(PUBLISHED[name], rel=0.01), name
    pub = np.array(list(PUBLISHED.values()))
    # the benchmark's metric, both parameter sets through the same filters
    emps = {"rate": 1.0, "moving_only": False}
    assert est.force_error <= cross_test(*_emps("estimation.csv"), TS, pub, est.cutoff_hz,
                                         **emps)
    ours = cross_test(*_emps("validation.csv"), TS, est.values, est.cutoff_hz, **emps)
    theirs = cross_test(*_emps("validation.csv"), TS, pub, est.cutoff_hz, **emps)
    assert ours <= theirs and ours == pytest.approx(5.98, abs=0.1)
    assert est.force_error == pytest.approx(4.08, abs=0.1)
    # the residual is coloured: the HAC intervals are wider than the white ones
    assert np.all(est.se_hac > 1.5 * est.se_white)
    # esoarm's default filter finds the same values
    ours = idim_ls([_emps("estimation.csv")], TS)
    for name in ("mass", "viscous_friction", "coulomb_friction"):
        assert ours.value(name) == pytest.approx(PUBLISHED[name], rel=0.02), name


def test_viscous_asymmetry_is_kept_only_when_the_data_support_it():
    """Issue 20, case 4 (asymmetric friction): the Wald test on the HAC covariance keeps
    Fv+ ≠ Fv− on a twin that has it (and recovers both) and not on a symmetric twin."""
    kept = 0
    for seed in range(10):
        est = idim_ls([_log(TRUE, n=12000, seed=seed)], TS, asymmetric=True)
        kept += viscous_asymmetry(est)[2] > ASYMMETRY_Z
    assert kept <= 1, kept
    est = idim_ls([_log(TRUE, seed=1, sigma=0.5, viscous_asymmetry=20.0)], TS,
                  asymmetric=True)
    diff, se, z = viscous_asymmetry(est)
    assert z > ASYMMETRY_Z and abs(diff - 20.0) <= 1.96 * se
    assert est.value("viscous_friction_pos") == pytest.approx(40.0, rel=0.05)
    assert est.value("viscous_friction_neg") == pytest.approx(20.0, rel=0.1)


def test_coulomb_asymmetry_is_the_offset_on_a_log_that_keeps_moving():
    """Why the Coulomb friction is not split: [q̇>0], [q̇<0] and the offset's ones are
    collinear (the split regressor matrix is singular)."""
    y, _u = _log(TRUE, n=12000, rho=0.0, sigma=0.1)
    _q, dq, _ddq = filtered_derivatives(y, TS, 100.0)
    pos, neg = (dq > 0).astype(float), (dq < 0).astype(float)
    x = np.column_stack([pos, -neg, np.ones_like(dq)])
    assert np.all(pos + neg == 1.0) and np.linalg.matrix_rank(x) == 2


def test_emps_viscous_friction_is_asymmetric_and_the_fit_beats_the_published_one():
    """EMPS: Fv+ and Fv− differ by 23 HAC standard errors; the split model's force error
    is below the published parameters' on estimation and cross-test data, and M, the mean
    Fv and Fc stay within 5 % of the published IDIM-LS values."""
    est = idim_ls([_emps("estimation.csv")], TS, asymmetric=True)
    diff, _se, z = viscous_asymmetry(est)
    assert z > ASYMMETRY_Z and diff < 0
    fv = 0.5 * (est.value("viscous_friction_pos") + est.value("viscous_friction_neg"))
    assert fv == pytest.approx(PUBLISHED["viscous_friction"], rel=0.05)
    for name in ("mass", "coulomb_friction"):
        assert est.value(name) == pytest.approx(PUBLISHED[name], rel=0.05), name
    pub = np.array(list(PUBLISHED.values()))
    assert est.force_error < cross_test(*_emps("estimation.csv"), TS, pub, est.cutoff_hz)
    ours = cross_test(*_emps("validation.csv"), TS, est.values, est.cutoff_hz,
                      asymmetric=True)
    assert ours < cross_test(*_emps("validation.csv"), TS, pub, est.cutoff_hz)


@pytest.mark.slow
def test_emps_segment_lengths_agree_or_the_output_error_fit_is_flagged(run_cli):
    """Issue 20, case 4: --segment 0.5, 2 and 5 s.  The written estimate (physical) of each
    lies within the others' intervals, M, Fv, Fc within 5 % of the published values.  The
    output-error fit's estimates either lie within each other's intervals too, or each run
    that disagrees says so in words and withholds its (noise-only) intervals."""
    runs = {}
    for seg in ("0.5", "2", "5"):
        res = run_cli("identify", str(EMPS / "estimation.csv"), "--scenario", "emps",
                      "--validate", str(EMPS / "validation.csv"), "--segment", seg, "--json")
        assert res.exit_code == 0, res.output
        runs[seg] = json.loads(res.stdout)
    for a in runs.values():
        for name in ("mass", "viscous_friction", "coulomb_friction"):
            assert a["physical"][name]["value"] == pytest.approx(PUBLISHED[name], rel=0.05)
        for b in runs.values():
            for name, e in a["physical"].items():
                lo, hi = e["ci95"]
                assert lo <= b["physical"][name]["value"] <= hi, name
    oe = {s: r["output_error"] for s, r in runs.items()}
    consistent = all(
        "ci95" in a["parameters"][n]
        and a["parameters"][n]["ci95"][0] <= b["parameters"][n]["value"]
        <= a["parameters"][n]["ci95"][1]
        for a in oe.values() for b in oe.values() for n in a["parameters"])
    if not consistent:
        for o in oe.values():
            if o["consistent_with_idim_ls"]:
                continue
            assert "model error" in o["warning"] and "withheld" in o["warning"]
            assert all("ci95" not in e and "ci95_noise_only" in e
                       for e in o["parameters"].values())
        # a run that claims intervals must not be contradicted by another run
        claimed = [s for s, o in oe.items() if o["consistent_with_idim_ls"]]
        for s in claimed:
            for b in oe.values():
                for n, e in oe[s]["parameters"].items():
                    assert e["ci95"][0] <= b["parameters"][n]["value"] <= e["ci95"][1], (s, n)


@pytest.mark.slow
def test_emps_cli_json_physical(run_cli):
    """Issue 20, case 3: a prismatic axis in SI units (mass, N·s/m, N), no mapping by hand,
    the offset fitted as an offset (not a gravity term)."""
    res = run_cli("identify", str(EMPS / "estimation.csv"), "--scenario", "emps", "--validate",
                  str(EMPS / "validation.csv"), "--json")
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    phys = data["physical"]
    assert set(phys) == {"mass", "viscous_friction", "viscous_friction_pos",
                         "viscous_friction_neg", "coulomb_friction", "offset"}
    assert phys["viscous_friction_pos"]["unit"] == "N·s/m"
    assert data["parameters"]["plant.viscous_asymmetry"]["value"] < 0
    assert data["friction_asymmetry"]["viscous"]["kept"] is True
    assert phys["mass"]["unit"] == "kg" and phys["viscous_friction"]["unit"] == "N·s/m"
    for name in ("mass", "viscous_friction", "coulomb_friction"):
        assert phys[name]["value"] == pytest.approx(PUBLISHED[name], rel=0.05)
        lo, hi = phys[name]["ci95"]
        assert lo < phys[name]["value"] < hi
    # no worse than the published parameters through the same filters (the scripts' own
    # filters give 6.00 % for them; identify's default filters, which follow the motion's
    # band since issue 30, give 10.7 % for them and 10.4 % for ours)
    theirs = cross_test(*_emps("validation.csv"), TS, np.array(list(PUBLISHED.values())),
                        data["idim_ls"]["cutoff_hz"])
    assert data["validation"]["cross_test_force_error_percent"] <= theirs
    assert data["output_error"]["converged"]
