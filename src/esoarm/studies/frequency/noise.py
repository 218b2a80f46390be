"""Noise budget of the linearized loop: what encoder noise costs in control and error.

The loop of :mod:`esoarm.studies.frequency.linearization` (plant P sampled with the
zero-order hold, controller K = observer + FLC) is closed with the measurement
y_k = θ_k + n_k, n_k white with variance σ² [rad²]::

    x⁺ = A x + B n,   u = Cu x + Du n,   e = Ce x

with x = (plant states, controller states).  The stationary covariance X solves
the discrete Lyapunov equation X = A X Aᵀ + σ² B Bᵀ
(:func:`scipy.linalg.solve_discrete_lyapunov`), and

    var(u)  = Cu X Cuᵀ + σ² Du²
    var(e)  = Ce X Ceᵀ
    var(Δu) = Cu (A − I) X (A − I)ᵀ Cuᵀ + σ² (Cu B − Du)² + σ² Du²

(Δu_k = u_k − u_{k−1}: x_k = A x_{k−1} + B n_{k−1}).  These are the
*noise-driven* parts: the twin's run with noise minus the same run without
(same seed otherwise), in RMS, is what they predict (the loop is linear about the
operating point; friction, saturation and quantization are outside).

The noise model is the scenario's: ``sensor.noise_deg`` white (σ in degrees), or coloured
(:mod:`esoarm.plants.noise`: an AR encoder noise ``sensor.noise_ar`` and an arm vibration
``sensor.vibration_*``).  A coloured noise is the output of its own linear state space
driven by unit white innovations ε (one per process)::

    s⁺ = F s + E ε,     n = H s + J ε

(each AR(p) in companion form, its output scaled to its stationary RMS), and the budget
is that of the loop augmented with s: z = (x, s),

    z⁺ = [[A, B H], [0, F]] z + [[B J], [E]] ε,   u = [Cu, Du H] z + Du J ε,   e = [Ce, 0] z

with the same three formulas (σ² B Bᵀ becoming Bz Bzᵀ, σ² Du² becoming ‖Du J‖²).
The encoder's quantization (``sensor.resolution_deg``) is left out of σ: the twin
quantizes with and without noise, so the difference holds the noise only.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.linalg import solve_discrete_lyapunov

from esoarm.plants.noise import NoiseModel, noise_model, stationary_covariance
from esoarm.scenario import Scenario
from esoarm.studies.frequency.linearization import linearize, motor_damping

__all__ = ["NoiseBudget", "Recommendation", "noise_budget", "noise_state_space",
           "perturbation_bandwidth", "recommend_eps"]


@dataclass(frozen=True)
class NoiseBudget:
    """Predicted RMS of the noise-driven control and error of a scenario's loop.

    Attributes
    ----------
    noise_rms : float
        RMS of the encoder noise [rad] (σ white; the stationary RMS of w when coloured).
    rms_u, rms_du : float
        Noise-driven RMS of u_k and of u_k − u_{k−1} [N·m].
    rms_error : float
        Noise-driven RMS of the angle θ_k (so of the tracking error) [rad].
    u_per_noise : float
        rms_u / σ [N·m/rad], the H2 gain from noise to control (per sample).
    stable : bool
        The closed loop is stable (otherwise every value is inf).
    """

    noise_rms: float
    rms_u: float
    rms_du: float
    rms_error: float
    u_per_noise: float
    stable: bool

    def to_dict(self) -> dict[str, float | bool]:
        """JSON-ready.

        Returns
        -------
        dict
            Every field, non-finite numbers as None.
        """
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)  # type: ignore[misc]
                for k, v in asdict(self).items()}


def noise_budget(scn: Scenario, *, theta0: float | None = None, friction: str = "viscous",
                 noise_rms: float | None = None) -> NoiseBudget:
    """The noise budget of ``scn``'s loop linearized at θ0 (module docstring).

    Parameters
    ----------
    scn : Scenario
        Lever arm with the FLC and any observer kind, without a ``[motor]`` (its
        back-EMF compensation makes the plant's torque differ from u).
    theta0 : float, optional
        Operating angle [rad]; default ``rig.theta0``.
    friction : {"viscous", "slope", "none"}
        Friction in the linear plant (:mod:`esoarm.studies.frequency.linearization`).
    noise_rms : float, optional
        σ [rad] of a white noise; default the scenario's noise model (``sensor.noise_deg``
        in radians, coloured with ``sensor.noise_ar`` / ``sensor.vibration_deg``).

    Returns
    -------
    NoiseBudget
        The noise-driven RMS of u and of Δu [N·m] and of the angle [rad], the noise-to-
        control gain, and whether the loop is stable.

    Raises
    ------
    ValueError
        With a ``[motor]`` table (not modelled here).
    """
    if motor_damping(scn) != 0.0:
        raise ValueError("the noise budget does not model the motor's back-EMF compensation "
                         "(remove [motor] to budget the torque loop)")
    sigma = math.radians(scn.sensor.noise_deg) if noise_rms is None else float(noise_rms)
    model = noise_model(scn)
    coloured = noise_rms is None and not model.white
    lin = linearize(scn, theta0=theta0, friction=friction)
    ap, bp, cp, _ = lin.plant
    ak, bk, ck, dk = lin.controller  # y -> -u
    n_p, n_k = ap.shape[0], ak.shape[0]
    a = np.zeros((n_p + n_k, n_p + n_k))
    a[:n_p, :n_p] = ap - bp @ dk @ cp
    a[:n_p, n_p:] = -bp @ ck
    a[n_p:, :n_p] = bk @ cp
    a[n_p:, n_p:] = ak
    b = np.vstack([-bp @ dk, bk])
    cu = -np.hstack([dk @ cp, ck])
    du = float(-dk[0, 0])
    ce = np.hstack([cp, np.zeros((1, n_k))])
    if np.max(np.abs(np.linalg.eigvals(a))) >= 1.0:
        inf = math.inf
        return NoiseBudget(_rms(model) if coloured else sigma, inf, inf, inf, inf, False)
    if coloured:
        return _coloured_budget(a, b, cu, du, ce, model)
    x = solve_discrete_lyapunov(a, sigma**2 * (b @ b.T))
    var_u = (cu @ x @ cu.T).item() + sigma**2 * du**2
    var_e = (ce @ x @ ce.T).item()
    am = a - np.eye(a.shape[0])
    var_du = ((cu @ am @ x @ am.T @ cu.T).item() + sigma**2 * ((cu @ b).item() - du) ** 2
              + sigma**2 * du**2)
    rms_u = math.sqrt(max(var_u, 0.0))
    return NoiseBudget(sigma, rms_u, math.sqrt(max(var_du, 0.0)), math.sqrt(max(var_e, 0.0)),
                       rms_u / sigma if sigma > 0 else math.nan, True)


def noise_state_space(model: NoiseModel) -> tuple[np.ndarray, ...]:
    """(F, E, H, J) of a coloured noise: s⁺ = F s + E ε, n = H s + J ε, ε unit white.

    One block per process (the AR encoder noise, the vibration): state (a_{k−1}, …,
    a_{k−p}), a_k = φᵀ s_k + ε_k, output g·a_k with g = RMS/√γ(0) (a white encoder noise
    has no state: n = σ ε).

    Parameters
    ----------
    model : NoiseModel
        The measurement disturbance (:func:`esoarm.plants.noise.noise_model`).

    Returns
    -------
    tuple of ndarray
        F (q, q), E (q, m), H (1, q), J (1, m).
    """
    blocks = []
    if model.sigma > 0.0:
        blocks.append((model.ar, model.sigma))
    if model.vibration > 0.0:
        blocks.append((model.vibration_coefficients, model.vibration))
    q = sum(len(phi) for phi, _ in blocks)
    m = len(blocks)
    f, e = np.zeros((q, q)), np.zeros((q, m))
    h, j = np.zeros((1, q)), np.zeros((1, m))
    i = 0
    for col, (phi, rms) in enumerate(blocks):
        p = len(phi)
        if p == 0:
            j[0, col] = rms
            continue
        g = rms / math.sqrt(float(stationary_covariance(phi)[0, 0]))
        f[i, i:i + p] = phi
        f[i + 1:i + p, i:i + p - 1] = np.eye(p - 1)
        e[i, col] = 1.0
        h[0, i:i + p] = g * np.asarray(phi)
        j[0, col] = g
        i += p
    return f, e, h, j


def _rms(model: NoiseModel) -> float:
    return math.hypot(model.sigma, model.vibration)


def _coloured_budget(a: np.ndarray, b: np.ndarray, cu: np.ndarray, du: float, ce: np.ndarray,
                     model: NoiseModel) -> NoiseBudget:
    """The budget of the loop (a, b, cu, du, ce) augmented with the noise's states."""
    f, e, h, j = noise_state_space(model)
    n, q = a.shape[0], f.shape[0]
    az = np.zeros((n + q, n + q))
    az[:n, :n] = a
    az[:n, n:] = b @ h
    az[n:, n:] = f
    bz = np.vstack([b @ j, e])
    cuz = np.hstack([cu, du * h])
    duz = du * j
    cez = np.hstack([ce, np.zeros((1, q))])
    x = solve_discrete_lyapunov(az, bz @ bz.T)
    var_u = (cuz @ x @ cuz.T).item() + float(np.sum(duz**2))
    var_e = (cez @ x @ cez.T).item()
    am = az - np.eye(n + q)
    var_du = ((cuz @ am @ x @ am.T @ cuz.T).item() + float(np.sum((cuz @ bz - duz) ** 2))
              + float(np.sum(duz**2)))
    rms = _rms(model)
    rms_u = math.sqrt(max(var_u, 0.0))
    return NoiseBudget(rms, rms_u, math.sqrt(max(var_du, 0.0)), math.sqrt(max(var_e, 0.0)),
                       rms_u / rms if rms > 0 else math.nan, True)


def perturbation_bandwidth(scn: Scenario) -> float:
    """−3 dB bandwidth [rad/s] of the observer's perturbation estimate f → ẑ3.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario.

    Returns
    -------
    float
        The bandwidth [rad/s]; nan when the gain never falls 3 dB below π/Ts.
    """
    from esoarm.studies.frequency.linearization import freqresp, perturbation_estimate
    from esoarm.studies.frequency.margins import _bandwidth, frequency_grid

    ts = scn.sample_time
    sys = perturbation_estimate(scn)
    return _bandwidth(lambda x: freqresp(sys, np.exp(1j * x * ts)), frequency_grid(ts, 800),
                      1.0 / math.sqrt(2.0))


@dataclass(frozen=True)
class Recommendation:
    """The ε of one observer kind that gives a target perturbation-estimate bandwidth.

    Attributes
    ----------
    kind : str
        Observer kind.
    eps : float
        ε [s] (for the cascade: of its last level, other keys as in the scenario or
        the kind's defaults).
    bandwidth : float
        Its f → ẑ3 bandwidth [rad/s].
    budget : NoiseBudget
        The noise budget at that ε.
    disturbance_peak : float
        Peak gain from a torque disturbance to the error [rad/(N·m)] of the loop at
        that ε: equal f → ẑ3 bandwidths do not mean equal rejection (the cascade's
        estimate lags more), so compare this too.
    """

    kind: str
    eps: float
    bandwidth: float
    budget: NoiseBudget
    disturbance_peak: float


#: The ε range :func:`recommend_eps` searches [s]: from 0.55·Ts (the Euler ESO's
#: stability edge is near Ts/2) up to this.
RECOMMEND_EPS_MAX = 5.0


def recommend_eps(scn: Scenario, bandwidth: float,
                  kinds: tuple[str, ...] | None = None,
                  why: list[str] | None = None) -> list[Recommendation]:
    """For each observer kind, the ε whose f → ẑ3 bandwidth is ``bandwidth`` [rad/s].

    Sorted by the noise-driven RMS Δu of the budget (the first is the recommendation:
    the least control chatter at that disturbance-rejection bandwidth).  A kind that
    cannot reach the bandwidth with ε in [0.55·Ts, :data:`RECOMMEND_EPS_MAX`] (or stay
    stable there) is left out; ``why``, if given, receives one phrase per kind left out,
    with the bandwidths it does reach.

    Parameters
    ----------
    scn : Scenario
        A lever-arm scenario without ``[motor]``.
    bandwidth : float
        The f → ẑ3 bandwidth wanted [rad/s].
    kinds : tuple of str, optional
        The observer kinds to try; default every registered kind that declares
        ``NOISE_BUDGET`` (:func:`esoarm.kinds.having`; the package's: linear, cascade).
    why : list of str, optional
        Receives one phrase per kind left out, with the bandwidths it does reach.

    Returns
    -------
    list of Recommendation
        Per kind that reaches it: ε [s] and its noise budget, least RMS Δu first.
    """
    from scipy.optimize import brentq

    if kinds is None:
        from esoarm.kinds import having

        kinds = having("observer", "NOISE_BUDGET")
    ts = scn.sample_time
    out = []
    for kind in kinds:
        base = scn.with_overrides({"observer.kind": kind}) if scn.observer.kind != kind else scn

        def gap(log_eps: float, base: Scenario = base) -> float:
            bw = perturbation_bandwidth(base.with_overrides({"observer.eps": math.exp(log_eps)}))
            return (bw if math.isfinite(bw) else math.pi / ts) - bandwidth

        lo, hi = math.log(0.55 * ts), math.log(RECOMMEND_EPS_MAX)
        try:
            g_lo, g_hi = gap(lo), gap(hi)
            if g_lo < 0:
                if why is not None:
                    why.append(f"{kind}: at most {g_lo + bandwidth:.3g} rad/s (at the smallest "
                               f"ε = 0.55·Ts = {0.55 * ts:.3g} s; Ts = {ts:g} s: raise "
                               "sensor.rate_hz or ask for less)")
                continue
            if g_hi > 0:
                if why is not None:
                    why.append(f"{kind}: at least {g_hi + bandwidth:.3g} rad/s (at the largest "
                               f"ε searched, {RECOMMEND_EPS_MAX:g} s: ask for more)")
                continue
            eps = math.exp(brentq(gap, lo, hi, xtol=1e-6))
        except (ValueError, np.linalg.LinAlgError) as exc:
            if why is not None:
                why.append(f"{kind}: the bandwidth could not be computed ({exc})")
            continue
        point = base.with_overrides({"observer.eps": eps})
        b = noise_budget(point)
        if not b.stable and why is not None:
            why.append(f"{kind}: reaches it at ε = {eps:.4g} s, but the loop is unstable there")
        if b.stable:
            from esoarm.studies.frequency.margins import analyze

            peak = analyze(point, over_range=False, n_freq=800).disturbance_peak
            out.append(Recommendation(kind, eps, perturbation_bandwidth(point), b, peak))
    return sorted(out, key=lambda r: r.budget.rms_du)
