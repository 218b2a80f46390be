"""Identification experiments: the excitation torque and the guard loop around it.

The lever arm is nearly neutrally stable: its gravity torque
(m1 l1 − m2 l2) g cos θ is about −0.02 N·m, so an open-loop torque signal makes
the arm drift to the end stops.  The experiment therefore runs *around a weak
closed loop*:

    u_k = sat( e(t_k) − kp (y_k − θc(t_k)) − kd (ẑ2_k − θ̇c(t_k)) )

* e(t) is a random-phase multisine: ``n_tones`` log-spaced tones from
  ``f_min`` to ``f_max`` [Hz] of equal amplitude, scaled to an RMS of
  ``amplitude`` [N·m] (Schroeder-like phases from ``seed``).  The low tones
  move the arm far enough and slowly enough that Coulomb and viscous friction
  show up with many sign changes of θ̇; the high tones are resisted by the
  inertia alone.
* θc(t) = ``sweep`` · sin(2π t / ``sweep_period``) is a slow setpoint sweep,
  so that cos θ varies and the gravity coefficient is not a constant torque
  indistinguishable from a bias.
* kp, kd [N·m/rad, N·m·s/rad] is the weak stabilizing PD; ẑ2 comes from the
  scenario's own observer kind (``observer.kind``, the same observer as ``esoarm run``,
  stepped by :class:`esoarm.engines.stepper.Stepper`), y is the measured angle.

What the guard loop does to identifiability: the torque u_k that the rig
actually receives is logged, and the fit simulates the rig from the logged
torque, so the loop is identified in open loop (the "direct" method).  The
feedback makes u correlated with past measurement noise; an output-error fit
stays unbiased because its prediction uses only past inputs, and the white
measurement noise at sample k is independent of them.  The PD lowers the
low-frequency angle excursion (and so the information about gravity and
viscous friction) -- keep kp small and the sweep large enough.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from esoarm._limits import MAX_SAMPLES
from esoarm.controllers.flc import saturate
from esoarm.engines.stepper import Stepper
from esoarm.scenario import Scenario, ScenarioError

__all__ = ["ExcitationController", "ExcitationPlan", "excitation_signal", "guard_delay",
           "guard_kd", "guard_margin", "plan_text", "signal_spectrum"]


@dataclass(frozen=True)
class ExcitationPlan:
    """An identification experiment (everything but the rig).

    Attributes
    ----------
    duration : float
        Length of the experiment [s].
    amplitude : float
        RMS of the multisine torque [N·m].
    f_min, f_max : float
        Lowest and highest tone [Hz]; f_max below the Nyquist frequency.
    n_tones : int
        Number of log-spaced tones.
    sweep : float
        Amplitude of the slow setpoint sweep θc [rad].
    sweep_period : float
        Period of the setpoint sweep [s].
    kp : float
        Stabilizing proportional gain [N·m/rad].
    kd : float
        Stabilizing rate gain [N·m·s/rad].
    seed : int
        Seed of the tone phases.
    """

    duration: float = 60.0
    amplitude: float = 0.2
    f_min: float = 0.1
    f_max: float = 5.0
    n_tones: int = 24
    sweep: float = 0.6
    sweep_period: float = 20.0
    kp: float = 1.0
    kd: float = 0.05
    seed: int = 0

    def check(self, ts: float) -> None:
        """Raise :class:`ScenarioError` (one line naming the argument) for a bad plan."""
        nyquist = 0.5 / ts
        checks = [  # (option, value, ok, allowed)
            ("duration", self.duration,
             0 < self.duration and self.duration / ts <= MAX_SAMPLES,
             f"> 0 s and at most {MAX_SAMPLES / (1 / ts):.4g} s ({MAX_SAMPLES:.0e} samples at "
             f"{1 / ts:g} Hz)"),
            ("amplitude", self.amplitude, self.amplitude >= 0, ">= 0 N·m"),
            ("f_min", self.f_min, self.f_min > 0, "> 0 Hz"),
            ("f_max", self.f_max, self.f_min < self.f_max < nyquist,
             f"above f-min and below the Nyquist frequency {nyquist:g} Hz"),
            ("tones", self.n_tones, 1 <= self.n_tones <= max(24, self.resolved_tones()),
             f">= 1 and at most the {self.resolved_tones()} frequencies a {self.duration:g} s "
             f"run resolves from f-min to f-max (1/duration = {1 / self.duration:.3g} Hz "
             "apart)" if self.duration > 0 else ">= 1"),
            ("sweep", self.sweep, self.sweep >= 0, ">= 0 rad"),
            ("sweep_period", self.sweep_period, self.sweep_period > 0, "> 0 s"),
            ("kp", self.kp, self.kp >= 0, ">= 0 N·m/rad"),
            ("kd", self.kd, self.kd >= 0, ">= 0 N·m·s/rad"),
        ]
        for name, value, ok, allowed in checks:
            if not (ok and math.isfinite(float(value))):
                raise ScenarioError(f"{name} {value:g}: must be {allowed}")

    def resolved_tones(self) -> int:
        """How many frequencies 1/duration apart lie in [f_min, f_max] (the DFT bins of the run)."""
        if not (self.duration > 0 and math.isfinite(self.duration * self.f_max)):
            return 0
        return max(0, math.floor(self.f_max * self.duration + 1e-9)
                   - math.ceil(self.f_min * self.duration - 1e-9) + 1)

    def frequencies(self) -> np.ndarray:
        """Tone frequencies [Hz], log-spaced from f_min to f_max."""
        if self.n_tones == 1:
            return np.array([self.f_min])
        return np.geomspace(self.f_min, self.f_max, self.n_tones)

    def phases(self) -> np.ndarray:
        """Tone phases [rad]: uniform random from ``seed`` (low crest factor on average)."""
        return np.random.default_rng(self.seed).uniform(0.0, 2.0 * np.pi, self.n_tones)


def excitation_signal(plan: ExcitationPlan, t: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                     np.ndarray]:
    """The multisine torque e(t) [N·m] and the setpoint θc, θ̇c [rad, rad/s] at times t [s]."""
    freqs, phases = plan.frequencies(), plan.phases()
    tone_amp = plan.amplitude * math.sqrt(2.0 / plan.n_tones)  # RMS of the sum = amplitude
    arg = 2.0 * np.pi * np.outer(t, freqs) + phases
    exc = tone_amp * np.sin(arg).sum(axis=1)
    w = 2.0 * np.pi / plan.sweep_period
    return exc, plan.sweep * np.sin(w * t), plan.sweep * w * np.cos(w * t)


def signal_spectrum(signal: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of a sampled signal: frequencies [Hz], amplitude [N·m]."""
    n = len(signal)
    spec = np.abs(np.fft.rfft(signal)) * 2.0 / max(n, 1)
    return np.fft.rfftfreq(n, ts), spec


#: A plan whose guard loop has less phase margin than this [deg] on the scenario's rig (its
#: transport delay and the hold included) gets a larger rate gain kd (the default plan on
#: test-1 at 50 Hz with viscous friction 0.001 N·m·s/rad: 14.7° without delay and 7.2° with
#: one sample, and ran within the angle limit; with two or three samples it has −0.3° and
#: −7.7° and swung past it).
GUARD_MARGIN_DEG = 5.0
#: ... raised until the margin is at least this [deg].
GUARD_TARGET_DEG = 20.0


def guard_margin(kp: float, kd: float, inertia: float, viscous: float,
                 delay_s: float, lag_s: float = 0.0) -> float:
    """Phase margin [deg] of the guard loop (kp + kd s) e^(−s τ) / ((T s + 1)(I s² + b s)).

    ``inertia`` I [kg·m²], ``viscous`` b [N·m·s/rad], ``delay_s`` τ [s] (transport delay and
    half a sample of hold), ``lag_s`` T [s] (the actuator's first-order lag).  Gravity (a few
    hundredths of a N·m on the lever arm) and Coulomb friction (which only adds damping) are
    left out.  inf when the loop gain never reaches 1.
    """
    w = np.geomspace(1e-3, 1e4, 20000)
    loop = (kp + 1j * kd * w) * np.exp(-1j * w * delay_s) / (
        (lag_s * 1j * w + 1.0) * (inertia * (1j * w) ** 2 + viscous * 1j * w))
    mag = np.abs(loop)
    cross = np.flatnonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))
    if cross.size == 0:
        return math.inf
    phase = np.degrees(np.unwrap(np.angle(loop)))  # from about −90° at the lowest frequency
    return float(min(180.0 + float(phase[i]) for i in cross))


def guard_delay(scn: Scenario) -> float:
    """The delay [s] the guard loop's torque meets: the transport delay and half a sample of
    zero-order hold (the actuator's lag enters :func:`guard_margin` as a lag)."""
    return (scn.actuator.delay_samples + 0.5) * scn.sample_time


def guard_kd(scn: Scenario, plan: ExcitationPlan) -> float:
    """The rate gain [N·m·s/rad] the guard loop runs with: ``plan.kd``, or, when its phase
    margin on the scenario's rig is under :data:`GUARD_MARGIN_DEG` (a transport delay of a
    few samples), the smallest larger kd (steps of 25 %) that gives
    :data:`GUARD_TARGET_DEG`.  Raises :class:`ScenarioError` when no kd up to 100× gives it:
    the plan would swing the arm past its limits; lower kp or the delay."""
    inertia = scn.plant.inertia * scn.rig.inertia_scale
    viscous = scn.rig.viscous_friction
    tau, lag = guard_delay(scn), scn.actuator.lag
    if plan.kp <= 0 or guard_margin(plan.kp, plan.kd, inertia, viscous, tau,
                                    lag) >= GUARD_MARGIN_DEG:
        return plan.kd
    kd = max(plan.kd, 1e-3)
    while kd <= 100.0 * max(plan.kd, 1e-3):
        if guard_margin(plan.kp, kd, inertia, viscous, tau, lag) >= GUARD_TARGET_DEG:
            return kd
        kd *= 1.25
    raise ScenarioError(
        f"kp {plan.kp:g}: the guard loop cannot be kept stable with a delay of "
        f"{scn.actuator.delay_samples} sample(s) ({tau * 1e3:.3g} ms with the hold, lag "
        f"{lag:g} s): its phase margin stays under {GUARD_TARGET_DEG:g}° for every kd; lower kp")


class ExcitationController:
    """The excitation torque plus the guard PD, stepped per sample like the FLC.

    Same interface as :class:`~esoarm.hardware.host_control.DeploymentController`
    (``step``, ``commit``, ``predict``, ``zhat``, ``reference``), so the real-time
    loop drives it unchanged, with all its safety checks.

    Parameters
    ----------
    scn : Scenario
        Rate, torque limit and observer (any registered observer kind, through the
        registry; its b0 from the plant).
    plan : ExcitationPlan
        The experiment.
    """

    def __init__(self, scn: Scenario, plan: ExcitationPlan) -> None:
        from esoarm.studies.identification.data import check_supported

        check_supported(scn, "the identification experiment")
        self.ts = scn.sample_time
        plan.check(self.ts)
        self.plan = plan
        #: The guard loop's rate gain [N·m·s/rad] (:func:`guard_kd`: raised over plan.kd for
        #: a delay that would leave the loop without phase margin).
        self.kd = guard_kd(scn, plan)
        self.n_samples = int(round(plan.duration * scn.sensor.rate_hz))
        t = np.arange(self.n_samples) * self.ts
        self.t = t.tolist()
        exc, ref, dref = excitation_signal(plan, t)
        self._exc, self._ref, self._dref = exc.tolist(), ref.tolist(), dref.tolist()
        self.torque_limit = scn.actuator.torque_limit
        # the scenario's own observer kind, designed at the experiment's rate
        self._obs = Stepper.observer_of(scn, self.ts)
        self.zhat: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def reference(self, k: int) -> float:
        """Setpoint θc(t_k) [rad] of the guard loop."""
        return self._ref[k]

    def excitation(self, k: int) -> float:
        """Multisine torque e(t_k) [N·m]."""
        return self._exc[k]

    def set_signal(self, k: int, exc: float, ref: float, dref: float) -> None:
        """Replace e(t_k) [N·m], θc(t_k) [rad] and θ̇c(t_k) [rad/s] before :meth:`step` ``k``.

        (The breakaway probe of :mod:`esoarm.studies.identification.experiment.probe` decides its
        torque and the multisine's scale as the run goes.)
        """
        self._exc[k], self._ref[k], self._dref[k] = float(exc), float(ref), float(dref)

    def step(self, k: int, y: float) -> float:
        """Torque u_k [N·m] (saturated) from the measured angle y_k [rad].

        Parameters
        ----------
        k : int
            Sample index.
        y : float
            Measured angle y_k [rad].

        Returns
        -------
        float
            The saturated torque u_k [N·m].
        """
        zhat = self._obs.estimate(y)
        self.zhat = (float(zhat[0]), float(zhat[1]), float(zhat[2]))
        p = self.plan
        u = self._exc[k] - p.kp * (y - self._ref[k]) - self.kd * (self.zhat[1] - self._dref[k])
        return float(saturate(u, self.torque_limit))

    def commit(self, u: float) -> None:
        """Advance the observer with the torque u_k [N·m] applied from t_k on.

        Parameters
        ----------
        u : float
            The torque applied [N·m].
        """
        self._obs.observe(u)

    def predict(self, u: float) -> tuple[float, float, float]:
        """Bridge a missing sample (the observer kind's ``predict``).

        Parameters
        ----------
        u : float
            The torque applied from t_k on [N·m].

        Returns
        -------
        tuple of float
            The estimate used for the missing sample [rad, rad/s, rad/s²].
        """
        zhat = self._obs.bridge(u)
        return float(zhat[0]), float(zhat[1]), float(zhat[2])


def plan_text(plan: ExcitationPlan, scn: Scenario, preview: dict | None = None) -> str:
    """The experiment as text: the signal, its spectrum and (optionally) a twin preview."""
    ts = scn.sample_time
    n = int(round(plan.duration * scn.sensor.rate_hz))
    t = np.arange(n) * ts
    exc, ref, _ = excitation_signal(plan, t)
    freqs, amps = signal_spectrum(exc, ts)
    kd = guard_kd(scn, plan)
    margin = guard_margin(plan.kp, plan.kd, scn.plant.inertia * scn.rig.inertia_scale,
                          scn.rig.viscous_friction, guard_delay(scn), scn.actuator.lag)
    lines = [
        f"excitation of '{scn.name}': {plan.duration:g} s at {scn.sensor.rate_hz:g} Hz "
        f"({n} samples), torque limit ±{scn.actuator.torque_limit:g} N·m",
        f"multisine: {plan.n_tones} tones {plan.f_min:g}-{plan.f_max:g} Hz (log-spaced, "
        f"seed {plan.seed}), RMS {np.sqrt(np.mean(exc**2)):.4g} N·m, "
        f"peak {np.max(np.abs(exc)) if n else 0.0:.4g} N·m",
        f"guard loop: u = e(t) − {plan.kp:g}·(y − θc) − {kd:g}·(ẑ2 − θ̇c), "
        f"setpoint sweep θc = {plan.sweep:g}·sin(2π t/{plan.sweep_period:g} s) rad",
        *([f"  kd raised from {plan.kd:g}: with the rig's delay ({guard_delay(scn) * 1e3:.3g} "
           f"ms with the hold) and lag the guard loop had a phase margin of "
           f"{margin:.3g}° (under {GUARD_MARGIN_DEG:g}°)"] if kd != plan.kd else []),
        "spectrum of e(t) (RMS per octave band):",
    ]
    edges = plan.f_min * 2.0 ** np.arange(0, 1 + math.ceil(math.log2(plan.f_max / plan.f_min)))
    bands = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=False):
        band = amps[(freqs >= lo * 0.999) & (freqs < hi * 0.999)]
        bands.append((lo, hi, float(np.sqrt(np.sum(band**2) / 2.0)) if len(band) else 0.0))
    peak = max([b[2] for b in bands] + [1e-12])
    for lo, hi, a in bands:
        lines.append(f"  {lo:7.3g}-{hi:<7.3g} Hz  RMS {a:7.4f} N·m  {'#' * round(40 * a / peak)}")
    if preview:
        lines.append(
            f"on the twin: |θ| up to {preview['max_abs_theta']:.3g} rad, RMS u "
            f"{preview['rms_u']:.3g} N·m, saturated {100 * preview['saturated']:.1f} % of samples")
    return "\n".join(lines)
