"""The least-squares problem of an identification and its solver.

:class:`Problem` holds one model structure (free parameters, delay) over a
set of logs: residuals y_k − θ̂(t_k) of the segment simulation
(:func:`~esoarm.studies.identification.data.simulate_segments`), a finite-difference
Jacobian, bounds and scales.  :func:`levenberg_marquardt` minimizes it.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from esoarm.plants.lever_arm import (
    CODE,
    DAMP,
    DFREQ,
    FC,
    FST,
    GCOEF,
    INERTIA,
    LAG,
    STOP_LO,
    VISC,
    VS,
    VST,
)
from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import Scenario
from esoarm.studies.identification.data import (
    IdentLog,
    segments,
    simulate_columns,
    simulate_segments_parallel,
)

__all__ = ["PARAMS", "Limit", "Problem", "Solution", "levenberg_marquardt", "limits_from_data"]

#: Parameters that can be fitted, in order: scenario key -> (label, unit, scale, bounds, advice).
#: The scale and bounds are those of the built-in rigs (about 2 N·m of torque, 0.02 kg·m²)
#: and serve only when no log is at hand; a fit takes both from its data
#: (:func:`limits_from_data`), so that a log in other units fits the same physics.
PARAMS: dict[str, tuple[str, str, float, tuple[float, float], str]] = {
    "rig.inertia_scale": ("true inertia / plant.inertia", "1", 1.0, (0.02, 50.0),
                          "more high-frequency torque (raise --f-max or --amplitude)"),
    "plant.m2": ("lumped mass 2 (gravity coefficient)", "kg", 0.05, (0.0, 50.0),
                 "a larger, slower angle sweep so that cos θ varies (raise --sweep)"),
    "rig.coulomb_friction": ("Coulomb friction Fc", "N·m", 0.05, (0.0, 10.0),
                             "more slow reversals of the rate (lower --f-min, more tones)"),
    "rig.viscous_friction": ("viscous friction b", "N·m·s/rad", 0.01, (0.0, 10.0),
                             "a wider range of speeds (raise --amplitude at low frequencies)"),
    "actuator.lag": ("actuator lag T", "s", 0.01, (0.0, 1.0),
                     "tones near and above 1/(2πT) (raise --f-max)"),
    "motor.torque_constant": ("motor torque constant Kt", "N·m/A", 0.02, (1e-6, 10.0),
                              "more torque amplitude (raise --amplitude)"),
    "rig.stiction": ("breakaway friction above Coulomb Fst (stick-slip)", "N·m", 0.05,
                     (0.0, 10.0), "more slow reversals of the rate (lower --f-min)"),
}


@dataclass(frozen=True)
class Limit:
    """The scale and bounds of one fitted parameter, taken from the data."""

    scale: float  #: a typical size (finite-difference steps, the identifiability floor)
    lower: float  #: physical lower bound (0 for a friction, a mass, a lag)
    upper: float  #: upper bound
    why: str  #: how the upper bound was set, in words (named when a value ends there)


#: Upper bounds as multiples of the data's own scales (see :func:`limits_from_data`).
TORQUE_BOUND = 10.0
INERTIA_RANGE = 50.0
LAG_SAMPLES = 50.0
KT_RANGE = 1000.0


def limits_from_data(scn: Scenario, logs: list[IdentLog],
                     inertia: float | None = None) -> dict[str, Limit]:
    """Scale and bounds of every key of :data:`PARAMS`, from the logs and the scenario.

    No absolute number: with U the largest torque in the fitting logs [N·m] (with a
    ``[motor]`` table, the stall torque N·Kt·Vs/R), I the inertia (the IDIM-LS
    estimate ``inertia`` when given, else plant.inertia × rig.inertia_scale)
    [kg·m²] and fs the sample rate [Hz]:

    * Coulomb friction and stiction: 0 … 10·U (a friction ten times every applied
      torque would never let the arm move);
    * viscous friction: 0 … 10·I·fs (a time constant I/b ten times shorter than a
      sample is beyond what the log resolves);
    * the gravity coefficient |G| ≤ 10·U, mapped onto plant.m2 (≥ 0);
    * inertia_scale: (I / plant.inertia) / 50 … × 50;
    * actuator lag: 0 … 50 samples; Kt: 1/1000 … 1000 × the scenario's.

    A log in other units (torque ×100, inertia ×100) scales every bound with it.
    """
    ts = logs[0].ts
    p = scn.plant
    if scn.motor is not None:
        m = scn.motor
        torque = abs(m.gear_ratio * m.torque_constant * m.supply_voltage / m.resistance)
    else:
        torque = max(float(np.nanmax(np.abs(log.u))) if np.isfinite(log.u).any() else 0.0
                     for log in logs)
    if not torque > 0.0:
        torque = scn.actuator.torque_limit
    i_ref = inertia if inertia is not None and inertia > 0 else p.inertia * scn.rig.inertia_scale
    ratio = i_ref / p.inertia
    g_l2 = p.g * p.l2 if p.g * p.l2 > 0 else 1.0
    g_max = TORQUE_BOUND * torque
    m1l1 = p.m1 * p.l1
    visc_max = TORQUE_BOUND * i_ref / ts
    out = {
        "rig.inertia_scale": Limit(ratio, ratio / INERTIA_RANGE, ratio * INERTIA_RANGE,
                                   f"{INERTIA_RANGE:g}× the inertia the log's inverse dynamic "
                                   "model gives" if inertia else
                                   f"{INERTIA_RANGE:g}× the scenario's inertia"),
        "plant.m2": Limit(0.035 * torque / g_l2, max(0.0, (m1l1 - g_max / p.g) / p.l2)
                          if p.g > 0 and p.l2 > 0 else 0.0, (m1l1 + g_max / p.g) / p.l2
                          if p.g > 0 and p.l2 > 0 else 1.0,
                          f"a gravity torque of {TORQUE_BOUND:g}× the largest logged torque"),
        "rig.coulomb_friction": Limit(0.025 * torque, 0.0, TORQUE_BOUND * torque,
                                      f"{TORQUE_BOUND:g}× the largest logged torque"),
        "rig.viscous_friction": Limit(0.01 * visc_max / TORQUE_BOUND, 0.0, visc_max,
                                      f"{TORQUE_BOUND:g}× inertia × sample rate"),
        "actuator.lag": Limit(0.5 * ts, 0.0, LAG_SAMPLES * ts, f"{LAG_SAMPLES:g} samples"),
        "motor.torque_constant": (
            Limit(0.1 * scn.motor.torque_constant, scn.motor.torque_constant / KT_RANGE,
                  scn.motor.torque_constant * KT_RANGE,
                  f"{KT_RANGE:g}× the scenario's motor.torque_constant")
            if scn.motor is not None else Limit(1.0, 0.0, math.inf, "")),
        "rig.stiction": Limit(0.025 * torque, 0.0, TORQUE_BOUND * torque,
                              f"{TORQUE_BOUND:g}× the largest logged torque"),
    }
    return out


class Problem:
    """Residuals and Jacobian of the segment output-error problem for one structure."""

    def __init__(self, scn: Scenario, logs: list[IdentLog], seg_samples: int, delay: int,
                 start: int, free: list[str], fixed: dict[str, float],
                 limits: dict[str, Limit] | None = None) -> None:
        self.scn, self.free, self.fixed = scn, free, fixed
        self.limits = limits if limits is not None else limits_from_data(scn, logs)
        self.motor = scn.motor
        ts = logs[0].ts
        self.h = scn.rig.step
        self.nsub = max(1, int(round(ts / self.h)))
        self.h = ts / self.nsub
        base, ts_all, ys, starts, lens = [], [], [], [], []
        offset = 0
        for log in logs:
            if self.motor is not None:
                from esoarm.plants.actuator import motor_of

                mp = motor_of(scn)
                raw = np.array([mp.effective_fraction(int(d)) for d in log.duty])  # type: ignore
            else:
                raw = log.u
            shifted = np.zeros(log.n)
            shifted[delay:] = raw[: log.n - delay] if delay else raw
            base.append(shifted)
            ts_all.append(log.t)
            ys.append(log.y)
            s, ln = segments(log.n, seg_samples, start)
            starts.append(s + offset)
            lens.append(ln)
            offset += log.n
        self.base = np.concatenate(base)
        self.t = np.concatenate(ts_all)
        self.y = np.concatenate(ys)
        self.seg_start = np.concatenate(starts)
        self.seg_len = np.concatenate(lens)
        rows = np.zeros(len(self.y), dtype=bool)
        for s, ln in zip(self.seg_start, self.seg_len, strict=True):
            rows[s:s + ln] = True
        self.mask = rows & np.isfinite(self.y)
        self.n_phys = len(free)
        self.n_seg = len(self.seg_start)
        self._out = np.zeros(len(self.y))
        # the last prediction (x, θ̂): the Jacobian at the point the solver just accepted
        # starts from the prediction that accepted it, instead of simulating it again
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def with_fixed(self, changes: dict[str, float]) -> Problem:
        """The same problem (data, segments, delay) with some held values changed."""
        other = copy.copy(self)
        other.fixed = {**self.fixed, **changes}
        other._out = np.zeros(len(self.y))
        other._last = None
        return other

    # -- parameters ----------------------------------------------------------
    def phys(self, x: np.ndarray) -> dict[str, float]:
        values = dict(self.fixed)
        values.update(zip(self.free, x[: self.n_phys].tolist(), strict=True))
        return values

    def rig_and_source(self, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        scn = self.scn
        p, r = scn.plant, scn.rig
        # entries not set here stay 0: no stiction, no backlash, no cogging; the vector ends
        # before the end stops' entries (a vector with them has stops; at 0 they held the
        # arm at θ = 0), as the lever arm's own design does without rig.end_stops
        rig = np.zeros(STOP_LO)
        rig[INERTIA] = values["rig.inertia_scale"] * p.inertia
        rig[GCOEF] = gravity_coefficient(p.m1, values["plant.m2"], p.l1, p.l2, p.g)
        rig[FC] = values["rig.coulomb_friction"]
        rig[VS] = r.friction_velocity
        rig[VISC] = values["rig.viscous_friction"]
        rig[DAMP] = r.disturbance.amplitude
        rig[DFREQ] = r.disturbance.frequency
        rig[LAG] = values["actuator.lag"]
        rig[FST] = values.get("rig.stiction", r.stiction)
        rig[VST] = r.stribeck_velocity
        src = self.base
        if self.motor is not None:
            m = self.motor
            nkt = m.gear_ratio * values["motor.torque_constant"]
            src = self.base * (nkt * m.supply_voltage / m.resistance)
            rig[VISC] += nkt * nkt / m.resistance
        return rig, src

    def initial_states(self) -> np.ndarray:
        x0 = np.empty(2 * self.n_seg)
        y, ts = self.y, self.t[1] - self.t[0]
        for s, k0 in enumerate(self.seg_start):
            window = y[k0:k0 + 5]
            good = np.isfinite(window)
            x0[2 * s] = window[good][0] if good.any() else 0.0
            x0[2 * s + 1] = (np.polyfit(np.arange(5)[good] * ts, window[good], 1)[0]
                             if good.sum() >= 2 else 0.0)
        return x0

    # -- model ---------------------------------------------------------------
    def design(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(design vector of the lever-arm kind, applied torque) at parameters ``x``."""
        rig, src = self.rig_and_source(self.phys(x))
        return np.concatenate([[float(CODE)], rig]), src

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Simulated angle θ̂ [rad] at every sample (rows outside the segments are 0)."""
        last = self._last
        if last is not None and np.array_equal(last[0], x):
            return last[1]
        plant, src = self.design(x)
        out = self._out
        simulate_segments_parallel(out, plant, src, self.t, self.seg_start, self.seg_len,
                                   np.ascontiguousarray(x[self.n_phys:]), self.h, self.nsub)
        pred = out.copy()
        pred.flags.writeable = False  # shared with the cache
        self._last = (x.copy(), pred)
        return pred

    def residual(self, x: np.ndarray) -> np.ndarray:
        r = (self.predict(x) - self.y)[self.mask]
        return np.where(np.isfinite(r), r, 1e3)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Forward differences: one simulation per rig parameter and two for all initial
        states (the segments are independent), run together on all cores."""
        base = self.predict(x)
        n_cols = self.n_phys + 2
        states = np.ascontiguousarray(x[self.n_phys:])
        plant0, src0 = self.design(x)
        plants = np.empty((n_cols, len(plant0)))
        srcs = np.empty((n_cols, len(src0)))
        x0s = np.empty((n_cols, len(states)))
        steps = np.empty(n_cols)
        scales = self.scales()
        for i in range(self.n_phys):
            step = 1e-6 * max(abs(x[i]), scales[i])
            if x[i] + step > self.limits[self.free[i]].upper:
                step = -step
            xp = x.copy()
            xp[i] += step
            plants[i], srcs[i] = self.design(xp)
            x0s[i] = states
            steps[i] = step
        for j, step in ((0, 1e-6), (1, 1e-5)):
            plants[self.n_phys + j], srcs[self.n_phys + j] = plant0, src0
            x0s[self.n_phys + j] = states
            x0s[self.n_phys + j, j::2] += step
            steps[self.n_phys + j] = step
        outs = np.zeros((n_cols, len(self.y)))
        simulate_columns(outs, plants, srcs, self.t, self.seg_start, self.seg_len, x0s,
                         self.h, self.nsub)
        cols = np.zeros((len(self.y), len(x)))
        for i in range(self.n_phys):
            cols[:, i] = (outs[i] - base) / steps[i]
        seg_of = np.repeat(np.arange(self.n_seg), self.seg_len)
        rows = np.concatenate([np.arange(s, s + n) for s, n in zip(self.seg_start, self.seg_len,
                                                                   strict=True)])
        for j in (0, 1):
            diff = (outs[self.n_phys + j] - base) / steps[self.n_phys + j]
            cols[rows, self.n_phys + 2 * seg_of + j] = diff[rows]
        jac = cols[self.mask]
        return np.where(np.isfinite(jac), jac, 0.0)

    def scales(self) -> np.ndarray:
        phys = [self.limits[k].scale for k in self.free]
        return np.array(phys + [0.1, 1.0] * self.n_seg)

    @property
    def lag_floor(self) -> float:
        """The smallest lag T [s] the fit takes: 2h, twice the RK4 step (RK4 needs T ≳ 2h)."""
        return 2.0 * self.h

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [self.limits[k].lower for k in self.free] + [-np.inf] * (2 * self.n_seg)
        hi = [self.limits[k].upper for k in self.free] + [np.inf] * (2 * self.n_seg)
        if "actuator.lag" in self.free:
            lo[self.free.index("actuator.lag")] = self.lag_floor
        return np.array(lo), np.array(hi)

    def solve(self, x_start: np.ndarray, max_iter: int = 200) -> Solution:
        """Projected Levenberg-Marquardt from ``x_start`` (see :func:`levenberg_marquardt`)."""
        lo, hi = self.bounds()
        return levenberg_marquardt(self.residual, self.jacobian, np.clip(x_start, lo, hi), lo,
                                    hi, max_iter)


@dataclass
class Solution:
    """Where :func:`levenberg_marquardt` stopped; ``jac`` (the Jacobian there, for the
    intervals) is computed when first asked for: a fit that only warm-starts another
    never needs it."""

    x: np.ndarray
    fun: np.ndarray
    cost: float  # ½‖r‖²
    converged: bool
    iterations: int
    message: str
    jac_at: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    _jac: np.ndarray | None = field(default=None, repr=False)

    @property
    def jac(self) -> np.ndarray:
        """The Jacobian of the residual at ``x``."""
        if self._jac is None:
            self._jac = self.jac_at(self.x)
        return self._jac


def levenberg_marquardt(fun, jac, x, lo, hi, max_iter):  # type: ignore[no-untyped-def]
    """Levenberg-Marquardt with Marquardt's diagonal scaling, steps projected on the bounds.

    A parameter at a bound that the gradient pushes outwards is held there for the step
    (an active set), and the step is solved for the others.

    Written out (instead of scipy's trust-region solvers) because the problem is
    small in columns and long in rows: the normal equations are formed once per
    iteration in O(M P²), with no SVD of the M × P Jacobian.  Stops when an
    iteration moves every parameter by less than 1 % of its standard error
    (or lowers the cost by less than 1e-12 relative), or when no damping gives
    a decrease.
    """
    r = fun(x)
    cost = float(r @ r)
    lam = 1e-3
    it = 0
    message = "iteration limit reached"
    converged = False
    J_final = None
    for it in range(1, max_iter + 1):  # noqa: B007
        J = jac(x)
        A = J.T @ J
        g = J.T @ r
        d = np.maximum(np.diag(A), 1e-12 * max(float(np.max(np.diag(A))), 1e-300))
        # the active set: a parameter at a bound that the descent direction −g pushes out of
        # it is held there, and the step is solved for the others.  (Solving for all and then
        # clipping gives the others the step of a model in which the held one moved: with the
        # viscous friction at 0 on a log that sticks most of the time the fit then crawled,
        # 141 iterations of 1-3 % of a standard error, and stopped at a higher cost than the
        # 17 iterations with the active set.)
        free = ~(((x <= lo) & (g > 0.0)) | ((x >= hi) & (g < 0.0)))
        while True:
            step = np.zeros_like(x)
            try:
                step[free] = np.linalg.solve((A + lam * np.diag(d))[np.ix_(free, free)],
                                             -g[free])
            except np.linalg.LinAlgError:
                step = np.full_like(x, np.nan)
            xn = np.clip(x + step, lo, hi)
            rn = fun(xn) if np.all(np.isfinite(xn)) else np.full_like(r, np.inf)
            cn = float(rn @ rn)
            if np.isfinite(cn) and cn <= cost:
                break
            lam *= 4.0
            if lam > 1e12:
                break
        if not (np.isfinite(cn) and cn <= cost):
            converged = True  # no damping lowers the cost: a (local) minimum
            message = "no further decrease"
            J_final = J  # x did not move
            break
        # stop when the step is a hundredth of a standard error (its statistical size)
        s2 = cn / max(len(r) - len(x), 1)
        try:
            se = np.sqrt(np.maximum(s2 * np.diag(np.linalg.inv(A)), 0.0))
        except np.linalg.LinAlgError:
            se = np.abs(x) + 1e-8
        small_step = bool(np.all(np.abs(xn - x) <= 1e-2 * se + 1e-14))
        small_drop = cost - cn <= 1e-12 * cost
        x, r, cost = xn, rn, cn
        lam = max(lam / 3.0, 1e-9)
        if small_step or small_drop:
            converged = True
            message = "converged"
            break
    return Solution(x, r, 0.5 * cost, converged, it, message, jac, J_final)
