"""``esoarm identify`` for an axis (plant kind "axis"): IDIM-LS, output error beside it.

1. **IDIM-LS** (:mod:`esoarm.studies.identification.idim`) on the fitting logs:
   M, Fv, Fc, offset (and G for a rotary axis with gravity), 95 % intervals from
   the Newey-West (HAC) covariance.  This is the estimate written into the fitted
   scenario: it needs no simulation, no starting value and no bound, and on a
   log recorded in closed loop -- where the controller keeps the position near
   its reference whatever the parameters -- the force, which the IDM predicts,
   carries the information the position does not.
2. **Consistency**: IDIM-LS on each half of the fitting data; a parameter whose
   halves differ by more than their combined 95 % half-width
   (1.96·√(se₁² + se₂²)) refuses the fit (:class:`AxisFitRefused`, naming the
   parameter and both values).
   The viscous friction is also fitted split by direction (Fv+, Fv−): kept
   when the HAC Wald test of Fv+ − Fv− rejects symmetry at 99 %
   (:func:`~esoarm.studies.identification.idim.asymmetry_threshold`), reported as
   ``viscous_friction_pos``/``_neg`` beside their mean and written as
   ``plant.viscous_asymmetry``.  The Coulomb friction's asymmetry is not
   identifiable apart from the offset (:data:`COULOMB_ASYMMETRY`).
3. **Output error** (:mod:`esoarm.studies.identification.axis.fit`), started from
   and scaled by the IDIM-LS estimate, over ``segment``-long pieces: reported
   beside it, with whether each parameter agrees (within the combined
   interval).  Its intervals cover noise, not model error; when a parameter
   disagrees with IDIM-LS (which does not depend on the segment length) the
   output-error fit is flagged in words and its intervals are withheld
   (``ci95_noise_only``): on EMPS its estimates move with ``--segment`` and
   their intervals would exclude each other.  A gross disagreement (beyond
   :data:`GROSS` combined half-widths and :data:`GROSS_SHARE` of the value)
   refuses the fit: the model explains the force and the motion differently.
4. **Validation** on logs not used for fitting: the benchmark's relative force
   error of the IDIM-LS parameters (cross-test) and the simulated position with
   only each segment's initial state fitted.  A cross-test force error above
   max(2 × the estimation error, estimation + 10 %) refuses the fit.

Sensor noise: the axis's sensor keys are angles [deg]; an axis fit never writes
them.  The residual is reported as model error (its largest autocorrelation
says whether it could be sensor noise at all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from esoarm.plants.axis import units
from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.identification.axis.fit import OeResult, axis_vector, fit_axis_oe
from esoarm.studies.identification.data import IdentLog
from esoarm.studies.identification.idim import (
    IdimResult,
    asymmetry_threshold,
    cross_test,
    idim_ls,
    viscous_asymmetry,
)

__all__ = ["AxisFitRefused", "AxisIdentResult", "GROSS", "identify_axis", "physical_names"]

#: Output error and IDIM-LS further apart than this many combined 95 % half-widths, and
#: than :data:`GROSS_SHARE` of the IDIM-LS value: refused.
GROSS = 3.0
#: See :data:`GROSS`.  The output-error intervals cover noise, not model error, so on real
#: data a few half-widths apart is common (EMPS: the mass 2-3 % apart, 3-8 half-widths);
#: a quarter of the value apart is not a model of this axis.
GROSS_SHARE = 0.25
#: Scenario key of each physical parameter of an axis.
KEYS = {"mass": "plant.mass", "inertia": "plant.mass", "viscous_friction":
        "plant.viscous_friction", "coulomb_friction": "plant.coulomb_friction",
        "offset": "plant.offset", "gravity": "plant.gravity"}


class AxisFitRefused(RuntimeError):
    """The estimate is not trustworthy (one line naming the evidence; nothing is written)."""


def physical_names(motion: str, names: tuple[str, ...]) -> list[str]:
    """The SI names of the IDIM columns: "mass" is "inertia" on a rotary axis."""
    return [("inertia" if n == "mass" and motion == "rotary" else n) for n in names]


def unit_of(motion: str, name: str, input_unit: str = "") -> str:
    """The SI unit of a physical parameter (a direction's friction has its friction's); with
    ``input_unit`` (the logged u in, e.g., V instead of N or N·m) the units that follow from
    it: inertia V·s²/rad, mass V·s²/m, viscous friction V·s/rad, friction and offset V."""
    key = name.removesuffix("_pos").removesuffix("_neg")
    if input_unit:
        per = "rad" if motion == "rotary" else "m"
        return {"mass": f"{input_unit}·s²/{per}", "inertia": f"{input_unit}·s²/{per}",
                "viscous_friction": f"{input_unit}·s/{per}"}.get(key, input_unit)
    return units(motion)[key]


#: What the JSON says of the Coulomb friction's asymmetry.
COULOMB_ASYMMETRY = (
    "not identifiable apart from the offset: on a log that keeps moving, Fc(q̇ > 0) − "
    "Fc(q̇ < 0) and twice the offset add the same force, so the difference between the "
    "directions' Coulomb friction is in 'offset' (plant.coulomb_asymmetry is left as given)")


def _physical(motion: str, est: IdimResult) -> dict:
    """{SI name: {value, ci95, unit}} of an IDIM-LS estimate; with the viscous friction split
    by direction, also its mean ``viscous_friction`` (what plant.viscous_friction holds)."""
    names = physical_names(motion, est.names)
    out = {}
    for i, name in enumerate(names):
        if name == "viscous_friction_pos":
            j = est.names.index("viscous_friction_neg")
            cov = est.cov_hac
            var = (float(cov[i, i] + cov[j, j] + 2.0 * cov[i, j]) / 4.0 if cov is not None
                   else float(est.se_hac[i] ** 2 + est.se_hac[j] ** 2) / 4.0)
            mean = 0.5 * float(est.values[i] + est.values[j])
            half = 1.96 * math.sqrt(max(var, 0.0))
            out["viscous_friction"] = {"value": mean, "ci95": [mean - half, mean + half],
                                       "unit": unit_of(motion, "viscous_friction")}
        out[name] = {"value": float(est.values[i]), "ci95": list(est.ci95(est.names[i])),
                     "unit": unit_of(motion, name)}
    return out


@dataclass
class AxisIdentResult:
    """What :func:`identify_axis` found."""

    scenario: Scenario
    idim: IdimResult
    #: IDIM-LS of the two halves of the motion; empty with one excited stretch (not checked).
    halves: tuple[IdimResult, ...]
    oe: OeResult | None
    validation: dict
    fit_logs: list[str]
    validation_logs: list[str]
    physical: dict = field(default_factory=dict)
    #: The viscous friction's asymmetry Fv+ − Fv− (the Wald test on the split fit):
    #: {difference, ci95, z, threshold_z, kept}; empty when not tested.
    asymmetry: dict = field(default_factory=dict)
    #: Words for what the output-error fit does not support ("" when nothing).
    oe_warning: str = ""

    def fitted_scenario(self) -> Scenario:
        """The scenario with the IDIM-LS estimate as the axis."""
        over: dict[str, object] = {"name": f"{self.scenario.name}-fitted"}
        for key, entry in self.parameters().items():
            over[key] = float(entry["value"])
        return self.scenario.with_overrides(over)

    def parameters(self) -> dict:
        """{scenario key: {value, ci95, unit}}: what the fitted scenario holds."""
        out = {KEYS[n]: {"value": e["value"], "ci95": e["ci95"], "unit": e["unit"]}
               for n, e in self.physical.items() if n in KEYS}
        if self.asymmetry:
            # the Wald test's interval of Fv+ − Fv−; the value is 0 when symmetry was kept
            a = self.asymmetry
            out["plant.viscous_asymmetry"] = {
                "value": a["difference"] if a["kept"] else 0.0, "ci95": a["ci95"],
                "unit": self.physical["viscous_friction"]["unit"]}
        return out

    def to_json(self) -> dict:
        """One JSON object: physical parameters (SI), the methods beside each other, validation."""
        motion = self.scenario.plant.motion
        names = physical_names(motion, self.idim.names)
        oe = None
        if self.oe is not None:
            onames = physical_names(motion, self.oe.names)
            oe = {"segment_s": self.oe.segment_s, "fit_percent": self.oe.fit_percent,
                  "residual_rms": self.oe.residual_rms,
                  "residual_max_autocorrelation": self.oe.max_autocorrelation,
                  "hac_bandwidth_samples": self.oe.bandwidth, "converged": self.oe.converged,
                  "consistent_with_idim_ls": not self.oe_warning,
                  **({"warning": self.oe_warning} if self.oe_warning else {}),
                  "parameters": {
                      onames[i]: {"value": float(self.oe.values[i]),
                                  ("ci95_noise_only" if self.oe_warning else "ci95"):
                                      [float(self.oe.values[i] - self.oe.ci95_half[i]),
                                       float(self.oe.values[i] + self.oe.ci95_half[i])],
                                  "unit": unit_of(motion, onames[i]),
                                  **({"bound": self.oe.at_bound[i]} if self.oe.at_bound[i]
                                     else {}),
                                  "agrees_with_idim_ls": _agree(self.idim, self.oe, i)}
                      for i in range(len(self.oe.names))}}
        return {
            "scenario": self.scenario.name,
            "method": "IDIM-LS (band-pass filtered derivatives, least squares on the inverse "
                      "dynamic model), HAC 95 % intervals; output error beside it",
            "physical": self.physical,
            "parameters": self.parameters(),
            "friction_asymmetry": {"viscous": self.asymmetry or None,
                                   "coulomb": COULOMB_ASYMMETRY},
            "idim_ls": {"force_error_percent": self.idim.force_error,
                        "condition_number": self.idim.condition, "rows": self.idim.n,
                        "decimation": self.idim.decimation, "cutoff_hz": self.idim.cutoff_hz,
                        "hac_bandwidth_rows": self.idim.bandwidth,
                        "residual_max_autocorrelation": self.idim.max_autocorrelation,
                        "ci95_white": {names[i]: [float(self.idim.values[i]
                                                        - 1.96 * self.idim.se_white[i]),
                                                  float(self.idim.values[i]
                                                        + 1.96 * self.idim.se_white[i])]
                                       for i in range(len(names))},
                        "halves": [dict(zip(names, map(float, h.values), strict=True))
                                   for h in self.halves]},
            "output_error": oe,
            "validation": {**self.validation, "logs": self.validation_logs},
            "noise": "not written: the residual is model error (an axis's sensor keys are "
                     "angles and stay as given)",
            "fit_logs": self.fit_logs,
        }


#: A log whose moving samples go the less frequent way less than this share of the time
#: (a step's overshoot) cannot tell the Coulomb friction from the offset.
ONE_WAY_SHARE = 0.1


def _minority_direction(logs: list[IdentLog], ts: float, cutoff_hz: float) -> float:
    """Share of the moving samples (filtered speed ≥ MOVING_SHARE of its peak) that go the
    less frequent way [1]."""
    from esoarm.studies.identification.idim import MOVING_SHARE, filtered_derivatives

    pos = neg = 0
    for lg in logs:
        _q, dq, _ddq = filtered_derivatives(lg.y, ts, cutoff_hz)
        moving = np.abs(dq) >= MOVING_SHARE * float(np.max(np.abs(dq), initial=0.0))
        pos += int(np.sum(moving & (dq > 0)))
        neg += int(np.sum(moving & (dq < 0)))
    return min(pos, neg) / max(pos + neg, 1)


def _peak_speed(logs: list[IdentLog], ts: float, cutoff_hz: float) -> float:
    from esoarm.studies.identification.idim import filtered_derivatives

    return max((float(np.max(np.abs(filtered_derivatives(lg.y, ts, cutoff_hz)[1]),
                             initial=0.0)) for lg in logs), default=0.0)


def _at_rest(validation: list[IdentLog], logs: list[IdentLog], ts: float,
             cutoff_hz: float) -> str:
    """Why the validation data cannot validate ("" if it can): it is at rest -- its peak
    filtered speed below MOVING_SHARE of the fitting data's (the rest after a step, kept
    as the last --validate-fraction of a single log)."""
    from esoarm.studies.identification.idim import MOVING_SHARE

    if not validation:
        return ""
    v, f = _peak_speed(validation, ts, cutoff_hz), _peak_speed(logs, ts, cutoff_hz)
    if f > 0 and v < MOVING_SHARE * f:
        return (f"the validation data ({', '.join(sorted({lg.path for lg in validation}))}) "
                f"is at rest (peak speed {v:.3g}, under {MOVING_SHARE:.0%} of the fitting "
                f"data's {f:.3g}): it carries no motion to validate on; give --validate LOG "
                "with motion")
    return ""


def _collinear(est: IdimResult, a: str, b: str, limit: float = 0.99) -> bool:
    """Whether IDIM-LS cannot tell ``a`` from ``b``: their estimates' correlation (HAC)
    beyond ``limit`` (e.g. Coulomb friction and offset on a motion in one direction)."""
    if est.cov_hac is None or a not in est.names or b not in est.names:
        return False
    i, j = est.names.index(a), est.names.index(b)
    c = est.cov_hac
    den = math.sqrt(max(float(c[i, i] * c[j, j]), 0.0))
    return bool(den > 0 and abs(float(c[i, j])) / den > limit)


def _agree(idim: IdimResult, oe: OeResult, i: int, factor: float = 1.0) -> bool:
    j = idim.names.index(oe.names[i])
    half = math.hypot(1.96 * float(idim.se_hac[j]), float(oe.ci95_half[i]))
    return bool(abs(float(idim.values[j]) - float(oe.values[i])) <= factor * half)


#: Rest between two excited stretches lasts at least this long [s] (shorter pauses, such as a
#: reversal, belong to the stretch).
REST_GAP = 0.2


def _stretches(y: np.ndarray, ts: float, cutoff_hz: float) -> list[tuple[int, int, float]]:
    """The excited stretches of a log: (start, stop, Σ q̇²) of each run of samples where the
    filtered speed is at least MOVING_SHARE of its peak, runs closer than REST_GAP merged."""
    from esoarm.studies.identification.idim import MOVING_SHARE, filtered_derivatives

    _q, dq, _ddq = filtered_derivatives(y, ts, cutoff_hz)
    moving = np.abs(dq) >= MOVING_SHARE * float(np.max(np.abs(dq), initial=0.0))
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return []
    gap = max(1, int(round(REST_GAP / ts)))
    breaks = np.flatnonzero(np.diff(idx) > gap)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks] + 1, [idx[-1] + 1]])
    return [(int(a), int(b), float(np.sum(dq[a:b] ** 2))) for a, b in zip(starts, stops,
                                                                           strict=True)]


def _halves(logs: list[IdentLog], ts: float,
            cutoff_hz: float) -> tuple[list[tuple[np.ndarray, np.ndarray]], ...] | None:
    """The fitting data cut in two between its *excited stretches*, where half of the motion
    (Σ q̇² of the filtered speed) lies; None when it has only one stretch.

    A step followed by rest is one short stretch: its rest carries no information, and the
    tail of its transient alone makes mass, friction and offset collinear, so "halves" of it
    would disagree about nothing; the check is then skipped (and said so).  One stretch that
    is most of the data (a motion that keeps going) is cut where half its motion lies."""
    runs = [(k, a, b, e) for k, lg in enumerate(logs)
            for a, b, e in _stretches(lg.y, ts, cutoff_hz)]
    if len(runs) == 1 and runs[0][2] - runs[0][1] >= 0.5 * logs[runs[0][0]].n:
        # one stretch that is most of the data (a motion that keeps going): cut it where
        # half of its motion lies
        k, a, b, _e = runs[0]
        from esoarm.studies.identification.idim import filtered_derivatives

        _q, dq, _ddq = filtered_derivatives(logs[k].y, ts, cutoff_hz)
        energy = np.cumsum(dq[a:b] ** 2)
        mid = a + int(np.searchsorted(energy, 0.5 * energy[-1]))
        n = logs[k].n
        mid = min(max(mid, n // 4), n - n // 4)
        runs = [(k, a, mid, 0.5), (k, mid, b, 0.5)]
    if len(runs) < 2:
        return None
    total = sum(e for *_r, e in runs)
    acc, cut = 0.0, 1
    for i, (*_r, e) in enumerate(runs[:-1]):
        acc += e
        cut = i + 1
        if acc >= 0.5 * total:
            break
    first, second = [], []
    k_cut, a_cut = runs[cut][0], runs[cut][1]
    b_prev = runs[cut - 1][2] if runs[cut - 1][0] == k_cut else 0
    mid = (b_prev + a_cut) // 2  # in the rest between the two stretches
    for k, lg in enumerate(logs):
        if k < k_cut:
            first.append((lg.y, lg.u))
        elif k > k_cut:
            second.append((lg.y, lg.u))
        else:
            if mid > 0:
                first.append((lg.y[:mid], lg.u[:mid]))
            second.append((lg.y[mid:], lg.u[mid:]))
    from esoarm.studies.identification.idim import BORDER

    if any(len(y) < 4 * BORDER for part in (first, second) for y, _u in part):
        return None  # a stretch too short for the filters' borders
    return first, second


def _negative_friction(physical: dict, motion: str) -> None:
    """A friction that IDIM-LS puts below 0: written as 0 and said so when 0 is inside its
    interval (a friction too small for the log to tell from none), refused when the whole
    interval is below 0 (the model does not describe the axis)."""
    for name in ("coulomb_friction", "viscous_friction"):
        e = physical.get(name)
        if e is None or e["value"] >= 0.0:
            continue
        ci = e.get("ci95")
        if ci is not None and ci[1] < 0.0:
            raise AxisFitRefused(
                f"IDIM-LS gives a negative {name.replace('_', ' ')}: {e['value']:.4g} "
                f"{unit_of(motion, name)}, 95 % [{ci[0]:.4g}, {ci[1]:.4g}], below 0 beyond "
                "its interval: a friction that pushes the axis along is not a model of it "
                "(another force the model lacks, or the input's sign)")
        e["estimate"] = e["value"]
        e["value"] = 0.0
        e["note"] = (f"IDIM-LS gives {e['estimate']:.4g}, below 0 but with 0 inside its 95 % "
                     "interval: the log cannot tell this friction from none; written as 0")


def identify_axis(scn: Scenario, logs: list[IdentLog], validation: list[IdentLog],
                  segment: float = 2.0, validate_fraction: float = 0.25,
                  cutoff: float | None = None) -> AxisIdentResult:
    """Identify the axis of ``scn`` from ``logs`` (see the module docstring).

    Raises
    ------
    ScenarioError
        Bad input: a log at another rate than the scenario, a lost sample.
    AxisFitRefused
        Halves inconsistent, output error grossly off, or validation failed.
    """
    ts = logs[0].ts
    for log in [*logs, *validation]:
        if abs(log.ts - scn.sample_time) > 1e-9 * scn.sample_time:
            from esoarm.studies.identification.identify import rate_mismatch

            raise ScenarioError(rate_mismatch(log.path, log.ts, scn.sensor.rate_hz))
        if np.isnan(log.y).any():
            raise ScenarioError(f"log '{log.path}': lost samples (y = nan); IDIM-LS needs "
                                "every sample (fill or cut them)")
    if not validation and validate_fraction > 0:
        if len(logs) > 1:
            logs, validation = logs[:-1], logs[-1:]
        else:
            cut = int(round(logs[0].n * (1.0 - validate_fraction)))
            logs, validation = [logs[0].part(0, cut)], [logs[0].part(cut, logs[0].n)]
    p = scn.plant
    gravity = p.motion == "rotary" and p.gravity != 0.0
    motion = p.motion
    parts = [(lg.y, lg.u) for lg in logs]
    est = idim_ls(parts, ts, cutoff, gravity=gravity)  # cutoff None: the input's band
    # the viscous friction split by direction, kept when the data support it (Wald, HAC)
    asymmetry: dict = {}
    split = idim_ls(parts, ts, est.cutoff_hz, gravity, asymmetric=True, around=est.around_hz)
    # (tested only when both directions carry the split: a log moving one way makes it
    # ill-conditioned, and its asymmetry meaningless)
    if split.condition <= 100.0 * est.condition:
        diff, se, z = viscous_asymmetry(split)
        z_limit = asymmetry_threshold(split)
        kept = bool(np.isfinite(z) and z > z_limit)
        asymmetry = {"difference": diff, "ci95": [diff - 1.96 * se, diff + 1.96 * se],
                     "z": z, "threshold_z": z_limit, "kept": kept,
                     "force_error_percent": split.force_error,
                     "unit": unit_of(motion, "viscous_friction")}
        if kept:
            est = split
    names = physical_names(motion, est.names)
    split_at = _halves(logs, ts, est.cutoff_hz)
    if split_at is None:  # one excited stretch (a step then rest): nothing to compare
        halves: tuple[IdimResult, ...] = ()
    else:
        halves = tuple(idim_ls(h, ts, est.cutoff_hz, gravity, est.asymmetric) for h in split_at)
    h1, h2 = halves if halves else (est, est)
    for i, name in enumerate(names):
        if name in ("offset", "gravity"):
            continue
        gap = abs(float(h1.values[i] - h2.values[i]))
        half = 1.96 * math.hypot(float(h1.se_hac[i]), float(h2.se_hac[i]))
        if gap > half:
            raise AxisFitRefused(
                f"the halves disagree (IDIM-LS), the estimate is not consistent: {name} is "
                f"{h1.values[i]:.5g} "
                f"{unit_of(motion, name)} on the first half of the fitting data's motion and "
                f"{h2.values[i]:.5g} on the second (apart by {gap:.3g}, more than their "
                f"combined 95 % half-width {half:.3g}): the axis changed during the log, or "
                "the model does not describe it")
    physical = _physical(motion, est)
    _negative_friction(physical, motion)
    oe = fit_axis_oe(logs[0].y, logs[0].u, ts, est, segment, vs=p.friction_velocity,
                     lag=scn.actuator.lag, nsub=scn.substeps)
    oe_warning = ""
    one_way = _collinear(est, "coulomb_friction", "offset") or \
        _minority_direction(logs, ts, est.cutoff_hz) < ONE_WAY_SHARE
    if one_way:
        for key in ("coulomb_friction", "offset"):
            if key in physical:
                physical[key]["ci95"] = None
                physical[key]["withheld"] = ("the axis moves (nearly) one way: only the sum "
                                             "of Coulomb friction and offset is determined")
        oe_warning = ("the axis moves (nearly) one way only: IDIM-LS cannot tell the "
                      "Coulomb friction from the offset (their sum is determined, not each); "
                      "the output error's Coulomb friction is not checked against it")
    for i, name in enumerate(physical_names(motion, oe.names)):
        if name in ("offset", "gravity") or (one_way and name == "coulomb_friction"):
            continue
        j = est.names.index(oe.names[i])
        if oe.at_bound[i]:
            raise AxisFitRefused(f"the output-error fit ended at the bound {oe.at_bound[i]} "
                                 f"for {name} (IDIM-LS: {est.values[j]:.5g} "
                                 f"{unit_of(motion, name)}): the model does not explain the "
                                 "motion")
        if not _agree(est, oe, i, GROSS) and \
                abs(oe.values[i] - est.values[j]) > GROSS_SHARE * abs(est.values[j]):
            raise AxisFitRefused(
                f"the methods disagree: {name} is {est.values[j]:.5g} {unit_of(motion, name)} "
                f"by IDIM-LS and {oe.values[i]:.5g} by output error over {segment:g} s "
                f"segments, more than {GROSS:g}× their combined 95 % half-width and "
                f"{GROSS_SHARE:.0%} apart: the model explains the force and the motion "
                "differently")
        if not oe_warning and not _agree(est, oe, i):
            oe_warning = (
                f"output error over {oe.segment_s:g} s segments gives {name} "
                f"{oe.values[i]:.5g}, IDIM-LS {est.values[j]:.5g} ± "
                f"{1.96 * est.se_hac[j]:.3g} {unit_of(motion, name)}, outside their combined "
                "95 % intervals: the output-error "
                "fit has model error that depends on the segment length, which its intervals "
                "(noise only) do not cover, so they are withheld; the written estimate is "
                "IDIM-LS, which does not depend on --segment")
    val: dict = {"estimation_force_error_percent": est.force_error}
    still = _at_rest(validation, logs, ts, est.cutoff_hz)
    if still:
        val["not_validated"] = still
        validation = []
    if validation:
        errors = [cross_test(lg.y, lg.u, ts, est.values, est.cutoff_hz, gravity,
                             est.asymmetric)
                  for lg in validation]
        cross = float(max(errors))
        val["cross_test_force_error_percent"] = cross
        limit = max(2.0 * est.force_error, est.force_error + 10.0)
        val["cross_test_limit_percent"] = limit
        if cross > limit:
            raise AxisFitRefused(
                f"validation failed: the relative force error on the validation log is "
                f"{cross:.3g} % against {est.force_error:.3g} % on the fitting data (at most "
                f"{limit:.3g} %): the estimate does not carry over")
        sim = _simulated_validation(validation[0], ts, est, segment, p.friction_velocity,
                                    scn.actuator.lag, scn.substeps)
        val.update(sim)
    val["halves"] = ("compared: the fitting data cut between its excited stretches at half "
                     "its motion" if halves else "not compared: the fitting data has one "
                     "excited stretch (a step then rest), fitted on its motion only")
    return AxisIdentResult(scn, est, halves, oe, val, sorted({lg.path for lg in logs}),
                           sorted({lg.path for lg in validation}), physical, asymmetry,
                           oe_warning)


def _simulated_validation(log: IdentLog, ts: float, est: IdimResult, segment: float,
                          vs: float, lag: float, nsub: int) -> dict:
    """The IDIM-LS axis simulated over the validation log's segments (initial states fitted)."""
    from esoarm.studies.identification.axis.fit import segment_bounds, simulate_axis_segments
    from esoarm.studies.identification.idim import filtered_derivatives

    seg_n = max(5, int(round(segment / ts)))
    seg_start, seg_len = segment_bounds(log.n, seg_n)
    q, dq, _ = filtered_derivatives(log.y, ts, 0.1 / ts)
    x0 = np.empty(2 * len(seg_start))
    x0[0::2], x0[1::2] = q[seg_start], dq[seg_start]
    out = np.empty(log.n)
    simulate_axis_segments(out, axis_vector(est.names, est.values), vs, lag, log.u, seg_start,
                           seg_len, x0, ts / nsub, nsub)
    r = log.y - out
    fit = float(100.0 * (1.0 - np.linalg.norm(r) / np.linalg.norm(log.y - log.y.mean())))
    return {"simulated_fit_percent": fit, "simulated_residual_rms": float(np.sqrt(np.mean(r**2))),
            "simulated_segment_s": seg_n * ts}
