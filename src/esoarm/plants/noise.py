"""Coloured measurement noise: an AR encoder noise and a band-limited arm vibration.

The encoder reading of sample k is y_k = Q(θ(t_k) + w_k) (:mod:`esoarm.plants.sensor`),
where the measurement disturbance w_k [rad] of each joint is the sum of two independent,
zero-mean, stationary Gaussian processes:

encoder noise (``sensor.noise_deg`` = σ, ``sensor.noise_ar`` = [φ1, …, φp])
    a_k = φ1·a_{k−1} + … + φp·a_{k−p} + e_k,    e_k ~ N(0, 1) white,

    n_k = σ · a_k / √γ_a(0),

    an autoregressive AR(p) process scaled so that its *stationary standard deviation*
    is σ whatever the coefficients (γ_a(0) is the variance of a with unit innovation).
    ``noise_ar = []`` (p = 0) is white noise, the historical model: n_k = σ e_k.
    The innovation standard deviation of n is σ/√γ_a(0).

arm vibration (``sensor.vibration_deg`` = σ_v, ``vibration_hz`` = f0, ``vibration_damping`` = ζ)
    a lightly damped mode driven by white noise, sampled: the impulse-invariant AR(2)
    of the resonance s² + 2ζω0 s + ω0² (ω0 = 2π f0), poles z = exp(s Ts):

    v_k = 2r·cos(ωd Ts)·v_{k−1} − r²·v_{k−2} + e'_k,   r = exp(−ζ ω0 Ts),
    ωd = ω0 √(1 − ζ²),

    scaled to RMS σ_v.  Its spectrum peaks near f0 with a −3 dB width of about 2ζ f0
    [Hz]; f0 must be below the Nyquist frequency rate_hz/2 (a mode above it is seen
    at its alias, which is the frequency to give).

w_k = n_k + σ_v · v_k / √γ_v(0).

Both processes start in their stationary distribution (the state of the previous p
samples drawn from the stationary covariance, so the variance is the same from sample 0)
and every joint has its own processes.  Seeding: the innovations e_k are exactly the
draws of the white model, ``numpy.random.default_rng(seed).standard_normal``, joint index
fastest; the vibration's innovations come from ``default_rng([seed, 1])`` and the
stationary initial states from ``default_rng([seed, 2])`` (AR states then vibration
states, joint by joint).  The sequence is built once per run by :func:`draws` (every
engine takes it) or sample by sample by :class:`NoiseStream` (the emulated rig), one
recurrence written once (:meth:`NoiseStream.next`), so both give the same bits.

The engines scale the sequence they are given by :func:`sequence_scale`: σ for the white
model (they are given the standard-normal draws), 1 otherwise (they are given w in rad).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from esoarm.plants.sensor import noise_sequence

if TYPE_CHECKING:
    from esoarm.scenario import Scenario

__all__ = ["MAX_AR_ORDER", "NoiseModel", "NoiseStream", "ar_autocovariance", "ar_spectrum",
           "check_noise", "draws", "noise_model", "sequence_scale", "stationary_covariance",
           "vibration_ar"]

#: Longest AR polynomial accepted for ``sensor.noise_ar``.
MAX_AR_ORDER = 20
#: Largest pole modulus accepted: a process this close to a random walk is not a noise.
MAX_POLE = 0.999


class NoiseModel(NamedTuple):
    """The measurement disturbance of one joint (see the module docstring).

    Attributes
    ----------
    sigma : float
        Stationary standard deviation σ of the encoder noise [rad].
    ar : tuple of float
        AR coefficients φ1 … φp of the encoder noise [1] (empty: white).
    vibration : float
        RMS σ_v of the arm vibration [rad] (0: none).
    vibration_hz : float
        Natural frequency f0 of the vibration mode [Hz].
    vibration_damping : float
        Damping ratio ζ of the vibration mode [1].
    ts : float
        Sample period Ts [s].
    """

    sigma: float
    ar: tuple[float, ...]
    vibration: float
    vibration_hz: float
    vibration_damping: float
    ts: float

    @property
    def white(self) -> bool:
        """True for the historical model: white encoder noise (or none) and no vibration."""
        return (not self.ar or self.sigma == 0.0) and self.vibration == 0.0

    @property
    def vibration_coefficients(self) -> tuple[float, float]:
        """(φ1, φ2) of the vibration's AR(2) (:func:`vibration_ar`)."""
        return vibration_ar(self.vibration_hz, self.vibration_damping, self.ts)

    @property
    def key(self) -> tuple[float, ...] | None:
        """What the sequence depends on besides seed and length (None for the white model)."""
        if self.white:
            return None
        return (self.sigma, *self.ar, math.nan, self.vibration, self.vibration_hz,
                self.vibration_damping, self.ts)


def noise_model(scn: Scenario) -> NoiseModel:
    """The scenario's measurement disturbance (``[sensor]`` keys, degrees made radians).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    NoiseModel
        σ [rad], φ, σ_v [rad], f0 [Hz], ζ, Ts [s].
    """
    s = scn.sensor
    return NoiseModel(math.radians(s.noise_deg), tuple(float(a) for a in s.noise_ar),
                      math.radians(s.vibration_deg), float(s.vibration_hz),
                      float(s.vibration_damping), scn.sample_time)


def vibration_ar(f0: float, zeta: float, ts: float) -> tuple[float, float]:
    """AR(2) coefficients of a resonance f0 [Hz], damping ζ, sampled every ts [s].

    Impulse invariance: the continuous poles s = −ζω0 ± jω0√(1−ζ²) map to z = exp(s·ts),
    so φ1 = 2r cos(ωd ts), φ2 = −r², r = exp(−ζ ω0 ts).

    Parameters
    ----------
    f0 : float
        Natural frequency [Hz].
    zeta : float
        Damping ratio, 0 < ζ < 1 [1].
    ts : float
        Sample period [s].

    Returns
    -------
    (float, float)
        φ1, φ2 [1].

    Examples
    --------
    >>> p1, p2 = vibration_ar(10.0, 0.05, 0.02)
    >>> round(p1, 6), round(p2, 6)
    (0.583203, -0.881911)
    """
    w0 = 2.0 * math.pi * f0
    r = math.exp(-zeta * w0 * ts)
    wd = w0 * math.sqrt(1.0 - zeta * zeta)
    return 2.0 * r * math.cos(wd * ts), -r * r


def _companion(phi: tuple[float, ...] | np.ndarray) -> np.ndarray:
    p = len(phi)
    f = np.zeros((p, p))
    f[0, :] = phi
    if p > 1:
        f[1:, :-1] = np.eye(p - 1)
    return f


def stationary_covariance(phi: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """Covariance of (a_k, …, a_{k−p+1}) of a stationary AR(p) with unit innovation.

    Solves P = F P Fᵀ + e1 e1ᵀ (F the companion matrix) by the discrete Lyapunov equation.

    Parameters
    ----------
    phi : sequence of float
        φ1 … φp (stationary: every root of z^p − φ1 z^(p−1) − … − φp inside |z| < 1).

    Returns
    -------
    ndarray, shape (p, p)
        The Toeplitz matrix of autocovariances γ(|i − j|) [unit innovation variance].
    """
    from scipy.linalg import solve_discrete_lyapunov

    f = _companion(phi)
    q = np.zeros_like(f)
    q[0, 0] = 1.0
    out: np.ndarray = solve_discrete_lyapunov(f, q)
    sym: np.ndarray = 0.5 * (out + out.T)
    return sym


def ar_autocovariance(phi: tuple[float, ...] | np.ndarray, lags: int) -> np.ndarray:
    """Autocovariances γ(0) … γ(lags) of a stationary AR(p) with unit innovation variance.

    γ(h) = (F^h P)[0, 0] with F the companion matrix and P :func:`stationary_covariance`.

    Parameters
    ----------
    phi : sequence of float
        φ1 … φp (empty: white noise, γ = 1, 0, 0, …).
    lags : int
        Largest lag [samples].

    Returns
    -------
    ndarray, shape (lags + 1,)
        γ(h) [unit innovation variance].

    Examples
    --------
    >>> ar_autocovariance([0.5], 2).round(6).tolist()   # 1/(1−φ²) · φ^h
    [1.333333, 0.666667, 0.333333]
    """
    out = np.zeros(lags + 1)
    if len(phi) == 0:
        out[0] = 1.0
        return out
    f = _companion(phi)
    m = stationary_covariance(phi)
    for h in range(lags + 1):
        out[h] = m[0, 0]
        m = np.asarray(f @ m)
    return out


def ar_spectrum(phi: tuple[float, ...] | np.ndarray, freq_hz: np.ndarray, ts: float,
                innovation_var: float = 1.0) -> np.ndarray:
    """One-sided power spectral density of an AR(p) process sampled every ts.

    S(f) = 2·ts·σe² / |1 − Σ φi e^{−j2πf i ts}|²  (integrates to the variance over
    0 … 1/(2 ts)).

    Parameters
    ----------
    phi : sequence of float
        φ1 … φp.
    freq_hz : ndarray
        Frequencies [Hz], 0 … rate/2.
    ts : float
        Sample period [s].
    innovation_var : float
        Innovation variance σe² [unit²].

    Returns
    -------
    ndarray
        S(f) [unit²/Hz].
    """
    zinv = np.exp(-2j * np.pi * np.asarray(freq_hz, dtype=float) * ts)
    den = np.ones_like(zinv)
    for i, a in enumerate(phi, start=1):
        den = den - a * zinv ** i
    spectrum: np.ndarray = 2.0 * ts * innovation_var / np.abs(den) ** 2
    return spectrum


def _pole_modulus(phi: tuple[float, ...] | list[float]) -> float:
    if len(phi) == 0:
        return 0.0
    return float(np.max(np.abs(np.linalg.eigvals(_companion(tuple(phi))))))


def check_noise(scn: Scenario) -> tuple[str, str] | None:
    """(key, message) of the first sensor-noise key out of range, or None.

    Parameters
    ----------
    scn : Scenario
        A scenario (schema-validated; this checks what the schema cannot).

    Returns
    -------
    (str, str) or None
        The offending key and why, for the scenario's one-line error.
    """
    s = scn.sensor
    if len(s.noise_ar) > MAX_AR_ORDER:
        return "sensor.noise_ar", (f"{len(s.noise_ar)} coefficients; at most {MAX_AR_ORDER} "
                                   "(an AR order above that is not a noise model)")
    rho = _pole_modulus(list(s.noise_ar))
    if not rho < MAX_POLE:
        return "sensor.noise_ar", (
            f"{list(s.noise_ar)} is not a stationary noise: its largest pole has modulus "
            f"{rho:.4g}; every root of z^p − φ1 z^(p−1) − … − φp must lie inside "
            f"|z| < {MAX_POLE} (e.g. [0.8] or [1.2, -0.5])")
    if s.vibration_deg > 0.0:
        nyq = 0.5 * s.rate_hz
        if not s.vibration_hz < nyq:
            return "sensor.vibration_hz", (
                f"{s.vibration_hz:g} Hz must be below the Nyquist frequency rate_hz/2 = "
                f"{nyq:g} Hz (give the alias a faster mode shows at)")
        rho_v = math.exp(-s.vibration_damping * 2.0 * math.pi * s.vibration_hz / s.rate_hz)
        if not rho_v < MAX_POLE:
            return "sensor.vibration_damping", (
                f"{s.vibration_damping:g} at {s.vibration_hz:g} Hz puts the mode's pole at "
                f"{rho_v:.5g}; it must be below {MAX_POLE} (raise the damping or the frequency)")
    return None


def sequence_scale(model: NoiseModel) -> float:
    """The factor the engines multiply the noise sequence by: σ [rad] white, else 1.

    Parameters
    ----------
    model : NoiseModel
        The measurement disturbance.

    Returns
    -------
    float
        σ [rad] for the white model (the sequence is standard-normal), 1.0 otherwise (the
        sequence is w_k in rad).
    """
    return model.sigma if model.white else 1.0


class _Process(NamedTuple):
    """One AR process: coefficients, output gain, and each joint's last p values."""

    phi: tuple[float, ...]
    gain: float
    states: list[list[float]]


def _process(phi: tuple[float, ...], rms: float, joints: int,
             init: np.random.Generator) -> _Process:
    """An AR process scaled to stationary RMS ``rms``, its states drawn stationary."""
    p = len(phi)
    if p == 0:
        return _Process((), rms, [[] for _ in range(joints)])
    cov = stationary_covariance(phi)
    chol = np.linalg.cholesky(cov)
    gain = rms / math.sqrt(float(cov[0, 0]))
    states = [(chol @ init.standard_normal(p)).tolist() for _ in range(joints)]
    return _Process(phi, gain, states)


class NoiseStream:
    """w_0, w_1, … of a run (joint index fastest), sample by sample.

    Yields exactly the values of :func:`draws` (seed, N·joints) for its first N·joints
    draws, and goes on past them if a host runs longer.  For the white model it yields the
    standard-normal draws themselves (the engines scale them by σ).

    Parameters
    ----------
    model : NoiseModel
        The measurement disturbance.
    seed : int
        The sensor's seed.
    joints : int
        Number of joints (one process per joint).
    block : int
        Draws per call of the generator.
    """

    __slots__ = ("_block", "_buf", "_bufv", "_enc", "_i", "_j", "_joints", "_rng", "_rngv",
                 "_vib", "_zero")

    def __init__(self, model: NoiseModel, seed: int, joints: int = 1, block: int = 4096) -> None:
        self._zero = model.white and not model.sigma > 0.0
        self._rng = np.random.default_rng(seed)
        self._block = block
        self._buf: list[float] = []
        self._bufv: list[float] = []
        self._i = 0
        self._j = 0
        self._joints = joints
        self._enc: _Process | None = None
        self._vib: _Process | None = None
        self._rngv: np.random.Generator | None = None
        if not model.white:
            init = np.random.default_rng([seed, 2])
            self._enc = _process(model.ar if model.sigma > 0.0 else (), model.sigma, joints,
                                 init)
            if model.vibration > 0.0:
                self._vib = _process(model.vibration_coefficients, model.vibration, joints,
                                     init)
                self._rngv = np.random.default_rng([seed, 1])

    def next(self) -> float:
        """The next value: a standard-normal draw (white model) or w_k [rad].

        Returns
        -------
        float
            0.0 without noise.
        """
        if self._zero:
            return 0.0
        if self._i == len(self._buf):
            self._buf = self._rng.standard_normal(self._block).tolist()
            if self._rngv is not None:
                self._bufv = self._rngv.standard_normal(self._block).tolist()
            self._i = 0
        e = self._buf[self._i]
        ev = self._bufv[self._i] if self._rngv is not None else 0.0
        self._i += 1
        j = self._j
        self._j = j + 1 if j + 1 < self._joints else 0
        if self._enc is None:
            return e
        # the recurrence a_k = φ1 a_{k−1} + … + φp a_{k−p} + e_k, then the gain
        w = self._enc.gain * _ar_next(self._enc.phi, self._enc.states[j], e)
        if self._vib is not None:
            w = w + self._vib.gain * _ar_next(self._vib.phi, self._vib.states[j], ev)
        return w


def _ar_next(phi: tuple[float, ...], state: list[float], e: float) -> float:
    """a_k = e_k + φ1 a_{k−1} + … + φp a_{k−p}; ``state`` (a_{k−1}, …) shifted in place."""
    a = e
    for i, c in enumerate(phi):
        a += c * state[i]
    if phi:
        state.insert(0, a)
        state.pop()
    return a


def draws(model: NoiseModel, seed: int, n_samples: int, joints: int = 1) -> np.ndarray:
    """The noise sequence of one run as the engines take it (joint index fastest).

    White model: exactly :func:`esoarm.plants.sensor.noise_sequence` (standard-normal
    draws, scaled by σ in the engines).  Otherwise w_k [rad] (scale 1), the values of
    :class:`NoiseStream`.

    Parameters
    ----------
    model : NoiseModel
        The measurement disturbance.
    seed : int
        The sensor's seed.
    n_samples : int
        Length N·joints.
    joints : int
        Number of joints.

    Returns
    -------
    ndarray, shape (n_samples,)
        The sequence (multiply by :func:`sequence_scale` for rad).
    """
    if model.white:
        return noise_sequence(seed, n_samples, math.degrees(model.sigma))
    stream = NoiseStream(model, seed, joints, block=max(n_samples, 1))
    return np.array([stream.next() for _ in range(n_samples)], dtype=np.float64)
