"""esoarm.plants.arms.rigid_body against Pinocchio: RNEA, CRBA, bias and forward dynamics.

Every built-in arm and, when the optional package ``example-robot-data`` is
installed, its arms of revolute/prismatic joints (UR5, Panda with its prismatic
fingers, ...): 25 seeded random states each, nominal and true models (payload,
inertia scale), relative error ≤ 1e-10.  The functions run here as plain Python;
the compiled engine runs the same source (tests/engines/test_arms_compiled.py).
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from esoarm.plants.arms import rigid_body as rb  # noqa: E402
from esoarm.plants.arms.model import UrdfError, builtin_robot, load_arm  # noqa: E402

TOL = 1e-10

#: URDFs of example-robot-data checked when it is installed (arms of 1-dof joints).
EXAMPLE_ROBOTS = (
    "ur_description/urdf/ur5_robot.urdf",
    "ur_description/urdf/ur10_robot.urdf",
    "panda_description/urdf/panda.urdf",
    "kinova_description/robots/kinova.urdf",
    "double_pendulum_description/urdf/double_pendulum.urdf",
    "z1_description/urdf/z1.urdf",
    "so_arm_description/urdf/so101.urdf",
)


def _example_dir() -> Path | None:
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path if path.is_dir() else None


def _robots() -> list:
    out = [pytest.param(builtin_robot(name), id=name) for name in ("two-link", "lever-arm")]
    base = _example_dir()
    for rel in EXAMPLE_ROBOTS:
        mark = pytest.mark.skipif(base is None or not (base / rel).is_file(),
                                  reason="example-robot-data not installed (optional)")
        out.append(pytest.param((base / rel) if base else Path(rel), id=Path(rel).stem,
                                marks=mark))
    return out


def _full(m: np.ndarray) -> np.ndarray:
    return np.triu(m) + np.triu(m, 1).T


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / max(1.0, np.abs(b).max()))


@pytest.mark.parametrize("path", _robots())
def test_against_pinocchio_on_random_states(path):
    try:
        arm = load_arm(path, payload_mass=0.7, payload_offset=[0.05, -0.02, 0.1],
                       inertia_scale=1.4)
    except UrdfError as exc:  # pragma: no cover - a robot esoarm does not take
        pytest.skip(str(exc))
    rng = np.random.default_rng(20261203)
    for model in (arm.nominal, arm.true):
        packed = rb.pack_model(model)
        n = int(packed[0])
        assert n == arm.n_joints
        data = model.createData()
        ws = np.full(rb.workspace_size(n), np.nan)  # nothing may be read before it is written
        states = []
        for _ in range(25):
            q = rng.uniform(-np.pi, np.pi, n)
            v = rng.uniform(-4.0, 4.0, n)
            a = rng.uniform(-10.0, 10.0, n)
            tau = rng.uniform(-20.0, 20.0, n)
            cfg = arm.configuration(q)
            out = np.empty(n)
            rb.rnea(packed, q, v, a, ws, out)
            assert _rel(out, pin.rnea(model, data, cfg, v, a)) <= TOL
            rb.bias(packed, q, v, ws, out)
            assert _rel(out, pin.nonLinearEffects(model, data, cfg, v)) <= TOL
            mass = np.empty((n, n))
            rb.crba(packed, q, ws, mass)
            assert _rel(mass, _full(pin.crba(model, data, cfg))) <= TOL
            assert np.array_equal(mass, mass.T)
            nb = np.empty(n)
            mass2 = np.empty((n, n))
            rb.mass_and_bias(packed, q, v, ws, mass2, nb)
            assert np.array_equal(mass2, mass)
            rb.bias(packed, q, v, ws, out)
            assert np.array_equal(nb, out)
            rb.forward_dynamics(packed, q, v, tau, ws, out)
            assert _rel(out, pin.aba(model, data, cfg, v, tau)) <= TOL
            states.append((q, v, tau, out.copy()))
        _assert_block_same_bits(packed, states)


def _assert_block_same_bits(packed: np.ndarray, states: list, compiled: bool = False) -> None:
    """forward_dynamics_block on the states as one block: each column the one-run bits."""
    q, v, tau, want = (np.ascontiguousarray(np.column_stack([s[k] for s in states]))
                       for k in range(4))
    wb = np.full((rb.workspace_size(int(packed[0])), len(states)), np.nan)
    got = np.empty_like(q)
    fd_block = _compiled_block() if compiled else rb.forward_dynamics_block
    fd_block(packed, q, v, tau, wb, got)
    np.testing.assert_array_equal(got, want)


_COMPILED_BLOCK: list = []


def _compiled_block():
    if not _COMPILED_BLOCK:
        from numba import njit

        from esoarm import _jit
        _jit.register_all()

        @njit(error_model="numpy")
        def fd_block(m, q, v, tau, wb, out):  # pragma: no cover - compiled
            rb.forward_dynamics_block(m, q, v, tau, wb, out)

        @njit(error_model="numpy")
        def fd_one(m, q, v, tau, ws, out):  # pragma: no cover - compiled
            rb.forward_dynamics(m, q, v, tau, ws, out)

        _COMPILED_BLOCK.extend([fd_block, fd_one])
    return _COMPILED_BLOCK[0]


@pytest.mark.slow
@pytest.mark.parametrize("path", _robots())
def test_compiled_block_is_the_one_run_bits(path):
    """Compiled, the block of runs (vectorised across runs) gives each run's own bits."""
    try:
        arm = load_arm(path, payload_mass=0.7, payload_offset=[0.05, -0.02, 0.1],
                       inertia_scale=1.4)
    except UrdfError as exc:  # pragma: no cover - a robot esoarm does not take
        pytest.skip(str(exc))
    _compiled_block()
    fd_one = _COMPILED_BLOCK[1]
    rng = np.random.default_rng(11)
    packed = rb.pack_model(arm.true)
    n = int(packed[0])
    ws = np.empty(rb.workspace_size(n))
    states = []
    for _ in range(37):  # not a multiple of the vector width: the loops' remainders too
        q, v, tau = rng.uniform(-np.pi, np.pi, n), rng.uniform(-4, 4, n), rng.uniform(-20, 20, n)
        out = np.empty(n)
        fd_one(packed, q, v, tau, ws, out)
        states.append((q, v, tau, out))
    _assert_block_same_bits(packed, states, compiled=True)


def test_prismatic_and_unaligned_joints(tmp_path):
    """A prismatic joint along a tilted axis after a revolute one with an offset placement."""
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="pr">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0.1 0.02 0" rpy="0.1 0.2 0.3"/><mass value="1.5"/>
    <inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0.002" izz="0.04"/></inertial></link>
  <link name="b"><inertial><origin xyz="0 0.05 0.1"/><mass value="0.8"/>
    <inertia ixx="0.01" ixy="0" ixz="0.001" iyy="0.01" iyz="0" izz="0.005"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.3" rpy="0.3 0 0"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0.4 0 0" rpy="0 0.5 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-0.5" upper="0.5" effort="10" velocity="1"/></joint>
</robot>""")
    arm = load_arm(urdf)
    packed = rb.pack_model(arm.nominal)
    assert packed[rb.HEAD + rb.ROW + 1] == rb.PRISMATIC
    rng = np.random.default_rng(7)
    data = arm.nominal.createData()
    ws = np.empty(rb.workspace_size(2))
    states = []
    for _ in range(25):
        q, v, tau = rng.uniform(-1, 1, 2), rng.uniform(-2, 2, 2), rng.uniform(-5, 5, 2)
        out = np.empty(2)
        rb.forward_dynamics(packed, q, v, tau, ws, out)
        assert _rel(out, pin.aba(arm.nominal, data, q, v, tau)) <= TOL
        states.append((q, v, tau, out.copy()))
    _assert_block_same_bits(packed, states)
    _assert_block_same_bits(packed, states, compiled=True)


def test_cholesky_solve_against_numpy():
    rng = np.random.default_rng(3)
    for n in (1, 2, 6, 9):
        a = rng.normal(size=(n, n))
        spd = a @ a.T + n * np.eye(n)
        b = rng.normal(size=n)
        x = b.copy()
        rb.cholesky_solve(spd.copy(), x)
        np.testing.assert_allclose(x, np.linalg.solve(spd, b), rtol=1e-12, atol=0)
