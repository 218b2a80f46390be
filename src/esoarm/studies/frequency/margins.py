"""Frequency-domain analysis of the sampled-data loop (``esoarm analyze``).

The loop of :mod:`esoarm.studies.frequency.linearization` (the rig linearized at θ0 and
sampled with the zero-order hold, the lag and the delay; the ESO + FLC as one
discrete controller K) is analyzed at the sample period Ts.

Loop, margins and sensitivities
    L(z) = K(z) P(z), the loop transfer broken at the plant input;
    ``control.feedback(L, 1)`` is the closed loop T = L/(1+L), S = 1/(1+L).
    Margins follow python-control's conventions: the gain margin is the loop
    gain factor closest to 1 (in log) at which the Nyquist curve passes through
    −1 (a ratio, not dB), the phase margin [deg] the smallest |180° + ∠L| at a
    gain crossover, the delay margin [s] the smallest PM/ω over the gain
    crossovers ω [rad/s] with positive phase margin.  All frequencies are in
    rad/s, up to the Nyquist frequency π/Ts.

Motor
    With a ``[motor]`` table its linear part (back-EMF damping, the host's
    back-EMF compensation) is in the loop; what is left out is named in
    ``FrequencyAnalysis.motor`` and by :func:`motor_note`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from esoarm.plants.actuator import motor_of
from esoarm.scenario import Scenario
from esoarm.studies.frequency.linearization import (
    LinearLoop,
    _load,
    closed_loop_matrix,
    closed_loop_radius,
    freqresp,
    linearize,
    observer_linearization,
    perturbation_estimate,
)

__all__ = ["FrequencyAnalysis", "Margins", "analyze", "frequency_grid", "freqresp_dc",
           "left_out_notes", "margins", "motor_note", "motor_terms"]


# ---------------------------------------------------------------------------
# margins and figures of merit


def frequency_grid(ts: float, n: int = 2000, lowest: float | None = None) -> np.ndarray:
    """Log-spaced frequencies [rad/s] up to the Nyquist frequency π/Ts (included).

    Parameters
    ----------
    ts : float
        Sample time Ts [s].
    n : int
        Number of frequencies.
    lowest : float, optional
        The first frequency [rad/s]; default 1e-5 π/Ts.

    Returns
    -------
    ndarray, shape (n,)
        The frequencies [rad/s], ascending.
    """
    wn = math.pi / ts
    lo = wn * 1e-5 if lowest is None else lowest
    return np.geomspace(lo, wn, n)


@dataclass(frozen=True)
class Margins:
    """Stability margins of a discrete loop transfer.

    Attributes
    ----------
    gain_margin : float
        Ratio (not dB); ``inf`` when the phase never crosses −180°.
    gain_crossover_phase : float
        Frequency [rad/s] of the −180° crossing that sets the gain margin.
    phase_margin : float
        Degrees; ``inf`` without a gain crossover.
    gain_crossover : float
        Frequency [rad/s] where |L| = 1 that sets the phase margin.
    delay_margin : float
        Seconds: the smallest PM/ω over the gain crossovers.
    """

    gain_margin: float
    phase_crossover: float
    phase_margin: float
    gain_crossover: float
    delay_margin: float


def margins(lin: LinearLoop, w: np.ndarray | None = None) -> Margins:
    """Gain, phase and delay margins of ``lin.loop`` (module docstring conventions).

    Crossings are bracketed on a dense log grid up to π/Ts and refined with
    Brent's method; the loop is real, so the Nyquist frequency itself is a
    −180° crossing whenever L(−1) < 0.

    Parameters
    ----------
    lin : LinearLoop
        The loop linearized (:func:`~esoarm.studies.frequency.linearization.linearize`).
    w : ndarray, optional
        The frequency grid [rad/s] that brackets the crossings; default
        :func:`frequency_grid`.

    Returns
    -------
    Margins
        Gain margin, phase margin [deg], delay margin [s] and their crossover
        frequencies [rad/s].
    """
    ts = lin.ts
    w = frequency_grid(ts) if w is None else w

    def resp(x: float) -> complex:
        return complex(lin.response("loop", np.array([x]))[0])

    big = lin.response("loop", w)
    mag = np.abs(big)
    # −180° crossings: Im L changes sign where Re L < 0
    w180: list[float] = []
    for i in np.nonzero(np.diff(np.sign(big.imag)))[0]:
        x = brentq(lambda x: resp(x).imag, w[i], w[i + 1], xtol=1e-14, rtol=1e-13)
        if resp(x).real < 0:
            w180.append(x)
    wn = math.pi / ts
    if resp(wn).real < 0 and (not w180 or abs(w180[-1] - wn) > 1e-9 * wn):
        w180.append(wn)
    gm, wpc = math.inf, math.nan
    if w180:
        gms = np.array([1.0 / abs(resp(x)) for x in w180])
        best = int(np.argmin(np.abs(np.log(gms))))
        gm, wpc = float(gms[best]), float(w180[best])
    # gain crossovers
    pm, wgc, dm = math.inf, math.nan, math.inf
    for i in np.nonzero(np.diff(np.sign(mag - 1.0)))[0]:
        x = brentq(lambda x: abs(resp(x)) - 1.0, w[i], w[i + 1], xtol=1e-14, rtol=1e-13)
        phase = math.degrees(np.angle(resp(x)))
        pm_i = (phase % 360.0) - 180.0
        if abs(pm_i) < abs(pm):
            pm, wgc = pm_i, x
        if pm_i > 0:
            dm = min(dm, math.radians(pm_i) / x)
    return Margins(gm, wpc, pm, wgc, dm)


def _peak(fun: Any, w: np.ndarray) -> tuple[float, float]:
    """Maximum of |fun(w)| on the grid, refined locally; (peak, frequency [rad/s])."""
    vals = np.abs(fun(w))
    i = int(np.argmax(vals))
    lo, hi = w[max(i - 1, 0)], w[min(i + 1, len(w) - 1)]
    if hi > lo:
        res = minimize_scalar(lambda x: -abs(fun(np.array([x]))[0]), bounds=(lo, hi),
                              method="bounded", options={"xatol": 1e-10 * hi})
        if -res.fun > vals[i]:
            return float(-res.fun), float(res.x)
    return float(vals[i]), float(w[i])


def _bandwidth(fun: Any, w: np.ndarray, level: float) -> float:
    """First frequency [rad/s] where |fun| falls below ``level`` (nan if it never does)."""
    vals = np.abs(fun(w)) - level
    below = np.nonzero(vals < 0)[0]
    if len(below) == 0:
        return math.nan
    i = int(below[0])
    if i == 0:
        return float(w[0])
    return float(brentq(lambda x: abs(fun(np.array([x]))[0]) - level, w[i - 1], w[i]))


@dataclass(frozen=True)
class FrequencyAnalysis:
    """Figures of merit of one linearized loop (see :func:`analyze`)."""

    scenario: str
    theta0: float
    friction: str
    ts: float
    nyquist: float
    stable: bool
    closed_loop_radius: float
    gain_margin: float
    phase_crossover: float
    phase_margin: float
    gain_crossover: float
    delay_margin: float
    ms: float
    ms_frequency: float
    mt: float
    mt_frequency: float
    closed_loop_bandwidth: float
    observer_bandwidth: float
    observer_pole_frequency: float
    noise_to_control_peak: float
    noise_to_control_frequency: float
    disturbance_peak: float
    disturbance_peak_frequency: float
    disturbance_dc: float
    disturbance_at_scenario: float
    scenario_disturbance_error: float
    eps: float
    discretization: str
    observer: str = "linear"
    observer_label: str = "ESO"
    range: dict[str, Any] = field(default_factory=dict)
    motor: dict[str, Any] = field(default_factory=dict)
    curves: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: no curves, non-finite numbers as None.

        Returns
        -------
        dict
            Every field but ``curves``.
        """
        out = {k: v for k, v in asdict(self).items() if k != "curves"}
        return _clean(out)  # type: ignore[no-any-return]


#: What a ``[motor]`` table adds that the linear loop leaves out.
MOTOR_LEFT_OUT = ("deadband", "pwm_quantization", "supply_saturation")


def motor_terms(scn: Scenario) -> dict[str, Any]:
    """The motor's terms in the analysis ({} without a ``[motor]`` table).

    ``damping`` (N·Kt)²/R [N·m·s/rad], in the plant and, as the host's
    compensation Dm·ẑ2, in the controller; ``stall_torque`` N·Kt·Vs/R [N·m],
    the supply's limit at rest; ``pwm_step`` the arm torque of one duty count
    after the deadband pre-compensation, N·Kt·Vs/(R·(1 − δ)·pwm_max) [N·m];
    ``deadband`` δ; ``left_out`` the nonlinear parts (:data:`MOTOR_LEFT_OUT`).

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    dict
        The terms above by name.
    """
    m = motor_of(scn)
    if m is None:
        return {}
    return {"damping": m.damping, "stall_torque": m.stall_gain,
            "pwm_step": m.stall_gain / ((1.0 - m.deadband) * m.pwm_max),
            "deadband": m.deadband, "left_out": list(MOTOR_LEFT_OUT)}


def motor_note(a: FrequencyAnalysis, values: bool = True) -> str:
    """One line: the motor's linear terms in the loop and what is left out ('' without one).

    Parameters
    ----------
    a : FrequencyAnalysis
        An analysis (:func:`analyze`).
    values : bool
        Quote the terms' values (damping [N·m·s/rad], PWM step [N·m]); False: words only.

    Returns
    -------
    str
    """
    m = a.motor
    if not m:
        return ""
    if not values:
        return ("motor: the back-EMF damping (N·Kt)²/R is in the plant and the host's "
                "compensation +(N·Kt)²/R·ẑ2 in the controller; left out (nonlinear): the driver "
                "deadband (pre-compensated by the host), the PWM quantization, the supply "
                "saturation")
    return (f"motor: back-EMF damping (N·Kt)²/R = {m['damping']:.4g} N·m·s/rad in the plant "
            f"and the host's compensation +{m['damping']:.4g}·ẑ2 in the controller; left out "
            f"(nonlinear): the driver deadband {m['deadband']:g} (pre-compensated by the host), "
            f"the PWM quantization ({m['pwm_step']:.3g} N·m per duty count at the arm), the "
            f"supply saturation (|u + {m['damping']:.4g}·ẑ2| ≤ {m['stall_torque']:.4g} N·m)")


def eso_label(a: FrequencyAnalysis) -> str:
    """The observer kind's name for its linear model.

    Parameters
    ----------
    a : FrequencyAnalysis
        An analysis (:func:`analyze`).

    Returns
    -------
    str
        "ESO"; the nonlinear kind adds the zone the linear analysis holds in.
    """
    return a.observer_label


def _clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def analyze(scenario: Scenario | str | Path = "test-1", overrides: dict | list[str] | None = None,
            *, theta0: float | None = None, friction: str = "viscous",
            over_range: bool = True, n_freq: int = 2000) -> FrequencyAnalysis:
    """Margins, sensitivities, bandwidths and disturbance rejection of a scenario's loop.

    Parameters
    ----------
    scenario, overrides
        As for :func:`esoarm.simulate`.
    theta0 : float, optional
        Operating angle [rad] of the linearization; default ``rig.theta0``.
    friction : {"viscous", "slope", "none"}
        Friction model (module docstring).
    over_range : bool
        Also linearize at 5 angles spanning the reference's range and report
        the worst margins there (``range``).
    n_freq : int
        Points of the log frequency grid up to π/Ts.

    Returns
    -------
    FrequencyAnalysis
        Frequencies in rad/s; ``gain_margin`` a ratio, ``phase_margin`` in
        degrees, ``delay_margin`` in s; ``disturbance_*`` gains from a torque
        added at the plant input to the tracking error [rad/(N·m)];
        ``scenario_disturbance_error`` the steady-state error amplitude [rad]
        the linear loop predicts for the scenario's sine disturbance;
        ``noise_to_control_peak`` the largest gain from measurement noise to
        the control, max |K S| [N·m/rad] (what a small ε costs).
    """
    scn = _load(scenario, overrides)
    lin = linearize(scn, theta0=theta0, friction=friction)
    ts = lin.ts
    wn = math.pi / ts
    w = frequency_grid(ts, n_freq)
    zs = np.exp(1j * w * ts)
    L = freqresp(lin.loop, zs)
    P = freqresp(lin.plant, zs)
    sens = 1.0 / (1.0 + L)
    comp = L / (1.0 + L)
    dist = P / (1.0 + L)
    mg = margins(lin, w)
    radius = closed_loop_radius(lin.plant, lin.controller)

    def s_fun(x: np.ndarray) -> np.ndarray:
        return 1.0 / (1.0 + lin.response("loop", x))

    def t_fun(x: np.ndarray) -> np.ndarray:
        lx = lin.response("loop", x)
        return lx / (1.0 + lx)

    def d_fun(x: np.ndarray) -> np.ndarray:
        return lin.response("plant", x) / (1.0 + lin.response("loop", x))

    fest = perturbation_estimate(scn)

    def f_fun(x: np.ndarray) -> np.ndarray:
        return freqresp(fest, np.exp(1j * x * ts))

    ms, w_ms = _peak(s_fun, w)
    mt, w_mt = _peak(t_fun, w)
    dpk, w_dpk = _peak(d_fun, w)

    def n_fun(x: np.ndarray) -> np.ndarray:
        return lin.response("controller", x) / (1.0 + lin.response("loop", x))

    npk, w_npk = _peak(n_fun, w)
    dist_w = scn.rig.disturbance.frequency
    inertia = scn.rig.inertia_scale * scn.plant.inertia
    d_at = float(abs(d_fun(np.array([dist_w]))[0])) if 0 < dist_w < wn else math.nan
    d_dc = float(abs(freqresp_dc(lin)))
    olin = observer_linearization(scn)  # the kind's model, its design pole
    pole = olin.pole
    pole_freq = -math.log(abs(pole)) / ts if pole != 0 else math.inf
    rng: dict[str, Any] = {}
    if over_range:
        rng = _over_range(scn, friction, n_freq)
    return FrequencyAnalysis(
        scenario=scn.name, theta0=lin.theta0, friction=friction, ts=ts, nyquist=wn,
        stable=bool(radius < 1.0), closed_loop_radius=radius,
        gain_margin=mg.gain_margin, phase_crossover=mg.phase_crossover,
        phase_margin=mg.phase_margin, gain_crossover=mg.gain_crossover,
        delay_margin=mg.delay_margin, ms=ms, ms_frequency=w_ms, mt=mt, mt_frequency=w_mt,
        closed_loop_bandwidth=_bandwidth(t_fun, w, 1.0 / math.sqrt(2.0)),
        observer_bandwidth=_bandwidth(f_fun, w, 1.0 / math.sqrt(2.0)),
        observer_pole_frequency=pole_freq,
        noise_to_control_peak=npk, noise_to_control_frequency=w_npk,
        disturbance_peak=dpk, disturbance_peak_frequency=w_dpk, disturbance_dc=d_dc,
        disturbance_at_scenario=d_at,
        scenario_disturbance_error=d_at * inertia * abs(scn.rig.disturbance.amplitude),
        eps=olin.eps, discretization=olin.discretization,
        observer=scn.observer.kind, observer_label=olin.label, range=rng, motor=motor_terms(scn),
        curves={"w": w, "loop": L, "sensitivity": sens, "complementary": comp,
                "disturbance": dist, "perturbation_estimate": f_fun(w)},
    )


def freqresp_dc(lin: LinearLoop) -> complex:
    """Input-disturbance-to-error gain at z = 1 [rad/(N·m)] (0 with integral action).

    Evaluated from the closed loop's state matrices, so plant poles at z = 1
    (the double integrator) are handled: e = θ for the input (0, …) at the
    plant input, i.e. C_cl (I − A_cl)⁻¹ B_cl.

    Parameters
    ----------
    lin : LinearLoop
        The loop linearized.

    Returns
    -------
    complex
        The gain [rad/(N·m)] (inf where I − A_cl is singular).
    """
    ap, bp, cp, _ = lin.plant
    a_cl = closed_loop_matrix(lin.plant, lin.controller)
    n = a_cl.shape[0]
    b_cl = np.zeros((n, 1))
    b_cl[: ap.shape[0]] = bp
    c_cl = np.zeros((1, n))
    c_cl[:, : ap.shape[0]] = cp
    try:
        return complex((c_cl @ np.linalg.solve(np.eye(n) - a_cl, b_cl))[0, 0])
    except np.linalg.LinAlgError:
        return complex(math.inf)


def _over_range(scn: Scenario, friction: str, n_freq: int) -> dict[str, Any]:
    """Margins at 5 angles over the reference's range [rad] (min over them)."""
    from esoarm.reference import evaluate_reference

    t = np.arange(scn.n_samples) * scn.sample_time
    ref = evaluate_reference(scn.reference, t)[0]  # type: ignore[arg-type]  # lever: one joint
    lo, hi = float(np.min(ref)), float(np.max(ref))
    angles = np.linspace(lo, hi, 5) if hi > lo else np.array([lo])
    w = frequency_grid(scn.sample_time, n_freq // 2)
    rows = []
    for th in angles:
        lin = linearize(scn, theta0=float(th), friction=friction)
        mg = margins(lin, w)
        rows.append((mg.gain_margin, mg.phase_margin, mg.delay_margin))
    arr = np.array(rows)
    return {"theta_min": lo, "theta_max": hi, "angles": [float(a) for a in angles],
            "gain_margin_min": float(np.min(arr[:, 0])),
            "phase_margin_min": float(np.min(arr[:, 1])),
            "delay_margin_min": float(np.min(arr[:, 2]))}


def left_out_notes(scn: Scenario) -> list[str]:
    """What of the scenario's rig the linear model leaves out, beyond the motor's (one line each).

    Parameters
    ----------
    scn : Scenario
        The scenario analyzed.

    Returns
    -------
    list of str
        Empty when the linear model holds all of it (saturation, quantization and noise
        are left out always, as the help says).
    """
    out = []
    backlash = getattr(scn.rig, "backlash_deg", 0.0)
    if backlash > 0:
        out.append(f"left out (nonlinear): the gear backlash rig.backlash_deg = {backlash:g}° "
                   "(a dead zone of the two-mass drive train): the linear model takes a rigid "
                   "gear; simulate or sweep the scenario to see what the play costs")
    cog = getattr(scn.rig, "cogging", None)
    if cog is not None and cog.amplitude != 0.0:
        out.append(f"left out: the cogging torque rig.cogging (A = {cog.amplitude:g} N·m, "
                   f"{cog.periods:g} periods a turn), linearized a spring of up to A·n = "
                   f"{abs(cog.amplitude) * cog.periods:.3g} N·m/rad that the linear model does "
                   "not hold; simulate or sweep the scenario to see what it costs")
    table = getattr(scn.controller, "feedforward_map", None)
    if table:
        # the drive's −I0·m(ẑ1): between nodes 2π/N apart, a slope of I0·Δm·N/(2π)
        n = len(table)
        slope = max(abs(table[(i + 1) % n] - table[i]) for i in range(n)) * n / (2 * math.pi)
        out.append(f"left out: the learned feedforward table controller.feedforward_map ({n} "
                   f"bins), in the drive and not seen by the ESO, a feedback on ẑ1 of up to "
                   f"I0·{slope:.3g} = {scn.plant.inertia * slope:.3g} N·m/rad: the margins are "
                   "the loop's without it; simulate or sweep the scenario to see it")
    stops = getattr(scn.rig, "end_stops", None)
    if stops:
        gate = getattr(scn.actuator, "stop_gate", 0.0)
        out.append(f"left out (nonlinear): the hard end stops rig.end_stops = "
                   f"[{min(stops):g}, {max(stops):g}] rad"
                   + (f" and the ESO's gate actuator.stop_gate = {gate:g} rad" if gate else "")
                   + ": the linear model holds away from them")
    return out
