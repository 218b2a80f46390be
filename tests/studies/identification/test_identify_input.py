"""Identification: logs that must be refused (or accepted) before any fit.

Each bad log gets one line naming the file and what is wrong, exit status 2,
and nothing written; each log made on a twin as a user would make it
(``excite_twin``) is built in memory from a short experiment.
"""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.plants.motor import MotorParams
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.identification.data import MAX_SATURATED, read_ident_log
from esoarm.studies.identification.experiment.excitation import ExcitationPlan

#: A weak motor: 50 · 0.02 N·m/A · 2 V / 2 Ω = 1 N·m at full duty, below the 2 N·m torque
#: limit, so a strong excitation drives the duty to ±pwm_max while |u| stays below the limit.
WEAK_MOTOR = ["motor.supply_voltage=2"]


def _motor_log(tmp_path, sets, amplitude, name):
    scn = load_scenario("test-1", sets)
    path = tmp_path / name
    excite_twin(scn, ExcitationPlan(duration=8.0, amplitude=amplitude), path)
    return scn, path


def _column(path, name):
    return np.genfromtxt(path, delimiter=",", names=True)[name]


def test_saturated_motor_log_is_refused(run_cli, tmp_path):
    """Saturation with a [motor] table is judged on the duty (full supply), not on |u|."""
    scn, path = _motor_log(tmp_path, WEAK_MOTOR, 0.8, "sat.csv")
    duty, u = _column(path, "duty"), _column(path, "u")
    assert np.mean(np.abs(duty) >= scn.motor.pwm_max) > MAX_SATURATED  # the log is saturated
    assert np.max(np.abs(u)) < 0.999 * scn.actuator.torque_limit  # ... but not in torque terms
    out = tmp_path / "never.toml"
    res = run_cli("identify", str(path), "--set", WEAK_MOTOR[0], "--out", str(out))
    assert res.exit_code == 2, res.stdout + res.stderr
    # the error in one line (beside it, the warning that --set motor.X on test-1 adds a
    # whole DC motor model)
    line = "\n".join(x for x in res.stderr.strip().splitlines()
                     if not x.startswith("esoarm: warning: --set motor."))
    assert len(line.splitlines()) == 1
    assert "saturated" in line and "duty" in line and "255" in line and str(path) in line
    assert not out.exists()


def test_unsaturated_motor_log_is_accepted(tmp_path):
    scn, path = _motor_log(tmp_path, WEAK_MOTOR, 0.2, "ok.csv")
    duty = _column(path, "duty")
    assert 0 < np.mean(np.abs(duty) >= scn.motor.pwm_max) < MAX_SATURATED  # touches the limit
    log = read_ident_log(path, scn.actuator.torque_limit, MotorParams.from_scenario(scn))
    assert log.duty is not None and log.n == 400


def test_motor_log_at_the_torque_limit_is_refused(tmp_path):
    """With a motor the logged u is the torque the duty gives (within a duty count of the
    limit when the command was clipped): judged with that count as the tolerance."""
    scn, path = _motor_log(tmp_path, ["motor.torque_constant=0.02"], 0.2, "m.csv")
    motor = MotorParams.from_scenario(scn)
    data = np.genfromtxt(path, delimiter=",", names=True)
    count = motor.stall_gain / motor.pwm_max
    u = data["u"].copy()
    u[::2] = np.sign(u[::2]) * (scn.actuator.torque_limit - 0.4 * count)
    lines = path.read_text().splitlines()
    col = lines[0].split(",").index("u")
    rows = [line.split(",") for line in lines[1:]]
    for row, value in zip(rows, u, strict=True):
        row[col] = repr(float(value))
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    with pytest.raises(ScenarioError,
                       match=r"saturated: 50% of the samples at the torque limit ±2 N·m"):
        read_ident_log(path, scn.actuator.torque_limit, motor)


def _with_column(src, dst, name, value):
    lines = src.read_text().splitlines()
    col = lines[0].split(",").index(name)
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[col] = value
    dst.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    return dst


@pytest.fixture(scope="module")
def torque_log(tmp_path_factory):
    """A log of an ideal torque source (no [motor] table): its duty column is nan."""
    path = tmp_path_factory.mktemp("input") / "torque.csv"
    excite_twin(load_scenario("test-1"), ExcitationPlan(duration=8.0), path)
    return path


@pytest.mark.parametrize("column, sets, words", [
    ("duty", ["--set", "motor.torque_constant=0.02"], "without a [motor] table"),
    ("u", [], "the torque applied"),
])
def test_all_nan_column_is_named(run_cli, torque_log, tmp_path, column, sets, words):
    """A column that is nan in every row: one line naming the column and the file."""
    path = torque_log if column == "duty" else _with_column(torque_log, tmp_path / "nan.csv",
                                                            column, "nan")
    out = tmp_path / "never.toml"
    res = run_cli("identify", str(path), *sets, "--out", str(out))
    assert res.exit_code == 2, res.stdout + res.stderr
    # the error in one line (beside it, the warning that --set motor.X on test-1 adds a
    # whole DC motor model)
    line = "\n".join(x for x in res.stderr.strip().splitlines()
                     if not x.startswith("esoarm: warning: --set motor."))
    assert len(line.splitlines()) == 1 and res.exception is None
    assert f"column {column} is nan in every row" in line and str(path) in line
    assert words in line
    assert not out.exists()


def test_one_nan_in_u_still_names_its_line(run_cli, torque_log, tmp_path):
    lines = torque_log.read_text().splitlines()
    col = lines[0].split(",").index("u")
    row = lines[10].split(",")
    row[col] = "nan"
    lines[10] = ",".join(row)
    path = tmp_path / "one.csv"
    path.write_text("\n".join(lines) + "\n")
    res = run_cli("identify", str(path))
    assert res.exit_code == 2
    assert "line 11: non-finite value u = nan" in res.stderr


def _with_angle(src, dst, theta):
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    cols = [header.index(c) for c in ("theta", "y") if c in header]
    rows = [line.split(",") for line in lines[1:]]
    for row, value in zip(rows, theta, strict=True):
        for c in cols:
            row[c] = repr(float(value))
    dst.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    return dst


@pytest.mark.parametrize("case", ["constant", "encoder noise only"])
def test_arm_that_never_moved_is_refused(run_cli, torque_log, tmp_path, case):
    """The torque varied but the arm did not move: the angle is constant, or only its
    encoder noise (0.2°, quantized to 0.05°) -- which the fit would happily explain."""
    n = len(torque_log.read_text().splitlines()) - 1
    q = np.radians(0.05)
    noise = np.radians(0.2) * np.random.default_rng(0).standard_normal(n)
    theta = np.full(n, 0.3) if case == "constant" else q * np.round((0.3 + noise) / q)
    path = _with_angle(torque_log, tmp_path / "still.csv", theta)
    out = tmp_path / "never.toml"
    res = run_cli("identify", str(path), "--out", str(out))
    assert res.exit_code == 2, res.stdout + res.stderr
    # the error in one line (beside it, the warning that --set motor.X on test-1 adds a
    # whole DC motor model)
    line = "\n".join(x for x in res.stderr.strip().splitlines()
                     if not x.startswith("esoarm: warning: --set motor."))
    assert len(line.splitlines()) == 1 and str(path) in line
    assert "the experiment did not excite the arm" in line and "--amplitude" in line
    assert not out.exists()


def test_a_moving_arm_with_a_noisy_encoder_is_accepted(tmp_path):
    """The motion check compares the angle's spread with its sample-to-sample jitter: a
    real experiment seen through 4° of encoder noise (the paper twin's) still passes."""
    path = tmp_path / "noisy.csv"
    excite_twin(load_scenario("test-1", ["sensor.noise_deg=4"]), ExcitationPlan(duration=8.0),
                path)
    assert read_ident_log(path, 2.0).n == 400


def test_a_simulated_series_is_fitted_on_its_measured_angle(tmp_path):
    """'esoarm simulate --out' writes the true angle as theta and the measurement as y:
    the fit uses y (it fitted the noise-free theta: σ = 0, residual 1e-16 rad)."""
    from esoarm.engines.simulation import simulate
    from esoarm.studies.identification.identify import identify

    truth = load_scenario("test-2", ["duration=20", "rig.inertia_scale=1.25"])
    path = tmp_path / "sim.csv"
    simulate(truth, warn=False).to_csv(path)
    header = path.read_text().splitlines()[0].split(",")
    assert "y" in header and "theta" in header
    res = identify(load_scenario("test-2"), [read_ident_log(path, 2.0)], max_delay=0,
                   fix=("actuator.lag",))
    assert res.value("sensor.noise_deg") == pytest.approx(truth.sensor.noise_deg, rel=0.15)
    assert res.residual_rms > 1e-3
    lo, hi = res.estimates["rig.inertia_scale"].ci95
    assert lo <= 1.25 <= hi
