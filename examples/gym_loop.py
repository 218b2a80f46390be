"""The twin as a Gymnasium environment, driven by the ESO-FLC (nothing is trained).

Shows the loop an RL agent would sit in: observation (measured angle, reference,
ESO estimates) -> action (torque) -> reward, one sample period per step; and a
residual policy that adds a correction on top of the ESO-FLC. The ESO-FLC as a
fixed policy reproduces `esoarm simulate` bit for bit.

Run:  python examples/gym_loop.py [OUTPUT_DIR]      (needs: pip install 'esoarm[gym]')
"""

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import esoarm
import esoarm.envs  # registers esoarm/LeverArm-v0 and friends

out = Path(sys.argv[1] if len(sys.argv) > 1 else "example-output")
out.mkdir(parents=True, exist_ok=True)

# 1. The ESO-FLC as a fixed policy on the torque action
env = gym.make("esoarm/LeverArm-v0", observe_estimates=True, render_mode="rgb_array")
policy = esoarm.envs.EsoFlcPolicy(env)
obs, info = env.reset()                  # first reset: the scenario's own noise seed
errors, torques, total = [], [], 0.0
done = False
while not done:
    action = policy(obs)                 # obs = (y, θd, θ̇d, θ̈d, ẑ1, ẑ2, ẑ3)
    obs, reward, terminated, truncated, info = env.step(action)
    errors.append(info["error"])
    torques.append(info["u"])
    total += reward                      # reward = −(e² + λ u²), λ = 0 by default
    done = terminated or truncated
frame = env.render()                     # the arm at the end of the episode
sim = esoarm.simulate("test-1")
same = np.array_equal(errors, sim.error) and np.array_equal(torques, sim.u)
print(f"ESO-FLC policy, {len(errors)} steps of Ts = {env.unwrapped.scenario.sample_time} s:")
print(f"  RMS error {np.sqrt(np.mean(np.square(errors))):.5f} rad "
      f"(esoarm simulate: {sim.rms_error:.5f}); sqrt(-return/N) = "
      f"{np.sqrt(-total / len(errors)):.5f}")
print(f"  the same trajectory as esoarm simulate, bit for bit: {same}")

# 2. A residual policy: the ESO-FLC plus a (here: fixed, untrained) correction
env2 = gym.make("esoarm/LeverArm-test-2-v0", action_mode="residual", effort_weight=0.01)
obs, info = env2.reset(seed=7)           # seed 7 = esoarm simulate test-2 --set sensor.seed=7
ret = 0.0
for _ in range(env2.unwrapped.n_steps):
    correction = np.array([-0.05 * (obs[0] - obs[1])])  # a small extra proportional term
    obs, reward, terminated, truncated, info = env2.step(correction)
    ret += reward
    if terminated or truncated:
        break
print(f"residual policy on test-2, seed 7: return {ret:.4f}")

import matplotlib.image  # noqa: E402  (only for saving the rendered frame)

matplotlib.image.imsave(out / "gym_frame.png", frame)
print(f"wrote {out / 'gym_frame.png'}")
