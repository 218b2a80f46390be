"""The residual's spectrum as an AR model, and whether it is sensor noise (``identify``).

The validation residual r_k = y_k − ŷ_k of an output-error fit is what the fitted model
does not explain. This module estimates its spectrum as an autoregressive model

    r_k = φ1 r_{k−1} + … + φp r_{k−p} + ε_k,     ε white, variance σε²

by Yule-Walker (the biased sample autocovariances, solved by the Levinson-Durbin
recursion, which always gives a stationary model), the order p = 0 … ``max_order`` by
Akaike's criterion AIC(p) = M·ln σ̂ε²(p) + 2p (M samples), and decides whether the
residual is sensor noise (Ljung, *System Identification*, 2nd ed., 1999, §16.6: residual
analysis):

1. the prewhitened residual ε must be white: at most 2 of its autocorrelations at lags
   1 … 20 outside ±1.96/√M (the test :mod:`esoarm.studies.identification.identify` applies
   to the residual itself);
2. ε must be uncorrelated with the *past* input u_{k−τ}, τ = 1 … 20: Ljung's portmanteau
   test, M·Σ ρ̂²(τ) below the 95 % quantile of χ² with 20 degrees of freedom (one large
   correlation fails it, as do many small ones).  What the model misses is a function of the input
   and shows here; sensor noise does not.  The innovation ε_k is independent of everything
   before sample k, so the test holds in closed loop too (the excitation's guard PD feeds the
   noise back into u; the raw residual would correlate with past u through its colour).

If both hold the residual is sensor noise with the AR spectrum (p = 0: white); otherwise it
is model error, and the AR model describes the error, not the encoder.  An input-independent
disturbance the model lacks (a wrong d(t)) passes test 2 and would be taken for coloured
noise: the test cannot tell them apart, and the report says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ARFit", "NoiseVerdict", "cross_correlation_outside", "fit_ar", "levinson_durbin",
           "noise_verdict", "whiteness_outside"]

#: Lags of the whiteness and cross-correlation tests; at most OUTSIDE_ALLOWED outside the band.
LAGS = 20
OUTSIDE_ALLOWED = 2
#: 95 % quantile of χ² with LAGS degrees of freedom (scipy.stats.chi2.ppf(0.95, 20)).
CHI2_95_LAGS = 31.410432844230918
#: Largest AR order tried.
MAX_ORDER = 10


def levinson_durbin(acov: np.ndarray, order: int) -> tuple[np.ndarray, float]:
    """Yule-Walker AR coefficients from autocovariances γ(0) … γ(order) (Levinson-Durbin).

    Parameters
    ----------
    acov : ndarray
        γ(0), γ(1), … [unit²], at least order + 1 values.
    order : int
        p ≥ 0.

    Returns
    -------
    phi : ndarray, shape (p,)
        φ1 … φp (r_k = Σ φi r_{k−i} + ε_k).
    innovation_var : float
        σε² [unit²].

    Examples
    --------
    >>> phi, s2 = levinson_durbin(np.array([1 / 0.75, 0.5 / 0.75, 0.25 / 0.75]), 2)
    >>> phi.round(12).tolist(), round(s2, 12)     # AR(1), φ = 0.5, unit innovation
    ([0.5, 0.0], 1.0)
    """
    phi = np.zeros(order)
    err = float(acov[0])
    for m in range(order):
        acc = float(acov[m + 1]) - float(np.dot(phi[:m], acov[m:0:-1]))
        kappa = acc / err if err > 0.0 else 0.0
        prev = phi[:m].copy()
        phi[m] = kappa
        phi[:m] = prev - kappa * prev[::-1]
        err *= 1.0 - kappa * kappa
    return phi, err


@dataclass(frozen=True)
class ARFit:
    """An AR model of a series, its order chosen by AIC.

    Attributes
    ----------
    phi : tuple of float
        φ1 … φp [1].
    innovation_var : float
        σε² [unit²].
    variance : float
        The series' sample variance γ̂(0) [unit²].
    aic : tuple of float
        AIC(p) for p = 0 … max order tried.
    samples : int
        M.
    """

    phi: tuple[float, ...]
    innovation_var: float
    variance: float
    aic: tuple[float, ...]
    samples: int

    @property
    def order(self) -> int:
        """p."""
        return len(self.phi)

    def innovations(self, x: np.ndarray) -> np.ndarray:
        """ε_k = x_k − Σ φi x_{k−i} for k ≥ p (the prewhitened series).

        Parameters
        ----------
        x : ndarray
            The series the model was fitted to.

        Returns
        -------
        ndarray, shape (M − p,)
            The innovations [unit].
        """
        p = self.order
        out = np.array(x[p:], dtype=float)
        for i, c in enumerate(self.phi, start=1):
            out -= c * x[p - i: len(x) - i]
        return out


def fit_ar(x: np.ndarray, max_order: int = MAX_ORDER) -> ARFit:
    """Yule-Walker AR fit of the zero-mean series x, order 0 … max_order by AIC.

    Parameters
    ----------
    x : ndarray
        The series (a residual: zero-mean by construction; it is not demeaned).
    max_order : int
        Largest order tried (capped at M/10).

    Returns
    -------
    ARFit
        The model of least AIC(p) = M ln σ̂ε²(p) + 2p.
    """
    x = np.asarray(x, dtype=float)
    m = len(x)
    top = max(0, min(max_order, m // 10))
    acov = np.array([float(np.dot(x[: m - h], x[h:])) / m for h in range(top + 1)])
    aics, fits = [], []
    for p in range(top + 1):
        phi, s2 = levinson_durbin(acov, p)
        aics.append(m * math.log(max(s2, 1e-300)) + 2.0 * p)
        fits.append((phi, s2))
    best = int(np.argmin(aics))
    phi, s2 = fits[best]
    return ARFit(tuple(float(v) for v in phi), float(s2), float(acov[0]),
                 tuple(float(a) for a in aics), m)


def whiteness_outside(x: np.ndarray, lags: int = LAGS) -> tuple[int, float]:
    """How many autocorrelations at lags 1 … ``lags`` lie outside ±1.96/√M, and the band.

    Parameters
    ----------
    x : ndarray
        The series.
    lags : int
        Largest lag.

    Returns
    -------
    (int, float)
        Lags outside the band, the band 1.96/√M.
    """
    m = len(x)
    denom = float(np.dot(x, x)) or 1.0
    rho = np.array([float(np.dot(x[:-k], x[k:])) / denom for k in range(1, lags + 1)])
    band = 1.96 / math.sqrt(m)
    return int(np.sum(np.abs(rho) > band)), band


def cross_correlation_outside(eps: np.ndarray, u: np.ndarray,
                              lags: int = LAGS) -> tuple[int, float]:
    """Correlations of ε_k with the past input u_{k−τ}, τ = 1 … lags: how many exceed
    1.96/√M, and the portmanteau statistic M·Σρ̂² (χ² with ``lags`` degrees of freedom
    under independence).

    Parameters
    ----------
    eps : ndarray
        The prewhitened residual (aligned with u: ε_k and u_k of the same sample).
    u : ndarray
        The input, same length.
    lags : int
        Largest τ.

    Returns
    -------
    (int, float)
        Lags outside ±1.96/√M, and M·Σρ̂².
    """
    m = len(eps)
    uc = u - np.mean(u)
    norm = math.sqrt(float(np.dot(eps, eps)) * float(np.dot(uc, uc))) or 1.0
    band = 1.96 / math.sqrt(m)
    rho = np.array([float(np.dot(eps[tau:], uc[: m - tau])) / norm for tau in range(1, lags + 1)])
    return int(np.sum(np.abs(rho) > band)), float(m * np.sum(rho**2))


@dataclass(frozen=True)
class NoiseVerdict:
    """The residual's AR model and whether it is sensor noise.

    Attributes
    ----------
    fit : ARFit
        The AR model of the residual (rad).
    innovation_outside : int
        Lags of the innovation's autocorrelation outside the band (of :data:`LAGS`).
    input_outside : int
        Lags of the innovation-input cross-correlation outside the band.
    input_statistic : float
        M·Σρ̂² of the innovation-input cross-correlation (χ² with :data:`LAGS` dof).
    is_sensor_noise : bool
        innovation_outside ≤ :data:`OUTSIDE_ALLOWED` and input_statistic below the χ²
        95 % quantile.
    notes : list of str
        What the verdict rests on.
    """

    fit: ARFit
    innovation_outside: int
    input_outside: int
    input_statistic: float
    is_sensor_noise: bool
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: coefficients, order, AIC, the tests and the verdict.

        Returns
        -------
        dict
            ``noise_ar``, ``order``, ``innovation_std_deg``, ``residual_std_deg``, the tests'
            counts, ``sensor_noise`` and ``meaning``.
        """
        return {"noise_ar": list(self.fit.phi), "order": self.fit.order,
                "aic": list(self.fit.aic),
                "innovation_std_deg": math.degrees(math.sqrt(self.fit.innovation_var)),
                "residual_std_deg": math.degrees(math.sqrt(self.fit.variance)),
                "innovation_autocorrelation_outside": self.innovation_outside,
                "input_cross_correlation_outside": self.input_outside,
                "input_cross_correlation_chi2": self.input_statistic,
                "chi2_95": CHI2_95_LAGS,
                "lags": LAGS, "sensor_noise": self.is_sensor_noise,
                "meaning": ("sensor noise with this spectrum" if self.is_sensor_noise else
                            "model error: the spectrum of what the model misses"),
                "notes": list(self.notes)}


def noise_verdict(residual: np.ndarray, u: np.ndarray, max_order: int = MAX_ORDER) -> NoiseVerdict:
    """AR model of the residual and Ljung's two residual tests (see the module docstring).

    Parameters
    ----------
    residual : ndarray
        r_k = y_k − ŷ_k [rad], consecutive samples.
    u : ndarray
        The input of the same samples (the applied torque [N·m] or duty fraction).
    max_order : int
        Largest AR order tried.

    Returns
    -------
    NoiseVerdict
        The AR fit, the tests, and whether the residual is sensor noise.
    """
    r = np.asarray(residual, dtype=float)
    u = np.asarray(u, dtype=float)
    fit = fit_ar(r, max_order)
    eps = fit.innovations(r)
    white, _ = whiteness_outside(eps)
    cross, stat = cross_correlation_outside(eps, u[fit.order:])
    ok = white <= OUTSIDE_ALLOWED and stat < CHI2_95_LAGS
    notes = [f"AR order {fit.order} by AIC (0 … {min(max_order, len(r) // 10)})",
             f"innovation autocorrelation: {white} of {LAGS} lags outside ±1.96/√M",
             f"innovation vs past input: M·Σρ² = {stat:.3g} (χ²₂₀ 95 %: {CHI2_95_LAGS:.4g}), "
             f"{cross} of {LAGS} lags outside ±1.96/√M"]
    if ok and fit.order > 0:
        notes.append("an input-independent disturbance missing from the model would look the "
                     "same (the tests cannot tell it from coloured encoder noise)")
    return NoiseVerdict(fit, white, cross, stat, ok, notes)
