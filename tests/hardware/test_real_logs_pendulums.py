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


@book_ip
@pytest.mark.xfail(reason="issue 30 items 4-5: IDIM-LS's fixed derivative cutoff and the "
                   "halves check on a log that rests (docs/real-data-pendulums.md)",
                   strict=False)
@pytest.mark.parametrize("rig", sorted(RIGS))
def test_identify_fits_the_published_values(run_cli, tmp_path, rig):
    name, yvar, _kp, _ref, mass, viscous = RIGS[rig]
    log = tmp_path / f"{rig}.csv"
    assert run_cli("log", "import", str(_path(name)), "--map", f"t=t,y={yvar},u=v", "--out",
                   str(log)).exit_code == 0
    motion = ["--set", "plant.motion=rotary"] if rig == "arm" else []
    res = run_cli("identify", str(log), "--scenario", "emps", *motion, "--set",
                  f"plant.mass={mass:.4g}", "--set", f"plant.viscous_friction={viscous:.4g}",
                  "--set", "plant.coulomb_friction=0.01", "--set", "plant.offset=0", "--set",
                  "actuator.torque_limit=10", "--json")
    assert res.exit_code == 0, res.stderr
    params = json.loads(res.stdout)["parameters"]
    assert params["plant.mass"]["value"] == pytest.approx(mass, rel=0.10)
    assert params["plant.viscous_friction"]["value"] == pytest.approx(viscous, rel=0.10)


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
@pytest.mark.xfail(reason="issue 30 item 5: the halves check on a log that rests",
                   strict=False)
def test_identify_fits_the_published_lego_arm(run_cli, tmp_path):
    log = tmp_path / "lego.csv"
    assert run_cli("log", "import", str(Path(LEGO) / "arm_data.mat"), "--map",
                   "t=t,y=theta1,u=u,theta_ref=r", "--out", str(log)).exit_code == 0
    res = run_cli("identify", str(log), "--scenario", "emps", "--set", "plant.motion=rotary",
                  "--set", "plant.mass=0.242", "--set", "plant.viscous_friction=0.967", "--set",
                  "plant.coulomb_friction=1.51", "--set", "plant.offset=0", "--set",
                  "actuator.torque_limit=100", "--set", "sensor.rate_hz=200", "--set",
                  "rig.step=0.005", "--json")
    assert res.exit_code == 0, res.stderr
    params = json.loads(res.stdout)["parameters"]
    assert params["plant.mass"]["value"] == pytest.approx(0.242, rel=0.10)
