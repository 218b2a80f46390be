"""Gymnasium environments of the twin (needs ``pip install 'esoarm[gym]'``).

Importing this package registers ``esoarm/LeverArm-v0`` (the built-in test-1)
and one ``esoarm/LeverArm-<scenario>-v0`` per built-in scenario::

    import gymnasium as gym
    import esoarm.envs  # noqa: F401  (registers the environments)

    env = gym.make("esoarm/LeverArm-v0", action_mode="residual", observe_estimates=True)

``gym.make("esoarm.envs:esoarm/LeverArm-v0")`` imports and registers in one go.
Keyword arguments of :class:`~esoarm.envs.lever_arm.LeverArmEnv` pass through
``gym.make``; episodes are truncated by the environment itself after
duration · rate_hz steps.
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError:  # pragma: no cover - exercised only without the extra
    raise ImportError("the Gymnasium environments need gymnasium: pip install 'esoarm[gym]'"
                      ) from None

from esoarm.envs.lever_arm import ACTION_MODES, EsoFlcPolicy, LeverArmEnv
from esoarm.scenario import builtin_names

__all__ = ["ACTION_MODES", "ENV_IDS", "EsoFlcPolicy", "LeverArmEnv", "register_envs"]

#: Registered ids, the default first.
ENV_IDS: list[str] = []


def register_envs() -> list[str]:
    """Register the environments (idempotent); returns their ids."""
    if ENV_IDS:
        return ENV_IDS
    entries = [("esoarm/LeverArm-v0", "test-1")]
    entries += [(f"esoarm/LeverArm-{name}-v0", name) for name in builtin_names()]
    for env_id, scenario in entries:
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point="esoarm.envs.lever_arm:LeverArmEnv",
                               kwargs={"scenario": scenario}, disable_env_checker=False)
        ENV_IDS.append(env_id)
    return ENV_IDS


register_envs()
