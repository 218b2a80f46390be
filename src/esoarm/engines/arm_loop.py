"""The sampled-data closed loop of the lever arm, run on a URDF arm joint by joint.

The same sample loop as :func:`esoarm.engines.simulation.run_reference`, with vectors
where the lever arm has scalars.  For k = 0 … N−1, t_k = k·Ts:

1. y_k = Q(q(t_k) + σ n_k) per joint, n_k row k of
   ``default_rng(seed).standard_normal((N, n))`` (one joint: the lever arm's draws);
2. reference (qd, q̇d, q̈d) at t_k per joint;
3. ẑ_k from each joint's ESO, u_k by computed torque (:mod:`esoarm.controllers.computed_torque`),
   saturated per joint;
4. log t_k, q(t_k), qd, e_k = q(t_k) − qd, u_k, ẑ_k and the true perturbation
   f_k = q̈(t_k) − v_k (v_k the observers' input, so f_k is what ẑ3 estimates);
5. observer update with (y_k, v_k);
6. apply u_{k−delay} over [t_k, t_{k+1}), RK4 of the twin with one ABA per stage.

Metrics: ``rms_error``, ``rms_u``, ``max_abs_error`` over every joint and
sample (on one joint: the lever arm's), and the same three per joint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from esoarm.controllers.computed_torque import ArmController, JointObservers
from esoarm.engines.simulation import within_limits
from esoarm.plants.sensor import measure
from esoarm.plants.urdf_twin import ArmTwin

__all__ = ["ArmLog", "ArmRun", "run_arm"]


@dataclass(frozen=True)
class ArmRun:
    """Everything one arm run needs (the arm's :class:`~esoarm.engines.simulation.RunInputs`).

    Attributes
    ----------
    t : ndarray (N,)
        Sample times t_k = k·Ts [s].
    ts : float
        Sample period Ts [s].
    q_ref, v_ref, a_ref : ndarray (N, n)
        Reference per joint [rad, rad/s, rad/s²].
    noise : ndarray (N, n)
        Standard-normal draws (zeros without noise).
    sigma, quant : float
        Noise std dev and quantization step [rad].
    twin : ArmTwin
    controller : ArmController
    eps : ndarray (n,)
        ε per joint [s].
    discretization : str
    h : float
        RK4 step [s].
    nsub : int
        RK4 steps per sample.
    delay : int
        Transport delay [samples].
    q0 : ndarray (n,)
        Initial angles [rad]; initial rates are zero.
    """

    t: np.ndarray
    ts: float
    q_ref: np.ndarray
    v_ref: np.ndarray
    a_ref: np.ndarray
    noise: np.ndarray
    sigma: float
    quant: float
    twin: ArmTwin
    controller: ArmController
    eps: np.ndarray
    discretization: str
    h: float
    nsub: int
    delay: int
    q0: np.ndarray


@dataclass(frozen=True)
class ArmLog:
    """Time series of one arm run, row k at t_k; arrays (N, n) unless noted.

    ``rows`` < N when the run diverged (the rows logged up to and including
    the sample that diverged are kept).  ``z`` is (N, n, 3).
    """

    t: np.ndarray
    theta: np.ndarray
    theta_ref: np.ndarray
    error: np.ndarray
    u: np.ndarray
    z: np.ndarray
    f_true: np.ndarray
    omega: np.ndarray
    diverged_at: int | None = None


def _measure(q: np.ndarray, noise: np.ndarray, sigma: float, quant: float) -> np.ndarray:
    return np.array([measure(q[i], noise[i], sigma, quant) for i in range(len(q))])


def run_arm(run: ArmRun) -> ArmLog:
    """The closed loop over prepared inputs, one sample at a time (module docstring)."""
    n_samples, n = run.q_ref.shape
    twin, ctl = run.twin, run.controller
    theta = np.full((n_samples, n), np.nan)
    error = np.full((n_samples, n), np.nan)
    u_log = np.full((n_samples, n), np.nan)
    z_log = np.full((n_samples, n, 3), np.nan)
    f_log = np.full((n_samples, n), np.nan)
    omega = np.full((n_samples, n), np.nan)
    q = np.array(run.q0, dtype=float)
    v = np.zeros(n)
    tau = np.zeros(n)
    zero = np.zeros(n)
    y0 = _measure(q, run.noise[0], run.sigma, run.quant) if n_samples else q
    observers = JointObservers(run.eps, run.ts, run.discretization, y0)
    for k in range(n_samples):
        tk = float(run.t[k])
        y = _measure(q, run.noise[k], run.sigma, run.quant)
        zhat = observers.estimate(y)
        u, drive = ctl(zhat, run.q_ref[k], run.v_ref[k], run.a_ref[k])
        u_log[k] = u
        u_applied = u_log[k - run.delay] if k >= run.delay else zero
        acc = twin.acceleration(q, v, twin.applied(tau, u_applied), tk)
        theta[k] = q
        error[k] = q - run.q_ref[k]
        z_log[k] = zhat
        f_log[k] = acc - drive
        omega[k] = v
        if not all(within_limits(q[i], zhat[i, 0], zhat[i, 1], zhat[i, 2], u[i])
                   for i in range(n)):
            return _log(run, theta, error, u_log, z_log, f_log, omega, k + 1, diverged=k)
        observers.update(drive)
        q, v, tau = twin.advance(q, v, tau, u_applied, tk, run.h, run.nsub)
    return _log(run, theta, error, u_log, z_log, f_log, omega, n_samples)


def _log(run: ArmRun, theta: np.ndarray, error: np.ndarray, u: np.ndarray, z: np.ndarray,
         f: np.ndarray, omega: np.ndarray, rows: int, diverged: int | None = None) -> ArmLog:
    return ArmLog(t=run.t[:rows], theta=theta[:rows], theta_ref=run.q_ref[:rows],
                  error=error[:rows], u=u[:rows], z=z[:rows], f_true=f[:rows],
                  omega=omega[:rows], diverged_at=diverged)
