"""Processor in the loop: a chip running the generated step, the twin and the Python reference.

Per sample k (the sampled-data loop of :mod:`esoarm.engines.loop`):

1. the twin's measurement y_k = Q(θ(t_k) + σ n_k) (the simulators' noise and quantizer);
2. the chip steps the generated controller on y_k and the reference r_k = (θd, θ̇d, θ̈d)
   sent by the host (the Python reference's, :mod:`esoarm.reference`) and answers
   (u_k, drive_k);
3. the Python reference in float64 (:class:`esoarm.hardware.host_control.DeploymentController`,
   the step functions every engine calls) steps on the same y_k: u_ref,k;
4. the chip's drive is held over [t_k, t_{k+1}) after the transport delay and the
   plant kind integrates the twin to t_{k+1}.

So the chip closes the loop, and Δu_k = u_chip,k − u_ref,k is the numerical
difference of the generated code on that chip alone (both fed the same y_k).

With a motor the torque becomes a whole number of duty counts.  Where the
reference's duty lies at a rounding tie (u_ref moved by 1e-6 of the torque limit
gives the chip's duty) the two roundings are equally right, but the observers
would then be updated with torques one count apart and drift apart for reasons
that are not the code's arithmetic.  There the reference adopts the chip's
duty; such samples are counted (:attr:`LockstepRun.duty_ties`).  A duty that
differs otherwise is left alone and shows in Δu.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from esoarm.engines.simulation import prepare
from esoarm.hardware.host_control import DeploymentController
from esoarm.plants.actuator import MOTOR, MOTOR_BLOCK, actuator_vector, delayed_input, table_bins
from esoarm.plants.motor import duty_to_torque, torque_to_duty
from esoarm.plants.sensor import measure
from esoarm.scenario import Scenario

__all__ = ["Chip", "LockstepRun", "lockstep"]


class Chip(Protocol):
    """A target running the generated controller, stepped one sample at a time."""

    target: str
    precision: str
    timing: str
    cycles: list[int]
    flash_bytes: int
    ram_bytes: int

    def step(self, y: float, ref: tuple[float, float, float] = (0.0, 0.0, 0.0)
             ) -> tuple[float, float, float]:
        """y_k [rad] and the reference (θd [rad], θ̇d [rad/s], θ̈d [rad/s²]) at sample k
        -> (u_k [N·m], torque driving the plant [N·m], duty [counts] or 0)."""

    def close(self) -> None:
        """Release the emulator."""


@dataclass
class LockstepRun:
    """What a lockstep run measured.

    Attributes
    ----------
    steps : int
        Samples stepped.
    u_chip, u_ref : ndarray
        Commands of the chip and of the Python float64 reference [N·m].
    y : ndarray
        Measurements fed to both [rad].
    theta : ndarray
        True angle of the twin at each sample [rad].
    theta_ref : ndarray
        θd(t_k) [rad].
    torque_limit : float
        [N·m].
    cycles : list of int
        Per-step cycles (or instruction-count proxy) reported by the chip.
    duty_ties : int
        Samples where the reference adopted the chip's duty at a rounding tie.
    drive_chip, drive_ref : ndarray
        With a learned table and no motor: the torque driving the twin, the chip's and the
        reference's [N·m] (the table's torque is in it, not in u); empty otherwise.
    """

    steps: int
    u_chip: np.ndarray
    u_ref: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    theta_ref: np.ndarray
    torque_limit: float
    cycles: list[int] = field(default_factory=list)
    duty_ties: int = 0
    drive_chip: np.ndarray = field(default_factory=lambda: np.zeros(0))
    drive_ref: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def max_abs_du(self) -> float:
        """max_k |u_chip − u_ref| [N·m] (inf if the chip answered a non-finite value), and
        of the drives where they are compared (a learned table, no motor)."""
        du = np.abs(self.u_chip - self.u_ref)
        if self.drive_chip.size:
            du = np.concatenate([du, np.abs(self.drive_chip - self.drive_ref)])
        return float(np.max(du)) if np.all(np.isfinite(du)) else math.inf

    @property
    def max_rel_du(self) -> float:
        """max |Δu| / torque_limit [1]."""
        return self.max_abs_du / self.torque_limit

    @property
    def ref_finite(self) -> bool:
        """The float64 Python reference's command stayed finite (else the design diverges)."""
        return bool(np.all(np.isfinite(self.u_ref)))

    @property
    def ref_diverged_at(self) -> int | None:
        """First sample where the reference's command is not finite (None: never)."""
        bad = np.flatnonzero(~np.isfinite(self.u_ref))
        return int(bad[0]) if bad.size else None

    @property
    def first_move(self) -> int | None:
        """First sample where the reference θd (or θ̇d) leaves its starting value, None if
        it does not within the run (the arm is not asked to move)."""
        if not self.steps:
            return None
        moving = np.flatnonzero(self.theta_ref != self.theta_ref[0])
        return int(moving[0]) if moving.size else None

    @property
    def covers_motion(self) -> bool:
        """The run reaches the moving part: the reference moves within it and the command
        is not identically zero (an agreement over a resting arm proves little)."""
        return self.first_move is not None and bool(np.any(self.u_ref != 0.0))


def lockstep(scn: Scenario, chip: Chip, steps: int | None = None,
             progress: Callable[[int], None] | None = None,
             stop: Callable[[int, Chip], bool] | None = None) -> LockstepRun:
    """Run ``chip`` in the loop with the twin of ``scn`` for ``steps`` samples (default: all).

    Parameters
    ----------
    scn : Scenario
        The scenario the chip's code was generated from.
    chip : Chip
        A started target (:class:`esoarm.codegen.host.HostChip`, the AVR or the Cortex-M4).
    steps : int, optional
        Samples to run (at most N).
    progress : callable, optional
        Called with the samples done every 100 samples (say what a long check is doing).
    stop : callable, optional
        Called with (k, chip) after each sample; True ends the run there (the first step
        over the chip's budget: no need to run the rest to refuse).

    Returns
    -------
    LockstepRun
    """
    inp = prepare(scn)
    n = scn.n_samples if steps is None else min(steps, scn.n_samples)
    plant = inp.plant
    x = np.array(plant.x0, dtype=float)
    ref = DeploymentController(scn)
    hist = np.zeros(max(n, 1))
    drive = np.zeros(1)
    applied = np.zeros(1)
    u_chip, u_ref = np.full(n, np.nan), np.full(n, np.nan)
    ys, theta = np.full(n, np.nan), np.full(n, np.nan)
    advance = inp.kinds.plant.advance
    act = actuator_vector(scn)
    motor = act[MOTOR_BLOCK:] if act[MOTOR] else None
    table = table_bins(act) > 0 and motor is None
    drive_chip, drive_ref = np.full(n, np.nan), np.full(n, np.nan)
    tie = 1e-6 * ref.torque_limit
    k_done = ties = 0
    for k in range(n):
        y = measure(x[0], inp.noise[k], inp.sigma, inp.q)
        u_c, d_c, duty_c = chip.step(y, (float(inp.refs[0, k]), float(inp.refs[1, k]),
                                         float(inp.refs[2, k])))
        u_r = ref.step(k, y)
        u_app, duty_r = ref.actuate(u_r)
        if motor is not None and duty_c != duty_r and math.isfinite(duty_c):
            rate = ref.zhat[1]
            if duty_c in (torque_to_duty(u_r - tie, rate, motor),
                          torque_to_duty(u_r + tie, rate, motor)):
                u_app = float(duty_to_torque(duty_c, rate, motor))
                ties += 1
        ref.commit(u_app)
        ys[k], theta[k], u_chip[k], u_ref[k] = y, x[0], u_c, u_r
        drive_chip[k], drive_ref[k] = d_c, ref.drive
        k_done = k + 1
        if not (math.isfinite(u_c) and math.isfinite(d_c) and math.isfinite(u_r)):
            break
        if progress is not None and k_done % 100 == 0:
            progress(k_done)
        if stop is not None and stop(k, chip):
            break
        drive[0] = d_c
        delayed_input(hist, k, inp.delay, drive, applied)
        advance(x, applied, k * inp.ts, inp.h, inp.nsub, plant.vector)
    return LockstepRun(k_done, u_chip[:k_done], u_ref[:k_done], ys[:k_done], theta[:k_done],
                       inp.refs[0, :k_done].copy(), ref.torque_limit, list(chip.cycles), ties,
                       drive_chip[:k_done] if table else np.zeros(0),
                       drive_ref[:k_done] if table else np.zeros(0))
