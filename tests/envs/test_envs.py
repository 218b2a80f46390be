"""The Gymnasium environment: Gymnasium's checker, bit-identity with the simulator, seeding."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import esoarm
from esoarm.scenario import builtin_names

LEVERS = builtin_names(plant="lever-arm")

gym = pytest.importorskip("gymnasium")
envs = pytest.importorskip("esoarm.envs")

SIMULATED = [
    ("test-1", {}),
    ("test-2", {}),
    ("test-1", {"observer.discretization": "zoh", "observer.eps": 0.05}),
    ("test-2", {"observer.discretization": "current", "controller.compensation": "model",
                "actuator.lag": 0.02, "actuator.delay_samples": 2}),
    ("test-1", {"actuator.torque_limit": 0.3, "duration": 6.0}),  # saturating
    ("test-2", {"rig.stiction": 0.05, "duration": 8.0}),  # Stribeck friction
    ("test-1", {"sensor.noise_ar": [0.8], "sensor.vibration_deg": 0.05}),  # coloured noise
    ("test-1", {"rig.backlash_deg": 1.5, "actuator.pwm_bits": 8}),  # gear play, PWM drive
]


def _episode(env, policy) -> tuple[np.ndarray, list[float], bool]:
    obs, _ = env.reset()
    rows, rewards = [], []
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        rows.append([info[k] for k in esoarm.result.CSV_COLUMNS])
        rewards.append(reward)
        if terminated or truncated:
            return np.array(rows), rewards, terminated


def test_ids_are_registered_for_every_builtin() -> None:
    want = {"esoarm/LeverArm-v0", *(f"esoarm/LeverArm-{n}-v0" for n in LEVERS)}
    assert set(envs.ENV_IDS) == want
    for env_id in want:
        assert env_id in gym.registry


@pytest.mark.parametrize("env_id", ["esoarm/LeverArm-v0",
                                    *(f"esoarm/LeverArm-{n}-v0" for n in LEVERS)])
@pytest.mark.parametrize("kwargs", [{}, {"action_mode": "residual", "observe_estimates": True,
                                         "effort_weight": 0.1, "render_mode": "rgb_array"}])
def test_passes_gymnasium_env_checker(env_id: str, kwargs: dict) -> None:
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, **kwargs)
    with warnings.catch_warnings():
        # the checker recommends a [-1, 1] action box and finite observation bounds; the torque
        # [N·m] and the angles are kept in their units on purpose (bit-identity, readability)
        warnings.filterwarnings("ignore", message=".*(normalized|infinity).*")
        check_env(env.unwrapped, skip_render_check=False)
    env.close()


@pytest.mark.parametrize("name, over", SIMULATED)
@pytest.mark.parametrize("mode", ["torque", "residual"])
def test_eso_flc_policy_reproduces_simulate_bit_for_bit(name: str, over: dict, mode: str) -> None:
    env = gym.make("esoarm/LeverArm-v0", scenario=name, overrides=over, action_mode=mode,
                   observe_estimates=True)
    if mode == "torque":
        policy = envs.EsoFlcPolicy(env)
    else:
        def policy(obs):  # type: ignore[no-untyped-def]
            return np.zeros(1)
    rows, rewards, terminated = _episode(env, policy)
    sim = esoarm.simulate(name, over)
    assert not terminated
    np.testing.assert_array_equal(rows, sim.table())
    # reward = −(e² + 0·u²): the return is −N·rms_error²
    assert np.sqrt(-np.mean(rewards)) == pytest.approx(sim.rms_error, rel=1e-12)


def test_seeded_resets() -> None:
    env = gym.make("esoarm/LeverArm-test-2-v0", action_mode="residual")

    def run(seed):  # type: ignore[no-untyped-def]
        obs, info = env.reset(seed=seed)
        first = [obs]
        for _ in range(50):
            first.append(env.step(np.zeros(1))[0])
        return np.array(first), info

    a, info = run(11)
    b, _ = run(11)
    np.testing.assert_array_equal(a, b)
    assert info["noise_seed"] == 11
    sim = esoarm.simulate("test-2", {"sensor.seed": 11, "duration": 1.02})
    # the observation's first entry is the measured angle y_k = Q(θ(t_k) + σ n_k)
    from esoarm.plants.sensor import measure

    scn = sim.scenario
    q, sigma = np.radians(scn.sensor.resolution_deg), np.radians(scn.sensor.noise_deg)
    noise = np.random.default_rng(11).standard_normal(scn.n_samples)
    y = [measure(th, n, sigma, q) for th, n in zip(sim.theta, noise, strict=True)]
    np.testing.assert_array_equal(a[:, 0], y)
    c, info_c = run(None)  # unseeded after a seeded reset: a new draw from np_random
    assert info_c["noise_seed"] != 11 and not np.array_equal(a, c)
    # the first unseeded reset of a fresh environment uses the scenario's sensor.seed
    fresh = gym.make("esoarm/LeverArm-test-2-v0")
    assert fresh.reset()[1]["noise_seed"] == 0


def test_effort_weight_and_termination() -> None:
    env = gym.make("esoarm/LeverArm-v0", effort_weight=0.5)
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.array([1.5]))
    assert reward == pytest.approx(-(info["error"] ** 2 + 0.5 * 1.5**2))
    _, _, _, _, info = env.step(np.array([9.0]))
    assert info["u"] == 2.0  # saturated to torque_limit
    bad = gym.make("esoarm/LeverArm-v0", overrides={"observer.eps": 0.005},
                   action_mode="residual")
    bad.reset()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(1000):
            *_, terminated, truncated, _ = bad.step(np.zeros(1))
            if terminated or truncated:
                break
    assert terminated and not truncated


def test_render_draws_the_arm() -> None:
    env = gym.make("esoarm/LeverArm-v0", render_mode="rgb_array", action_mode="residual")
    env.reset(seed=0)
    first = env.render()
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
    for _ in range(150):  # the arm moves to 1 rad from t = 1 s
        env.step(np.zeros(1))
    moved = env.render()
    assert not np.array_equal(first, moved)
    assert (moved != 255).any(axis=2).sum() > 500  # something is drawn
    assert gym.make("esoarm/LeverArm-v0").unwrapped.render() is None


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="action_mode"):
        envs.LeverArmEnv(action_mode="speed")
    with pytest.raises(ValueError, match="render_mode"):
        envs.LeverArmEnv(render_mode="human")
    with pytest.raises(ValueError, match="effort_weight"):
        envs.LeverArmEnv(effort_weight=-1.0)
    with pytest.raises(esoarm.ScenarioError, match="observer.epz"):
        envs.LeverArmEnv(overrides={"observer.epz": 1})
    env = envs.LeverArmEnv(overrides={"duration": 0.04})
    env.reset()
    env.step(np.zeros(1))
    *_, truncated, _ = env.step(np.zeros(1))
    assert truncated
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(1))


@pytest.mark.parametrize("over", [{}, {"actuator.delay_samples": 1, "duration": 4.0}])
def test_an_arm_whose_observer_input_is_not_u_reproduces_simulate(over: dict) -> None:
    """test-1 as a one-joint URDF arm: the observer input is M̂⁻¹(u − n̂), not u.

    The environment takes the sample of every engine (esoarm.engines.sample), so the
    observer advances with the plant kind's observer input and f_true = θ̈ − b0·v: the
    simulator's numbers bit for bit (an environment that fed u to the observer, as
    this one once did, drifts from the first sample on).
    """
    pytest.importorskip("pinocchio")
    env = envs.LeverArmEnv("test-1-urdf", over, action_mode="residual")
    rows, _, terminated = _episode(env, lambda obs: np.zeros(1))
    sim = esoarm.simulate("test-1-urdf", over)
    assert not terminated
    np.testing.assert_array_equal(rows, sim.table())
