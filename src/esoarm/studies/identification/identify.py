"""Grey-box identification of the rig from logs (``esoarm identify``).

The model is the twin's rig (:mod:`esoarm.plants.lever_arm`), its parameters read as
scenario keys:

=========================  =======================================  ============
key                        meaning                                  unit
=========================  =======================================  ============
``rig.inertia_scale``      I / plant.inertia                        1
``plant.m2``               sets the gravity coefficient             kg
                           (m1 l1 − m2 l2) g, m1, l1, l2, g held
``rig.coulomb_friction``   Fc                                       N·m
``rig.viscous_friction``   b                                        N·m·s/rad
``rig.stiction``           breakaway friction above Coulomb Fst     N·m
                           (stick-slip; kept by a likelihood-ratio
                           test, rig.stribeck_velocity held)
``actuator.lag``           first-order torque lag T                 s
``actuator.delay_samples`` transport delay                          samples
``motor.torque_constant``  Kt (with a ``[motor]`` table; R, Vs, N   N·m/A
                           held: only N·Kt/R and the total damping
                           b + (N·Kt)²/R are identifiable)
``sensor.noise_deg``       encoder noise σ (from the residual)      deg
=========================  =======================================  ============

Beside the fit, the inverse-dynamic-model least squares (IDIM-LS,
:mod:`esoarm.studies.identification.lever_checks`) is computed from the same
logs: it refuses angles that cannot be in rad, a scenario disturbance the log
clearly lacks, and an output-error inertia grossly off its own.  The encoder
noise goes into the fitted scenario only when the validation residual is white, or when it
is coloured sensor noise: then with its AR spectrum as ``sensor.noise_ar``
(:mod:`esoarm.studies.identification.residual.noise_ar`: Yule-Walker, order by AIC,
the AR innovation white and uncorrelated with the past input, and the validation residual's
RMS at most
:data:`NOISE_CARRY_OVER` times the fit's); otherwise the spectrum is reported as model
error.

Held at the scenario's values: ``rig.friction_velocity`` (the tanh smoothing
is far below what 50 Hz data resolves), the disturbance d(t) (taken as known,
as in the paper's eq. 6), the motor's other constants.

Fit: least squares on the measured angle, y_k − θ̂(t_k), over segments of the
log with each segment's initial angle and rate estimated
(:mod:`esoarm.studies.identification.data`); Levenberg-Marquardt
(:func:`esoarm.studies.identification.fit.levenberg_marquardt`) with a
finite-difference Jacobian that costs one simulation per rig parameter plus
two for all initial states (run together, in parallel over the columns).  The
delay (integer) is chosen by the cost over 0 … ``max_delay`` (and on, by at most
:data:`EXTEND_DELAY` samples, while the best is the longest tried): the scenario's
delay gets :data:`FIRST_ITER` iterations from the scenario's values, every
other delay :data:`TRY_ITER` from there, and only the best is carried to
convergence (its neighbours, and a delay whose cost comes within
:data:`CLOSE_DELAY` thresholds of it, are tried again from the converged fit); once the lag
and the stiction are decided, the delay's profile is walked again with that final model
(:func:`_delay_with_final_structure`: on from every new best, and past every delay inside
the delay's threshold, the lag moved by the delay's change).  The lag is kept by a
likelihood-ratio test of T > 0 against T = 0, after a screen (a quarter-sample
lag with everything else held must lower the cost, else T = 0 is kept without
a fit).  95 % intervals: ±1.96 standard
errors from σ̂² (JᵀJ)⁻¹ (rig parameters, the initial states profiled out), or the
AR noise's sandwich when the residual is coloured sensor noise (the restricted
likelihood's AR model, or on segments too long for it the Yule-Walker one:
:func:`_ar_filter_sandwich`), and never narrower
than the segment-cluster sandwich (:func:`_segment_floor`: valid under any
correlation within a segment); for the delay, every delay whose cost is within the
χ²₁ 95 % threshold of the best, times the residual's long-run variance ratio (a
correlated residual inflates the likelihood ratio by it).  When the evidence rejects
the model (:func:`_model_rejected`) the intervals are those of
:func:`_model_error_intervals`, or withheld.  Every written interval is then joined with
the fits the log cannot rule out: the other delays inside the delay's interval
(:func:`_ridge_intervals`; the delay and the lag trade along a ridge) and, when a stiction
won its test but is poorly determined, the fit without it (:func:`_stiction_alternative`).

The inertia is that of the rigid drive train: with gear backlash, the arm's plus the
motor side's reflected to the arm (the twin's ``rig.motor_inertia``), which a rigid
model cannot tell apart.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np

from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.identification.data import IdentLog, check_supported
from esoarm.studies.identification.fit import PARAMS, Problem, limits_from_data
from esoarm.studies.identification.residual.noise_ar import SegmentResidual, segment_verdict

__all__ = ["FREE_KEYS", "FitFailed", "IdentResult", "Estimate", "identify"]

DELAY_KEY = "actuator.delay_samples"
NOISE_KEY = "sensor.noise_deg"
NOISE_AR_KEY = "sensor.noise_ar"
#: Coloured noise is written only when the validation residual's RMS is at most this many
#: times the fit's (sensor noise does not grow on new data; model error does).
NOISE_CARRY_OVER = 1.25
#: Segments longer than this [samples] get the plain Yule-Walker verdict of the validation
#: residual instead of the segments' restricted likelihood (dense n×n per evaluation).
REML_MAX_SEGMENT = 400
FREE_KEYS = (*PARAMS, DELAY_KEY)
#: Why the inertia is held by default with a ``[motor]`` table.
MOTOR_SCALE_NOTE = (
    "held: with a [motor] table the angle determines only ratios to the inertia (stall torque, "
    "friction and gravity scale with it; the known disturbance alone anchors the scale); give "
    "the inertia, or --fix motor.torque_constant to fit the inertia instead")
#: χ²₁ 95 % quantile (likelihood-ratio tests of the delay and the lag).
CHI2_95 = 3.841458820694124
#: A parameter is flagged poorly identifiable beyond this relative 95 % half-width.
POOR_REL = 0.25
#: A residual that is not white and larger than this many times the encoder's resolution
#: or noise is model error, and the fit is refused (:meth:`IdentResult.implausible_residual`).
NOISE_SANITY = 20.0
#: Levenberg-Marquardt iterations of the first fit (the scenario's delay, from the
#: scenario's values) before the other delays are tried from it, and of each try.
FIRST_ITER = 6
TRY_ITER = 4
#: A fitted lag below this multiple of its floor (:attr:`Problem.lag_floor`) is taken as
#: at the floor: no evidence of a lag.
AT_FLOOR = 1.05
#: Iterations of the stiction fit before it is judged worth converging (see _fit_stiction).
STICTION_SCREEN_ITER = 10
#: A tried delay whose cost is within this many χ²₁ 95 % thresholds of the best is tried
#: again from the best fit (its cost after a few iterations is only an upper bound).
CLOSE_DELAY = 10.0
#: While the best delay is the longest tried, the search goes on past ``max_delay``, by at
#: most this many samples.
EXTEND_DELAY = 3


class FitFailed(RuntimeError):
    """The fit did not converge, or its result is not trustworthy (nothing is written).

    ``result`` holds the untrustworthy result when there is one (for inspection).
    """

    def __init__(self, message: str, result: IdentResult | None = None) -> None:
        super().__init__(message)
        self.result = result


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter: value, 95 % interval, and whether the log determines it."""

    key: str
    value: float
    ci95: tuple[float, float]
    unit: str
    label: str
    fitted: bool = True
    identifiable: bool = True
    advice: str = ""
    #: "lower" or "upper" when the value ended at that bound of the fit (the log pulls
    #: it beyond); "" inside the bounds.
    bound: str = ""
    #: Whether the 95 % interval was clipped to the bounds of the fit.
    ci_clipped: bool = False
    #: How the bound the value ended at was set ("" inside the bounds; see
    #: :func:`esoarm.studies.identification.fit.limits_from_data`).
    bound_why: str = ""
    #: Why the 95 % interval is withheld ("" when it is written): the evidence rejects the
    #: model and no interval valid under model error could be given for this parameter.
    withheld: str = ""

    @property
    def bound_text(self) -> str:
        """"the upper bound 20 N·m (10× the largest logged torque)", or "" inside them."""
        if not self.bound:
            return ""
        return (f"the {self.bound} bound {self.value:g} {self.unit}"
                + (f" ({self.bound_why})" if self.bound_why else ""))

    @property
    def at_bound(self) -> bool:
        """The fit ended at a bound (the value is that bound)."""
        return bool(self.bound)

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"value": self.value,
                "ci95": None if self.withheld else list(self.ci95), "unit": self.unit,
                "fitted": self.fitted, "identifiable": self.identifiable,
                **({"withheld": self.withheld} if self.withheld else {}),
                "at_bound": self.at_bound, "ci95_clipped": self.ci_clipped,
                **({"bound": self.bound} if self.bound else {}),
                **({"bound_set_by": self.bound_why} if self.bound_why else {}),
                **({"advice": self.advice} if self.advice else {})}


@dataclass
class IdentResult:
    """What :func:`identify` found (see the module docstring for the method)."""

    scenario: Scenario
    estimates: dict[str, Estimate]
    gravity: Estimate
    fit_percent: float
    validation: dict
    residual_rms: float
    cost_by_delay: dict[int, float]
    n_fit: int
    segment_seconds: float
    elapsed: float
    iterations: int
    fit_logs: list[str]
    validation_logs: list[str]
    curves: dict = field(default_factory=dict, repr=False)
    #: The IDIM-LS estimate of the fitting logs (esoarm.studies.identification.lever_checks),
    #: reported beside the output-error fit; empty when it could not be computed.
    idim: dict = field(default_factory=dict)
    #: The evidence that the model does not describe the log (empty: none), each a sentence;
    #: with any, the intervals are from :func:`_model_error_intervals` or withheld.
    model_error: list[str] = field(default_factory=list)
    #: How the written intervals were computed.
    interval_method: str = "white noise: σ̂² (JᵀJ)⁻¹"
    #: What the excitation achieved, from the ``# esoarm excite:`` header of each fitting log
    #: that has one (:func:`esoarm.studies.identification.experiment.probe.read_header`).
    excitation: dict = field(default_factory=dict)

    def value(self, key: str) -> float:
        """Fitted value of a scenario key."""
        return self.estimates[key].value

    def to_json(self) -> dict:
        """One JSON object: parameters by scenario key, then the fit quality."""
        return {
            "scenario": self.scenario.name,
            "parameters": {k: e.to_dict() for k, e in self.estimates.items()},
            "gravity_coefficient": self.gravity.to_dict(),
            "fit": {"fit_percent": self.fit_percent, "residual_rms_rad": self.residual_rms,
                    "samples": self.n_fit, "segment_s": self.segment_seconds,
                    "cost_by_delay": {str(d): c for d, c in self.cost_by_delay.items()},
                    "iterations": self.iterations, "elapsed_s": self.elapsed,
                    "logs": self.fit_logs},
            "validation": {**self.validation, "logs": self.validation_logs},
            "physical": self.physical(),
            "idim_ls": self.idim or None,
            "noise": ("written: the validation residual is white" if self.noise_is_sensor()
                      else "written white (sensor.noise_ar = []): the residual's spectrum, with "
                      "the segments' initial-state fit accounted for, is white sensor noise"
                      if self.coloured_noise() == []
                      else "written with sensor.noise_ar: the validation residual is coloured "
                      "sensor noise (its AR innovation is white and uncorrelated with the past "
                      "input)" if self.coloured_noise() is not None
                      else "not written: the validation residual is not white, so it is model "
                      "error, not sensor noise; sensor.noise_deg stays as given"),
            "model_error": self.model_error,
            "excitation": self.excitation,
            "interval_method": self.interval_method,
            "withheld": [k for k, e in self.estimates.items() if e.withheld],
            "poorly_identifiable": [k for k, e in self.estimates.items() if not e.identifiable],
            "at_bound": [k for k, e in self.estimates.items() if e.at_bound],
        }

    def coloured_noise(self) -> list[float] | None:
        """AR coefficients of the encoder noise (``[]``: white) when the validation residual
        fails the plain whiteness test but the residual is sensor noise by its spectrum
        (:mod:`esoarm.studies.identification.residual.noise_ar`), else None."""
        spec = self.validation.get("noise_spectrum")
        if self.noise_is_sensor() or not spec or not spec["sensor_noise"]:
            return None
        # sensor noise has the same level on the validation logs as on the fit's: a
        # validation residual well above the fit's is the model failing to carry over
        if not self.validation["residual_rms_rad"] <= NOISE_CARRY_OVER * self.residual_rms:
            return None
        return [float(v) for v in spec["noise_ar"]]

    def noise_is_sensor(self) -> bool:
        """Whether the residual supports calling it sensor noise: the validation residual is
        white (no validation: the fit's own residual cannot tell, and it is not called so)."""
        return bool(self.validation.get("whiteness", {}).get("white", False))

    def physical(self) -> dict[str, dict]:
        """The fit in SI names: inertia [kg·m²], viscous_friction [N·m·s/rad],
        coulomb_friction [N·m], offset [N·m] (none in the lever-arm model: 0, not fitted)
        and gravity (the coefficient (m1 l1 − m2 l2) g [N·m]), each {value, ci95, unit}."""
        i0 = self.scenario.plant.inertia
        scale = self.estimates["rig.inertia_scale"]
        out = {"inertia": {"value": scale.value * i0,
                           "ci95": [scale.ci95[0] * i0, scale.ci95[1] * i0], "unit": "kg·m²"}}
        for name, key in (("viscous_friction", "rig.viscous_friction"),
                          ("coulomb_friction", "rig.coulomb_friction")):
            e = self.estimates[key]
            out[name] = {"value": e.value, "ci95": list(e.ci95), "unit": e.unit}
        out["offset"] = {"value": 0.0, "ci95": [0.0, 0.0], "unit": "N·m", "fitted": False}
        out["gravity"] = {"value": self.gravity.value, "ci95": list(self.gravity.ci95),
                          "unit": "N·m"}
        return out

    def untrustworthy(self) -> str:
        """Why the result is not trustworthy ("" if it is): a parameter ended at a bound of
        the fit and the validation residual is not white (the model does not explain the
        log, and the intervals mean nothing).

        A value at a lower bound of 0 (no gravity term, no friction, no lag) is a physical
        answer, not a sign of a model that does not fit: it is reported but does not make the
        fit untrustworthy (the whiteness test alone flags a few per cent of white residuals,
        which refused exact fits of frictionless twins)."""
        why = self.implausible_residual()
        if why:
            return why
        # a lag at its lower bound 2h (the RK4 floor) is the physical answer T = 0 too
        pinned = [e for e in self.estimates.values()
                  if e.at_bound and not (e.bound == "lower" and (e.value == 0.0
                                                                 or e.key == "actuator.lag"))]
        white = self.validation.get("whiteness", {}).get("white", True)
        if not pinned or white:
            return ""
        w = self.validation["whiteness"]
        ends = ", ".join(f"{e.key} at {e.bound_text}" for e in pinned)
        return (f"the fit is not trustworthy: it ended with {ends}, and the validation residual "
                f"is not white ({w['outside']} of {w['lags']} autocorrelation lags outside "
                f"±{w['band']:.3g}): the model does not explain this log; check the rig and "
                "the log (a blocked or unusual arm), hold that parameter (--fix, --set) or "
                "record a richer experiment (esoarm excite)")

    def implausible_residual(self) -> str:
        """Why the residual cannot be the sensor's ("" if it can): not white and more than
        :data:`NOISE_SANITY` times the encoder's resolution or noise.

        A residual of that size is model error the fit did not remove (issue 20's case 7:
        an open-loop motor log simulated over long segments drifts, and its "noise" came
        out at 147° and 734° with the inertia 31× off); the fit is not trusted.
        """
        sensor = self.scenario.sensor
        floor = max(sensor.resolution_deg, sensor.noise_deg)
        rms = self.validation.get("residual_rms_rad", self.residual_rms)
        whiteness = self.validation.get("whiteness", {})
        if floor <= 0.0 or whiteness.get("white", False) or self.coloured_noise() is not None:
            return ""  # white, or coloured sensor noise by its spectrum (noise_ar)
        rms_deg = math.degrees(rms)
        if rms_deg <= NOISE_SANITY * floor:
            return ""
        return (f"the fit is not trustworthy: its residual is {rms_deg:.3g}° RMS, "
                f"{rms_deg / floor:.3g}× the encoder's {floor:g}° (sensor.resolution_deg, "
                "sensor.noise_deg), and not white: the model does not follow this log over "
                f"{self.segment_seconds:g} s segments (an open-loop log drifts: try a shorter "
                "--segment), or the scenario does not describe the rig; nothing written")

    def fitted_scenario(self) -> Scenario:
        """The scenario with the fitted rig as the twin and the plant updated to the fit.

        plant.inertia = Î (so rig.inertia_scale = 1), plant.m2 from the gravity
        fit (twin and model share G), friction, lag, delay, noise and Kt fitted.
        """
        scn = self.scenario
        over: dict[str, object] = {"name": f"{scn.name}-fitted",
                                   "plant.inertia": self.value("rig.inertia_scale")
                                   * scn.plant.inertia,
                                   "rig.inertia_scale": 1.0}
        coloured = self.coloured_noise()
        if coloured is not None:
            over[NOISE_AR_KEY] = coloured
        elif self.noise_is_sensor():
            over[NOISE_AR_KEY] = []  # the residual is white: so is the encoder's noise
        for key, est in self.estimates.items():
            if key == NOISE_KEY and not self.noise_is_sensor() and coloured is None:
                continue  # model error, not sensor noise: the scenario's noise stays
            if key != "rig.inertia_scale" and (scn.motor is not None
                                               or not key.startswith("motor.")):
                over[key] = int(est.value) if key == DELAY_KEY else float(est.value)
        return scn.with_overrides(over)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Hold the BLAS libraries (numpy's, scipy's) to one thread inside the block.

    Uses threadpoolctl when it is installed; without it nothing is changed.

    Yields
    ------
    None
        Inside the ``with`` block BLAS runs on one thread; the limit is lifted after.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        yield
        return
    import scipy.linalg  # noqa: F401 - loads scipy's BLAS: only loaded libraries are held

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def rate_mismatch(path: str, ts: float, rate_hz: float) -> str:
    """The message for a log sampled every ``ts`` [s] against ``sensor.rate_hz``: time stamps
    in ms or µs (a step 1000 or 10⁶ times the scenario's) are named as such, with the
    rescaling; any other rate is set with --set sensor.rate_hz."""
    ratio = ts * rate_hz
    for factor, unit in ((1e3, "milliseconds"), (1e6, "microseconds")):
        if abs(ratio / factor - 1.0) < 0.02:
            return (f"log '{path}': the time column steps by {ts:g}, {factor:g}× the "
                    f"scenario's {1.0 / rate_hz:g} s at sensor.rate_hz = {rate_hz:g}: t looks "
                    f"like {unit}; rescale it to seconds ('esoarm log import {path} --map "
                    f"t=t,y=…,u=u --scale t={1.0 / factor:g} --out LOG.csv')")
    return (f"log '{path}': sampled every {ts:g} s but sensor.rate_hz = {rate_hz:g}; use "
            f"--set sensor.rate_hz={1.0 / ts:g}")


def _values(scn: Scenario) -> dict[str, float]:
    """The scenario's values of every fittable key (the starting point of the fit)."""
    motor = scn.motor
    return {"rig.inertia_scale": scn.rig.inertia_scale, "plant.m2": scn.plant.m2,
            "rig.coulomb_friction": scn.rig.coulomb_friction,
            "rig.viscous_friction": scn.rig.viscous_friction, "actuator.lag": scn.actuator.lag,
            "motor.torque_constant": motor.torque_constant if motor else 0.0,
            "rig.stiction": scn.rig.stiction}


def _split(logs: list[IdentLog], validation: list[IdentLog] | None,
           fraction: float) -> tuple[list[IdentLog], list[IdentLog]]:
    if validation:
        return logs, validation
    if len(logs) > 1:
        return logs[:-1], logs[-1:]
    log = logs[0]
    cut = int(round(log.n * (1.0 - fraction)))
    return [log.part(0, cut)], ([log.part(cut, log.n)] if fraction > 0 else [])


def identify(scn: Scenario, logs: list[IdentLog], *, validation: list[IdentLog] | None = None,
             validate_fraction: float = 0.25, segment: float = 2.0, max_delay: int = 2,
             fix: tuple[str, ...] = (), progress=None,
             cutoff: float | None = None) -> IdentResult:  # type: ignore[no-untyped-def]
    """Fit the rig model of ``scn`` to logs (see the module docstring).

    The linear algebra runs on one BLAS thread (:func:`one_blas_thread`): its matrices are
    small (the noise model's are a segment long), and a second BLAS thread spinning beside
    the compiled simulation's threads cost more CPU than all the fits together (10.9 s of
    CPU against 4.6 s for a 60 s log at 50 Hz).

    Parameters
    ----------
    scn : Scenario
        Nominal values (the starting point and the held parameters), the motor.
    logs : list of IdentLog
        Logs to fit; with one log and no ``validation``, its last
        ``validate_fraction`` is kept for validation; with several, the last one.
    validation : list of IdentLog, optional
        Logs used only for validation.
    segment : float
        Simulation horizon of one segment [s].
    max_delay : int
        Largest transport delay tried [samples] (the search goes on, by at most
        :data:`EXTEND_DELAY` samples, while the best delay is the longest tried).
    fix : tuple of str
        Keys held at the scenario's values.
    progress : callable, optional
        Called with a one-line description before each fit.
    cutoff : float, optional
        Cut-off of the IDIM-LS derivative filter [Hz] (default: from the input's band,
        :func:`esoarm.studies.identification.idim.band_cutoff`).

    Raises
    ------
    ScenarioError
        Bad input (unknown key to fix, a log at another rate, too short a part).
    FitFailed
        The solver did not converge, or the result is not trustworthy: a
        parameter ended at a bound of the fit and the validation residual is not
        white (:meth:`IdentResult.untrustworthy`; the result is in the exception).
    """
    with one_blas_thread():
        return _identify(scn, logs, validation, validate_fraction, segment, max_delay, fix,
                         progress, cutoff)


def _identify(scn, logs, validation, validate_fraction, segment, max_delay, fix,  # type: ignore[no-untyped-def]
              progress, cutoff) -> IdentResult:
    """:func:`identify`'s work (its arguments, in order)."""
    t_start = time.perf_counter()
    check_supported(scn)
    for key in fix:
        if key not in FREE_KEYS:
            raise ScenarioError(f"fix {key}: not a fitted key (one of {', '.join(FREE_KEYS)})")
    ts = logs[0].ts
    for log in [*logs, *(validation or [])]:
        if abs(log.ts - scn.sample_time) > 1e-9 * scn.sample_time:
            raise ScenarioError(rate_mismatch(log.path, log.ts, scn.sensor.rate_hz))
    if scn.motor is not None and not {"rig.inertia_scale", "motor.torque_constant"} & set(fix):
        fix = (*fix, "rig.inertia_scale")  # see MOTOR_SCALE_NOTE
    fit_logs, val_logs = _split(logs, validation, validate_fraction)
    say = progress or (lambda _msg: None)
    idim = None
    if scn.motor is None:  # with a motor the logged u is the host's torque, not the drive's
        from esoarm.studies.identification.lever_checks import (
            check_log_against_scenario,
            lever_idim,
        )

        say("inverse dynamic model (IDIM-LS): filtered derivatives and least squares")
        idim = lever_idim(scn, fit_logs, cutoff)
        why = check_log_against_scenario(scn, idim, fit_logs[0].path)
        if why:
            raise FitFailed(why)
    # scales and bounds from the data (no absolute numbers: a log in other units fits the
    # same physics), the inertia's from IDIM-LS when it is decisive
    i_idim = None
    if idim is not None:
        k = idim.names.index("inertia")
        if idim.values[k] > 0 and 1.96 * idim.se[k] < 0.5 * idim.values[k]:
            i_idim = float(idim.values[k])
    limits = limits_from_data(scn, fit_logs, i_idim)
    seg_samples = max(5, int(round(segment / ts)))
    # the delay search goes past --max-delay while the best delay is at its end, up to
    # EXTEND_DELAY samples more; every delay is fitted on the same samples (from `start`)
    top_delay = max_delay + EXTEND_DELAY if DELAY_KEY not in fix else max_delay
    if min(log.n for log in fit_logs) < top_delay + seg_samples:
        raise ScenarioError(f"log '{fit_logs[0].path}': the part used for fitting is shorter "
                            f"than one segment ({segment:g} s); use a longer log or --segment")
    free = [k for k in PARAMS if k not in fix and (scn.motor is not None
                                                   or k != "motor.torque_constant")]
    fit_lag = "actuator.lag" in free
    nominal = _values(scn)
    delays = [scn.actuator.delay_samples] if DELAY_KEY in fix else list(range(max_delay + 1))
    start = max(top_delay, *delays)

    def fit(delay: int, names: list[str], fixed: dict[str, float], x_phys: list[float],
            x_states: np.ndarray | None, max_iter: int = 200):  # type: ignore[no-untyped-def]
        prob = Problem(scn, fit_logs, seg_samples, delay, start, names, fixed, limits)
        states = prob.initial_states() if x_states is None else x_states
        return prob, prob.solve(np.concatenate([x_phys, states]), max_iter)

    fit_stiction = "rig.stiction" in free
    base_free = [k for k in free if k not in ("actuator.lag", "rig.stiction")]
    fixed0 = {**nominal, **({"actuator.lag": 0.0} if fit_lag else {})}
    # 1. the scenario's delay, from the scenario's values: a few iterations, enough to rank it
    d_nom = scn.actuator.delay_samples if scn.actuator.delay_samples in delays else delays[0]
    n_d = len(delays)
    say(f"output-error fit of {', '.join(base_free)}: delay {d_nom} ({delays.index(d_nom) + 1} "
        f"of {n_d} delays)")
    tried = {d_nom: fit(d_nom, base_free, fixed0, [nominal[k] for k in base_free], None,
                        max_iter=FIRST_ITER)}
    # 2. the other delays, warm-started from that fit (a few iterations: an upper bound)
    for d in delays:
        if d != d_nom:
            say(f"output-error fit: trying delay {d} ({delays.index(d) + 1} of {n_d} delays)")
            p0, s0 = tried[d_nom]
            tried[d] = fit(d, base_free, fixed0, list(s0.x[: p0.n_phys]), s0.x[p0.n_phys:],
                           max_iter=TRY_ITER)
    cost = {d: 2.0 * sol.cost for d, (_p, sol) in tried.items()}
    # 3. the best delay to convergence; a delay whose cost (an upper bound) comes close to
    # it gets a few more iterations from the converged fit, and the best is decided again
    refined: set[int] = set()
    full: set[int] = set()  # delays fitted to the end (each at most once: no endless loop)
    while True:
        d_best = min(cost, key=lambda d: cost[d])
        prob, sol = tried[d_best]
        if not sol.converged and d_best not in full:
            say(f"output-error fit: delay {d_best} (the best so far) to convergence")
            full.add(d_best)
            before = sol.iterations
            prob, sol = tried[d_best] = fit(d_best, base_free, fixed0,
                                            list(sol.x[: prob.n_phys]), sol.x[prob.n_phys:])
            sol.iterations += before  # reported: all iterations of this model
            cost[d_best] = 2.0 * sol.cost
            continue
        if not sol.converged:
            break  # reported below as a fit that did not converge
        m = int(prob.mask.sum())
        # the neighbouring delays always (a delay of one sample more or less trades off with
        # a lag and the friction: at 200 Hz a 4-iteration upper bound missed the true delay
        # by more than the threshold), the others when their upper bound comes close
        close = [d for d in delays if d != d_best and d not in refined
                 and (abs(d - d_best) == 1
                      or m * math.log(cost[d] / cost[d_best]) <= CLOSE_DELAY * CHI2_95)]
        if not close:
            if DELAY_KEY in fix or d_best != max(delays) or d_best >= top_delay:
                break
            # the best delay is the longest tried: try one more (a longer delay than the
            # search covered is otherwise fitted as a lag and a shorter delay)
            d = d_best + 1
            delays.append(d)
            refined.add(d)  # tried from the converged fit already
            say(f"output-error fit: delay {d_best} is the longest tried; trying delay {d}")
            tried[d] = fit(d, base_free, fixed0, list(sol.x[: prob.n_phys]),
                           sol.x[prob.n_phys:], max_iter=TRY_ITER)
            cost[d] = 2.0 * tried[d][1].cost
            continue
        for d in close:
            refined.add(d)
            if tried[d][1].converged:
                continue
            say(f"output-error fit: delay {d} again from the converged fit")
            tried[d] = fit(d, base_free, fixed0, list(sol.x[: prob.n_phys]),
                           sol.x[prob.n_phys:], max_iter=TRY_ITER)
            cost[d] = min(cost[d], 2.0 * tried[d][1].cost)
    m = int(prob.mask.sum())
    # 3. the actuator lag: T > 0 kept only if it lowers the cost significantly (χ²₁ test)
    if fit_lag:
        names = [*base_free, "actuator.lag"]
        lag_lo = prob.lag_floor
        best_lag = None
        lag_rejected = None
        probe = ts / 4.0
        for d in [dd for dd in (d_best, d_best - 1) if dd in cost]:
            if d == d_best and not _lag_lowers_cost(prob, sol, lag_lo, probe):
                lag_rejected = lag_lo + probe  # screened out: no fit needed
                continue
            say(f"output-error fit: the actuator lag with delay {d}")
            x_phys = [*sol.x[: prob.n_phys], max(ts / 2.0, 3.0 * lag_lo)]
            pl, sl = fit(d, names, nominal, x_phys, sol.x[prob.n_phys:], max_iter=8)
            if best_lag is None or sl.cost < best_lag[1].cost:
                best_lag = (pl, sl, d)
        if best_lag is not None and best_lag[1].x[len(base_free)] > AT_FLOOR * lag_lo and \
                m * math.log(2.0 * sol.cost / max(2.0 * best_lag[1].cost, 1e-300)) > CHI2_95:
            prob, sol, d_best = best_lag
            lag_rejected = None
            if not sol.converged:
                before = sol.iterations
                prob, sol = fit(d_best, names, nominal, list(sol.x[: prob.n_phys]),
                                sol.x[prob.n_phys:])
                sol.iterations += before
            cost[d_best] = min(cost.get(d_best, math.inf), 2.0 * sol.cost)
        elif best_lag is not None:
            lag_rejected = max(float(best_lag[1].x[len(base_free)]), lag_rejected or 0.0)
    else:
        lag_rejected = None
    # 4. stick-slip: breakaway friction above Coulomb (rig.stiction), kept only if it lowers
    # the cost significantly (χ²₁ test), after a screen as for the lag
    stiction_rejected = None
    without_stiction: dict[str, float] = {}  # the model with Fst = 0, when Fst > 0 won
    if fit_stiction and sol.converged:
        before = prob.phys(sol.x)
        prob, sol, stiction_rejected = _fit_stiction(prob, sol, m, fit, d_best, say)
        if stiction_rejected is None:
            without_stiction = before
        cost[d_best] = min(cost.get(d_best, math.inf), 2.0 * sol.cost)
    # 4a. a lag that ended at its floor 2h (the RK4 step's) once the stiction was fitted:
    # the model without a lag (T = 0 exactly, below the floor) is tried too, and kept when
    # it fits as well (at 200 Hz a twin's true delay with a lag held at 2 ms lost to one
    # sample less of delay and a 5 ms lag; without the lag it wins)
    if fit_lag and "actuator.lag" in prob.free and sol.converged:
        i_lag = prob.free.index("actuator.lag")
        if sol.x[i_lag] <= AT_FLOOR * lag_lo:
            say(f"output-error fit: without the lag (it ended at its floor) with delay {d_best}")
            names0 = [k for k in prob.free if k != "actuator.lag"]
            x0 = [float(v) for k, v in zip(prob.free, sol.x, strict=False)
                  if k != "actuator.lag"]
            p0, s0 = fit(d_best, names0, {**prob.fixed, "actuator.lag": 0.0}, x0,
                         sol.x[prob.n_phys:])
            if s0.converged and s0.cost <= sol.cost:
                s0.iterations += sol.iterations
                prob, sol = p0, s0
                lag_rejected = lag_lo + probe
                cost[d_best] = min(cost.get(d_best, math.inf), 2.0 * sol.cost)
    # 4b. the neighbouring delays again with the final structure (lag, stiction): before
    # them a delay of one sample more or less can win by carrying a lag or a stiction the
    # model did not have yet (a 1-sample delay was written as 0 samples and a 5 ms lag)
    ridge: dict[int, dict[str, float]] = {}
    if DELAY_KEY not in fix and sol.converged:
        prob, sol, d_best, ridge = _delay_with_final_structure(
            prob, sol, d_best, top_delay, delays, cost, fit, say, tried, m)
        if fit_lag and "actuator.lag" not in prob.free and lag_rejected is None:
            lag_rejected = lag_lo + probe  # the delay won without the lag (T = 0)
    # 5. the scenario's disturbance is taken as known: unless the log confirms it, a fit
    # without it must not be significantly better (a template's sine that the log lacks)
    why = _disturbance_lacking(scn, idim, prob, sol, m, fit_logs, (seg_samples, d_best, start),
                               limits, say)
    evidence = []  # model error found on the way (added to res.model_error below)
    if why:
        if not why.startswith(NOT_DECISIVE):
            raise FitFailed(why)
        why = why[len(NOT_DECISIVE):]
        # the likelihood ratio assumes the model: with a residual that is not white (model
        # error) it is no proof that the log lacks d(t), but neither is d(t) confirmed
        evidence.append(why.split(": the scenario does not")[0] + "; the residual is not "
                        "white, and divided by its long-run variance ratio the ratio is "
                        "below the threshold: not decisive")
    if not (sol.converged and np.isfinite(sol.cost)) or np.any(sol.fun >= 1e3):
        lo_b, hi_b = prob.bounds()
        at = [f"{k} at its {'lower' if sol.x[i] <= lo_b[i] else 'upper'} bound "
              f"{sol.x[i]:g} {PARAMS[k][1]}"
              + ("" if sol.x[i] <= lo_b[i] else f" ({limits[k].why})")
              for i, k in enumerate(prob.free)
              if sol.x[i] <= lo_b[i] and lo_b[i] != 0.0 or sol.x[i] >= hi_b[i]]
        raise FitFailed(f"the fit did not converge ({sol.message} after {sol.iterations} "
                        "iterations" + (f"; it ran into {', '.join(at)}" if at else "")
                        + "); try other starting values (--set) or a longer, richer "
                        "log (esoarm excite)")
    say("intervals: the Jacobian at the fit")

    def intervals(cov=None):  # type: ignore[no-untyped-def]
        """:func:`_estimates` from ``cov``, with the stiction that was fitted and lost its
        likelihood-ratio test (Fst = 0 won) written as 0 in [0, the fitted value]."""
        est, grav, resid = _estimates(scn, prob, sol, m, cost, d_best, delays, lag_rejected,
                                      cov)
        if stiction_rejected is not None:
            est["rig.stiction"] = Estimate(
                "rig.stiction", 0.0, (0.0, stiction_rejected), "N·m",
                PARAMS["rig.stiction"][0], True, True, "")
        return est, grav, resid

    estimates, gravity, resid_s = intervals()
    if val_logs:
        say("validation: the fitted rig on the held-out part of the log")
    val = _validate(scn, prob.phys(sol.x), val_logs, seg_samples, d_best, start) if val_logs else {}
    if val:
        say("noise model: the residual's spectrum (AR, restricted likelihood)")
        # the residual's spectrum from the fit's and the validation's segments together, the
        # part of it each segment's initial-state fit removed accounted for
        vsegs = val.pop("_segments")
        segs = _segment_residuals(prob, sol) + vsegs
        q = math.radians(scn.sensor.resolution_deg)
        if max(len(sg.r) for sg in segs) > REML_MAX_SEGMENT:  # dense likelihood too costly:
            # the plain one
            from esoarm.studies.identification.residual.noise_ar import noise_verdict

            verdict = None
            val["noise_spectrum"] = noise_verdict(np.concatenate([sg.r for sg in vsegs]),
                                                  np.concatenate([sg.u for sg in vsegs])).to_dict()
        else:
            verdict = segment_verdict(segs, q * q / 12.0)
            val["noise_spectrum"] = verdict.to_dict()
        if verdict is not None and verdict.is_sensor_noise and \
                val["residual_rms_rad"] <= NOISE_CARRY_OVER * resid_s and not \
                val["whiteness"]["white"]:
            f = verdict.fit
            # coloured noise: the intervals of the rig parameters from the sandwich
            # (JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹ with Σ the AR noise's covariance on each segment (the
            # white-noise intervals would be too narrow by up to √((1 + φ)/(1 − φ)))
            estimates, gravity, _s = intervals(_sandwich(prob, sol, f))
            val["noise_spectrum"]["parameter_intervals"] = (
                "with the AR noise's covariance: (JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹")
            estimates[NOISE_KEY] = Estimate(
                NOISE_KEY, math.degrees(f.std), (math.degrees(f.std_ci[0]),
                                                 math.degrees(f.std_ci[1])), "deg",
                "encoder noise σ (stationary std of the AR noise, quantization apart)")
        elif verdict is None and val["noise_spectrum"]["sensor_noise"] and \
                val["noise_spectrum"]["noise_ar"] and \
                val["residual_rms_rad"] <= NOISE_CARRY_OVER * resid_s and not \
                val["whiteness"]["white"]:
            # coloured noise on segments too long for the restricted likelihood (1 kHz):
            # the same sandwich with the Yule-Walker AR model of the plain verdict (without
            # it the white-noise intervals were too narrow by √(long-run variance ratio),
            # 2-3× under AR(1) φ 0.7-0.8: a lag written ±0.05 ms that missed)
            ar = [float(v) for v in val["noise_spectrum"]["noise_ar"]]
            estimates, gravity, _s = intervals(_ar_filter_sandwich(prob, sol, ar))
            val["noise_spectrum"]["parameter_intervals"] = (
                "with the AR noise's covariance (Yule-Walker): (JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹")
    y_fit = prob.predict(sol.x)
    mask = prob.mask
    fit_pct = _fit_percent(prob.y[mask], y_fit[mask])
    curves = {"fit": (prob.t, prob.y, np.where(mask, y_fit, np.nan))}
    if val:
        curves["validation"] = val.pop("_curves")
    res = IdentResult(
        scenario=scn, estimates=estimates, gravity=gravity, fit_percent=fit_pct,
        validation=val, residual_rms=resid_s, cost_by_delay=cost, n_fit=m,
        segment_seconds=seg_samples * ts, elapsed=time.perf_counter() - t_start,
        iterations=int(sol.iterations), fit_logs=sorted({lg.path for lg in fit_logs}),
        validation_logs=sorted({lg.path for lg in val_logs}), curves=curves,
        idim=idim.to_dict() if idim is not None else {})
    why = res.untrustworthy() or _methods_disagree(res, idim) or _validation_failed(res)
    if why:
        raise FitFailed(why, res)
    say("checking the model against the evidence (whiteness, IDIM-LS, excitation)")
    res.excitation = _excitation_headers(fit_logs)
    res.model_error = evidence + _model_rejected(res, prob, sol, idim)
    if res.model_error:
        _model_error_intervals(res, prob, sol, idim)
    else:
        _segment_floor(res, prob, sol)
    _ridge_intervals(res, ridge)
    _stiction_alternative(res, without_stiction)
    res.elapsed = time.perf_counter() - t_start
    return res


#: IDIM-LS and output error disagree when their inertias are further apart than this many
#: combined standard errors (and than MILD_SHARE of the IDIM-LS inertia).
MILD_Z = 1.96
MILD_SHARE = 0.05
#: Keys with an IDIM-LS counterpart (lever_checks.NAMES) whose interval can be checked there.
IDIM_OF = {"rig.inertia_scale": "inertia", "rig.viscous_friction": "viscous_friction",
           "rig.coulomb_friction": "coulomb_friction", "plant.m2": "gravity"}


def _validation_failed(res: IdentResult) -> str:
    """Why the validation refuses the fit ("" if it does not): the fitted rig simulated over
    the validation logs explains none of the angle's variation (fit ≤ 0 %, or nan)."""
    fit = res.validation.get("fit_percent") if res.validation else None
    if fit is None or fit > 0.0:
        return ""
    return (f"validation failed (output error): the fitted rig simulated over "
            f"{', '.join(res.validation_logs)} fits {fit:.4g} % of the measured angle's "
            "variation (0 % is its mean: the model predicts nothing there); nothing written")


#: A log whose excitation left the arm stuck more than this share of the time (the header of
#: ``esoarm excite``) is evidence against white-noise intervals.
MAX_STUCK = 0.5


def _excitation_headers(logs: list[IdentLog]) -> dict[str, dict[str, float]]:
    """{path: header} of the fitting logs that carry an ``# esoarm excite:`` header."""
    from esoarm.studies.identification.experiment.probe import read_header

    out = {}
    for path in sorted({lg.path for lg in logs}):
        head = read_header(path)
        if head:
            out[path] = head
    return out


def _long_run_ratio(r: np.ndarray, lags: int = 20) -> float:
    """Long-run variance of ``r`` over its variance, 1 + 2 Σ (1 − k/(L+1)) ρ_k (Bartlett
    window, Newey-West, L = ``lags``), at least 1: the factor by which a correlated residual
    inflates a likelihood-ratio statistic computed as if it were white [1]."""
    r = r - np.mean(r)
    denom = float(np.dot(r, r)) or 1.0
    k = np.arange(1, min(lags, len(r) - 1) + 1)
    rho = np.array([float(np.dot(r[:-j], r[j:])) / denom for j in k])
    return max(1.0, 1.0 + 2.0 * float(np.sum((1.0 - k / (lags + 1.0)) * rho)))


def _whiteness(r: np.ndarray) -> dict:
    """The residual's autocorrelation at lags 1 … 20 against ±1.96/√M (white: ≤ 2 outside)."""
    lags = np.arange(1, 21)
    r = r - np.mean(r)
    denom = float(np.dot(r, r)) or 1.0
    rho = np.array([float(np.dot(r[:-k], r[k:])) / denom for k in lags])
    band = 1.96 / math.sqrt(len(r))
    outside = int(np.sum(np.abs(rho) > band))
    return {"lags": len(lags), "band": band, "outside": outside,
            "max_abs_autocorrelation": float(np.max(np.abs(rho))), "white": outside <= 2}


def _model_rejected(res: IdentResult, prob: Problem, sol, idim) -> list[str]:  # type: ignore[no-untyped-def]
    """The evidence that the model does not describe the log, each in words (empty: none).

    * the validation residual (the fit's, without validation) is not white and not sensor
      noise by its spectrum (:meth:`IdentResult.coloured_noise`);
    * IDIM-LS and the output-error fit disagree on the inertia (beyond :data:`MILD_Z`
      combined standard errors and :data:`MILD_SHARE`);
    * the delay ended at the longest one tried (``--max-delay``);
    * the log's ``esoarm excite`` header says the arm was stuck more than :data:`MAX_STUCK`
      of the time, or never broke away.
    A non-white residual also voids the likelihood-ratio tests of the delay, the lag and the
    stiction (a cost ratio friction error alone can produce).
    """
    out = []
    w: dict = res.validation["whiteness"] if res.validation else _whiteness(-sol.fun)
    if not w["white"] and res.coloured_noise() is None:
        where = "validation" if res.validation else "fit"
        out.append(f"the {where} residual is not white ({w['outside']} of {w['lags']} "
                   f"autocorrelation lags outside ±{w['band']:.3g}, max |ρ| "
                   f"{w['max_abs_autocorrelation']:.2f}) and is not sensor noise by its "
                   "spectrum")
    for path, head in res.excitation.items():
        stuck = head.get("stuck_fraction", math.nan)
        if stuck > MAX_STUCK:
            out.append(f"the excitation left the arm stuck {stuck:.0%} of the time ({path}'s "
                       "header): the log says little about the inertia, the delay and the lag")
        elif head.get("broke_away", 1.0) == 0.0:
            out.append(f"the excitation's probe did not break the arm away in both directions "
                       f"({path}'s header)")
    delay = res.estimates.get(DELAY_KEY)
    if delay is not None and delay.bound == "upper":
        out.append(f"the delay ended at the longest one tried ({delay.value:g} samples, "
                   "--max-delay): a longer one would move every other parameter")
    if idim is not None and res.scenario.motor is None:
        est = res.estimates["rig.inertia_scale"]
        i0 = res.scenario.plant.inertia
        k = idim.names.index("inertia")
        ls, se_ls = float(idim.values[k]), float(idim.se[k])
        oe, se_oe = est.value * i0, (est.ci95[1] - est.ci95[0]) / 3.92 * i0
        if est.fitted and abs(oe - ls) > max(MILD_Z * math.hypot(se_oe, se_ls),
                                             MILD_SHARE * abs(ls)):
            out.append(f"IDIM-LS gives an inertia of {ls:.4g} ± {1.96 * se_ls:.2g} kg·m², the "
                       f"output-error fit {oe:.4g} ± {1.96 * se_oe:.2g} kg·m² "
                       f"({100 * (oe / ls - 1):+.0f} %)")
    return out


def _segment_covariance(prob: Problem, sol) -> tuple[np.ndarray, int]:  # type: ignore[no-untyped-def]
    """Cluster-robust covariance of the rig parameters with the segments as clusters
    (a sandwich with HAC over segments: valid under model error and any correlation within
    a segment), with the small-sample factor G/(G − p); and the number of segments G."""
    jac = sol.jac
    r = -sol.fun
    a_inv = np.linalg.pinv(jac.T @ jac)
    pos = np.cumsum(prob.mask) - 1
    b = np.zeros_like(a_inv)
    g = 0
    for k0, n in zip(prob.seg_start, prob.seg_len, strict=True):
        rows = np.arange(k0, k0 + n)
        rows = pos[rows[prob.mask[rows]]]
        if len(rows) == 0:
            continue
        score = jac[rows].T @ r[rows]
        b += np.outer(score, score)
        g += 1
    p = prob.n_phys
    cov = a_inv @ b @ a_inv * (g / max(g - p, 1))
    return cov[:p, :p], g


def _segment_floor(res: IdentResult, prob: Problem, sol) -> None:  # type: ignore[no-untyped-def]
    """Widen every written interval of a fitted rig parameter to at least the
    segment-cluster sandwich's (:func:`_segment_covariance`, Student t with G − 1 degrees
    of freedom), when there are more segments than parameters.

    The white-noise and AR-noise intervals are valid only when the noise model is right;
    the segment clusters are valid under any correlation within a segment (coloured noise
    the whiteness test passed, PWM steps, vibration, small model error) as long as the
    segments are independent.  Used as a floor, never to narrow: on held-out calibration
    rigs the white-noise intervals were as narrow as ±0.03 % of the inertia and ±0.01 % of
    plant.m2 while the residual's AR(1) coefficient was 0.4 (2 of 20 lags outside: judged
    white).  The gravity coefficient follows plant.m2; ``interval_method`` says so.
    """
    from scipy.stats import t as student_t

    cov, g = _segment_covariance(prob, sol)
    if g <= prob.n_phys + 1:
        return
    q = float(student_t.ppf(0.975, g - 1))
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    lower, upper = prob.bounds()
    widened = []
    for i, key in enumerate(prob.free):
        est = res.estimates.get(key)
        if est is None or est.withheld or not est.fitted:
            continue
        half = q * float(se[i])
        lo, hi = est.value - half, est.value + half
        if lo >= est.ci95[0] and hi <= est.ci95[1]:
            continue
        ci = (max(min(lo, est.ci95[0]), float(lower[i])),
              min(max(hi, est.ci95[1]), float(upper[i])))
        scale = prob.limits[key].scale
        poor = not (ci[1] - ci[0]) / 2 <= POOR_REL * max(abs(est.value), 0.1 * scale)
        res.estimates[key] = replace(
            est, ci95=ci, identifiable=est.identifiable and not poor,
            advice=est.advice or ("the segments disagree more than the noise model "
                                  "allows" if poor else ""),
            ci_clipped=est.ci_clipped or ci != (min(lo, est.ci95[0]), max(hi, est.ci95[1])))
        widened.append(key)
    if "plant.m2" in widened:
        m2 = res.estimates["plant.m2"]
        pl = res.scenario.plant
        gv = sorted(gravity_coefficient(pl.m1, mass, pl.l1, pl.l2, pl.g) for mass in m2.ci95)
        res.gravity = replace(res.gravity, ci95=(gv[0], gv[1]),
                              identifiable=res.gravity.identifiable and m2.identifiable)
    if widened:
        res.interval_method += (f"; at least the segment-cluster sandwich's (t, G − 1 = "
                                f"{g - 1}): wider for {', '.join(widened)}")


def _model_error_intervals(res: IdentResult, prob: Problem, sol, idim) -> None:  # type: ignore[no-untyped-def]
    """Replace the white-noise intervals of a rejected model (``res.model_error``).

    Inertia, friction and gravity: the segment-cluster sandwich
    (:func:`_segment_covariance`, Student t with G − 1 degrees of freedom) joined with the
    IDIM-LS interval of the same quantity (HAC) and widened on each side by the distance
    between the two estimates (both are biased by the model error, by an unknown amount);
    where the two intervals do not overlap, the methods disagree and the interval is
    withheld. Delay, lag, stiction and the noise are decided by likelihood-ratio tests and a
    residual variance that assume the model: their intervals are withheld.
    """
    from scipy.stats import t as student_t

    cov, g = _segment_covariance(prob, sol)
    q = float(student_t.ppf(0.975, max(g - 1, 1)))
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    pl = res.scenario.plant
    because_short = ("decided by a likelihood-ratio test or a residual variance that assume "
                     "the model, which the evidence rejects")
    idim_vals = {}
    if idim is not None:
        for n, v, s in zip(idim.names, idim.values, idim.se, strict=True):
            idim_vals[n] = (float(v), 1.96 * float(s))

    def to_key(key: str, v: float) -> float:  # IDIM-LS quantity -> the scenario key's value
        if key == "rig.inertia_scale":
            return v / pl.inertia
        if key == "plant.m2":
            return (pl.m1 * pl.l1 - v / pl.g) / pl.l2
        return v

    lower, upper = prob.bounds()
    for key, est in list(res.estimates.items()):
        if not est.fitted:
            continue
        if key in prob.free and key in IDIM_OF:
            i = prob.free.index(key)
            half = q * float(se[i])
            lo, hi = est.value - half, est.value + half
            name = IDIM_OF[key]
            if name in idim_vals:
                v, h = idim_vals[name]
                a, b = sorted((to_key(key, v - h), to_key(key, v + h)))
                if b < lo or a > hi:
                    res.estimates[key] = _withhold(
                        est, f"the methods disagree: output error {est.value:.4g} "
                        f"[{lo:.4g}, {hi:.4g}], IDIM-LS {to_key(key, v):.4g} [{a:.4g}, "
                        f"{b:.4g}] {est.unit}")
                    continue
                # both methods are biased by the model error the evidence shows, by an unknown
                # amount: as much again as their disagreement is allowed on either side (a
                # high-Coulomb twin's inertia: output error +3 %, IDIM-LS +10 %)
                spread = abs(est.value - to_key(key, v))
                lo, hi = min(lo, a) - spread, max(hi, b) + spread
            ci = (max(lo, float(lower[i])), min(hi, float(upper[i])))
            res.estimates[key] = Estimate(
                key, est.value, ci, est.unit, est.label, True,
                est.identifiable and (ci[1] - ci[0]) / 2 <= POOR_REL * max(abs(est.value), 1e-12),
                est.advice, est.bound, est.ci_clipped or ci != (lo, hi), est.bound_why)
        else:
            res.estimates[key] = _withhold(est, because_short)
    m2 = res.estimates["plant.m2"]
    g_of = lambda mass: gravity_coefficient(pl.m1, mass, pl.l1, pl.l2, pl.g)  # noqa: E731
    gv = sorted((g_of(m2.ci95[0]), g_of(m2.ci95[1])))
    res.gravity = Estimate("gravity_coefficient", g_of(m2.value), (gv[0], gv[1]), "N·m",
                           res.gravity.label, m2.fitted, m2.identifiable, m2.advice,
                           withheld=m2.withheld)
    res.interval_method = ("model error: segment-cluster sandwich (t, G − 1 = "
                           f"{g - 1}) joined with IDIM-LS (HAC), widened by their distance; "
                           "delay, lag, stiction and noise withheld")


def _ridge_intervals(res: IdentResult, ridge: dict[int, dict[str, float]]) -> None:
    """Widen the written intervals over the delay's interval: when delays other than the
    chosen one fit alike (the delay's interval spans them), every rig parameter's interval
    is joined with the same interval moved to its value at each of those delays (``ridge``:
    the final model fitted at that delay, :func:`_delay_with_final_structure`), since the
    interval of the chosen delay is conditional on it.  The lag trades with the delay most
    (one sample of delay for one sample period of lag); a delay inside the interval that
    was not fitted with the final model leaves the lag's interval withheld instead.  The
    gravity coefficient follows plant.m2."""
    d = res.estimates.get(DELAY_KEY)
    if d is None or not d.fitted or d.ci95[1] - d.ci95[0] < 1.0:
        return
    chosen = int(d.value)
    inside = [k for k in range(int(d.ci95[0]), int(d.ci95[1]) + 1) if k != chosen]
    known = [ridge[k] for k in inside if k in ridge]
    if "actuator.lag" in res.estimates and len(known) < len(inside):
        lag = res.estimates["actuator.lag"]
        if lag.fitted and not lag.withheld:
            res.estimates["actuator.lag"] = _withhold(
                lag, f"trades off with the delay: delays {d.ci95[0]:g} … {d.ci95[1]:g} "
                "samples fit alike, and this interval is the chosen delay's only")
    _join_alternatives(res, known, f"trades off with the delay: the interval covers the "
                       f"fits at delays {d.ci95[0]:g} … {d.ci95[1]:g} samples",
                       f"joined over the delays {d.ci95[0]:g} … {d.ci95[1]:g} that fit alike")


def _stiction_alternative(res: IdentResult, without: dict[str, float]) -> None:
    """Join the intervals with the model without stiction (Fst = 0, ``without``) when the
    stiction won its likelihood-ratio test but its own interval is poorly determined: which
    of the two models holds is then uncertain, and each parameter's interval of the chosen
    model is conditional on it.  (A held-out 50 Hz twin without stiction was fitted a
    stiction of 0.003 N·m [0.0001, 0.0055], flagged, and with it a gravity term ±1e-4 that
    missed by 3.4 standard errors; without the stiction it missed by 1.4.)"""
    est = res.estimates.get("rig.stiction")
    if not without or est is None or not est.fitted or est.value <= 0.0 or est.identifiable:
        return
    _join_alternatives(res, [without], "the stiction is poorly determined: the interval "
                       "covers the fit without it too", "joined with the fit without "
                       "stiction (poorly determined)", skip=("rig.stiction",))


def _join_alternatives(res: IdentResult, alternatives: list[dict[str, float]], advice: str,
                       method: str, skip: tuple[str, ...] = ()) -> None:
    """Join every written interval of a rig parameter with the same interval moved to the
    parameter's value in each alternative model (fitted values by key) that the log cannot
    rule out; the gravity coefficient follows plant.m2; ``advice`` and ``method`` say why."""
    widened = []
    for key, est in list(res.estimates.items()):
        if key in (DELAY_KEY, NOISE_KEY, *skip) or not est.fitted or est.withheld:
            continue
        vals = [v[key] for v in alternatives if key in v]
        below, above = est.value - est.ci95[0], est.ci95[1] - est.value
        lo = min([est.ci95[0], *(v - below for v in vals)])
        hi = max([est.ci95[1], *(v + above for v in vals)])
        if key != "rig.inertia_scale":  # a friction, a mass, a lag: never below 0
            lo = max(lo, 0.0)
        if (lo, hi) == est.ci95:
            continue
        res.estimates[key] = replace(est, ci95=(lo, hi), advice=est.advice or advice)
        widened.append(key)
    if "plant.m2" in widened:
        m2 = res.estimates["plant.m2"]
        pl = res.scenario.plant
        gv = sorted(gravity_coefficient(pl.m1, mass, pl.l1, pl.l2, pl.g) for mass in m2.ci95)
        res.gravity = replace(res.gravity, ci95=(gv[0], gv[1]))
    if widened:
        res.interval_method += f"; {method}: {', '.join(widened)}"


def _withhold(est: Estimate, why: str) -> Estimate:
    """``est`` with its interval withheld for ``why``."""
    return Estimate(est.key, est.value, est.ci95, est.unit, est.label, est.fitted,
                    est.identifiable, est.advice, est.bound, est.ci_clipped, est.bound_why,
                    withheld=why)


#: The output-error inertia and IDIM-LS's further apart than this share, and than
#: GROSS_DISAGREEMENT combined 95 % half-widths, refuse the fit (the IDIM-LS model has no
#: delay or lag, hence the generous share).
INERTIA_DISAGREEMENT = 0.25
GROSS_DISAGREEMENT = 3.0
#: ... and they refuse only beyond this ratio (IDIM-LS's lever-arm filter put it 26× off
#: the output-error inertia, which was 4 % from the truth, on a 1 kHz calibration twin;
#: angles that cannot be in rad are refused before, by lever_checks).
GROSS_RATIO = 100.0


def _methods_disagree(res: IdentResult, idim) -> str:  # type: ignore[no-untyped-def]
    """Why the output-error inertia cannot be trusted next to IDIM-LS's ("" if it can).

    Only a disagreement by more than :data:`GROSS_RATIO` times refuses; a
    smaller one is model error (:func:`_model_rejected`): the inertia's interval is then
    joined with IDIM-LS's, or withheld where they do not overlap.  IDIM-LS's derivative
    filter and its model without delay or lag put it off by 7× to 26× on logs that the
    output-error fit follows (a 1 kHz log, a step followed by rest, a sticking arm)."""
    if idim is None or res.scenario.motor is not None:
        return ""
    phys = res.physical()["inertia"]
    oe, (lo, hi) = phys["value"], phys["ci95"]
    i = idim.names.index("inertia")
    ls, half_ls = float(idim.values[i]), 1.96 * float(idim.se[i])
    half = math.hypot(0.5 * (hi - lo), half_ls)
    gross = not (ls > 0 and oe > 0 and 1.0 / GROSS_RATIO < oe / ls < GROSS_RATIO)
    if gross and abs(oe - ls) > max(INERTIA_DISAGREEMENT * abs(ls), GROSS_DISAGREEMENT * half):
        return (f"the methods disagree: the output-error fit gives an inertia of {oe:.3g} "
                f"kg·m², the inverse dynamic model (IDIM-LS) {ls:.3g} ± {half_ls:.2g} kg·m² "
                f"(apart by more than {GROSS_RATIO:g}× and {GROSS_DISAGREEMENT:g} "
                "combined 95 % half-widths): the model does not describe this log (friction, "
                "a delay, the units); check the rig and the log, or try another --segment")
    return ""


#: Marks a disturbance test that neither fit's residual supports (see _disturbance_lacking).
NOT_DECISIVE = "[not decisive] "


def _disturbance_lacking(scn, idim, prob, sol, m, logs, layout, limits, say) -> str:  # type: ignore[no-untyped-def]
    """Why the scenario's disturbance d(t) cannot be taken as known ("" if it can).

    Skipped when IDIM-LS confirms d(t) on the log
    (:func:`esoarm.studies.identification.lever_checks.disturbance_confirmed`).  Otherwise
    the fit is run again (:data:`FIRST_ITER` iterations) with d(t) = 0 from the fitted
    point; if that lowers the cost
    significantly (likelihood ratio beyond χ²₁ 95 %), the log lacks the disturbance the
    scenario assumes -- decided on the fit itself, so also on a log shorter than two of
    its periods, where IDIM-LS cannot tell.  When the ratio does not exceed the threshold
    once divided by the long-run variance ratio of the residual without d(t)
    (:func:`_long_run_ratio`), the reason starts with :data:`NOT_DECISIVE`: the caller
    counts it as model error, not a refusal.
    """
    from esoarm.studies.identification.lever_checks import disturbance_confirmed

    d = scn.rig.disturbance
    if d.amplitude == 0.0 or d.frequency <= 0.0 or not np.isfinite(sol.cost) \
            or disturbance_confirmed(scn, idim):
        return ""
    seg_samples, delay, start = layout
    say("output-error fit: without the scenario's disturbance d(t)")
    scn0 = scn.with_overrides({"rig.disturbance.amplitude": 0.0})
    p0 = Problem(scn0, logs, seg_samples, delay, start, prob.free, prob.fixed, limits)
    # a few iterations: the cost they reach is an upper bound of the fit without d(t), so a
    # significant drop is already decisive (and a log that has d(t) only gets worse)
    s0 = p0.solve(sol.x.copy(), max_iter=FIRST_ITER)
    if not np.isfinite(s0.cost) or s0.cost <= 0.0:
        return ""
    ratio = m * math.log(max(sol.cost, 1e-300) / s0.cost)
    if ratio <= CHI2_95:
        return ""
    # the test assumes the model without d(t) leaves white noise; with a correlated residual
    # (model error beside d(t): backlash, a delay beyond the search) the ratio is inflated
    # by the residual's long-run variance ratio, and it is decisive only beyond it
    decisive = ratio / _long_run_ratio(-s0.fun) > CHI2_95
    period = 2.0 * math.pi / d.frequency
    seconds = sum(log.n for log in logs) * logs[0].ts
    short = (f"; the log, {seconds:.3g} s, is shorter than two of its periods "
             f"({2.0 * period:.3g} s)" if seconds < 2.0 * period else "")
    return ("" if decisive else NOT_DECISIVE) + (
            f"the scenario's disturbance d(t) = {d.amplitude:g}·sin({d.frequency:g} t) rad/s² "
            "is taken as known, but the log fits better without it (likelihood ratio "
            f"{ratio:.3g} > {CHI2_95:.2f}{short}): the scenario does not describe this rig; "
            "set rig.disturbance.amplitude (0 if it had none)")


def _fit_stiction(prob: Problem, sol, m: int, fit, delay: int, say):  # type: ignore[no-untyped-def]
    """Try Fst > 0 on the converged fit: (problem, solution, upper end of the rejected Fst).

    A fit without breakaway friction inflates the Coulomb friction to carry it, so the
    fit with Fst free starts from a quarter of the fitted Coulomb friction moved into a
    stiction of half of it (at least 0.005 N·m); it is kept if the likelihood-ratio test
    against Fst = 0 passes (χ²₁ 95 %) and Fst ends above 0.  The Stribeck velocity is
    held at the scenario's ``rig.stribeck_velocity``.  The fit first runs
    :data:`STICTION_SCREEN_ITER` iterations and goes on to convergence only when its cost
    has by then dropped by at least half the test's threshold (a stiction the log does not
    show took 30 iterations, a third of identify's work, to be rejected).
    """
    names = [*prob.free, "rig.stiction"]
    x_phys = list(sol.x[: prob.n_phys])
    fc = x_phys[names.index("rig.coulomb_friction")] if "rig.coulomb_friction" in names else 0.0
    probe = max(0.5 * fc, 0.005)
    if "rig.coulomb_friction" in prob.free:
        x_phys[prob.free.index("rig.coulomb_friction")] = 0.75 * fc
    say(f"output-error fit: stiction (breakaway friction) with delay {delay}")
    fixed = {k: v for k, v in prob.fixed.items() if k != "rig.stiction"}
    fixed["rig.stiction"] = 0.0
    p2, s2 = fit(delay, names, fixed, [*x_phys, probe], sol.x[prob.n_phys:],
                 max_iter=STICTION_SCREEN_ITER)
    gain = m * math.log(max(sol.cost, 1e-300) / max(s2.cost, 1e-300))
    if not s2.converged and gain > 0.5 * CHI2_95:  # on its way to passing: to the end
        before = s2.iterations
        p2, s2 = fit(delay, names, fixed, list(s2.x[: p2.n_phys]), s2.x[p2.n_phys:],
                     max_iter=200)
        s2.iterations += before
    fst = float(s2.x[len(names) - 1])
    if s2.converged and fst > 1e-6 and \
            m * math.log(max(sol.cost, 1e-300) / max(s2.cost, 1e-300)) > CHI2_95:
        s2.iterations += sol.iterations
        return p2, s2, None
    return prob, sol, float(max(fst, probe))


def _delay_with_final_structure(prob: Problem, sol, d_best: int, top: int,  # type: ignore[no-untyped-def]
                                delays: list[int], cost: dict[int, float], fit, say,
                                tried: dict, m: int):
    """The delay's profile with every parameter of the final model (lag, stiction): the
    delays around ``d_best`` fitted again, each from the best (lower cost) of three starts:
    the best model so far with its lag moved by the delay's change (one sample more of
    delay, one sample period less of lag: at low frequency both are the same phase, so this
    start lies in the other delay's valley), the best model so far as it is, and that
    delay's own earlier fit (``tried``; without lag or stiction) with the lag at its floor
    and the best model's stiction.  Where the moved lag falls below the lag's floor 2h (the
    RK4 step's), that delay is fitted without a lag (T = 0 exactly): a lag held at 2 ms is
    0.4 samples at 200 Hz, and with it a twin's true delay lost to one sample less of delay
    and a 5 ms lag.

    The walk goes on from every delay that becomes the best (its other neighbour next), and
    past every delay whose cost is within the delay's likelihood-ratio threshold of the
    best (χ²₁ 95 % times the residual's long-run variance ratio, as for the delay's
    interval): the delay and the lag trade along a ridge, and the interval must see all of
    it.  (On held-out 1 kHz rigs with coloured noise, a delay chosen before the stiction
    was fitted stayed two samples off the truth with a lag two samples short, because only
    one neighbour was tried again; the truth's delay, its lag moved, fitted better.)

    :data:`TRY_ITER` iterations per delay, and to convergence when that comes within
    :data:`CLOSE_DELAY` thresholds (or twice the long-run threshold) of the best.  ``cost``
    (2 × the least-squares cost by delay) and ``delays`` are updated in place; returns the
    (problem, solution, delay) of the best (its problem may lack the lag) and the ridge:
    {delay: fitted values} of every delay fitted to convergence with the final model."""
    best = (prob, sol, d_best)
    ts = prob.h * prob.nsub  # the sample period [s]
    lrv = _long_run_ratio(-sol.fun)
    near_thr = max(CLOSE_DELAY, 2.0 * lrv) * CHI2_95
    ridge: dict[int, dict[str, float]] = {d_best: prob.phys(sol.x)}
    profile: dict[int, float] = {d_best: 2.0 * sol.cost}
    failed: set[int] = set()

    def next_delays() -> list[int]:
        b = best[2]
        out = []
        for step in (-1, 1):  # each side: past the delays inside the threshold
            d = b + step
            while d in profile and m * math.log(max(profile[d], 1e-300)
                                                / max(2.0 * best[1].cost, 1e-300)) \
                    <= CHI2_95 * lrv:
                d += step
            if 0 <= d <= top and d not in profile and d not in failed:
                out.append(d)
        return out

    while True:
        todo = next_delays()
        if not todo:
            break
        d = todo[0]
        say(f"output-error fit: delay {d} again with the final model (lag, stiction)")
        p, s, d_from = best
        x_best = list(s.x[: p.n_phys])
        names, fixed = list(p.free), dict(p.fixed)
        starts = [(names, fixed, x_best, s.x[p.n_phys:])]  # (names, fixed, x, states)
        if "actuator.lag" in p.free:  # the best model, the lag moved by the delay's change
            xs = list(x_best)
            i_lag = p.free.index("actuator.lag")
            xs[i_lag] = xs[i_lag] - (d - d_from) * ts
            if xs[i_lag] > AT_FLOOR * p.lag_floor:
                starts.append((names, fixed, xs, s.x[p.n_phys:]))
            else:  # below the lag's floor 2h: that delay without a lag (T = 0 exactly)
                starts.append(([k for k in names if k != "actuator.lag"],
                               {**fixed, "actuator.lag": 0.0},
                               [v for k, v in zip(names, xs, strict=True)
                                if k != "actuator.lag"], s.x[p.n_phys:]))
        if d in tried:  # the delay's own fit: its values, no lag
            p_d, s_d = tried[d]
            x0 = list(x_best)
            for i, key in enumerate(p.free):
                if key in p_d.free:
                    x0[i] = float(s_d.x[p_d.free.index(key)])
                elif key == "actuator.lag":
                    x0[i] = 0.0  # clipped to the lag's floor
            starts.append((names, fixed, x0, s_d.x[p_d.n_phys:]))
        costs = [fit(d, nm, fx, xs, st, max_iter=0)[1].cost for nm, fx, xs, st in starts]
        nm, fx, x0, states = starts[int(np.argmin(costs))]
        pd, sd = fit(d, nm, fx, x0, states, max_iter=TRY_ITER)
        near = m * math.log(max(sd.cost, 1e-300) / max(best[1].cost, 1e-300)) <= near_thr
        if near and not sd.converged:
            before = sd.iterations
            pd, sd = fit(d, nm, fx, list(sd.x[: pd.n_phys]), sd.x[pd.n_phys:])
            sd.iterations += before
        if d not in delays:
            delays.append(d)
        cost[d] = min(cost.get(d, math.inf), 2.0 * sd.cost)
        if not sd.converged:
            failed.add(d)
            continue
        profile[d] = 2.0 * sd.cost
        ridge[d] = pd.phys(sd.x)
        if sd.cost < best[1].cost:
            best = (pd, sd, d)
    cost[best[2]] = min(cost.get(best[2], math.inf), 2.0 * best[1].cost)
    return best[0], best[1], best[2], ridge


def _lag_lowers_cost(prob: Problem, sol, lag_lo: float, probe: float) -> bool:  # type: ignore[no-untyped-def]
    """Screen: does a lag of ``lag_lo + probe`` [s] lower the cost of the T = 0 fit?

    Everything else held at the T = 0 fit; if a lag of a quarter sample does not
    help there, the lag is not worth a fit (T = 0 is kept).
    """
    def cost(lag: float) -> float:
        r = prob.with_fixed({"actuator.lag": lag}).residual(sol.x)
        return float(r @ r)

    return cost(lag_lo + probe) < cost(lag_lo)


def _fit_percent(y: np.ndarray, yhat: np.ndarray) -> float:
    """100·(1 − ‖y − ŷ‖/‖y − ȳ‖) [%]."""
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / np.linalg.norm(y - np.mean(y))))


def _estimates(scn, prob, sol, m, cost, d_best, delays, lag_rejected,  # type: ignore[no-untyped-def]
               cov=None):
    """The estimates with 95 % intervals from ``cov`` (default σ̂² (JᵀJ)⁻¹: white noise)."""
    jac = sol.jac
    p = jac.shape[1]
    dof = max(m - p, 1)
    s2 = 2.0 * sol.cost / dof
    if cov is None:
        cov = s2 * np.linalg.pinv(jac.T @ jac)
    se = np.sqrt(np.maximum(np.diag(cov)[: prob.n_phys], 0.0))
    corr = cov[: prob.n_phys, : prob.n_phys] / np.maximum(np.outer(se, se), 1e-300)
    lower, upper = prob.bounds()
    out: dict[str, Estimate] = {}
    for i, key in enumerate(prob.free):
        label, unit, _scale, _b, advice = PARAMS[key]
        scale = prob.limits[key].scale
        v = float(sol.x[i])
        half = 1.96 * float(se[i])
        others = [prob.free[j] for j in range(prob.n_phys) if j != i and abs(corr[i, j]) > 0.98]
        poor = not half <= POOR_REL * max(abs(v), 0.1 * scale) or bool(others)
        if key == "rig.viscous_friction" and scn.motor is not None:
            advice = ("with a [motor] table b adds to the back-EMF damping (N·Kt)²/R; only "
                      "their sum is well determined")
        note = advice + (f"; strongly correlated with {', '.join(others)}" if others else "")
        # a value at a bound of the fit: the interval (a local linearization) runs past it;
        # clip it to the bounds and say so (the value is then a limit, not an optimum)
        lo_b, hi_b = float(lower[i]), float(upper[i])
        tol = 1e-9 * max(scale, abs(lo_b), abs(hi_b) if math.isfinite(hi_b) else 0.0)
        bound = "lower" if v <= lo_b + tol else "upper" if v >= hi_b - tol else ""
        ci = (max(v - half, lo_b), min(v + half, hi_b))
        out[key] = Estimate(key, v, ci, unit, label, True, not poor, note if poor else "",
                            bound, ci != (v - half, v + half),
                            prob.limits[key].why if bound == "upper" else "")
    for key in PARAMS:
        if key not in out and (scn.motor is not None or key != "motor.torque_constant"):
            label, unit, *_ = PARAMS[key]
            v = prob.fixed[key]
            note = MOTOR_SCALE_NOTE if key == "rig.inertia_scale" and scn.motor else \
                "held at the scenario's value"
            out[key] = Estimate(key, v, (v, v), unit, label, False, True, note)
    if lag_rejected is not None:  # fitted, and T = 0 won the likelihood-ratio test
        out["actuator.lag"] = Estimate(
            "actuator.lag", 0.0, (0.0, lag_rejected), "s", PARAMS["actuator.lag"][0], True, True,
            "")
    best = cost[d_best] if d_best in cost else min(cost.values())
    # the likelihood ratio assumes a white residual: a correlated one (coloured noise, model
    # error) inflates it by its long-run variance ratio, so it is divided by that ratio
    lrv = _long_run_ratio(-sol.fun)
    inside = [d for d in delays if m * math.log(cost[d] / best) <= CHI2_95 * lrv] or [d_best]
    searched = len(delays) > 1
    at_end = searched and d_best == max(delays)  # the upper end of the search: may be longer
    out[DELAY_KEY] = Estimate(DELAY_KEY, float(d_best), (float(min(inside)), float(max(inside))),
                              "samples", "transport delay", searched,
                              len(inside) == 1 or not searched,
                              "raise --max-delay" if at_end else
                              "" if len(inside) == 1 or not searched else
                              "more high-frequency torque (raise --f-max)",
                              "upper" if at_end else "", at_end)
    q = math.radians(scn.sensor.resolution_deg)
    s = math.sqrt(s2)
    lo, hi = s * (1 - 1.96 / math.sqrt(2 * dof)), s * (1 + 1.96 / math.sqrt(2 * dof))

    def sigma_deg(x: float) -> float:
        return math.degrees(math.sqrt(max(x * x - q * q / 12.0, 0.0)))

    out[NOISE_KEY] = Estimate(NOISE_KEY, sigma_deg(s), (sigma_deg(lo), sigma_deg(hi)), "deg",
                              "encoder noise σ (residual, quantization removed)")
    pl = scn.plant
    m2 = out["plant.m2"]
    g_of = lambda mass: gravity_coefficient(pl.m1, mass, pl.l1, pl.l2, pl.g)  # noqa: E731
    gvals = sorted((g_of(m2.ci95[0]), g_of(m2.ci95[1])))
    gravity = Estimate("gravity_coefficient", g_of(m2.value), (gvals[0], gvals[1]), "N·m",
                       "gravity coefficient (m1 l1 − m2 l2) g", m2.fitted, m2.identifiable,
                       m2.advice)
    return out, gravity, s


def _validate(scn, values, logs, seg_samples, delay, start):  # type: ignore[no-untyped-def]
    """The fitted rig on logs not used for fitting; only the segments' initial states are fitted.

    Returns fit % of the measured angle, the residual RMS [rad] and a whiteness
    test: the residual's autocorrelation at lags 1 … 20 against ±1.96/√M.
    """
    prob = Problem(scn, logs, seg_samples, delay, start, [], values,
                   limits_from_data(scn, logs))
    sol = prob.solve(prob.initial_states())
    yhat = prob.predict(sol.x)
    mask = prob.mask
    r = (prob.y - yhat)[mask]
    m = len(r)
    lags = np.arange(1, 21)
    denom = float(np.dot(r, r)) or 1.0
    rho = np.array([float(np.dot(r[:-k], r[k:])) / denom for k in lags])
    band = 1.96 / math.sqrt(m)
    outside = int(np.sum(np.abs(rho) > band))
    return {"fit_percent": _fit_percent(prob.y[mask], yhat[mask]),
            "residual_rms_rad": float(np.sqrt(np.mean(r**2))), "samples": m,
            "_segments": _segment_residuals(prob, sol),
            "whiteness": {"lags": len(lags), "band": band, "outside": outside,
                          "max_abs_autocorrelation": float(np.max(np.abs(rho))),
                          "white": outside <= 2},
            "_curves": (prob.t, prob.y, np.where(mask, yhat, np.nan), lags, rho, band)}


def _segment_residuals(prob: Problem, sol) -> list[SegmentResidual]:  # type: ignore[no-untyped-def]
    """Each segment's residual y − ŷ, the prediction's sensitivities to its initial angle and
    rate (the columns of the Jacobian the fit used), the input, and the sample indices."""
    jac = sol.jac
    pos = np.cumsum(prob.mask) - 1  # row of each log sample in the masked arrays
    resid = -sol.fun
    out = []
    for s, (k0, n) in enumerate(zip(prob.seg_start, prob.seg_len, strict=True)):
        rows = np.arange(k0, k0 + n)
        rows = rows[prob.mask[rows]]
        if len(rows) < 3:
            continue
        at = pos[rows]
        cols = slice(prob.n_phys + 2 * s, prob.n_phys + 2 * s + 2)
        out.append(SegmentResidual(resid[at], jac[at][:, cols], prob.base[rows], rows - k0))
    return out


def _sandwich(prob: Problem, sol, noise) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Covariance of the least-squares estimate under correlated noise [parameter units²]:
    (JᵀJ)⁻¹ (Σ_s J_sᵀ Σ_s J_s) (JᵀJ)⁻¹, with Σ_s the noise model's covariance
    (:meth:`esoarm.studies.identification.residual.noise_ar.RemlFit.covariance`) on segment s."""
    jac = sol.jac
    a_inv = np.linalg.pinv(jac.T @ jac)
    pos = np.cumsum(prob.mask) - 1
    b = np.zeros_like(a_inv)
    for k0, n in zip(prob.seg_start, prob.seg_len, strict=True):
        rows = np.arange(k0, k0 + n)
        rows = rows[prob.mask[rows]]
        js = jac[pos[rows]]
        b += js.T @ noise.covariance(rows - k0) @ js
    return a_inv @ b @ a_inv


def _ar_filter_sandwich(prob: Problem, sol, ar: list[float]) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Covariance of the least-squares estimate under AR noise n = A⁻¹ e [parameter units²]:
    (JᵀJ)⁻¹ (Σ_s σ_e² (A⁻ᵀ J_s)ᵀ (A⁻ᵀ J_s)) (JᵀJ)⁻¹ with A the AR filter of coefficients
    ``ar`` (n_k = Σ a_i n_(k−i) + e_k) on each segment s, A⁻ᵀ J_s the columns filtered by
    1/A backwards in time, and σ_e² the innovation variance of the fit's own residual (each
    segment filtered by A).  The segments' start is taken as at rest (the AR's stationary
    start is ignored: its share is the AR's memory over a segment's length)."""
    from scipy.signal import lfilter

    jac = sol.jac
    r = -sol.fun
    den = np.concatenate([[1.0], -np.asarray(ar, dtype=float)])
    a_inv = np.linalg.pinv(jac.T @ jac)
    pos = np.cumsum(prob.mask) - 1
    b = np.zeros_like(a_inv)
    e2, n_e = 0.0, 0
    for k0, n in zip(prob.seg_start, prob.seg_len, strict=True):
        rows = np.arange(k0, k0 + n)
        at = pos[rows[prob.mask[rows]]]
        if len(at) <= len(ar):
            continue
        e = lfilter(den, [1.0], r[at])[len(ar):]
        e2 += float(e @ e)
        n_e += len(e)
        w = lfilter([1.0], den, jac[at][::-1], axis=0)[::-1]
        b += w.T @ w
    return a_inv @ (b * (e2 / max(n_e, 1))) @ a_inv
