"""An excitation that knows when it failed: breakaway probe, stuck share, reversals.

A multisine whose torque stays under the arm's breakaway torque (Coulomb
friction plus stiction plus the gravity torque where it rests) leaves the arm
stuck for long stretches: the log then holds little about inertia and viscous
friction, and a fit to it can look confident and be wrong.  This module makes
the experiment measure that, as it runs, on a rig as on the twin:

* **Probe phase** (:class:`ProbingExcitation`, the first ``probe_s`` seconds):
  with the guard loop holding the setpoint where the arm rests, the
  excitation torque rises geometrically, e_k = e0 · g^k, from
  e0 = :data:`PROBE_START` · torque_limit up to :data:`PROBE_TOP` ·
  torque_limit, first positive, then (in the second half) negative.  The arm
  has *broken away* when it moves faster than the motion threshold h (below)
  per window (below) -- the mean of its last 3 measured angles against
  the mean of the 3 taken a window before (a speed, not a displacement:
  a smoothed friction law lets an arm creep under any torque); the
  breakaway torque of that direction is the applied torque u at the last
  sample at which it moved less than h/2 per window (the onset, not
  the detection, which comes later by the time needed to speed up).  Once it
  has moved, the torque returns to 0 and the guard loop brings the arm back.
* **Scaling**: the multisine's RMS becomes
  a = min(max(amplitude, :data:`BREAKAWAY_FACTOR` · b), torque_limit / crest)
  with b the larger breakaway of the two directions and crest the multisine's
  peak/RMS, so that its peak stays within ``actuator.torque_limit``.  When the
  cap binds (or the arm never broke away) the header and ``--plan`` say so.
* **Motion statistics** (:class:`MotionStats`, over the multisine phase): the
  share of samples at which the arm is *stuck* -- over the last window it
  moved less than h: less than one encoder count, or than the sensor noise
  alone moves it -- and the number of *velocity reversals* (the angle turns
  back by more than 2h from its last extreme: a hysteresis of 2h, so noise at
  rest is not counted).

The window is W = max(:data:`WINDOW`, rate · :data:`WINDOW_S`) samples (5 at
50 Hz, 100 at 1 kHz: 0.1 s, so that the stuck share means the same speed at any
rate), and h = max(q, 3·√2·σ) [rad] with q the encoder count
(``sensor.resolution_deg``) and σ the white noise (``sensor.noise_deg``): the
difference of two noisy readings exceeds 3√2σ with probability 0.3 %.

The log header
--------------
:func:`format_header` writes one comment line before the CSV header of the
log, ``# esoarm excite: key=value key=value ...``, which :func:`read_header`
reads back (a dict of floats; ``nan`` where not measured).  The keys, with
their units, are :data:`HEADER_KEYS`.
"""

from __future__ import annotations

import math
import os
from collections import deque
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from esoarm._limits import MAX_SAMPLES
from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.identification.experiment.excitation import (
    ExcitationController,
    ExcitationPlan,
    excitation_signal,
)

__all__ = ["BREAKAWAY_FACTOR", "HEADER_KEYS", "HEADER_PREFIX", "MotionStats", "ProbeReport",
           "ProbingExcitation", "format_header", "motion_threshold", "probe_text",
           "read_header", "write_header"]

#: Least number of samples over which the motion is measured (stuck or moving) ...
WINDOW = 5
#: ... or over this long [s], whichever holds more samples (a fast sensor's noise needs a
#: longer look to tell slow motion from none).
WINDOW_S = 0.1
#: Target RMS of the multisine in breakaway torques.
BREAKAWAY_FACTOR = 2.0
#: Probe torque at the start of each direction, in torque limits.
PROBE_START = 0.01
#: Largest probe torque, in torque limits.
PROBE_TOP = 0.9
#: Default length of the probe phase [s] (half per direction).
PROBE_SECONDS = 6.0
#: Start of the header line a log of ``esoarm excite`` carries.
HEADER_PREFIX = "# esoarm excite:"
#: The header's keys and what each is (units in brackets).
HEADER_KEYS = {
    "probe_s": "length of the probe phase [s] (0: no probe)",
    "excitation_start_s": "time at which the multisine starts [s]",
    "breakaway_pos": "breakaway torque moving forward [N·m] (nan: not broken away)",
    "breakaway_neg": "breakaway torque moving back, as a magnitude [N·m] (nan: not broken away)",
    "broke_away": "1 if the arm broke away in both directions within the probe, else 0",
    "amplitude_planned": "RMS of the multisine asked for [N·m]",
    "amplitude": "RMS of the multisine applied (after scaling) [N·m]",
    "torque_limit": "actuator.torque_limit [N·m]",
    "limited": "1 if the torque limit kept the multisine below BREAKAWAY_FACTOR × breakaway",
    "share_above_breakaway": "share of the multisine's samples with |e| above the breakaway [1]",
    "threshold_rad": "motion threshold h over `window` samples [rad]",
    "window": "samples over which motion is measured",
    "samples": "samples of the multisine phase measured",
    "stuck_fraction": "share of those samples at which the arm was stuck [1]",
    "reversals": "velocity reversals in the multisine phase",
    "reversals_per_s": "reversals per second of the multisine phase [1/s]",
}


def motion_window(scn: Scenario) -> int:
    """Samples over which motion is measured: max(:data:`WINDOW`, rate · :data:`WINDOW_S`)."""
    return max(WINDOW, int(round(WINDOW_S * scn.sensor.rate_hz)))


def motion_threshold(scn: Scenario) -> float:
    """The motion threshold h [rad] over a window (see the module docstring)."""
    q = math.radians(scn.sensor.resolution_deg)
    sigma = math.radians(scn.sensor.noise_deg)
    return max(q, 3.0 * math.sqrt(2.0) * sigma, 1e-12)


class MotionStats:
    """Stuck share and velocity reversals of a measured angle, updated per sample.

    Parameters
    ----------
    threshold : float
        h [rad]: less motion than this over ``window`` samples is stuck; the
        half the hysteresis of a reversal.
    window : int
        Samples over which the motion is measured.
    """

    def __init__(self, threshold: float, window: int = WINDOW) -> None:
        self.threshold = float(threshold)
        self.window = int(window)
        self._buf: deque[float] = deque(maxlen=self.window + 1)
        self.samples = 0
        self.stuck = 0
        self.reversals = 0
        self._dir = 0
        self._ext = math.nan  # the extreme since the last reversal (the anchor before any)

    def update(self, y: float) -> None:
        """Take the measured angle y_k [rad] (a lost sample, nan, is skipped)."""
        if not math.isfinite(y):
            return
        buf = self._buf
        buf.append(y)
        h = self.threshold
        if len(buf) > self.window:
            self.samples += 1
            self.stuck += abs(buf[-1] - buf[0]) < h
        if self._dir == 0:
            if math.isnan(self._ext):
                self._ext = y
            elif abs(y - self._ext) > 2.0 * h:
                self._dir = 1 if y > self._ext else -1
                self._ext = y
        elif (y - self._ext) * self._dir >= 0:
            self._ext = y
        elif abs(y - self._ext) > 2.0 * h:
            self.reversals += 1
            self._dir = -self._dir
            self._ext = y

    @property
    def stuck_fraction(self) -> float:
        """Share of the measured samples at which the arm was stuck [1] (nan before any)."""
        return self.stuck / self.samples if self.samples else math.nan


@dataclass
class ProbeReport:
    """What the probe found and what the multisine did (the log header's values)."""

    probe_s: float
    excitation_start_s: float
    breakaway_pos: float
    breakaway_neg: float
    amplitude_planned: float
    amplitude: float
    torque_limit: float
    limited: bool
    share_above_breakaway: float
    threshold_rad: float
    window: int
    samples: int = 0
    stuck_fraction: float = math.nan
    reversals: int = 0
    reversals_per_s: float = math.nan

    @property
    def broke_away(self) -> bool:
        """The arm broke away in both directions within the probe."""
        return math.isfinite(self.breakaway_pos) and math.isfinite(self.breakaway_neg)

    def as_dict(self) -> dict[str, float]:
        """The header's key -> value (floats; flags as 0/1)."""
        out: dict[str, float] = {}
        for key in HEADER_KEYS:
            value = getattr(self, key)
            out[key] = float(value)
        return out


class ProbingExcitation:
    """The probe phase, then the scaled multisine, around the guard loop.

    Same per-sample interface as :class:`ExcitationController` (``step``,
    ``commit``, ``predict``, ``zhat``, ``reference``), so the real-time loop
    and the twin drive it unchanged.  The guard loop and its observer are an
    inner :class:`ExcitationController` over the whole run, whose excitation
    and setpoint this class sets sample by sample.

    Parameters
    ----------
    scn : Scenario
        Rate, torque limit, sensor (for the motion threshold), observer.
    plan : ExcitationPlan
        The multisine and the guard loop; ``plan.amplitude`` is the least RMS.
    probe_s : float
        Length of the probe phase [s] (0: none; the multisine keeps
        ``plan.amplitude`` and only the motion statistics are measured).
    """

    def __init__(self, scn: Scenario, plan: ExcitationPlan,
                 probe_s: float = PROBE_SECONDS) -> None:
        rate = scn.sensor.rate_hz
        plan.check(scn.sample_time)
        if not (math.isfinite(probe_s) and 0 <= probe_s
                and (probe_s + plan.duration) * rate <= MAX_SAMPLES):
            raise ScenarioError(f"probe {probe_s:g}: must be >= 0 s, and with the duration at "
                                f"most {MAX_SAMPLES:.0e} samples at {rate:g} Hz")
        self.n_probe = int(round(probe_s * rate))
        self.window = window = motion_window(scn)
        if 0 < self.n_probe < 2 * (window + 5):
            raise ScenarioError(f"probe {probe_s:g} s: at least {2 * (window + 5) / rate:.3g} s "
                                f"at {rate:g} Hz (or 0: no probe)")
        self.plan = plan
        self.inner = ExcitationController(scn, replace(plan, duration=plan.duration + probe_s))
        self.n_samples = self.inner.n_samples
        self.ts = self.inner.ts
        self.t = self.inner.t
        self.torque_limit = self.inner.torque_limit
        t_ms = np.asarray(self.t) - self.n_probe * self.ts
        unit, ref, dref = excitation_signal(replace(plan, amplitude=1.0), t_ms)
        self._unit, self._ref, self._dref = unit.tolist(), ref.tolist(), dref.tolist()
        peak = float(np.max(np.abs(unit[self.n_probe:]))) if self.n_samples > self.n_probe else 1.0
        self._crest = max(peak, 1e-12)
        self.zhat: tuple[float, float, float] = self.inner.zhat  # the guard loop's estimate
        self.threshold = motion_threshold(scn)
        self.stats = MotionStats(self.threshold, window)
        half = self.n_probe // 2
        self._half = half
        top, start = PROBE_TOP * self.torque_limit, PROBE_START * self.torque_limit
        # geometric ramp from start to top over 80 % of each half, then held at the top
        self._growth = (top / start) ** (1.0 / max(1, int(0.8 * half)))
        self._start, self._top = start, top
        self._dir = 0  # probe direction of the current half (+1, -1), 0 before it starts
        self._e = 0.0
        self._y0 = 0.0
        self._hist: list[tuple[float, float]] = []  # (|y − y0|, u) since the half started
        self._u_last = 0.0
        self._found = {1: math.nan, -1: math.nan}
        self._moved = False
        self.amplitude = plan.amplitude
        self.report = ProbeReport(
            probe_s=self.n_probe * self.ts, excitation_start_s=self.n_probe * self.ts,
            breakaway_pos=math.nan, breakaway_neg=math.nan, amplitude_planned=plan.amplitude,
            amplitude=plan.amplitude, torque_limit=self.torque_limit, limited=False,
            share_above_breakaway=math.nan, threshold_rad=self.threshold, window=window)
        if self.n_probe == 0:
            self._scale()

    # -- the SampleController interface -------------------------------------------------------
    def reference(self, k: int) -> float:
        """Setpoint θc(t_k) [rad] of the guard loop."""
        return self.inner.reference(k)

    def excitation(self, k: int) -> float:
        """Excitation torque e(t_k) [N·m] (probe ramp or scaled multisine)."""
        return self.inner.excitation(k)

    def step(self, k: int, y: float) -> float:
        """Torque u_k [N·m] (saturated) from the measured angle y_k [rad]."""
        if k < self.n_probe:
            e, ref = self._probe(k, y)
            self.inner.set_signal(k, e, ref, 0.0)
        else:
            if k == self.n_probe and self.n_probe:
                self._scale()
            self.inner.set_signal(k, self.amplitude * self._unit[k], self._ref[k], self._dref[k])
            self.stats.update(y)
        u = self.inner.step(k, y)
        self.zhat = self.inner.zhat
        self._u_last = u
        return u

    def commit(self, u: float) -> None:
        """Advance the observer with the torque u_k [N·m] applied from t_k on."""
        self._u_last = u
        self.inner.commit(u)

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a missing sample; return the estimate used."""
        return self.inner.predict(u)

    # -- the probe ------------------------------------------------------------------------------
    def _probe(self, k: int, y: float) -> tuple[float, float]:
        """Excitation and setpoint of probe sample k, from the measured angle y_k."""
        direction = 1 if k < self._half else -1
        if direction != self._dir:
            self._dir, self._e, self._moved, self._hist = direction, self._start, False, []
            self._recent: deque[float] = deque(maxlen=self.window + 3)
            self._y0 = y if math.isfinite(y) else self._y0
        if math.isfinite(y):
            self._recent.append(y)
        if not self._moved:
            r = self._recent
            if len(r) == r.maxlen:
                # speed, not displacement (a smoothed friction lets the arm creep): the mean
                # of the last 3 angles against the mean of the 3 taken `window` samples
                # before; the noise of that difference is 0.82 σ, the threshold >= 4.2 σ
                dev = abs((r[-1] + r[-2] + r[-3]) - (r[0] + r[1] + r[2])) / 3.0
                self._hist.append((dev, abs(self._u_last)))
                if dev > self.threshold:
                    self._moved = True
                    onset = [u for d, u in self._hist if d <= 0.5 * self.threshold]
                    self._found[direction] = onset[-1] if onset else abs(self._u_last)
            self._e = 0.0 if self._moved else min(self._e * self._growth, self._top)
        return direction * self._e, self._y0

    def _scale(self) -> None:
        """Set the multisine's RMS from the breakaways (see the module docstring)."""
        pos, neg = self._found[1], self._found[-1]
        rep = self.report
        rep.breakaway_pos, rep.breakaway_neg = pos, neg
        cap = self.torque_limit / self._crest
        if self.n_probe == 0:
            b = math.nan
            amplitude = self.plan.amplitude
        else:
            b = max(pos, neg) if rep.broke_away else math.inf
            amplitude = min(max(self.plan.amplitude, BREAKAWAY_FACTOR * b), cap)
        self.amplitude = amplitude
        rep.amplitude = amplitude
        rep.limited = bool(math.isfinite(b) and BREAKAWAY_FACTOR * b > cap) or math.isinf(b)
        if math.isfinite(b):
            tail = np.abs(np.asarray(self._unit[self.n_probe:])) * amplitude
            rep.share_above_breakaway = float(np.mean(tail > b)) if len(tail) else math.nan
        elif math.isinf(b):
            rep.share_above_breakaway = 0.0

    def finish(self) -> ProbeReport:
        """The report with the motion statistics so far (call after the run, or on a fault)."""
        rep = self.report
        if self.n_probe and math.isnan(rep.breakaway_pos) and math.isnan(rep.breakaway_neg):
            rep.breakaway_pos, rep.breakaway_neg = self._found[1], self._found[-1]
        st = self.stats
        rep.samples, rep.stuck_fraction, rep.reversals = st.samples, st.stuck_fraction, \
            st.reversals
        rep.reversals_per_s = st.reversals / (st.samples * self.ts) if st.samples else math.nan
        return rep


def format_header(report: ProbeReport) -> str:
    """The log's header line (without the newline): ``# esoarm excite: key=value ...``."""
    counts = ("broke_away", "limited", "window", "samples", "reversals")
    parts = [f"{key}={int(value)}" if key in counts else f"{key}={value!r}"
             for key, value in report.as_dict().items()]
    return f"{HEADER_PREFIX} " + " ".join(parts)


def read_header(path: str | Path) -> dict[str, float]:
    """The ``# esoarm excite:`` header of a log as {key: value} ({} when it has none).

    Only comment lines before the CSV header are looked at.  Values that are
    not numbers are skipped; ``nan`` reads as nan.
    """
    out: dict[str, float] = {}
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for line in fh:
                if not line.lstrip().startswith("#"):
                    break
                if line.startswith(HEADER_PREFIX):
                    for part in line[len(HEADER_PREFIX):].split():
                        key, sep, value = part.partition("=")
                        if sep:
                            try:
                                out[key] = float(value)
                            except ValueError:
                                continue
    except (OSError, UnicodeDecodeError):
        return {}
    return out


def write_header(path: str | Path, report: ProbeReport) -> None:
    """Put the header line at the top of the log at ``path`` (replacing one there).

    The rows are copied to a temporary file beside it which then replaces it,
    so the log is whole at every moment (the old one or the new one).
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.header-tmp")
    try:
        with open(path, encoding="utf-8") as src, open(tmp, "w", encoding="utf-8",
                                                        newline="\n") as dst:
            dst.write(format_header(report) + "\n")
            for line in src:
                if line.startswith(HEADER_PREFIX):
                    continue
                dst.write(line)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def probe_text(report: ProbeReport) -> str:
    """What the probe found and what the multisine did, for ``--plan`` and the run's summary."""
    lines = []
    if report.probe_s > 0:
        def fmt(v: float) -> str:
            return f"{v:.3g} N·m" if math.isfinite(v) else "not reached"

        lines.append(f"probe ({report.probe_s:g} s): breakaway {fmt(report.breakaway_pos)} "
                     f"forward, {fmt(report.breakaway_neg)} back (torque limit "
                     f"±{report.torque_limit:g} N·m)")
        scaled = ("kept" if report.amplitude == report.amplitude_planned else
                  f"raised from {report.amplitude_planned:.3g}")
        lines.append(f"multisine RMS {report.amplitude:.3g} N·m ({scaled}; target "
                     f"{BREAKAWAY_FACTOR:g} × breakaway), above the breakaway "
                     f"{100 * report.share_above_breakaway:.0f} % of the time")
        if not report.broke_away:
            lines.append("warning: the arm did not break away in both directions within "
                         f"{PROBE_TOP:g} × actuator.torque_limit: this experiment cannot "
                         "identify friction and inertia; raise actuator.torque_limit if the "
                         "rig allows it")
        elif report.limited:
            lines.append(f"note: actuator.torque_limit caps the multisine's RMS at "
                         f"{report.amplitude:.3g} N·m, below {BREAKAWAY_FACTOR:g} × the "
                         "breakaway")
    if report.samples:
        lines.append(f"motion: stuck {100 * report.stuck_fraction:.0f} % of the multisine's "
                     f"samples (moved < {math.degrees(report.threshold_rad):.3g}° over "
                     f"{report.window} samples), {report.reversals} velocity reversals "
                     f"({report.reversals_per_s:.3g}/s)")
        if report.stuck_fraction > 0.5:
            lines.append("warning: the arm was stuck most of the time: the log says little "
                         "about inertia and viscous friction")
    return "\n".join(lines)
