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

from esoarm.controllers.computed_torque import ArmController, JointObservers  # noqa: E402
from esoarm.engines.arm_loop import ArmRun, run_arm  # noqa: E402
from esoarm.engines.simulation import prepare, simulate  # noqa: E402
from esoarm.observers.linear import ExtendedStateObserver, design_observer  # noqa: E402
from esoarm.plants.lever_arm import RigParams, rig_acceleration, rig_advance  # noqa: E402
from esoarm.plants.urdf import UrdfError, builtin_robot, load_arm  # noqa: E402
from esoarm.plants.urdf_twin import ArmTwin, TwinParams  # noqa: E402
from esoarm.reference import evaluate_reference  # noqa: E402
from esoarm.scenario import QuinticSteps, load_scenario  # noqa: E402

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
# observers and controller


def test_joint_observers_are_the_lever_observer_per_joint():
    eps = np.array([0.05, 0.09])
    bank = JointObservers(eps, 0.02, "current", np.array([0.1, -0.2]))
    single = [ExtendedStateObserver(design_observer(e, 0.02, 1.0, "current"), y0)
              for e, y0 in zip(eps, (0.1, -0.2), strict=True)]
    rng = np.random.default_rng(1)
    for _ in range(30):
        y, v = rng.normal(size=2), rng.normal(size=2)
        zhat = bank.estimate(y)
        for i in range(2):
            assert tuple(zhat[i]) == single[i].estimate(y[i])
        bank.update(v)
        for i in range(2):
            single[i].update(v[i])
            assert tuple(bank.z[i]) == single[i].z


@pytest.mark.parametrize(("compensation", "feedforward"),
                         [("eso", False), ("eso", True), ("model", False)])
def test_computed_torque_law(compensation, feedforward):
    arm = load_arm(builtin_robot("two-link"))
    k1, k2 = np.array([10.0, 20.0]), np.array([25.0, 100.0])
    ctl = ArmController(arm, k1, k2, compensation, feedforward, np.full(2, 1e9))
    zhat = np.array([[0.1, 0.5, -3.0], [-0.4, 1.0, 2.0]])
    qr, vr, ar = np.array([0.2, -0.3]), np.array([0.4, 0.9]), np.array([1.0, -2.0])
    u, v = ctl(zhat, qr, vr, ar)
    alpha = ar - k1 * (zhat[:, 1] - vr) - k2 * (zhat[:, 0] - qr)  # eq. 16
    m = arm.mass_matrix(zhat[:, 0])
    n = arm.bias(zhat[:, 0], zhat[:, 1])
    if compensation == "model":
        np.testing.assert_allclose(u, m @ alpha + n, rtol=1e-14)
        np.testing.assert_allclose(v, np.linalg.solve(m, u), rtol=1e-12)
    else:
        np.testing.assert_allclose(u, m @ (alpha - zhat[:, 2]) + (n if feedforward else 0),
                                   rtol=1e-14)
        # unsaturated: the observers are told exactly the commanded acceleration
        np.testing.assert_allclose(v, alpha - zhat[:, 2], rtol=1e-12)


def test_saturation_per_joint():
    arm = load_arm(builtin_robot("two-link"))
    ctl = ArmController(arm, np.full(2, 10.0), np.full(2, 25.0), "model", False,
                        np.array([1.0, 0.2]))
    u, _ = ctl(np.zeros((2, 3)), np.array([1.0, 1.0]), np.zeros(2), np.zeros(2))
    assert u.tolist() == [1.0, 0.2]


# ---------------------------------------------------------------------------
# closed loop


def _lever_run(scn):
    inp = prepare(scn)
    arm, twin = _lever_twin(scn)
    ctl = ArmController(arm, np.array([scn.controller.k1]), np.array([scn.controller.k2]),
                        scn.controller.compensation, False,
                        np.array([scn.actuator.torque_limit]))
    return ArmRun(t=inp.t, ts=scn.sample_time, q_ref=inp.theta_ref[:, None],
                  v_ref=inp.omega_ref[:, None], a_ref=inp.accel_ref[:, None],
                  noise=inp.noise[:, None], sigma=inp.sigma, quant=inp.q, twin=twin,
                  controller=ctl, eps=np.array([scn.observer.eps]),
                  discretization=scn.observer.discretization, h=inp.h, nsub=inp.nsub,
                  delay=inp.delay, q0=np.array([inp.theta0]))


@pytest.mark.parametrize("overrides", [
    {},
    {"controller.compensation": "model"},
    {"observer.discretization": "zoh", "observer.eps": 0.05},
    {"observer.discretization": "current", "actuator.lag": 0.02, "actuator.delay_samples": 2},
], ids=["test-1", "model", "zoh", "current-lag-delay"])
def test_lever_urdf_closed_loop_reproduces_test_1(overrides):
    scn = load_scenario("test-1", overrides)
    ref = simulate(scn, warn=False)
    log = run_arm(_lever_run(scn))
    e, u = log.error[:, 0], log.u[:, 0]
    assert math.sqrt(np.mean(e**2)) == pytest.approx(ref.rms_error, rel=1e-9)
    assert math.sqrt(np.mean(u**2)) == pytest.approx(ref.rms_u, rel=1e-9)
    assert np.max(np.abs(e)) == pytest.approx(ref.max_abs_error, rel=1e-9)
    np.testing.assert_allclose(log.z[:, 0, :], ref.z, rtol=0, atol=1e-9)
    np.testing.assert_allclose(log.f_true[:, 0], ref.f_true, rtol=0, atol=1e-9)


def _two_link_reference(n, rate):
    t = np.arange(n) / rate
    refs = [evaluate_reference(QuinticSteps(start=0.0, moves=m), t) for m in (
        [[0.5, 2.0, 1.2], [4.0, 2.0, -0.5]], [[1.0, 2.0, -2.0], [4.5, 2.0, 1.0]])]
    return tuple(np.column_stack([r[i] for r in refs]) for i in range(3))


def _two_link_run(compensation, eps=0.02, feedforward=False, seed=0, duration=8.0):
    rate, n_joints = 200.0, 2
    n = int(duration * rate)
    t = np.arange(n) / rate
    q_ref, v_ref, a_ref = _two_link_reference(n, rate)
    arm = load_arm(builtin_robot("two-link"), payload_mass=0.3, payload_offset=(0.25, 0, 0))
    twin = ArmTwin(arm, TwinParams(np.full(2, 0.1), np.full(2, 0.01), np.full(2, 0.05),
                                   np.full(2, 0.2), np.full(2, 0.5)))
    ctl = ArmController(arm, np.full(2, 20.0), np.full(2, 100.0), compensation, feedforward,
                        np.full(2, 10.0))
    noise = np.random.default_rng(seed).standard_normal((n, n_joints))
    return run_arm(ArmRun(t=t, ts=1 / rate, q_ref=q_ref, v_ref=v_ref, a_ref=a_ref,
                          noise=noise, sigma=math.radians(0.2), quant=math.radians(0.05),
                          twin=twin, controller=ctl, eps=np.full(2, eps),
                          discretization="euler", h=0.001, nsub=5, delay=0,
                          q0=np.zeros(2)))


def test_two_link_eso_beats_the_computed_torque_baseline():
    """Payload error and friction: the ESO lowers every joint's RMS error (Fig. 7 analogue)."""
    rms = {}
    for comp, ff in (("model", False), ("eso", False), ("eso", True)):
        log = _two_link_run(comp, feedforward=ff)
        assert log.diverged_at is None
        rms[comp, ff] = np.sqrt(np.mean(log.error**2, axis=0))
    baseline = rms["model", False]
    assert np.all(rms["eso", False] < 0.5 * baseline), rms
    assert np.all(rms["eso", True] < 0.5 * baseline), rms


@pytest.mark.parametrize("compensation", ["eso", "model"])
def test_two_link_against_a_plain_pinocchio_loop(compensation):
    """A second engine, written with CRBA/RNEA and NumPy only, gives the same run."""
    from reference_arm import run_plain

    duration, rate = 3.0, 200.0
    log = _two_link_run(compensation, duration=duration)
    n = int(duration * rate)
    out = run_plain({
        "urdf": str(builtin_robot("two-link")), "g": 9.81, "payload_mass": 0.3,
        "payload_offset": (0.25, 0.0, 0.0), "inertia_scale": 1.0, "coulomb": 0.1, "vs": 0.01,
        "viscous": 0.05, "d_amp": 0.2, "d_freq": 0.5, "rate_hz": rate, "step": 0.001,
        "duration": duration, "noise_deg": 0.2, "resolution_deg": 0.05, "seed": 0,
        "eps": 0.02, "k1": 20.0, "k2": 100.0, "torque_limit": 10.0,
        "compensation": compensation,
        "reference": (log.theta_ref[:n], *_two_link_reference(n, rate)[1:]),
    })
    np.testing.assert_allclose(out["theta"], log.theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["u"], log.u, rtol=0, atol=1e-7)
    np.testing.assert_allclose(out["z3"], log.z[:, :, 2], rtol=0, atol=1e-6)


def test_arm_runs_are_deterministic():
    a, b = _two_link_run("eso", duration=1.0), _two_link_run("eso", duration=1.0)
    for name in ("theta", "u", "z", "f_true", "omega"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


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
