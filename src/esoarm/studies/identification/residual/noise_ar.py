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
is model error, and the AR model describes the error, not the encoder.

That is :func:`noise_verdict`, for one series.  ``identify`` uses :func:`segment_verdict`: its
residual comes in segments whose initial angle and rate were fitted, which removes the slow
part of a coloured noise and biases Yule-Walker low (φ = 0.7 came out 0.645 on a twin log).
There the AR model is the restricted maximum likelihood of the segments (their fitted
directions profiled out, the quantization q²/12 held as white noise beside the AR noise, order
by BIC, 95 % intervals from the observed information), and the two tests are run on its
innovations, corrected for the projection.  An input-independent
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
#: :func:`reml_ar` stops raising the order once BIC has not improved for this many orders.
STOP_AFTER = 2
#: Sensor noise: the AR model's stationary RMS is at most this many times the residual's
#: (the segments' initial-state fit removes a few per cent of an AR(1) 0.7's variance; a
#: model whose power is mostly slower than a segment is not identified by the log).
SLOW_POWER_MAX = 1.5
#: Iterations of one order's optimization in :func:`reml_ar` (a bound on its time: the fits
#: of twin logs converge in a few dozen).
MAX_ITER = 100
#: Largest order :func:`reml_ar` tries by default (each order costs an optimization of the
#: restricted likelihood; a residual that needs more is not called sensor noise).
REML_MAX_ORDER = 6


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


# -- the spectrum of a residual whose segments had their initial states fitted -------------


@dataclass(frozen=True)
class SegmentResidual:
    """The residual of one simulated segment of an output-error fit.

    Attributes
    ----------
    r : ndarray, shape (n,)
        y_k − ŷ_k [rad] at the segment's kept samples.
    x : ndarray, shape (n, c)
        The prediction's sensitivities to what was fitted on this segment alone (its
        initial angle and rate): the fit removed the residual's component along them.
    u : ndarray, shape (n,)
        The input of the same samples.
    k : ndarray of int, shape (n,)
        Sample index of each kept sample from the segment's start (a gap: a lost sample).
    """

    r: np.ndarray
    x: np.ndarray
    u: np.ndarray
    k: np.ndarray


def _kappa_to_phi(kappa: np.ndarray) -> np.ndarray:
    """AR coefficients from partial autocorrelations (Levinson step-up; |κ| < 1 ⇔ stationary)."""
    phi = np.zeros(0)
    for kap in kappa:
        phi = np.concatenate([phi - kap * phi[::-1], [kap]])
    return phi


def _phi_to_kappa(phi: np.ndarray) -> np.ndarray:
    """Partial autocorrelations of a stationary AR model (Levinson step-down)."""
    a = np.array(phi, dtype=float)
    out = np.zeros(len(a))
    for m in range(len(a), 0, -1):
        kap = a[m - 1]
        out[m - 1] = kap
        if m > 1:
            a = (a[: m - 1] + kap * a[m - 2::-1]) / (1.0 - kap * kap)
    return out


def _ar_correlation(kappa: np.ndarray, lags: int) -> np.ndarray:
    """ρ(0) … ρ(lags) of the stationary AR model with partial autocorrelations κ.

    ρ(m) = Σ_{i<m} φ_{m−1,i} ρ(m−i) + κ_m (1 − Σ_{i<m} φ_{m−1,i} ρ(i)) up to the order p
    (the Durbin-Levinson recursion read backwards), then ρ(h) = Σ φ_i ρ(h−i).
    """
    p = len(kappa)
    rho = np.zeros(lags + 1)
    rho[0] = 1.0
    phi = np.zeros(0)
    for m in range(1, min(p, lags) + 1):
        kap = float(kappa[m - 1])
        prev = rho[m - 1:0:-1]  # ρ(m−1) … ρ(1)
        rho[m] = float(np.dot(phi, prev)) + kap * (1.0 - float(np.dot(phi, rho[1:m])))
        phi = np.concatenate([phi - kap * phi[::-1], [kap]])
    if p > lags:
        return rho
    for h in range(p + 1, lags + 1):
        rho[h] = float(np.dot(phi, rho[h - p:h][::-1]))
    return rho


@dataclass(frozen=True)
class RemlFit:
    """AR model of a segmented residual by restricted maximum likelihood, with intervals.

    Attributes
    ----------
    phi : tuple of float
        φ1 … φp [1].
    phi_ci : tuple of (float, float)
        95 % intervals of φ1 … φp (observed information, delta method).
    std : float
        Stationary std of the AR noise σw [rad] (quantization apart).
    std_ci : tuple of float
        Its 95 % interval [rad].
    bic : tuple of float
        The order criterion −2 ln L_R + ln(M)·(p + 1) (Schwarz's BIC) for p = 0, 1, … .
    samples : int
        Residual samples used.
    quant_var : float
        The white quantization variance q²/12 held in the model [rad²].
    """

    phi: tuple[float, ...]
    phi_ci: tuple[tuple[float, float], ...]
    std: float
    std_ci: tuple[float, float]
    bic: tuple[float, ...]
    samples: int
    quant_var: float

    @property
    def order(self) -> int:
        """p."""
        return len(self.phi)

    def covariance(self, k: np.ndarray) -> np.ndarray:
        """Covariance of the noise at sample indices k: σw² ρ(|ki − kj|) + q²/12 δij [rad²].

        Parameters
        ----------
        k : ndarray of int
            Sample indices.

        Returns
        -------
        ndarray, shape (len(k), len(k))
        """
        k = np.asarray(k, dtype=np.int64)
        lag = np.abs(k[:, None] - k[None, :])
        rho = _ar_correlation(_phi_to_kappa(np.array(self.phi)), int(lag.max(initial=0)))
        return self.std**2 * rho[lag] + self.quant_var * np.eye(len(k))

    @property
    def innovation_var(self) -> float:
        """σε² = σw² · Π(1 − κi²) [rad²]."""
        kap = _phi_to_kappa(np.array(self.phi))
        return float(self.std**2 * np.prod(1.0 - kap**2))


class _Reml:
    """−2 × restricted log-likelihood of segmented residuals under AR(p) + white quantization.

    Each segment's residual is r = (I − P) w with P the least-squares projection on its
    sensitivities X; its restricted likelihood (Patterson & Thompson 1971; Harville 1977)
    depends on the noise covariance Σ only through
    ln|Σ| + ln|XᵀΣ⁻¹X| + rᵀ(Σ⁻¹ − Σ⁻¹X(XᵀΣ⁻¹X)⁻¹XᵀΣ⁻¹)r, which does not see the part of
    the noise the initial-state fit removed (the bias of a Yule-Walker fit on r).
    """

    def __init__(self, segments: list[SegmentResidual], quant_var: float) -> None:
        groups: dict[bytes, list[SegmentResidual]] = {}
        for s in segments:
            groups.setdefault(np.asarray(s.k, dtype=np.int64).tobytes(), []).append(s)
        self.groups = []
        for items in groups.values():
            k = np.asarray(items[0].k, dtype=np.int64)
            lag = np.abs(k[:, None] - k[None, :])
            r = np.stack([s.r for s in items], axis=1)  # (n, S)
            x = np.stack([s.x for s in items], axis=0)  # (S, n, c)
            self.groups.append((lag, r, x))
        self.quant_var = quant_var
        self.scale = float(np.sqrt(np.mean(np.concatenate([s.r for s in segments]) ** 2))) or 1.0
        self.max_lag = max(int(g[0].max()) for g in self.groups)

    def whiten(self, phi: np.ndarray, std: float):  # type: ignore[no-untyped-def]
        """Per group: (Cholesky factor, C⁻¹r, C⁻¹X)."""
        from scipy.linalg import cholesky, solve_triangular

        rho = _ar_correlation(_phi_to_kappa(phi), self.max_lag)
        out = []
        for lag, r, x in self.groups:
            cov = std * std * rho[lag] + self.quant_var * np.eye(len(lag))
            c = cholesky(cov, lower=True)
            z = solve_triangular(c, r, lower=True)
            s, n, m = x.shape
            zx = solve_triangular(c, x.transpose(1, 0, 2).reshape(n, s * m), lower=True)
            out.append((c, z, zx.reshape(n, s, m).transpose(1, 0, 2)))
        return out

    def m2ll(self, phi: np.ndarray, std: float) -> float:
        """−2 ln L_R (constants dropped)."""
        total = 0.0
        try:
            parts = self.whiten(phi, std)
        except np.linalg.LinAlgError:
            return math.inf
        for c, z, zx in parts:
            logdet = 2.0 * float(np.sum(np.log(np.diag(c))))
            zt = z.T  # (S, n)
            g = np.einsum("snc,snd->scd", zx, zx)
            xz = np.einsum("snc,sn->sc", zx, zt)
            _sign, ld = np.linalg.slogdet(g)
            b = np.linalg.solve(g, xz[..., None])[..., 0]
            total += float(len(zt) * logdet + np.sum(ld) + np.sum(zt * zt)
                           - np.sum(xz * b))
        return total

    def objective(self, theta: np.ndarray) -> float:
        p = len(theta) - 1
        phi = _kappa_to_phi(np.tanh(theta[:p]))
        return self.m2ll(phi, self.scale * math.exp(theta[p]))

    def innovations(self, phi: np.ndarray, std: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per segment: the standardized innovations (I − Z(ZᵀZ)⁻¹Zᵀ) C⁻¹ r and that
        projection matrix (their covariance if the model is right)."""
        out = []
        for c, z, zx in self.whiten(phi, std):
            for j in range(z.shape[1]):
                xj = zx[j]
                proj = np.eye(len(c)) - xj @ np.linalg.solve(xj.T @ xj, xj.T)
                out.append((proj @ z[:, j], proj))
        return out


def _hessian(f, x: np.ndarray, step: float = 1e-3) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Central-difference Hessian of f at x."""
    n = len(x)
    h = np.zeros((n, n))
    f0 = f(x)
    for i in range(n):
        for j in range(i, n):
            if i == j:
                e = np.zeros(n)
                e[i] = step
                h[i, i] = (f(x + e) - 2.0 * f0 + f(x - e)) / step**2
            else:
                ei, ej = np.zeros(n), np.zeros(n)
                ei[i], ej[j] = step, step
                h[i, j] = h[j, i] = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej)
                                     + f(x - ei - ej)) / (4.0 * step**2)
    return h


def reml_ar(segments: list[SegmentResidual], quant_var: float = 0.0,
            max_order: int = REML_MAX_ORDER) -> tuple[RemlFit, _Reml]:
    """AR(p) model of a segmented residual by restricted maximum likelihood, p by BIC.

    The order is Schwarz's criterion's, −2 ln L_R + ln(M)(p + 1), not Akaike's: AIC
    overfits white noise about one time in four (:func:`fit_ar`), and an encoder noise
    model of order 2 with coefficients of a few hundredths is worse than none.

    Parameters
    ----------
    segments : list of SegmentResidual
        The residual of each segment and what was fitted on it.
    quant_var : float
        Variance of the encoder's quantization q²/12 [rad²], held as white noise beside
        the AR noise.
    max_order : int
        Largest AR order tried (capped at a tenth of the shortest segment; the search
        stops once BIC has not improved for :data:`STOP_AFTER` orders).

    Returns
    -------
    (RemlFit, likelihood)
        The model of least BIC with 95 % intervals, and the likelihood object (for the
        innovations).
    """
    from scipy.optimize import minimize

    lik = _Reml(segments, quant_var)
    r_all = np.concatenate([s.r for s in segments])
    n_all = len(r_all)
    shortest = min(len(s.r) for s in segments)
    top = max(0, min(max_order, shortest // 10))
    lw = [math.log(max(float(np.mean(r_all**2)) - quant_var, 1e-6 * lik.scale**2)) / 2.0
          - math.log(lik.scale)]
    best = None
    aics: list[float] = []
    fits: list[np.ndarray] = []
    prev = np.zeros(0)
    for p in range(top + 1):
        # start from the order below (its κ and a new κ = 0) and from Yule-Walker's order p
        starts = [np.concatenate([prev, [0.0]]) if p else np.zeros(0)]
        if p:
            acov = np.array([float(np.dot(r_all[: len(r_all) - h], r_all[h:])) / len(r_all)
                             for h in range(p + 1)])
            starts.append(np.arctanh(np.clip(_phi_to_kappa(levinson_durbin(acov, p)[0]),
                                              -0.99, 0.99)))
        # one optimization, from the better of the two starts
        x0s = [np.concatenate([a0, lw]) for a0 in starts]
        vals = [lik.objective(x0) for x0 in x0s]
        with np.errstate(invalid="ignore"):  # a Σ too close to singular is +inf
            cand = minimize(lik.objective, x0s[int(np.argmin(vals))], method="L-BFGS-B",
                            bounds=[(-4.0, 4.0)] * p + [(-15.0, 5.0)],
                            options={"maxiter": MAX_ITER})
        assert cand is not None
        aics.append(float(cand.fun) + math.log(n_all) * (p + 1))
        fits.append(np.array(cand.x))
        prev = np.array(cand.x[:p])
        if best is None or aics[-1] < aics[best]:
            best = p
        elif p - best >= STOP_AFTER:
            break  # BIC has not improved for STOP_AFTER orders: higher ones are not tried
    assert best is not None
    theta = fits[best]
    p = best
    phi = _kappa_to_phi(np.tanh(theta[:p]))
    std = lik.scale * math.exp(theta[p])
    # 95 % intervals: observed information of −ln L_R = m2ll / 2, delta method to φ
    h = 0.5 * _hessian(lik.objective, theta)
    try:
        cov = np.linalg.inv(h)
        if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        cov = np.full((p + 1, p + 1), np.inf)
    jac = np.zeros((p, p + 1))
    for j in range(p):
        e = np.zeros(p + 1)
        e[j] = 1e-6
        jac[:, j] = (_kappa_to_phi(np.tanh((theta + e)[:p]))
                     - _kappa_to_phi(np.tanh((theta - e)[:p]))) / 2e-6
    var_phi = np.diag(jac @ cov @ jac.T) if p else np.zeros(0)
    half = 1.96 * np.sqrt(np.maximum(var_phi, 0.0))
    se_s = math.sqrt(max(float(cov[p, p]), 0.0))
    fit = RemlFit(tuple(float(v) for v in phi),
                  tuple((float(v - d), float(v + d)) for v, d in zip(phi, half, strict=True)),
                  std, (std * math.exp(-1.96 * se_s), std * math.exp(1.96 * se_s)),
                  tuple(aics), len(r_all), quant_var)
    return fit, lik


def _whiteness_statistic(parts: list[tuple[np.ndarray, np.ndarray]],
                         lags: int) -> tuple[np.ndarray, int]:
    """Standardized within-segment autocorrelation sums z_h, h = 1 … lags, and the
    number of lags with |z_h| > 1.96.

    z_h = (Σ e_t e_{t+h} − E₀) / √(pairs), with E₀ = Σ trace-offsets of the projection
    (the sum's mean when e is the projected white noise the model predicts)."""
    z = np.zeros(lags)
    for h in range(1, lags + 1):
        s = e0 = 0.0
        pairs = 0
        for e, proj in parts:
            n = len(e)
            if n > h:
                s += float(np.dot(e[:-h], e[h:]))
                e0 += float(np.trace(proj, offset=h))
                pairs += n - h
        z[h - 1] = (s - e0) / math.sqrt(max(pairs, 1))
    return z, int(np.sum(np.abs(z) > 1.96))


def _input_statistic(parts: list[tuple[np.ndarray, np.ndarray]], inputs: list[np.ndarray],
                     lags: int) -> tuple[np.ndarray, int]:
    """Standardized correlations of the innovation with the past input within segments,
    c_τ = Σ e_t ũ_{t−τ} / √Σ ũ²_{t−τ} (ũ: input less its mean), τ = 1 … lags."""
    mean = float(np.mean(np.concatenate(inputs)))
    c = np.zeros(lags)
    for tau in range(1, lags + 1):
        s = q = 0.0
        for (e, _proj), u in zip(parts, inputs, strict=True):
            if len(e) > tau:
                uc = u[: len(e) - tau] - mean
                s += float(np.dot(e[tau:], uc))
                q += float(np.dot(uc, uc))
        c[tau - 1] = s / math.sqrt(q) if q > 0 else 0.0
    return c, int(np.sum(np.abs(c) > 1.96))


def chi2_95(dof: int) -> float:
    """95 % quantile of χ² with ``dof`` degrees of freedom [1]."""
    from scipy.stats import chi2

    return float(chi2.ppf(0.95, max(dof, 1)))


@dataclass(frozen=True)
class SegmentVerdict:
    """The residual's AR model (restricted likelihood) and whether it is sensor noise.

    Attributes
    ----------
    fit : RemlFit
        The AR model with 95 % intervals.
    white_z : ndarray
        Standardized innovation autocorrelation sums at lags 1 … :data:`LAGS`.
    input_c : ndarray
        Standardized innovation / past-input correlations at lags 1 … :data:`LAGS`.
    is_sensor_noise : bool
        Both portmanteau statistics below their χ² 95 % quantiles.
    notes : list of str
        What the verdict rests on.
    """

    fit: RemlFit
    white_z: np.ndarray
    input_c: np.ndarray
    is_sensor_noise: bool
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: the model with intervals, the tests and the verdict.

        Returns
        -------
        dict
            ``noise_ar``, ``noise_ar_ci95``, ``order``, ``noise_std_deg`` and its interval,
            ``innovation_std_deg``, the tests, ``sensor_noise`` and ``meaning``.
        """
        f = self.fit
        wq = float(np.sum(self.white_z**2))
        iq = float(np.sum(self.input_c**2))
        return {"noise_ar": list(f.phi), "noise_ar_ci95": [list(c) for c in f.phi_ci],
                "order": f.order, "bic": list(f.bic),
                "method": "restricted maximum likelihood (the segments' initial states "
                          "profiled out), quantization q²/12 held as white noise",
                "noise_std_deg": math.degrees(f.std),
                "noise_std_ci95_deg": [math.degrees(v) for v in f.std_ci],
                "innovation_std_deg": math.degrees(math.sqrt(f.innovation_var)),
                "samples": f.samples,
                "innovation_autocorrelation_outside": int(np.sum(np.abs(self.white_z) > 1.96)),
                "innovation_autocorrelation_chi2": wq,
                "innovation_chi2_95": chi2_95(LAGS - f.order),
                "input_cross_correlation_outside": int(np.sum(np.abs(self.input_c) > 1.96)),
                "input_cross_correlation_chi2": iq,
                "chi2_95": CHI2_95_LAGS,
                "lags": LAGS, "sensor_noise": self.is_sensor_noise,
                "meaning": ("sensor noise with this spectrum" if self.is_sensor_noise else
                            "model error: the spectrum of what the model misses"),
                "notes": list(self.notes)}


def segment_verdict(segments: list[SegmentResidual], quant_var: float = 0.0,
                    max_order: int = REML_MAX_ORDER) -> SegmentVerdict:
    """AR model of a segmented residual (:func:`reml_ar`) and the two residual tests.

    The innovations are the residual whitened by the fitted model (Cholesky factor of
    its covariance) with the segments' fitted directions projected out; under the model
    they are white with a known covariance (the projection), whose mean autocorrelation
    is subtracted.  Sensor noise: the portmanteau Σ z_h² of their autocorrelation is below
    the χ² 95 % quantile with :data:`LAGS` − p degrees of freedom, Σ c_τ² of their
    correlation with the past input below that with :data:`LAGS`, and the model's RMS at
    most :data:`SLOW_POWER_MAX` times the residual's.

    Parameters
    ----------
    segments : list of SegmentResidual
        The residual of each segment.
    quant_var : float
        q²/12 [rad²].
    max_order : int
        Largest AR order tried.

    Returns
    -------
    SegmentVerdict
        The model, the tests, and whether the residual is sensor noise.
    """
    fit, lik = reml_ar(segments, quant_var, max_order)
    parts = lik.innovations(np.array(fit.phi), fit.std)
    # the same order as the groups: map each segment's input in
    inputs = []
    for key_items in _group_order(segments):
        inputs.extend(key_items)
    wz, wout = _whiteness_statistic(parts, LAGS)
    ic, iout = _input_statistic(parts, inputs, LAGS)
    wq, iq = float(np.sum(wz**2)), float(np.sum(ic**2))
    rms = lik.scale
    visible = fit.std <= SLOW_POWER_MAX * rms
    ok = wq < chi2_95(LAGS - fit.order) and iq < CHI2_95_LAGS and visible
    notes = [f"AR order {fit.order} by BIC of the restricted likelihood (0 … "
             f"{len(fit.bic) - 1})",
             f"innovation autocorrelation: Σz² = {wq:.3g} (χ²_{LAGS - fit.order} 95 %: "
             f"{chi2_95(LAGS - fit.order):.4g}), {wout} of {LAGS} lags outside ±1.96",
             f"innovation vs past input: Σc² = {iq:.3g} (χ²_{LAGS} 95 %: {CHI2_95_LAGS:.4g}), "
             f"{iout} of {LAGS} lags outside ±1.96"]
    if not visible:
        notes.append(f"the AR model's RMS {math.degrees(fit.std):.3g}° is more than "
                     f"{SLOW_POWER_MAX:g}× the residual's {math.degrees(rms):.3g}°: most of its "
                     "power would be slower than a segment, where the log cannot tell it from "
                     "the model's drift")
    if ok and fit.order > 0:
        notes.append("an input-independent disturbance missing from the model would look the "
                     "same (the tests cannot tell it from coloured encoder noise)")
    return SegmentVerdict(fit, wz, ic, ok, notes)


def _group_order(segments: list[SegmentResidual]) -> list[list[np.ndarray]]:
    """The segments' inputs in the order :class:`_Reml` groups them."""
    groups: dict[bytes, list[np.ndarray]] = {}
    for s in segments:
        groups.setdefault(np.asarray(s.k, dtype=np.int64).tobytes(), []).append(s.u)
    return list(groups.values())
