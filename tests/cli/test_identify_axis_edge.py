"""``esoarm identify`` on an axis: the checks at the command's edge.

A bare motor's step-response log (the torque held constant for each half, as in the
public HSM150 identification records, see docs/real-data-emps.md "Other real logs")
fits the inverse dynamic model exactly with no inertia: the command must say so
instead of blaming a change of the axis during the log.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from esoarm.cli.identify import constant_force_half
from esoarm.studies.identification.data import IdentLog

TS = 1e-3
J, FV, FC = 1.2e-4, 1.3e-4, 0.03  # a small DC motor [kg·m², N·m·s/rad, N·m]


def _step_log(levels: list[tuple[float, float]], n: int = 4000, sign: float = 1.0) -> IdentLog:
    """Exact response from rest to torque steps (t_start [s], u [N·m]), Euler at 0.1 ms."""
    t = np.arange(n) * TS
    u = np.zeros(n)
    for start, value in levels:
        u[t >= start] = sign * value
    q, w, y = 0.0, 0.0, np.empty(n)
    for k in range(n):
        y[k] = q
        for _ in range(10):
            acc = (u[k] - FV * w - FC * np.sign(w)) / J if w or abs(u[k]) > FC else 0.0
            w += acc * TS / 10
            q += w * TS / 10
    return IdentLog("step.csv", t, y, u, None, TS)


def test_a_half_with_one_force_per_direction_is_named():
    pos = _step_log([(0.0, 0.05), (2.0, 0.06)])
    neg = _step_log([(0.0, 0.035), (2.0, 0.045)], sign=-1.0)
    why = constant_force_half([pos, neg], True, 0.25)
    assert why is not None and why.startswith("the first half of the fitting data has one force")
    assert "0.05 moving forward" in why and "-0.035 moving back" in why
    assert "inertia and viscous friction are not determined" in why


def test_a_force_that_varies_within_each_half_passes():
    pos = _step_log([(0.0, 0.05), (0.5, 0.06), (1.0, 0.045), (2.5, 0.065), (3.2, 0.05)])
    neg = _step_log([(0.0, 0.05), (0.7, 0.04), (2.2, 0.06), (3.0, 0.035)], sign=-1.0)
    assert constant_force_half([pos, neg], True, 0.25) is None


def test_the_validation_part_is_left_out_as_identify_does():
    # one log: its last quarter is validation; the steps inside it do not excite the fit
    log = _step_log([(0.0, 0.05), (1.0, 0.06), (3.5, 0.07)])
    assert constant_force_half([log], False, 0.25) is not None  # halves 0-1.5 s, 1.5-3 s
    assert constant_force_half([log], True, 0.25) is None  # every sample fitted: 0.06, 0.07


def test_cli_refuses_with_exit_1_and_writes_nothing(run_cli, tmp_path):
    logs = []
    for name, log in (("pos.csv", _step_log([(0.0, 0.05), (2.0, 0.06)])),
                      ("neg.csv", _step_log([(0.0, 0.035), (2.0, 0.045)], sign=-1.0))):
        path = tmp_path / name
        np.savetxt(path, np.column_stack([log.t, log.y, log.u]), delimiter=",",
                   header="t,y,u", comments="", fmt="%.17g")
        logs.append(str(path))
    out = tmp_path / "fitted.toml"
    val = tmp_path / "val.csv"  # a validation log of its own (one also fitted is refused)
    val.write_bytes(Path(logs[0]).read_bytes())
    res = run_cli("identify", *logs, "--validate", str(val), "--scenario", "emps", "--set",
                  "plant.motion=rotary", "--set", "plant.mass=1.2e-4", "--set",
                  "plant.viscous_friction=1e-4", "--set", "plant.coulomb_friction=0.03",
                  "--set", "plant.offset=0", "--set", "actuator.torque_limit=0.3",
                  "--out", str(out))
    assert res.exit_code == 1, res.stderr
    assert "one force per direction of motion" in res.stderr
    assert "changed during the log" not in res.stderr
    assert not out.exists()


def _spring_logs(tmp_path):
    """A mass-spring-damper (resonance 5 Hz, cubic spring: a mechanical Silverbox) driven by
    a multisine [N], 1 kHz: a plant the axis kind cannot describe (it has no spring)."""
    m, d, k, k3 = 95.0, 200.0, 9.4e4, 2.0e7  # kg, N·s/m, N/m, N/m³
    n = 17000
    rng = np.random.default_rng(1)
    t = np.arange(n) * TS
    freqs = np.arange(1, 200) * 0.1
    phases = rng.uniform(0.0, 2.0 * np.pi, len(freqs))
    u = np.cos(2.0 * np.pi * freqs[:, None] * t[None, :] + phases[:, None]).sum(axis=0)
    u *= 150.0 / u.std()
    x, v, y = 0.0, 0.0, np.empty(n)

    def acc(x, v, uk):
        return (uk - d * v - k * x - k3 * x**3) / m

    h = TS / 4
    for i in range(n):
        y[i] = x
        for _ in range(4):  # RK4, four substeps per sample, u held
            a1 = acc(x, v, u[i])
            a2 = acc(x + h / 2 * v, v + h / 2 * a1, u[i])
            a3 = acc(x + h / 2 * (v + h / 2 * a1), v + h / 2 * a2, u[i])
            a4 = acc(x + h * (v + h / 2 * a2), v + h * a3, u[i])
            x, v = (x + h * (v + h / 6 * (a1 + a2 + a3)),
                    v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4))
    y += rng.normal(0.0, 1e-6, n)
    paths = []
    for name, part in (("est.csv", slice(0, 12000)), ("val.csv", slice(12000, n))):
        path = tmp_path / name
        np.savetxt(path, np.column_stack([t[part] - t[part][0], y[part], u[part]]),
                   delimiter=",", header="t,y,u", comments="", fmt="%.17g")
        paths.append(str(path))
    return paths


@pytest.mark.slow  # IDIM-LS, the output-error fit and the simulated validation: a minute
def test_a_spring_the_axis_does_not_have_is_refused(run_cli, tmp_path):
    # before: exit 0, mass 13 kg (truth 95), Fv− = −21 N·s/m, force error 92 %, simulated
    # validation fit −6.4e4 % (and with --out: exit 2 blaming --scenario 'emps')
    est, val = _spring_logs(tmp_path)
    out = tmp_path / "fitted.toml"
    res = run_cli("identify", est, "--validate", val, "--scenario", "emps", "--out", str(out))
    assert res.exit_code == 1, (res.stdout, res.stderr)
    assert not out.exists()
    assert "--scenario" not in res.stderr
