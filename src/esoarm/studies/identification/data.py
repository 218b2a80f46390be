"""Logs for identification: reading, checking, and the segment simulator of the fit.

A log is a CSV with at least ``t`` [s, uniform], ``theta`` or ``y`` [rad,
measured: ``y`` when the log has it, since a simulated series' ``theta`` is the
true angle] and ``u`` [N·m, the torque applied from that row on] -- the logs of
``esoarm excite``, ``esoarm run`` and ``esoarm simulate --out`` all qualify.  With a
``[motor]`` table the column ``duty`` [counts] is used instead of ``u``.  A row
whose angle is ``nan`` is a sample lost on the link (``esoarm run`` logs
them); it is left out of the residuals.  Any other non-finite value is bad input.

The fit simulates the rig over *segments* of the log (output error with the
initial state of each segment estimated, a multiple-shooting variant without
continuity constraints): the arm is nearly neutrally stable, so one open-loop
simulation over a whole minute would drift away from the data for any error
in the friction, while a horizon of a few seconds keeps the problem well
conditioned and still sees every parameter.  The simulator is
:func:`esoarm.plants.lever_arm.advance` -- the lever-arm plant step, the twin's
own RK4 integration of the rig -- compiled with numba, one sample at a time
with the input held over the sample (zero-order hold, as in every engine) and
the transport delay applied to the input sequence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit, prange

from esoarm.engines.batch import cover_with_physics_stamp  # registers the physics with numba
from esoarm.hardware.logfile import read_log_columns, sample_period
from esoarm.plants.lever_arm import LAG, advance
from esoarm.plants.motor import MotorParams
from esoarm.scenario import ScenarioError

# the compiled segment simulator is cached on disk, keyed on the physics sources too
cover_with_physics_stamp(__file__)

__all__ = ["IdentLog", "MIN_DURATION", "MIN_SAMPLES", "check_supported", "read_ident_log",
           "saturated_share", "simulate_columns", "simulate_segments",
           "simulate_segments_parallel"]

#: Shortest log accepted [s] and fewest samples.
MIN_DURATION = 4.0
MIN_SAMPLES = 150
#: A validation log needs only this long [s]: it is not fitted, only predicted (one step
#: of a P-controlled rig lasts 2-4 s), and MIN_SAMPLES rows.
MIN_VALIDATION_DURATION = 1.0
#: Largest share of saturated samples (a saturated log is bad input; see saturated_share).
MAX_SATURATED = 0.25
#: Largest share of lost samples (measured angle nan).
MAX_LOST = 0.05
#: The angle's RMS spread must exceed this many times its sample-to-sample jitter (motion).
MIN_MOTION_RATIO = 2.0


@dataclass(frozen=True)
class IdentLog:
    """One checked log.

    Attributes
    ----------
    path : str
        Where it came from.
    t, y, u : ndarray (N,)
        Time [s], measured angle [rad] (nan for a lost sample), torque [N·m].
    duty : ndarray (N,) or None
        PWM duty [counts] when the log has a finite ``duty`` column.
    ts : float
        Sample period [s].
    """

    path: str
    t: np.ndarray
    y: np.ndarray
    u: np.ndarray
    duty: np.ndarray | None
    ts: float

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.t)

    def part(self, start: int, stop: int) -> IdentLog:
        """Rows start … stop−1 as a log of its own."""
        duty = None if self.duty is None else self.duty[start:stop]
        return IdentLog(self.path, self.t[start:stop], self.y[start:stop], self.u[start:stop],
                        duty, self.ts)


def check_supported(scn: object, what: str = "identification") -> None:
    """One-line :class:`ScenarioError` unless the scenario's plant is the lever arm.

    Any registered observer kind runs (through the registry), so it is not checked.
    """
    from esoarm.kinds import can

    kind = getattr(getattr(scn, "plant", None), "kind", "?")
    if not can(scn, "RIG"):  # type: ignore[arg-type]  # what the plant kind declares
        raise ScenarioError(f"plant.kind = {kind!r}: {what} supports the lever arm "
                            "(plant.kind = \"lever-arm\") only")


def read_ident_log(path: str | Path, torque_limit: float,
                   motor: MotorParams | None = None, validation: bool = False) -> IdentLog:
    """Read and check one log; raise :class:`ScenarioError` with one line naming the file.

    Checks: the file exists and parses, has columns t, y or theta, u (and duty with
    a ``motor``), no non-finite t or u, a uniform time column, at most
    :data:`MAX_LOST` lost samples, at least :data:`MIN_DURATION` s (a ``validation``
    log, which is only predicted: :data:`MIN_VALIDATION_DURATION`) and
    :data:`MIN_SAMPLES` rows, some excitation, and at most :data:`MAX_SATURATED`
    of the samples saturated (:func:`saturated_share`).
    """
    least = MIN_VALIDATION_DURATION if validation else MIN_DURATION
    what = "validation" if validation else "identification"
    src = f"log '{path}'"
    need_duty = motor is not None
    duty_col = ["duty"] if need_duty else []

    def want(header: list[str]) -> list[str]:
        # the measured angle: y when the log has it (a simulated series' theta is the true
        # angle; in the logs of run and excite, y and theta are both the measurement)
        return ["t", "y" if "y" in header else "theta", "u", *duty_col]

    need = "need t [s], theta or y [rad, measured], u [N·m]" + (
        " and duty [counts] (the scenario has a [motor] table)" if need_duty else "")
    names, data = read_log_columns(path, want, need, lost_ok=("theta", "y"),
                                   all_nan_why=_NAN_COLUMN_WHY)
    t, y, u = data[:, 0], data[:, 1], data[:, 2]
    duty = data[:, 3] if need_duty else None
    n = len(t)
    if n < 2:
        raise ScenarioError(f"{src}: too short ({n} rows); {what} needs at least "
                            f"{least:g} s and {MIN_SAMPLES} samples")
    ts = sample_period(t, path)
    if n < MIN_SAMPLES or n * ts < least:
        raise ScenarioError(f"{src}: too short ({n} samples, {n * ts:.3g} s); {what} "
                            f"needs at least {least:g} s and {MIN_SAMPLES} samples")
    lost = np.isnan(y)  # never the first row (read_log_columns)
    if lost.mean() > MAX_LOST:
        raise ScenarioError(f"{src}: {int(lost.sum())} rows with {names[1]} = nan "
                            f"(at most {MAX_LOST:.0%} lost samples)")
    excitation = duty if duty is not None else u
    if np.std(excitation) < 1e-9 + 1e-3 * (np.max(np.abs(excitation)) if duty is None else 1):
        raise ScenarioError(f"{src}: not exciting enough: the input is (nearly) constant; "
                            "record an experiment with 'esoarm excite'")
    _check_the_arm_moved(src, y)
    sat, where = saturated_share(u, duty, torque_limit, motor)
    if sat > MAX_SATURATED:
        raise ScenarioError(f"{src}: saturated: {sat:.0%} of the samples {where} (at most "
                            f"{MAX_SATURATED:.0%}); lower the excitation amplitude")
    return IdentLog(str(path), t, y, u, duty, ts)


def _check_the_arm_moved(src: str, y: np.ndarray) -> None:
    """One-line :class:`ScenarioError` unless the measured angle ``y`` [rad] shows motion.

    Motion, not noise: the angle's RMS spread must exceed :data:`MIN_MOTION_RATIO`
    times its sample-to-sample jitter RMS(Δy)/√2 -- equal for white encoder noise
    on an arm at rest, tens of times larger for an arm that moves.
    """
    what = ""
    if np.nanmax(y) - np.nanmin(y) < 1e-3:
        what = "the measured angle stays within 1e-3 rad"
    else:
        spread = float(np.nanstd(y))
        jitter = float(np.nanstd(np.diff(y))) / math.sqrt(2.0)
        if spread <= MIN_MOTION_RATIO * jitter:
            what = (f"the measured angle varies by {spread:.2g} rad RMS, no more than its "
                    f"sample-to-sample jitter {jitter:.2g} rad: encoder noise, not motion")
    if what:
        raise ScenarioError(
            f"{src}: not exciting enough: the arm did not move ({what}); the experiment did "
            "not excite the arm: check that the motor drives it (power, wiring, no brake or "
            "block), then record again with more torque ('esoarm excite --amplitude')")


#: Why a column can be nan in every row, and what to do (the message of read_ident_log).
_NAN_COLUMN_WHY = {
    "duty": "the log was made without a [motor] table (an ideal torque source) but the "
            "scenario has one; identify it with a scenario without the [motor] table, or "
            "record the log with the [motor] table",
    "u": "the torque applied [N·m] was not logged, and identification needs it; record "
         "the log with 'esoarm excite' or 'esoarm run'",
}


def saturated_share(u: np.ndarray, duty: np.ndarray | None, torque_limit: float,
                    motor: MotorParams | None) -> tuple[float, str]:
    """Share of saturated samples and where they saturate (for the message).

    Without a motor: |u| at the torque limit [N·m] (within 0.1 %).  With one, in
    the motor's terms: the duty at ±pwm_max (full supply, the driver's limit), or
    the logged u -- the torque the duty gives, which the duty's rounding puts
    within one duty count of the limit when the command was clipped -- within
    one count's torque N·Kt·Vs/(R·pwm_max·(1 − deadband)) of the torque limit.
    """
    if motor is None or duty is None:
        at_torque = np.abs(u) >= 0.999 * torque_limit
        return float(np.mean(at_torque)), f"at the torque limit ±{torque_limit:g} N·m"
    count = motor.stall_gain / (motor.pwm_max * (1.0 - motor.deadband))
    full = np.abs(duty) >= motor.pwm_max
    at_torque = np.abs(u) >= torque_limit - count
    parts = []
    if full.any():
        parts.append(f"at full duty (|duty| = {motor.pwm_max} counts, the motor's limit)")
    if (at_torque & ~full).any() or not parts:
        parts.append(f"at the torque limit ±{torque_limit:g} N·m")
    return float(np.mean(full | at_torque)), " or ".join(parts)


def segments(n: int, length: int, start: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Split samples start … n−1 into consecutive segments of ``length`` (last one longer)."""
    count = max(1, (n - start) // length)
    starts = start + length * np.arange(count)
    lens = np.full(count, length)
    lens[-1] = n - starts[-1]
    return starts.astype(np.int64), lens.astype(np.int64)


@njit(cache=True)
def lag_state(src, k0, lag, h, nsub):  # pragma: no cover
    """The actuator lag's state τ(t_k0) [N·m] from the applied torques before sample k0.

    The lag τ̇ = (u − τ)/T does not depend on the arm, so its state at a segment's start is
    known from the input alone: the same ``nsub`` RK4 steps of h [s] per sample as the
    twin's (:func:`esoarm.plants.lever_arm.advance`; per step τ ← τ + (u − τ)(1 − ρ) with
    ρ = 1 − z + z²/2 − z³/6 + z⁴/24, z = h/T), run from rest at the torque held 30 T
    earlier.  (Starting every segment at the previous torque, as before, was model error:
    with a 27 ms lag at 50 Hz it left a 0.05° misfit that the noise σ absorbed.)
    """
    if k0 <= 0:
        return 0.0
    if not lag > 0.0:
        return src[k0 - 1]
    z = h / lag
    rho = 1.0 - z + z * z / 2.0 - z * z * z / 6.0 + z * z * z * z / 24.0
    a = rho ** nsub
    n_hist = min(k0, int(30.0 * lag / (h * nsub)) + 1)
    j0 = k0 - n_hist
    tau = src[j0 - 1] if j0 > 0 else 0.0
    for j in range(j0, k0):
        tau = a * tau + (1.0 - a) * src[j]
    return tau


@njit(cache=True)
def simulate_segments(out, plant, src, t, seg_start, seg_len, x0, h, nsub):  # pragma: no cover
    """Simulated angle θ(t_k) [rad] into ``out`` for every segment.

    Segment s starts at sample ``seg_start[s]`` from θ = x0[2s], θ̇ = x0[2s+1]
    (the lag state τ: the lag run over the applied torques before the segment, see
    :func:`lag_state`), and holds the applied (already delayed) torque ``src[k]`` [N·m]
    over [t_k, t_k + nsub·h): the plant step of the lever-arm kind,
    :func:`esoarm.plants.lever_arm.advance`, with ``plant`` its design vector (CODE, rig
    vector).
    """
    x = np.empty(3)
    u = np.empty(1)
    for s in range(len(seg_start)):
        k0 = seg_start[s]
        x[0] = x0[2 * s]
        x[1] = x0[2 * s + 1]
        x[2] = lag_state(src, k0, plant[1 + LAG], h, nsub)
        for j in range(seg_len[s]):
            k = k0 + j
            out[k] = x[0]
            u[0] = src[k]
            advance(x, u, t[k], h, nsub, plant)
            if not math.isfinite(x[0]):
                for m in range(k + 1, k0 + seg_len[s]):
                    out[m] = math.inf
                break


@njit(cache=True, parallel=True)
def simulate_segments_parallel(out, plant, src, t, seg_start, seg_len, x0, h,
                               nsub):  # pragma: no cover
    """:func:`simulate_segments`, the segments in parallel on all cores (they are
    independent: each starts from its own initial state).  The same numbers, bit for bit."""
    for s in prange(len(seg_start)):
        simulate_segments(out, plant, src, t, seg_start[s:s + 1], seg_len[s:s + 1],
                          x0[2 * s:2 * s + 2], h, nsub)


@njit(cache=True, parallel=True)
def simulate_columns(outs, plants, srcs, t, seg_start, seg_len, x0s, h, nsub):  # pragma: no cover
    """:func:`simulate_segments` for several parameter sets at once, in parallel on all cores.

    Row c of ``outs`` gets the simulation with design vector ``plants[c]``, applied
    torque ``srcs[c]`` and initial states ``x0s[c]`` -- the columns of a
    finite-difference Jacobian.  Each row is computed exactly as one call of
    :func:`simulate_segments` would (the same numbers, bit for bit).
    """
    for c in prange(outs.shape[0]):
        simulate_segments(outs[c], plants[c], srcs[c], t, seg_start, seg_len, x0s[c], h, nsub)
