"""URDF arms: Pinocchio dynamics, the twin, one ESO per joint, computed torque.

References: Pinocchio's RNEA and CRBA (independent of its ABA, which the twin
uses), the lever arm's own rig and closed loop (the one-joint URDF must
reproduce them), energy conservation at RK4's order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from esoarm.controllers.computed_torque import control, design  # noqa: E402
from esoarm.engines.simulation import prepare, simulate  # noqa: E402
from esoarm.plants.arms import urdf  # noqa: E402
from esoarm.plants.arms.model import UrdfError, builtin_robot, load_arm  # noqa: E402
from esoarm.plants.arms.twin import ArmTwin, TwinParams  # noqa: E402
from esoarm.plants.lever_arm import RigParams, rig_acceleration, rig_advance  # noqa: E402
from esoarm.scenario import load_scenario  # noqa: E402

CONTINUOUS_URDF = """<?xml version="1.0"?>
<robot name="wheel-arm">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0.1 0 0.02"/><mass value="0.7"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.004"/></inertial></link>
  <link name="b"><inertial><origin xyz="0.05 0.01 0"/><mass value="0.3"/>
    <inertia ixx="0.0005" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <link name="c"><inertial><origin xyz="0 0 0.04"/><mass value="0.2"/>
    <inertia ixx="0.0003" ixy="0" ixz="0" iyy="0.0003" iyz="0" izz="0.0002"/></inertial></link>
  <joint name="yaw" type="continuous"><parent link="base"/><child link="a"/>
    <axis xyz="0 0 1"/></joint>
  <joint name="pitch" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.2 0 0" rpy="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="5" velocity="3"/></joint>
  <joint name="slide" type="prismatic"><parent link="b"/><child link="c"/>
    <origin xyz="0.1 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.1" effort="20" velocity="1"/></joint>
</robot>
"""


def _arms(tmp_path):
    wheel = tmp_path / "wheel.urdf"
    wheel.write_text(CONTINUOUS_URDF)
    return {
        "lever-arm": load_arm(builtin_robot("lever-arm")),
        "two-link": load_arm(builtin_robot("two-link"), payload_mass=0.3,
                             payload_offset=(0.25, 0.0, 0.0), inertia_scale=1.1),
        "wheel": load_arm(wheel),
    }


# ---------------------------------------------------------------------------
# rigid-body dynamics


@pytest.mark.parametrize("name", ["lever-arm", "two-link", "wheel"])
def test_aba_against_rnea_and_crba(tmp_path, name):
    """M(q) q̈ + n(q, q̇) = τ with q̈ from ABA, M from CRBA, n from RNEA, random states."""
    arm = _arms(tmp_path)[name]
    rng = np.random.default_rng(7)
    for model in (arm.nominal, arm.true):
        data = model.createData()
        for _ in range(50):
            q = rng.uniform(-math.pi, math.pi, arm.n_joints)
            v = rng.uniform(-3, 3, arm.n_joints)
            tau = rng.uniform(-5, 5, arm.n_joints)
            cfg = arm.configuration(q)
            acc = np.array(pin.aba(model, data, cfg, v, tau))
            m = np.array(pin.crba(model, data, cfg))
            m = np.triu(m) + np.triu(m, 1).T
            n = np.array(pin.rnea(model, data, cfg, v, np.zeros(arm.n_joints)))
            scale = max(1.0, np.abs(tau).max())
            np.testing.assert_allclose(m @ acc + n, tau, rtol=0, atol=1e-12 * scale)


def test_nominal_terms_are_the_arm_model_methods(tmp_path):
    arm = _arms(tmp_path)["wheel"]
    q, v = np.array([0.4, -0.7, 0.05]), np.array([0.3, -1.0, 0.2])
    data = arm.nominal.createData()
    cfg = arm.configuration(q)
    assert cfg.shape == (4,)  # the continuous joint is (cos q, sin q)
    m = np.array(pin.crba(arm.nominal, data, cfg))
    np.testing.assert_array_equal(arm.mass_matrix(q), np.triu(m) + np.triu(m, 1).T)
    np.testing.assert_array_equal(arm.bias(q, v), pin.rnea(arm.nominal, data, cfg, v, 0 * v))
    np.testing.assert_allclose(arm.gravity(q), pin.rnea(arm.nominal, data, cfg, 0 * v, 0 * v),
                               rtol=0, atol=1e-15)
    assert arm.continuous.tolist() == [True, False, False]
    assert arm.lower[0] == -np.inf and arm.upper[2] == pytest.approx(0.1)


def test_lever_urdf_is_the_papers_lever_arm():
    """The one-joint URDF has I0 = 0.0225 kg·m² and G(θ) = (m1 l1 − m2 l2) g cos θ."""
    arm = load_arm(builtin_robot("lever-arm"))
    scn = load_scenario("test-1")
    gcoef = RigParams.from_scenario(scn).gcoef
    for theta in np.linspace(-3, 3, 13):
        q = np.array([theta])
        assert arm.mass_matrix(q)[0, 0] == pytest.approx(scn.plant.inertia, rel=1e-15)
        assert arm.gravity(q)[0] == pytest.approx(gcoef * math.cos(theta), rel=1e-12, abs=1e-17)


def test_payload_and_scale_change_the_twin_only():
    plain = load_arm(builtin_robot("two-link"))
    heavy = load_arm(builtin_robot("two-link"), payload_mass=0.3, payload_offset=(0.25, 0, 0))
    q = np.array([0.2, 0.5])
    np.testing.assert_array_equal(plain.mass_matrix(q), heavy.mass_matrix(q))
    # the payload hangs 0.25 m beyond the elbow: gravity torque of the true elbow grows
    true_g = pin.computeGeneralizedGravity(heavy.true, heavy.true.createData(), q)
    extra = 0.3 * 9.81 * 0.25 * math.cos(q.sum())
    assert true_g[1] - heavy.gravity(q)[1] == pytest.approx(extra, rel=1e-12)


# ---------------------------------------------------------------------------
# the twin


def _lever_twin(scn):
    rig = scn.rig
    arm = load_arm(builtin_robot("lever-arm"), g=scn.plant.g, inertia_scale=rig.inertia_scale)
    params = TwinParams(np.array([rig.coulomb_friction]), np.array([rig.friction_velocity]),
                        np.array([rig.viscous_friction]), np.array([rig.disturbance.amplitude]),
                        np.array([rig.disturbance.frequency]), scn.actuator.lag)
    return arm, ArmTwin(arm, params)


@pytest.mark.parametrize("lag", [0.0, 0.03])
def test_twin_on_lever_urdf_is_the_lever_rig(lag):
    scn = load_scenario("test-1", {"actuator.lag": lag})
    _, twin = _lever_twin(scn)
    vec = RigParams.from_scenario(scn).vector
    rng = np.random.default_rng(3)
    for _ in range(20):
        th, om, tau, u, t = rng.uniform(-2, 2, 5) + (0, 0, 0, 0, 2)
        acc = twin.acceleration(np.array([th]), np.array([om]), np.array([tau]), t)
        assert acc[0] == pytest.approx(rig_acceleration(th, om, tau, t, vec), rel=1e-13)
        q, v, s = twin.advance(np.array([th]), np.array([om]), np.array([tau]), np.array([u]),
                               t, 0.001, 20)
        ref = rig_advance(th, om, tau, u, t, 0.001, 20, vec)
        np.testing.assert_allclose([q[0], v[0], s[0]], ref, rtol=1e-12, atol=1e-14)


def _energy_drift(h: float) -> tuple[float, float]:
    arm = load_arm(builtin_robot("two-link"), payload_mass=0.3, payload_offset=(0.25, 0, 0),
                   inertia_scale=1.1)
    zeros = np.zeros(2)
    twin = ArmTwin(arm, TwinParams(zeros, np.ones(2), zeros, zeros, zeros))
    q, v, tau = np.array([0.3, 1.0]), np.array([2.0, -3.0]), zeros
    e0 = twin.energy(q, v)
    steps = int(round(0.5 / h))
    q, v, tau = twin.advance(q, v, tau, zeros, 0.0, h, steps)
    return twin.energy(q, v) - e0, e0


def test_unforced_frictionless_twin_conserves_energy_to_rk4_order():
    """The energy error shrinks at least 2⁴-fold per halving of h (RK4 is 4th order).

    (Measured here: ~2⁵ per halving, -1.6e-5 J at h = 4 ms, -4.9e-7 J at 2 ms,
    -1.5e-8 J at 1 ms over 0.5 s; the energy error of RK4 often converges one
    order faster than the state.)
    """
    coarse, e0 = _energy_drift(0.004)
    fine, _ = _energy_drift(0.002)
    assert abs(fine) < 1e-6 * abs(e0)
    order = math.log2(abs(coarse / fine))
    assert 3.8 < order < 5.5, order


# ---------------------------------------------------------------------------
# controller and observer input


@pytest.mark.parametrize(("compensation", "feedforward"),
                         [("eso", False), ("eso", True), ("model", False)])
def test_computed_torque_law(compensation, feedforward):
    scn = load_scenario("two-link", {"controller.k1": [10.0, 20.0], "controller.k2": [25.0, 100.0],
                                     "controller.compensation": compensation,
                                     "controller.feedforward": feedforward})
    plant = urdf.design(scn)
    ctl = design(scn, plant, scn.sample_time)
    arm = urdf.arm_of(plant.vector)
    zhat = np.array([0.1, 0.5, -3.0, -0.4, 1.0, 2.0])
    refs = np.array([[0.2], [0.4], [1.0], [-0.3], [0.9], [-2.0]])
    u = np.empty(2)
    control(np.zeros(1), zhat, np.zeros(2), refs, 0, ctl.vector, u)
    k1, k2 = np.array([10.0, 20.0]), np.array([25.0, 100.0])
    q_hat, v_hat, f_hat = zhat[0::3], zhat[1::3], zhat[2::3]
    alpha = refs[2::3, 0] - k1 * (v_hat - refs[1::3, 0]) - k2 * (q_hat - refs[0::3, 0])  # eq. 16
    m, n = arm.mass_matrix(q_hat), arm.bias(q_hat, v_hat)
    if compensation == "model":
        np.testing.assert_allclose(u, m @ alpha + n, rtol=1e-14)
    else:
        np.testing.assert_allclose(u, m @ (alpha - f_hat) + (n if feedforward else 0), rtol=1e-14)
    # the observers' input: with perfect bookkeeping the commanded acceleration α − ẑ3
    v = np.empty(2)
    urdf.observer_input(zhat, u, plant.vector, v)
    if compensation == "eso":
        np.testing.assert_allclose(v, alpha - f_hat, rtol=1e-12)
    else:
        np.testing.assert_allclose(v, np.linalg.solve(m, u), rtol=1e-14)


# ---------------------------------------------------------------------------
# closed loop against a second engine


@pytest.mark.parametrize("compensation", ["eso", "model"])
def test_two_link_against_a_plain_pinocchio_loop(compensation):
    """A second engine, written with CRBA/RNEA and NumPy only, gives the same run."""
    from reference_arm import run_plain

    scn = load_scenario("two-link", {"duration": 3.0, "controller.compensation": compensation})
    res = simulate(scn, warn=False)
    refs = prepare(scn, draw_noise=False).refs
    p, r = scn.plant, scn.rig
    out = run_plain({
        "urdf": p.file, "g": p.g, "payload_mass": p.payload_mass,
        "payload_offset": tuple(p.payload_offset), "inertia_scale": r.inertia_scale,
        "coulomb": r.coulomb_friction, "vs": r.friction_velocity, "viscous": r.viscous_friction,
        "d_amp": r.disturbance.amplitude, "d_freq": r.disturbance.frequency,
        "rate_hz": scn.sensor.rate_hz, "step": r.step, "duration": scn.duration,
        "noise_deg": scn.sensor.noise_deg, "resolution_deg": scn.sensor.resolution_deg,
        "seed": scn.sensor.seed, "eps": scn.observer.eps, "k1": scn.controller.k1,
        "k2": scn.controller.k2, "torque_limit": scn.actuator.torque_limit,
        "compensation": compensation,
        "reference": tuple(np.column_stack([refs[3 * j + i] for j in range(2)])
                           for i in range(3)),
    })
    theta = np.column_stack([j.theta for j in res.per_joint])
    u = np.column_stack([j.u for j in res.per_joint])
    z3 = np.column_stack([j.z[:, 2] for j in res.per_joint])
    np.testing.assert_allclose(out["theta"], theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["u"], u, rtol=0, atol=1e-7)
    np.testing.assert_allclose(out["z3"], z3, rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------
# bad URDFs: one line naming the file


@pytest.mark.parametrize(("text", "needle"), [
    (None, "no such URDF file"),
    ("<robot name='x'><link", "not valid XML"),
    ("<model/>", "root element is <model>"),
    ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
     "<parent link='a'/><child link='b'/></joint></robot>", "does not specify limits"),
    ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='floating'>"
     "<parent link='a'/><child link='b'/></joint></robot>", "revolute, continuous and prismatic"),
    ("<robot name='x'><link name='a'/></robot>", "no movable joint"),
])
def test_bad_urdf_is_one_line(tmp_path, capfd, text, needle):
    path = tmp_path / "arm.urdf"
    if text is not None:
        path.write_text(text)
    with pytest.raises(UrdfError) as info:
        load_arm(path)
    message = str(info.value)
    assert needle in message
    assert "\n" not in message and str(path) in message
    assert capfd.readouterr().err == ""  # urdfdom's own printout is captured



_FOREARM = ('<mass value="0.6"/>\n      <inertia ixx="0.00005" ixy="0.0" ixz="0.0" '
            'iyy="0.003125" iyz="0.0" izz="0.003125"/>')


@pytest.mark.parametrize(("old", "new", "needle"), [
    # the forearm massless: the elbow moves nothing (was a NaN run blamed on observer.eps)
    (_FOREARM, '<mass value="0"/>\n      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" '
     'izz="0"/>', "joint 'elbow' moves no mass: link 'forearm'"),
    ("<inertial>\n      <origin xyz=\"0.125 0 0\" rpy=\"0 0 0\"/>\n      " + _FOREARM +
     "\n    </inertial>", "", "joint 'elbow' moves no mass"),
    ('<mass value="0.6"/>', '<mass value="nan"/>', "mass [nan] is not a float"),
    ('<mass value="0.6"/>', '<mass value="0"/>', "link 'forearm' has an inertia tensor but mass 0"),
    ('<mass value="1.0"/>', '<mass value="-1.0"/>', "link 'upper_arm' has mass -1 kg"),
    ('iyy="0.003125"', 'iyy="-0.003125"', "link 'forearm': its inertia tensor is not positive"),
    ('lower="-2.5" upper="2.5"', 'lower="2.5" upper="-2.5"',
     "joint 'elbow': lower limit 2.5 is above the upper limit -2.5"),
], ids=["massless-leaf", "no-inertial", "nan-mass", "inertia-without-mass", "negative-mass",
        "negative-moment", "reversed-limits"])
def test_unphysical_urdf_is_one_line(tmp_path, capfd, old, new, needle):
    """Masses, inertias and limits a twin cannot run: bad input naming the link or joint
    (these ran silently, or diverged at sample 0 with a message about observer.eps)."""
    text = builtin_robot("two-link").read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "arm.urdf"
    path.write_text(text.replace(old, new), encoding="utf-8")
    with pytest.raises(UrdfError) as info:
        load_arm(path)
    message = str(info.value)
    assert needle in message and "\n" not in message and str(path) in message
    assert capfd.readouterr().err == ""
    with pytest.raises(UrdfError, match="is a directory"):
        load_arm(tmp_path)


def test_a_massless_rod_inside_the_chain_is_allowed(tmp_path):
    """A massless upper arm carrying a forearm with mass: M(q) stays invertible."""
    text = builtin_robot("two-link").read_text(encoding="utf-8")
    text = text.replace('<mass value="1.0"/>', '<mass value="0"/>').replace(
        'ixx="0.0001" ixy="0.0" ixz="0.0" iyy="0.0075" iyz="0.0" izz="0.0075"',
        'ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"')
    path = tmp_path / "arm.urdf"
    path.write_text(text, encoding="utf-8")
    arm = load_arm(path)
    m = arm.mass_matrix(np.array([0.3, -0.4]))
    assert np.linalg.eigvalsh(m).min() > 0
