"""Issue 20, case 7: a bare DC motor, open-loop torque steps at 1 kHz.

An emulated reproduction: the motor (inertia 1.2e-4 kg·m², no gravity) simulated by the
axis kind's RK4 step (not the lever-arm model the fit uses), torque steps held 0.2-0.6 s,
the angle quantized by a 4096-count encoder (0.088°).  Identified with the lever-arm
template test-1 at 1 kHz (its gravity masses free, so the gravity term is unobservable
noise for the fit), as a user with such a log would.

The code before accepted every segment length with exit 0: over 0.5 s the inertia was
right, over 2 s 41 % too large with a "noise" of 404°, over 5 s with 2570° -- the
issue's 31× and 147°/734° on the real motor.  Now the long segments are refused, naming
the residual against the encoder's resolution, and the short one stands.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from esoarm.plants.axis import axis_rk4_step

INERTIA = 1.2e-4
SETS = ("sensor.rate_hz=1000", f"plant.inertia={INERTIA}", "rig.inertia_scale=1",
        "rig.coulomb_friction=0.002", "rig.viscous_friction=2e-5",
        "rig.disturbance.amplitude=0", "actuator.torque_limit=0.02",
        "sensor.resolution_deg=0.088", "sensor.noise_deg=0")


def motor_log(path, seconds=10.0, seed=0, viscous=2e-5, coulomb=2e-3, torque=0.01,
              counts=4096):
    """Write (t, y, u) of the motor under open-loop torque steps; return the angle [rad]."""
    rng = np.random.default_rng(seed)
    ts = 1e-3
    n = int(round(seconds / ts))
    u = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.uniform(0.2, 0.6) / ts)
        u[k:k + hold] = torque * rng.choice([-1.0, -0.5, 0.0, 0.5, 1.0])
        k += hold
    ax = (INERTIA, viscous, viscous, coulomb, coulomb, 0.0, 0.0, 1e-3, 0.0)
    q = v = tq = 0.0
    y = np.empty(n)
    step = 2.0 * math.pi / counts
    for k in range(n):
        y[k] = step * math.floor(q / step + 0.5)
        for _ in range(10):
            q, v, tq = axis_rk4_step(q, v, tq, float(u[k]), ts / 10, ax)
    np.savetxt(path, np.column_stack([np.arange(n) * ts, y, u]), delimiter=",",
               header="t,y,u", comments="", fmt="%.17g")
    return y


def _identify(run_cli, path, segment, out=None):
    args = ["identify", str(path), "--scenario", "test-1"]
    for s in SETS:
        args += ["--set", s]
    args += ["--segment", segment, "--json"]
    if out is not None:
        args += ["--out", str(out)]
    return run_cli(*args)


def test_the_emulated_motor_spins_open_loop(tmp_path):
    y = motor_log(tmp_path / "m.csv")
    assert np.ptp(y) > 20.0  # many turns: cos θ of a gravity term averages out


@pytest.mark.slow
@pytest.mark.parametrize("segment", ["2", "5"])
def test_case_7_long_segments_are_refused_naming_the_residual(tmp_path, run_cli, segment):
    path = tmp_path / "motor.csv"
    motor_log(path)
    out = tmp_path / "fitted.toml"
    res = _identify(run_cli, path, segment, out)
    assert res.exit_code == 1, res.stdout
    line = res.stderr.strip().splitlines()[-1]
    assert "not trustworthy" in line and "0.088°" in line and "not white" in line
    assert "shorter" in line and not out.exists()


@pytest.mark.slow
def test_case_7_short_segments_find_the_motor(tmp_path, run_cli):
    path = tmp_path / "motor.csv"
    motor_log(path)
    res = _identify(run_cli, path, "0.5")
    assert res.exit_code == 0, res.stderr
    data = json.loads(res.stdout)
    inertia = data["physical"]["inertia"]["value"]
    assert inertia == pytest.approx(INERTIA, rel=0.05)
    assert data["idim_ls"]["parameters"]["inertia"]["value"] == pytest.approx(INERTIA, rel=0.05)
    # the residual is quantization (and the unobservable gravity): it is not called sensor
    # noise, or (since issue 30's fit, whose residual here passes the whiteness test) the noise
    # written is no more than the encoder's quantization, q/sqrt(12) = 0.025 deg (truth: 0)
    if not data["noise"].startswith("not written"):
        assert data["parameters"]["sensor.noise_deg"]["value"] <= 0.088 / math.sqrt(12)
