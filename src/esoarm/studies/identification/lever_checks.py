"""IDIM-LS of the lever arm, and the checks it makes possible before the output-error fit.

The lever arm's inverse dynamic model (:mod:`esoarm.plants.lever_arm`, d(t) = A sin(ωt)):

    τ = I θ̈ + b θ̇ + Fc sign(θ̇) + G cos θ − I A sin(ωt)

is linear in (I, b, Fc, G, c = −I A): one least-squares problem on band-pass
filtered derivatives (:mod:`esoarm.studies.identification.idim`), no simulation,
no starting value, no bound.  It is reported beside the output-error fit, and it
catches two things the output-error fit cannot tell from a bad model:

* **units that cannot be right**: angles logged in degrees make every
  acceleration 57.3 times larger, so the inertia comes out 57.3 times smaller
  (encoder counts: smaller by the counts per radian).  An IDIM-LS inertia below
  :data:`UNIT_RATIO` or above 1/UNIT_RATIO times the scenario's ``plant.inertia``
  is refused as bad input, naming the ratio and what would explain it;
* **a disturbance the log does not have**: the fit takes d(t) as known (the
  paper's eq. 6).  When the log's amplitude A = −c/I is far from the scenario's
  (decisive evidence only: the logs cover two periods of d(t), the 95 % HAC
  interval of A is narrower than half the scenario's amplitude, and A misses it
  by more than twice that interval and by more than the interval plus
  :data:`DISTURBANCE_SLACK` of it) the fit is refused, naming
  ``rig.disturbance.amplitude`` and the amplitude the log shows.
"""

from __future__ import annotations

import math

import numpy as np

from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.identification.data import IdentLog
from esoarm.studies.identification.idim import (
    BORDER,
    decimation_factor,
    filtered_derivatives,
    force_error,
    hac_bandwidth,
    hac_covariance,
)

__all__ = ["DISTURBANCE_SLACK", "UNIT_RATIO", "LeverIdim", "check_log_against_scenario",
           "disturbance_confirmed", "lever_idim"]

#: An IDIM-LS inertia below this share of plant.inertia (or above its inverse) is refused.
UNIT_RATIO = 0.05
#: The log's disturbance amplitude may miss the scenario's by its interval plus this share.
DISTURBANCE_SLACK = 0.25
#: The decimated rate in cut-offs (idim.DECIMATED_RATE on the axis path).
LEVER_RATE = 1.0
NAMES = ("inertia", "viscous_friction", "coulomb_friction", "gravity", "disturbance")


class LeverIdim:
    """IDIM-LS of the lever arm: values, HAC standard errors, force error [%]."""

    def __init__(self, names: tuple[str, ...], values: np.ndarray, se: np.ndarray,
                 force_error: float, rows: int, duration: float,
                 cutoff_hz: float = math.nan) -> None:
        self.names, self.values, self.se = names, values, se
        self.force_error, self.rows, self.duration = force_error, rows, duration
        #: The derivative filter's cut-off [Hz].
        self.cutoff_hz = cutoff_hz

    def value(self, name: str) -> float:
        """The estimate of ``name`` (:data:`NAMES`; "disturbance" is c = −I A [N·m])."""
        return float(self.values[self.names.index(name)])

    def to_dict(self) -> dict:
        """JSON-ready: {name: {value, ci95}}, the force error and the rows used."""
        return {"parameters": {n: {"value": float(v), "ci95": [float(v - 1.96 * s),
                                                                float(v + 1.96 * s)]}
                               for n, v, s in zip(self.names, self.values, self.se,
                                                  strict=True)},
                "force_error_percent": self.force_error, "rows": self.rows,
                "cutoff_hz": self.cutoff_hz}


def lever_idim(scn: Scenario, logs: list[IdentLog],
               cutoff_hz: float | None = None) -> LeverIdim | None:
    """IDIM-LS of the lever arm over ``logs``; None when a log is too short or has lost
    samples (the output-error fit handles those).  ``cutoff_hz`` [Hz] is the derivative
    filter's cut-off (--cutoff sets it); by default it is chosen from the motion's band up to
    a tenth of the sample rate, where the model explains the torque best
    (:func:`~esoarm.studies.identification.idim.select_cutoff`, as on the axis path), so the
    estimate follows the motion, not the sample rate (the fixed fs/10 of the EMPS scripts
    gave a 1 kHz log a filter ten times wider than its 100 Hz down-sample's), and the written
    standard errors cover how far the estimate moves between the neighbouring cut-offs that
    explain the torque about as well."""
    if any(np.isnan(log.y).any() for log in logs):
        return None
    ts = logs[0].ts
    if cutoff_hz is not None:
        return _lever_fixed(scn, logs, cutoff_hz)
    from esoarm.studies.identification.idim import motion_band, select_cutoff

    fits: dict[float, LeverIdim | None] = {}

    def fe_at(fc: float) -> float:
        fits[fc] = _lever_fixed(scn, logs, fc)
        est = fits[fc]
        return est.force_error if est is not None else math.inf

    best, around = select_cutoff(fe_at, ts, motion_band([lg.y for lg in logs], ts),
                                 min(lg.n for lg in logs) * ts)
    est = fits.get(best) or _lever_fixed(scn, logs, best)
    if est is None or not around:
        return est
    lo, hi = est.values - 1.96 * est.se, est.values + 1.96 * est.se
    for fc in around:
        other = fits.get(fc)
        if other is not None:
            lo = np.minimum(lo, other.values - 1.96 * other.se)
            hi = np.maximum(hi, other.values + 1.96 * other.se)
    # the joined interval written as a symmetric standard error around this estimate
    se = np.maximum(est.se, np.maximum(est.values - lo, hi - est.values) / 1.96)
    return LeverIdim(est.names, est.values, se, est.force_error, est.rows, est.duration,
                     best)


def _lever_fixed(scn: Scenario, logs: list[IdentLog], cutoff: float) -> LeverIdim | None:
    """IDIM-LS of the lever arm with one given cut-off [Hz] (see :func:`lever_idim`)."""
    ts = logs[0].ts
    nd = decimation_factor(ts, cutoff, LEVER_RATE)  # the scripts' nd = fs/cutoff (a delay's phase
    # above half the cut-off stays out of the fit)
    w = scn.rig.disturbance.frequency
    with_d = w > 0 and scn.rig.disturbance.amplitude != 0.0
    xs, fs = [], []
    for log in logs:
        if np.isnan(log.y).any() or log.n < 4 * BORDER + 20 * nd:
            return None
        q, dq, ddq = filtered_derivatives(log.y, ts, cutoff)
        cols = [ddq, dq, np.sign(dq), np.cos(q)]
        if with_d:
            cols.append(np.sin(w * log.t))
        keep = slice(BORDER - 1, log.n)
        x = np.column_stack(cols)[keep]
        f = _zoh_centred(log.u)[keep]
        if nd > 1:
            from esoarm.studies.identification.idim import staged_decimate

            x, f = staged_decimate(x, nd), staged_decimate(f, nd)
        xs.append(x)
        fs.append(f)
    x, f = np.vstack(xs), np.concatenate(fs)
    theta, *_ = np.linalg.lstsq(x, f, rcond=None)
    r = f - x @ theta
    se = np.sqrt(np.maximum(np.diag(hac_covariance(x, r, hac_bandwidth(r))), 0.0))
    return LeverIdim(NAMES[: x.shape[1]], theta, se, force_error(f, x @ theta), len(f),
                     sum(log.n for log in logs) * ts, cutoff)


def check_log_against_scenario(scn: Scenario, est: LeverIdim | None, path: str) -> str:
    """Raise :class:`ScenarioError` for units that cannot be right; return the refusal for a
    disturbance the log does not show ("" if none).  See the module docstring."""
    if est is None:
        return ""
    inertia = est.value("inertia")
    i0 = scn.plant.inertia
    ratio = inertia / i0
    half = 1.96 * float(est.se[est.names.index("inertia")])
    # decisive only: a positive inertia known to better than half its value (an arm that
    # hardly moves gives any inertia, negative ones included: the fit refuses that itself)
    decisive = inertia > 0 and half < 0.5 * inertia
    if decisive and not UNIT_RATIO <= ratio <= 1.0 / UNIT_RATIO:
        deg = math.pi / 180.0
        hint = ("angles in degrees give about 0.0175× (convert: esoarm log import --scale "
                "y=0.017453292519943295)" if 0.3 * deg <= ratio <= 3.0 * deg else
                "angles in encoder counts give 2π/(counts per turn)×" if ratio < UNIT_RATIO
                else "a torque column in other units (mN·m?) or a plant.inertia far too small")
        raise ScenarioError(
            f"log '{path}': the angle or torque units look wrong: the inverse dynamic model "
            f"gives an inertia of {inertia:.3g} kg·m², {ratio:.3g}× the scenario's "
            f"plant.inertia {i0:g} kg·m²; {hint}; if the rig really is that different, set "
            "plant.inertia")
    if "disturbance" in est.names:
        i = est.names.index("disturbance")
        a_log = -est.values[i] / inertia
        half = 1.96 * est.se[i] / abs(inertia)
        a_scn = scn.rig.disturbance.amplitude
        period = 2.0 * math.pi / scn.rig.disturbance.frequency
        # decisive evidence only: two periods of d(t) in the log, an interval narrower than
        # half the scenario's amplitude, and a miss beyond twice the interval
        decisive = est.duration >= 2.0 * period and half < 0.5 * abs(a_scn)
        if decisive and abs(a_log - a_scn) > max(2.0 * half,
                                                 half + DISTURBANCE_SLACK * abs(a_scn)):
            freq = scn.rig.disturbance.frequency
            return (f"the scenario's disturbance d(t) = {a_scn:g}·sin({freq:g} t) rad/s² is "
                    "taken as known, but the log shows an amplitude "
                    f"of {a_log:.3g} ± {half:.2g} rad/s²: the scenario does not describe this "
                    f"rig; set rig.disturbance.amplitude (0 if it had none)")
    return ""


def disturbance_confirmed(scn: Scenario, est: LeverIdim | None) -> bool:
    """Whether the log shows the scenario's disturbance: two periods of d(t) in the log and
    an IDIM-LS amplitude whose 95 % interval excludes 0 and lies within
    :data:`DISTURBANCE_SLACK` of the scenario's amplitude (a log that cannot tell --
    too short, too noisy -- does not confirm it)."""
    d = scn.rig.disturbance
    if est is None or "disturbance" not in est.names or d.frequency <= 0:
        return False
    inertia = est.value("inertia")
    if not inertia > 0:
        return False
    i = est.names.index("disturbance")
    a_log = -est.values[i] / inertia
    half = 1.96 * est.se[i] / abs(inertia)
    period = 2.0 * math.pi / d.frequency
    return bool(est.duration >= 2.0 * period and abs(a_log) > half
                and abs(a_log - d.amplitude) <= half + DISTURBANCE_SLACK * abs(d.amplitude))


def _zoh_centred(u: np.ndarray) -> np.ndarray:
    """The logged command as the motion at each sample instant answers it: u[k] is held
    from t_k to t_k + ts (zero-order hold), so the torque centred on t_k is the mean of
    u[k − 1] and u[k] (half a sample of delay, 18° at a tenth of a 50 Hz rate, otherwise
    read as inertia)."""
    out = np.asarray(u, dtype=float).copy()
    out[1:] = 0.5 * (out[1:] + out[:-1])
    return out
