"""The digital twin as a Gymnasium environment, stepped at the sensor rate.

One ``step`` is one sample period Ts of the sampled-data loop that
``esoarm simulate`` runs (:func:`esoarm.engines.loop.closed_loop`): the very
sample functions of :mod:`esoarm.engines.sample`, taken one at a time by
:class:`esoarm.engines.stepper.Stepper`, with the step functions of the
scenario's plant, observer and controller kinds (:mod:`esoarm.kinds`), the
action taking the controller's place, so that the environment driven by the
ESO-FLC gives the simulator's trajectory bit for bit (tested):

``reset``
    θ(0) = ``rig.theta0`` at rest; y_0 = Q(θ + σ n_0); ESO state z_0 = (y_0, 0, 0);
    the estimate ẑ_0 and the reference at t_0 go into the first observation.
``step(action)`` at sample k
    u_k = sat(action) (``action_mode="torque"``) or sat(FLC(ẑ_k) + action)
    (``"residual"``, a correction on top of the ESO-FLC); the reward is
    r_k = −(e_k² + effort_weight · u_k²) with e_k = θ(t_k) − θd(t_k) the
    true tracking error at the sample the action is taken (like Gymnasium's
    Pendulum, the cost of the state the action sees), so that with
    effort_weight = 0, −Σ r_k / N is ``rms_error``² of the run; the ESO
    advances with (y_k, v_k), v_k the plant kind's observer input for u_k (u_k
    itself for the lever arm); the plant integrates [t_k, t_{k+1}) with RK4 under
    u_{k−delay}; then y_{k+1}, ẑ_{k+1} and the next observation.

The observation is (y_k, θd, θ̇d, θ̈d) and, with ``observe_estimates=True``,
(ẑ1, ẑ2, ẑ3) appended [rad, rad, rad/s, rad/s², rad, rad/s, rad/s²].  ``info``
holds the simulator's log row of the step (t, theta, theta_ref, error, u, z1,
z2, z3, f_true, y, saturated).  An episode is truncated after N = duration · rate_hz steps
and terminated if the state leaves the finite range (the simulators'
divergence rule).

Seeding: the encoder noise of an episode is ``default_rng(s).standard_normal(N)``,
exactly as the simulator draws it for ``sensor.seed = s``.  ``reset(seed=s)``
uses s; the first ``reset()`` without a seed uses the scenario's
``sensor.seed``; later unseeded resets draw s from the environment's seeded
generator (``self.np_random``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from esoarm.engines.metrics import NROW
from esoarm.engines.simulation import prepare
from esoarm.engines.stepper import Stepper
from esoarm.plants.actuator import LIMIT
from esoarm.plants.noise import draws, noise_model
from esoarm.scenario import Scenario, load_scenario

__all__ = ["ACTION_MODES", "EsoFlcPolicy", "LeverArmEnv"]

ACTION_MODES = ("torque", "residual")
INFO_KEYS = ("t", "theta", "theta_ref", "error", "u", "z1", "z2", "z3", "f_true", "y",
             "saturated")


class LeverArmEnv(gym.Env):
    """The lever arm of a scenario as an environment (see the module docstring).

    Parameters
    ----------
    scenario : Scenario, str or Path
        A scenario, a built-in name or a TOML path (default "test-1").
    overrides : dict or list of str, optional
        Dotted-key overrides, e.g. ``{"observer.eps": 0.05}``.
    action_mode : {"torque", "residual"}
        The action is the torque u [N·m], or a correction [N·m] added to the
        ESO-FLC's command; saturated to ±torque_limit either way.
    observe_estimates : bool
        Append the ESO estimate ẑ = (ẑ1, ẑ2, ẑ3) to the observation.
    effort_weight : float
        Weight λ of the control effort in the reward −(e² + λ u²) [1/(N·m)²·rad²].
    render_mode : {None, "rgb_array"}
        "rgb_array": :meth:`render` returns an image of the arm (H × W × 3 uint8).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}

    def __init__(self, scenario: Scenario | str | Path = "test-1",
                 overrides: dict | list[str] | None = None, *, action_mode: str = "torque",
                 observe_estimates: bool = False, effort_weight: float = 0.0,
                 render_mode: str | None = None) -> None:
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {', '.join(ACTION_MODES)}; "
                             f"got {action_mode!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array'; got {render_mode!r}")
        if not (math.isfinite(effort_weight) and effort_weight >= 0):
            raise ValueError(f"effort_weight must be a finite number >= 0; got {effort_weight!r}")
        scn = scenario if isinstance(scenario, Scenario) and not overrides else \
            load_scenario(scenario, overrides)
        self.scenario = scn
        self.action_mode = action_mode
        self.observe_estimates = observe_estimates
        self.effort_weight = float(effort_weight)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": scn.sensor.rate_hz}
        self._inp = prepare(scn, draw_noise=False)
        self.n_steps = len(self._inp.t)
        self.n_joints = self._inp.plant.n_joints
        if self.n_joints != 1:
            raise ValueError("the environment drives one joint (the lever arm)")
        limit = float(self._inp.actuator[LIMIT])
        self.action_space = spaces.Box(-limit, limit, shape=(1,), dtype=np.float64)
        size = 7 if observe_estimates else 4
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float64)
        self._seeded_once = False
        self.noise_seed = scn.sensor.seed
        self._new_arrays()

    def _new_arrays(self) -> None:
        inp = self._inp
        self._noise = np.zeros(self.n_steps)
        self._x = np.array(inp.plant.x0)
        self._st = Stepper(inp.kinds, inp.plant, inp.observer, inp.controller, inp.actuator,
                           inp.refs, inp.sampling)
        self._log = np.full((NROW, max(self.n_steps, 1)), np.nan)
        self._k = 0

    # -- the loop: the sample functions of esoarm.engines.sample ----------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; see the module docstring for the noise seed."""
        super().reset(seed=seed)
        if seed is not None:
            noise_seed = int(seed)
        elif not self._seeded_once:
            noise_seed = self.scenario.sensor.seed
        else:
            noise_seed = int(self.np_random.integers(0, 2**31 - 1))
        self._seeded_once = True
        self.noise_seed = noise_seed
        self._new_arrays()
        self._noise = draws(noise_model(self.scenario), noise_seed, self.n_steps)
        if self.n_steps:
            self._st.sense(self._x, self._noise, 0)
        self._st.start()
        self._measure()
        return self._observation(), {"t": 0.0, "noise_seed": noise_seed}

    def _measure(self) -> None:
        """The controller half up to the estimate: y_k and ẑ_k at the current sample."""
        self._st.sense(self._x, self._noise, self._k)
        self._st.estimate()

    def _observation(self) -> np.ndarray:
        inp, k, st = self._inp, min(self._k, self.n_steps - 1), self._st
        head = (st.y[0], inp.refs[0, k], inp.refs[1, k], inp.refs[2, k])
        if self.observe_estimates:
            return np.array((*head, *st.zhat[:3]), dtype=np.float64)
        return np.array(head, dtype=np.float64)

    def flc_command(self) -> float:
        """The controller kind's raw command u_k [N·m] for the current sample (unsaturated)."""
        return float(self._st.control(self._k)[0])

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply the action over one sample period Ts; see the module docstring."""
        if self._k >= self.n_steps:
            raise RuntimeError("the episode is over (truncated): call reset()")
        inp, k, st = self._inp, self._k, self._st
        try:
            arr = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"action {action!r}: must be a number array of shape (1,) (the "
                             f"action space {self.action_space}); the episode is unchanged"
                             ) from None
        if arr.size != 1 or arr.ndim > 1:  # (1,) as action_space, or a scalar
            raise ValueError(f"action of shape {arr.shape}: must be shape (1,) (the action "
                             f"space {self.action_space}); the episode is unchanged")
        a = float(arr.reshape(-1)[0])
        if not math.isfinite(a):  # a NaN would end the episode as if the arm had diverged
            raise ValueError(f"action {a}: must be a finite torque [N·m] ({self.action_mode} "
                             "mode); the episode is unchanged")
        raw = a if self.action_mode == "torque" else self.flc_command() + a
        # the rest of the controller half (saturate, actuate), then the plant half
        st.limit(raw)
        st.hold(k)
        ok = st.record(self._log, self._x, k)
        row = self._log[:, k]
        info = dict(zip(INFO_KEYS, (float(inp.t[k]), *(float(value) for value in row[:-1])),
                        strict=True))
        error, u = info["error"], info["u"]
        reward = -(error * error + self.effort_weight * u * u)
        if not ok:
            return self._observation(), float(reward), True, False, info
        st.update()
        st.advance_plant(self._x, k)
        self._k = k + 1
        truncated = self._k >= self.n_steps
        if not truncated:
            self._measure()
        return self._observation(), float(reward), False, truncated, info

    # -- drawing -----------------------------------------------------------------------
    def render(self) -> np.ndarray | None:  # type: ignore[override]
        """An image of the arm (grey), its reference (thin vermilion line) and the torque (bar)."""
        if self.render_mode != "rgb_array":
            return None
        from esoarm.envs.render import draw_arm

        k = min(self._k, self.n_steps - 1)
        return draw_arm(float(self._x[0]), float(self._inp.refs[0, k]),
                        float(self._st.u[0]) / float(self._inp.actuator[LIMIT]))


class EsoFlcPolicy:
    """The scenario's own controller kind on the observation, as a fixed policy.

    For ``action_mode="torque"`` with ``observe_estimates=True``: the action is the
    controller kind's raw command (the paper's FLC, eq. 14-16, for the default
    ``controller.kind``; whatever kind the scenario names otherwise) from
    (ẑ, θd, θ̇d, θ̈d) and the measured y in the observation, with the controller's own
    state kept here; the environment saturates it as ``esoarm simulate`` does.  The kind
    is asked through the registry, never recognised by its parameters.
    """

    def __init__(self, env: gym.Env) -> None:
        base = env.unwrapped
        if not isinstance(base, LeverArmEnv) or not base.observe_estimates:
            raise ValueError("EsoFlcPolicy needs a LeverArmEnv with observe_estimates=True")
        inp = base._inp
        # (θd, θ̇d, θ̈d) of each observation, in the column of its sample: the kind is called
        # with the sample index k, as in simulate (a kind may act on k, e.g. "switch" at
        # controller.switch_at)
        self._refs = np.zeros((3, max(base.n_steps, 1)))
        self._st = Stepper(inp.kinds, inp.plant, inp.observer, inp.controller, inp.actuator,
                           self._refs, inp.sampling)
        self._k = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        y0, ref, dref, ddref, z1, z2, z3 = (float(v) for v in obs)
        st = self._st
        if self._k == 0:
            st.start(y0)  # the controller's own state from the first measurement
        st.y[0] = y0
        st.zhat[:3] = (z1, z2, z3)
        k = self._k
        if k >= self._refs.shape[1]:
            raise RuntimeError("EsoFlcPolicy: the episode is over; make a new policy after "
                               "reset()")
        self._refs[:, k] = (ref, dref, ddref)
        u = st.control(k).copy()
        self._k += 1
        return u
