"""Reference simulator: the sampled-data closed loop of SPEC §2, in plain Python.

This engine is the readable statement of the semantics; the compiled batch
engine follows it exactly and is tested against it.  One sample k:

1. y_k = Q(θ(t_k) + σ n_k)
2. reference (θd, θ̇d, θ̈d) at t_k
3. ẑ_k from the ESO, u_k = sat(FLC(ẑ_k, reference))
4. log t_k, θ(t_k), θd, e_k = θ(t_k) − θd, u_k, ẑ_k, f_k = θ̈(t_k) − b0 u_k
5. ESO update with (y_k, u_k)
6. apply u_{k−delay} over [t_k, t_{k+1}) and integrate the rig with RK4
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from esoarm._jit import jitable
from esoarm.controllers.flc import FLCParams, flc_control
from esoarm.observers.linear import design_observer, eso_advance, eso_estimate
from esoarm.plants.lever_arm import RigParams, applied_torque, rig_acceleration, rig_advance
from esoarm.plants.model import input_gain
from esoarm.plants.sensor import measure, noise_sequence
from esoarm.reference import evaluate_reference
from esoarm.result import SimResult
from esoarm.scenario import Scenario, ScenarioWarning, load_scenario, scenario_warnings

__all__ = [
    "DIVERGENCE_LIMIT",
    "RunInputs",
    "SimulationDiverged",
    "diverged_message",
    "prepare",
    "run_reference",
    "simulate",
    "within_limits",
]

#: |θ| or |z1| beyond this [rad] (or any non-finite value) ends a run as diverged.
DIVERGENCE_LIMIT = 1e6


class SimulationDiverged(RuntimeError):
    """A run left the finite range; ``result`` holds every row logged before."""

    def __init__(self, message: str, result: SimResult) -> None:
        super().__init__(message)
        self.result = result


@dataclass(frozen=True)
class RunInputs:
    """Everything one run needs, as plain arrays (shared by every engine).

    Attributes
    ----------
    t : ndarray (N,)
        Sample times t_k = k·Ts [s].
    theta_ref, omega_ref, accel_ref : ndarray (N,)
        Reference at t_k [rad, rad/s, rad/s²].
    noise : ndarray (N,)
        Standard-normal draws n_k (zeros without noise).
    sigma, q : float
        Noise std dev and quantization step [rad].
    rig, obs, ctl : ndarray
        Packed rig, observer and controller parameter vectors.
    h : float
        RK4 step [s].
    nsub : int
        RK4 steps per sample.
    delay : int
        Transport delay [samples].
    theta0 : float
        Initial angle [rad].
    b0 : float
        Nominal input gain 1/I0.
    """

    t: np.ndarray
    theta_ref: np.ndarray
    omega_ref: np.ndarray
    accel_ref: np.ndarray
    noise: np.ndarray
    sigma: float
    q: float
    rig: np.ndarray
    obs: np.ndarray
    ctl: np.ndarray
    h: float
    nsub: int
    delay: int
    theta0: float
    b0: float


def prepare(scn: Scenario, *, draw_noise: bool = True) -> RunInputs:
    """Resolve a scenario into the arrays and vectors every engine consumes.

    ``draw_noise=False`` leaves ``noise`` empty, for engines that draw the
    noise of each seed once for many runs (:mod:`esoarm.engines.batch`).
    """
    n = scn.n_samples
    ts = scn.sample_time
    t = np.arange(n) * ts
    theta_ref, omega_ref, accel_ref = evaluate_reference(scn.reference, t)
    b0 = input_gain(scn.plant.inertia)
    return RunInputs(
        t=t,
        theta_ref=theta_ref,
        omega_ref=omega_ref,
        accel_ref=accel_ref,
        noise=(noise_sequence(scn.sensor.seed, n, scn.sensor.noise_deg) if draw_noise
               else np.empty(0)),
        sigma=math.radians(scn.sensor.noise_deg),
        q=math.radians(scn.sensor.resolution_deg),
        rig=RigParams.from_scenario(scn).vector,
        obs=design_observer(scn.observer.eps, ts, b0, scn.observer.discretization).vector,
        ctl=FLCParams.from_scenario(scn).vector,
        h=scn.rig.step,
        nsub=scn.substeps,
        delay=scn.actuator.delay_samples,
        theta0=scn.rig.theta0,
        b0=b0,
    )


def simulate(
    scenario: Scenario | str | Path = "test-1",
    overrides: dict | list[str] | None = None,
    *,
    warn: bool = True,
) -> SimResult:
    """Simulate one closed-loop run with the reference engine (SPEC §2).

    Parameters
    ----------
    scenario : Scenario, str or Path
        A scenario, a built-in name or a TOML path.
    overrides : dict or list of str, optional
        Dotted-key overrides, e.g. ``{"observer.eps": 0.05}``.
    warn : bool
        Emit :class:`~esoarm.scenario.ScenarioWarning` for risky settings.

    Returns
    -------
    SimResult
        Time series and metrics.

    Raises
    ------
    SimulationDiverged
        The state left the finite range; the exception holds the partial result.
    """
    scn = load_scenario(scenario, overrides) if overrides or not isinstance(
        scenario, Scenario) else scenario
    if warn:
        for msg in scenario_warnings(scn):
            warnings.warn(msg, ScenarioWarning, stacklevel=2)
    return run_reference(scn, prepare(scn))


def run_reference(scn: Scenario, inp: RunInputs) -> SimResult:
    """The SPEC §2 loop over prepared inputs, one sample at a time."""
    n = len(inp.t)
    rig, obs, ctl = inp.rig, inp.obs, inp.ctl
    log = np.full((n, 8), np.nan)  # theta, theta_ref, error, u, z1, z2, z3, f_true
    omega_log = np.full(n, np.nan)
    u_hist = np.zeros(n)
    theta, omega, tau = inp.theta0, 0.0, 0.0
    z1 = measure(inp.theta0, inp.noise[0], inp.sigma, inp.q) if n else 0.0
    z2 = z3 = 0.0
    for k in range(n):
        tk = inp.t[k]
        y = measure(theta, inp.noise[k], inp.sigma, inp.q)
        ref, dref, ddref = inp.theta_ref[k], inp.omega_ref[k], inp.accel_ref[k]
        h1, h2, h3 = eso_estimate(z1, z2, z3, y, obs)
        u = flc_control(h1, h2, h3, ref, dref, ddref, ctl)
        u_hist[k] = u
        u_applied = u_hist[k - inp.delay] if k >= inp.delay else 0.0
        acc = rig_acceleration(theta, omega, applied_torque(tau, u_applied, rig), tk, rig)
        log[k] = (theta, ref, theta - ref, u, h1, h2, h3, acc - inp.b0 * u)
        omega_log[k] = omega
        if not within_limits(theta, h1, h2, h3, u):
            return _diverged(scn, inp, log, omega_log, k)
        z1, z2, z3 = eso_advance(z1, z2, z3, h1, h2, h3, y, u, obs)
        theta, omega, tau = rig_advance(theta, omega, tau, u_applied, tk, inp.h, inp.nsub, rig)
    return SimResult.from_log(scn, inp.t, log, omega_log)


@jitable
def within_limits(theta: float, z1: float, z2: float, z3: float, u: float) -> bool:
    """The divergence rule shared by every engine: all finite, |θ| and |z1| below the limit.

    A NaN anywhere fails (NaN compares false), so does ±inf.
    """
    lim = DIVERGENCE_LIMIT
    return (
        math.isfinite(theta + z2 + z3 + u) and abs(theta) < lim and abs(z1) < lim
    )


def _diverged(scn: Scenario, inp: RunInputs, log: np.ndarray, omega: np.ndarray,
              k: int) -> SimResult:
    rows = k + 1
    result = SimResult.from_log(scn, inp.t[:rows], log[:rows], omega[:rows])
    raise SimulationDiverged(diverged_message(scn.name, float(inp.t[k]), k), result)


def diverged_message(name: str, tk: float, k: int) -> str:
    """The one-line message of a run that left the finite range at sample k (t_k [s])."""
    return (
        f"simulation of '{name}' diverged at t = {tk:.4g} s (sample {k}): "
        f"the state left the finite range (|θ| or |z| > {DIVERGENCE_LIMIT:g} or not finite); "
        f"check observer.eps against the sample rate"
    )
