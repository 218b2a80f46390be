"""URDF arms through the scenario, the engines and the command line (plant.kind = "urdf")."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from esoarm.engines.simulation import prepare, simulate  # noqa: E402
from esoarm.plants.arms.model import UrdfError, builtin_robot, import_pinocchio  # noqa: E402
from esoarm.scenario import ScenarioError, load_scenario  # noqa: E402


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "esoarm", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=600, check=False)


# ---------------------------------------------------------------------------
# the general path reproduces the paper's system


@pytest.mark.parametrize("overrides", [
    [],
    ["controller.compensation=model"],
    ["observer.discretization=zoh", "observer.eps=0.05"],
    ["observer.discretization=current", "actuator.lag=0.02", "actuator.delay_samples=2"],
    ["reference.kind=multisine"],
], ids=["test-1", "model", "zoh", "current-lag-delay", "multisine"])
def test_test_1_urdf_gives_test_1s_metrics(overrides):
    ref = simulate(load_scenario("test-1", overrides), warn=False)
    arm = simulate(load_scenario("test-1-urdf", overrides), warn=False)
    for key in ("rms_error", "rms_u", "max_abs_error", "max_abs_u", "rms_rate_error"):
        assert arm.metrics[key] == pytest.approx(ref.metrics[key], rel=1e-9), key
    np.testing.assert_allclose(arm.z, ref.z, rtol=0, atol=1e-9)
    np.testing.assert_allclose(arm.f_true, ref.f_true, rtol=0, atol=1e-9)


def test_test_1_urdf_csv_has_test_1s_columns(tmp_path):
    a = simulate("test-1", warn=False).to_csv(tmp_path / "a.csv")
    b = simulate("test-1-urdf", warn=False).to_csv(tmp_path / "b.csv")
    assert a.read_text().splitlines()[0] == b.read_text().splitlines()[0]


# ---------------------------------------------------------------------------
# two-link


@pytest.fixture(scope="module")
def two_link_runs():
    out = {}
    for label, over in (("eso", []), ("ff", ["controller.feedforward=true"]),
                        ("model", ["controller.compensation=model"])):
        out[label] = simulate(load_scenario("two-link", ["duration=10.0", *over]), warn=False)
    return out


def test_two_link_eso_beats_computed_torque_without_estimation(two_link_runs):
    """The Fig. 7 analogue: per joint, RMS error with the ESO well below the baseline's."""
    model = two_link_runs["model"].per_joint
    for label in ("eso", "ff"):
        for joint, base in zip(two_link_runs[label].per_joint, model, strict=True):
            assert joint.rms_error < 0.5 * base.rms_error, label


def test_two_link_overall_metrics_combine_the_joints(two_link_runs):
    res = two_link_runs["eso"]
    assert len(res.joints) == 2 and res.joint_names == ("shoulder", "elbow")
    errors = np.concatenate([p.error for p in res.per_joint])
    assert res.rms_error == pytest.approx(math.sqrt(np.mean(errors**2)), rel=1e-12)
    assert res.max_abs_error == max(p.max_abs_error for p in res.per_joint)
    joints = res.summary()["joints"]
    assert [j["name"] for j in joints] == ["shoulder", "elbow"]
    assert joints[1]["rms_error"] == res.joints[1].rms_error


def test_eps_trade_off_on_two_link():
    """Too small an ε amplifies noise, too large lags: the middle one is best (as Table II)."""
    rms = {eps: simulate(load_scenario("two-link", ["duration=10.0", f"observer.eps={eps}"]),
                         warn=False).rms_error for eps in (0.006, 0.02, 0.08)}
    assert rms[0.02] < rms[0.006] and rms[0.02] < rms[0.08], rms


def test_per_joint_lists_equal_scalars():
    base = ["duration=1.0"]
    a = simulate(load_scenario("two-link", base), warn=False)
    b = simulate(load_scenario("two-link", [*base, "observer.eps=[0.02, 0.02]",
                                            "controller.k1=[20.0, 20.0]",
                                            "controller.k2=[100.0, 100.0]"]), warn=False)
    np.testing.assert_array_equal(a.table(), b.table())
    c = simulate(load_scenario("two-link", [*base, "observer.eps=[0.02, 0.03]"]), warn=False)
    # sample 2: the observers have seen the same y and v; only the elbow's gains differ
    np.testing.assert_array_equal(c.joints[0].z[2], a.joints[0].z[2])
    assert not np.array_equal(c.joints[1].z[2], a.joints[1].z[2])


def test_range_reference_spans_each_joints_limits():
    scn = load_scenario("two-link")
    refs = prepare(scn, draw_noise=False).refs
    # fraction 0.75 of ±1.6 (shoulder) and ±2.5 (elbow), reached between the moves
    assert refs[0].max() == pytest.approx(0.75 * 1.6)
    assert refs[3].min() == pytest.approx(-0.75 * 2.5)
    assert refs[0, 0] == 0.0 and refs[1].max() > 0


def test_per_joint_reference():
    scn = load_scenario("two-link", [
        "reference.kind=per-joint",
        'reference.joints=[{kind = "quintic-steps", moves = [[0.5, 1.0, 0.4]]}, '
        '{kind = "multisine", amplitudes = [0.3], frequencies = [2.0]}]'])
    refs = prepare(scn, draw_noise=False).refs
    t = np.arange(scn.n_samples) * scn.sample_time
    assert refs[0, -1] == pytest.approx(0.4)
    np.testing.assert_allclose(refs[3], 0.3 * np.sin(2.0 * t), atol=1e-15)


def test_feedforward_scenario_runs_deterministically():
    over = ["duration=1.0", "controller.feedforward=true"]
    a = simulate(load_scenario("two-link", over), warn=False)
    b = simulate(load_scenario("two-link", over), warn=False)
    np.testing.assert_array_equal(a.table(), b.table())


# ---------------------------------------------------------------------------
# scenario files


def test_urdf_path_is_relative_to_the_scenario_file(tmp_path):
    shutil.copy(builtin_robot("two-link"), tmp_path / "arm.urdf")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "my.toml").write_text(
        'duration = 0.5\n[plant]\nkind = "urdf"\nfile = "../arm.urdf"\n'
        '[controller]\nkind = "computed-torque"\n[sensor]\nrate_hz = 200.0\n')
    scn = load_scenario(tmp_path / "sub" / "my.toml")
    assert scn.plant.file == str(tmp_path / "arm.urdf")
    shown = tmp_path / "shown.toml"
    shown.write_text(scn.to_toml())
    assert load_scenario(shown).plant == scn.plant  # `show` output loads again
    assert simulate(scn, warn=False).joint_names == ("shoulder", "elbow")


CONTINUOUS = """<robot name="c"><link name="a"/><link name="b"><inertial><origin xyz="0.1 0 0"/>
<mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
</inertial></link><joint name="spin" type="continuous"><parent link="a"/><child link="b"/>
<axis xyz="0 -1 0"/></joint></robot>"""


@pytest.mark.parametrize(("urdf", "extra", "needle"), [
    (None, "", "no such URDF file"),
    ("<robot name='x'><link", "", "not valid XML"),
    ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
     "<parent link='a'/><child link='b'/></joint></robot>", "", "does not specify limits"),
    ("two-link", "[observer]\neps = [0.02, 0.03, 0.04]\n", "key 'observer.eps': 3 entries"),
    ("two-link", "[controller]\nkind = \"computed-torque\"\nk2 = [100.0]\n",
     "key 'controller.k2': 1 entries"),
    (CONTINUOUS, "[reference]\nkind = \"range\"\n", "continuous (no limits)"),
    ("two-link", "[reference]\nkind = \"per-joint\"\n[[reference.joints]]\nkind = \"multisine\"\n",
     "key 'reference.joints': 1 entries"),
])
@pytest.mark.slow
def test_bad_arm_input_is_one_line_exit_2_nothing_written(tmp_path, urdf, extra, needle):
    if urdf == "two-link":
        shutil.copy(builtin_robot("two-link"), tmp_path / "arm.urdf")
    elif urdf is not None:
        (tmp_path / "arm.urdf").write_text(urdf)
    ctl = "" if "[controller]" in extra else '[controller]\nkind = "computed-torque"\n'
    (tmp_path / "s.toml").write_text(
        f'duration = 0.2\n[plant]\nkind = "urdf"\nfile = "arm.urdf"\n{ctl}{extra}')
    res = _cli("simulate", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o.csv"))
    assert res.returncode == 2, res.stderr
    assert needle in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize(("scenario", "sets", "needle"), [
    ("two-link", ["controller.kind=flc"], "a URDF arm uses 'computed-torque'"),
    ("test-1", ["controller.kind=computed-torque"], "needs plant.kind = 'urdf'"),
    ("test-1", ["reference.kind=range"], "has none"),
    ("two-link", ["rig.stiction=0.5"], "no Stribeck term"),
])
def test_mismatched_kinds_are_bad_input(scenario, sets, needle):
    with pytest.raises(ScenarioError, match=needle):
        load_scenario(scenario, sets)


def test_missing_pinocchio_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pinocchio", None)
    with pytest.raises(UrdfError, match=r"esoarm\[arms\]"):
        import_pinocchio()


# ---------------------------------------------------------------------------
# commands


@pytest.mark.slow
def test_simulate_json_has_joints_and_csv_per_joint_columns(tmp_path):
    res = _cli("simulate", "two-link", "--set", "duration=0.5", "--json", "--out",
               str(tmp_path / "r.csv"), "--plot", str(tmp_path / "r.png"))
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert {"rms_error", "rms_u", "max_abs_error"} <= set(data)
    assert [j["name"] for j in data["joints"]] == ["shoulder", "elbow"]
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    assert header[:9] == ["t", "theta", "theta_ref", "error", "u", "z1", "z2", "z3", "f_true"]
    for col in ("theta_1", "theta_ref_2", "u_2", "z1_1", "z3_2", "f_true_2"):
        assert col in header
    assert (tmp_path / "r.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_sweep_runs_an_arm_in_processes(tmp_path):
    out = tmp_path / "s.csv"
    res = _cli("sweep", "two-link", "--vary", "observer.eps=0.01,0.02", "--set", "duration=0.5",
               "--out", str(out))
    assert res.returncode == 0, res.stderr
    rows = out.read_text().splitlines()
    assert len(rows) == 3


@pytest.mark.slow
def test_arm_study_writes_a_report(tmp_path):
    out = tmp_path / "study"
    res = _cli("arm-study", "two-link", "--set", "duration=1.0", "--eps", "0.01,0.02",
               "--workers", "1", "--out", str(out))
    assert res.returncode == 0, res.stderr
    html = (out / "report.html").read_text()
    assert "no estimation" in html and "data:image/png;base64" in html
    data = json.loads((out / "summary.json").read_text())
    assert data["joints"] == ["shoulder", "elbow"] and len(data["eps_sweep"]) == 2


def test_rig_commands_refuse_an_arm():
    res = _cli("emulate", "two-link")
    assert res.returncode == 2 and "lever-arm rig" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_replay_of_an_arms_simulate_csv_gives_back_its_estimates(tmp_path):
    sim = tmp_path / "sim.csv"
    assert _cli("simulate", "two-link", "--set", "duration=0.5", "--out", str(sim)).returncode == 0
    out = tmp_path / "replay.csv"
    res = _cli("replay", str(sim), "--scenario", "two-link", "--set", "duration=0.5", "--out",
               str(out))
    assert res.returncode == 0, res.stderr
    a = np.genfromtxt(sim, delimiter=",", names=True)
    b = np.genfromtxt(out, delimiter=",", names=True)
    for j in (1, 2):
        for c in ("z1", "z2", "z3"):
            np.testing.assert_array_equal(b[f"{c}_{j}"], a[f"{c}_{j}"])


def test_per_joint_lists_on_the_command_line(run_cli, tmp_path):
    """A per-joint ε prints and runs; a run diverging with per-joint gains is one line, exit 1."""
    out = tmp_path / "a.csv"
    res = run_cli("simulate", "two-link", "--set", "observer.eps=[0.015,0.02]", "--set",
                  "duration=0.5", "--out", str(out), "-v")
    assert res.exit_code == 0, res.stderr
    assert "ε = [0.015, 0.02] s" in res.stderr and out.exists()
    res = run_cli("simulate", "two-link", "--set", "observer.eps=[0.001,0.02]", "--set",
                  "controller.k1=[20,20]", "--set", "duration=0.5")
    assert res.exit_code == 1 and "Traceback" not in res.stderr
    failed = [line for line in res.stderr.splitlines() if "failed" in line]
    assert len(failed) == 1 and "observer.eps = [0.001, 0.02] s" in failed[0]



@pytest.mark.parametrize("sets", [["observer.kind=nonlinear"], ["observer.kind=cascade"]])
def test_nonlinear_and_cascade_observers_run_per_joint(sets):
    """One ESO per joint on a two-joint arm: each joint's state is what the same kind
    computes for that joint alone, fed the same measurement and input (exact)."""
    from esoarm.kinds import kinds_of

    scn = load_scenario("two-link", [*sets, "duration=2"])
    res = simulate(scn, warn=False)
    assert res.metrics["diverged"] == 0.0 and math.isfinite(res.rms_error)
    _, observer, _ = kinds_of(scn)
    design = prepare(scn, draw_noise=False).observer
    per_joint = design.n_state // 2
    block = (len(design.vector) - 1) // 2  # cascade: one block per joint
    rng = np.random.default_rng(5)
    z = rng.normal(size=design.n_state)
    y, v = rng.normal(size=2), rng.normal(size=2)
    zhat = np.empty(design.n_state)
    observer.estimate(z, y, design.vector, zhat)
    z_next = z.copy()
    observer.advance(z_next, zhat, y, v, design.vector)
    for j in range(2):
        own = design.vector[1 + block * j:1 + block * (j + 1)]
        vec = (design.vector if sets[0].endswith("nonlinear") else
               np.concatenate([design.vector[:1], own]))
        zj = z[per_joint * j:per_joint * (j + 1)].copy()
        zh = np.empty(per_joint)
        observer.estimate(zj, y[j:j + 1], vec, zh)
        assert np.array_equal(zh[:3], zhat[3 * j:3 * j + 3])
        observer.advance(zj, zh, y[j:j + 1], v[j:j + 1], vec)
        assert np.array_equal(zj, z_next[per_joint * j:per_joint * (j + 1)])
