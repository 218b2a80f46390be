"""Real logs of the cart and the arms of three inverted pendulums
(docs/real-data-pendulums.md).

The files are public (github.com/Prof-Carter/book_ip, commit 7d5e476, mfiles/p1c3/; and
github.com/Prof-Carter/LEGO-Based_Inverted_Pendulum_Platform, commit 082c669,
matlab_files_arduino_mega/file01_ident_arm/arm_data.mat) but carry no licence, so they are
not shipped: set ESOARM_BOOK_IP (a clone's mfiles/p1c3) and ESOARM_LEGO_IP (the folder of
arm_data.mat). Without them every test here is skipped.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

FOLDER = os.environ.get("ESOARM_BOOK_IP", "")
book_ip = pytest.mark.skipif(not FOLDER, reason="set ESOARM_BOOK_IP to the folder of the "
                             "book_ip .mat files (docs/real-data-pendulums.md)")

SHA256 = {
    "cdip_least_square_data.mat":
        "4e0416325a1d22bc07f26d8706d92b95c69a1f411061329e22399dcbc4612d4a",
    "adip_least_square_data.mat":
        "e413e425ddbf20493cf8d547dd473aecc9889cf387f32fbd34cee896ff383355",
    "cdip_cart_pcont_data_kP_025_ref_02.mat":
        "f844fa03e8110cd517da8aea65d162a7ff215d08da9753d586e1804ce5699363",
    "cdip_cart_pcont_data_kP_050_ref_02.mat":
        "686220677c7cf3d83694a4a0a436b38db244fb6e7bf802f9201220e941922feb",
    "cdip_cart_pcont_data_kP_100_ref_02.mat":
        "906bc5676a45fa90c6b47d6879b64ff023a8c90c71765f096be68af121829d51",
    "cdip_cart_pcont_data_kP_200_ref_02.mat":
        "056f6d5fd54b9aaadf5da02ad1a884e37be4a3f09aa875bf3f8ecff56cb964d6",
    "adip_arm_pcont_data_kP_1_ref_1.mat":
        "bb9168d72351b76cbc11d50b35fafcb5c58461ab85cbb5f02432ad64e2c7903a",
    "adip_arm_pcont_data_kP_2_ref_1.mat":
        "d8909c7105bf8cff88f6c7f8bba1a6ede08b77fbd60c97dada35b9e441e1cbc7",
    "adip_arm_pcont_data_kP_3_ref_1.mat":
        "7b1bafd5c4c167eeb94696e7ee91c8d59d42be8ec76ff05f424949cc9610c4c0",
    "adip_arm_pcont_data_kP_4_ref_1.mat":
        "f87c14c4dc5901f3e356708b9c52592c670e45f3ad3ab8b3dc11e527ba2172b5",
    "adip_arm_pcont_data_kP_5_ref_1.mat":
        "57789789dd64ac88674cd2d5f71924f4f2782a8ea3db9d3e464da37a87acd0af",
}
# (file, y variable, kP [V/unit], setpoint [m or rad], published 1/b, published a/b)
RIGS = {
    "cart": ("cdip_least_square_data.mat", "z", 10.0, 0.2, 1 / 4.36, 6.25 / 4.36),
    "arm": ("adip_least_square_data.mat", "phi1", 3.0, 1.0, 1 / 15.8, 6.20 / 15.8),
}


def _path(name: str) -> Path:
    return Path(FOLDER) / name


@book_ip
def test_the_files_are_the_cited_ones():
    for name, digest in SHA256.items():
        assert hashlib.sha256(_path(name).read_bytes()).hexdigest() == digest, name


@book_ip
@pytest.mark.parametrize("rig", sorted(RIGS))
def test_import_and_the_p_law(run_cli, tmp_path, rig):
    """1 kHz on the uniform grid; the logged voltage is exactly kP (r − y)."""
    import scipy.io

    name, yvar, kp, ref, _m, _fv = RIGS[rig]
    out = tmp_path / f"{rig}.csv"
    res = run_cli("log", "import", str(_path(name)), "--map", f"t=t,y={yvar},u=v", "--out",
                  str(out), "--json")
    assert res.exit_code == 0, res.stderr
    info = json.loads(res.stdout)
    assert info["rate_hz"] == 1000.0 and info["jitter_samples"] < 1e-9
    raw = scipy.io.loadmat(_path(name))
    t, y, v = (raw[k].ravel() for k in ("t", yvar, "v"))
    assert np.max(np.abs(kp * (ref * (t >= 1.0) - y) - v)) == 0.0
    at_rest = t >= 3.0
    assert np.max(np.abs(v[at_rest])) < 5e-3


@book_ip
def test_the_step_files_are_the_least_square_runs():
    import scipy.io

    for ls, step, yls, ystep in (
            ("cdip_least_square_data.mat", "cdip_cart_pcont_data_kP_100_ref_02.mat", "z", "z"),
            ("adip_least_square_data.mat", "adip_arm_pcont_data_kP_3_ref_1.mat", "phi1",
             "theta1")):
        a, b = scipy.io.loadmat(_path(ls)), scipy.io.loadmat(_path(step))
        np.testing.assert_array_equal(a["t"], b["t"])
        np.testing.assert_array_equal(a[yls], b[ystep])


def _import(run_cli, tmp_path, rig: str, every: int = 1) -> Path:
    """The rig's least-squares log as a CSV (every ``every``-th row: a down-sample)."""
    name, yvar, *_rest = RIGS[rig]
    log = tmp_path / f"{rig}.csv"
    assert run_cli("log", "import", str(_path(name)), "--map", f"t=t,y={yvar},u=v", "--out",
                   str(log)).exit_code == 0
    if every > 1:
        lines = log.read_text(encoding="utf-8").splitlines()
        log = tmp_path / f"{rig}_{every}.csv"
        log.write_text("\n".join([lines[0], *lines[1::every]]) + "\n", encoding="utf-8")
    return log


def _identify(run_cli, rig: str, log: Path, *extra: str) -> dict:
    *_r, mass, viscous = RIGS[rig]
    motion = ["--set", "plant.motion=rotary"] if rig == "arm" else []
    res = run_cli("identify", str(log), "--scenario", "emps", *motion, "--set",
                  f"plant.mass={mass:.4g}", "--set", f"plant.viscous_friction={viscous:.4g}",
                  "--set", "plant.coulomb_friction=0.01", "--set", "plant.offset=0", "--set",
                  "actuator.torque_limit=10", "--input-unit", "V", *extra, "--json")
    assert res.exit_code == 0, res.stderr
    return json.loads(res.stdout)


def _step_file(tmp_path, rig: str) -> Path:
    """The kP = 5 V/m cart step (kP = 2 V/rad arm), 3.97 s, its voltage rebuilt from the P law
    (the least-squares file's voltage is exactly that law)."""
    import scipy.io

    name, yvar, kp, ref = {"cart": ("cdip_cart_pcont_data_kP_050_ref_02.mat", "z", 5.0, 0.2),
                           "arm": ("adip_arm_pcont_data_kP_2_ref_1.mat", "theta1", 2.0,
                                   1.0)}[rig]
    raw = scipy.io.loadmat(_path(name))
    t, y = raw["t"].ravel(), raw[yvar].ravel()
    out = tmp_path / f"{rig}_step.csv"
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(len(t))  # the stamps are a 1 kHz grid (jitter 1e-12 s)
    np.savetxt(out, np.column_stack([grid - grid[0], y, kp * (ref * (t >= 1.0) - y)]),
               delimiter=",", header="t,y,u", comments="")
    return out


@book_ip
@pytest.mark.parametrize("rig", sorted(RIGS))
def test_identify_fits_the_published_values(run_cli, tmp_path, rig):
    """Issue 30: a step followed by rest is fitted, not refused, with intervals that cover
    the published parameters (before: refused, "the halves disagree" or "the methods
    disagree", IDIM-LS's inertia 7× too small with the derivative filter at fs/10); every
    unit follows u in volts."""
    *_r, mass, viscous = RIGS[rig]
    data = _identify(run_cli, rig, _import(run_cli, tmp_path, rig))
    params = data["parameters"]
    for key, published in (("plant.mass", mass), ("plant.viscous_friction", viscous)):
        lo, hi = params[key]["ci95"]
        assert lo <= published <= hi, (key, params[key])
        assert params[key]["value"] == pytest.approx(published, rel=0.10)
    per = "rad" if rig == "arm" else "m"
    assert params["plant.mass"]["unit"] == f"V·s²/{per}"
    assert params["plant.viscous_friction"]["unit"] == f"V·s/{per}"
    assert params["plant.coulomb_friction"]["value"] >= 0.0
    assert "kg" not in json.dumps(data["physical"])


@book_ip
@pytest.mark.parametrize("rig", sorted(RIGS))
def test_the_1khz_log_and_its_100hz_down_sample_agree(run_cli, tmp_path, rig):
    """Issue 30, done-when: the same real step log at 1 kHz and down-sampled to 100 Hz gives
    estimates inside each other's intervals (the derivative filter follows the motion)."""
    fast = _identify(run_cli, rig, _import(run_cli, tmp_path, rig))["parameters"]
    slow = _identify(run_cli, rig, _import(run_cli, tmp_path, rig, every=10), "--set",
                     "sensor.rate_hz=100", "--set", "rig.step=0.01")["parameters"]
    for key in ("plant.mass", "plant.viscous_friction"):
        a, b = fast[key], slow[key]
        assert a["ci95"][0] <= b["value"] <= a["ci95"][1], (key, a, b)
        assert b["ci95"][0] <= a["value"] <= b["ci95"][1], (key, a, b)


@book_ip
@pytest.mark.parametrize("rig", sorted(RIGS))
def test_a_short_step_validates(run_cli, tmp_path, rig):
    """Issue 30: a validation log may be shorter than the fitting minimum (was: "too short
    (3971 samples, 3.97 s); identification needs at least 4 s")."""
    data = _identify(run_cli, rig, _import(run_cli, tmp_path, rig), "--validate",
                     str(_step_file(tmp_path, rig)))
    val = data["validation"]
    assert val["logs"] and "not_validated" not in val
    assert val["simulated_fit_percent"] > 50.0
    assert val["cross_test_force_error_percent"] <= val["cross_test_limit_percent"]


LEGO = os.environ.get("ESOARM_LEGO_IP", "")
LEGO_SHA256 = "9af4b693859417af913e9cf4b50694cef746e1a7c6e548c7a115211bf0042535"


@pytest.mark.skipif(not LEGO, reason="set ESOARM_LEGO_IP to the folder of arm_data.mat")
def test_lego_arm_file_import_and_p_law(run_cli, tmp_path):
    import scipy.io

    src = Path(LEGO) / "arm_data.mat"
    assert hashlib.sha256(src.read_bytes()).hexdigest() == LEGO_SHA256
    res = run_cli("log", "import", str(src), "--map", "t=t,y=theta1,u=u,theta_ref=r", "--out",
                  str(tmp_path / "lego.csv"), "--json")
    assert res.exit_code == 0, res.stderr
    info = json.loads(res.stdout)
    assert info["rate_hz"] == 200.0 and info["samples"] == 1001
    raw = scipy.io.loadmat(src)
    t, y, u, r = (raw[k].ravel() for k in ("t", "theta1", "u", "r"))
    assert np.max(np.abs(20.0 * (r - y) - u)) < 2e-6


@pytest.mark.skipif(not LEGO, reason="set ESOARM_LEGO_IP to the folder of arm_data.mat")
def test_identify_fits_the_published_lego_arm(run_cli, tmp_path):
    """The LEGO arm (200 Hz, a step that ends stuck on Coulomb friction): fitted, every
    interval covering the published α1, μ1, δ1 (before: refused, "the halves disagree")."""
    log = tmp_path / "lego.csv"
    assert run_cli("log", "import", str(Path(LEGO) / "arm_data.mat"), "--map",
                   "t=t,y=theta1,u=u,theta_ref=r", "--out", str(log)).exit_code == 0
    res = run_cli("identify", str(log), "--scenario", "emps", "--set", "plant.motion=rotary",
                  "--set", "plant.mass=0.242", "--set", "plant.viscous_friction=0.967", "--set",
                  "plant.coulomb_friction=1.51", "--set", "plant.offset=0", "--set",
                  "actuator.torque_limit=100", "--set", "sensor.rate_hz=200", "--set",
                  "rig.step=0.005", "--input-unit", "cmd", "--json")
    assert res.exit_code == 0, res.stderr
    params = json.loads(res.stdout)["parameters"]
    assert params["plant.mass"]["value"] == pytest.approx(0.242, rel=0.10)
    for key, published in (("plant.mass", 0.242), ("plant.viscous_friction", 0.967),
                           ("plant.coulomb_friction", 1.51)):
        lo, hi = params[key]["ci95"]
        assert lo <= published <= hi, (key, params[key])
    assert params["plant.mass"]["unit"] == "cmd·s²/rad"
