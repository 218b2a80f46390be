"""IDIM-LS: least squares on the inverse dynamic model, the robotics standard.

For one axis the inverse dynamic model (IDM) is linear in its parameters
(Khalil and Dombre; the EMPS benchmark's eq. 1-2):

    τ = M q̈ + Fv q̇ + Fc sign(q̇) + offset  [+ G cos q, rotary with gravity]
      = φ(q, q̇, q̈) θ

so with q̇ and q̈ estimated from the measured position the parameters follow
from one linear least-squares problem -- no simulation, no starting values,
no bounds, in whatever units the log is written.  The estimation is the data
set's own (Gautier 1997; the EMPS scripts ``Script_IDIM_LS.m``):

1. *band-pass filtered derivatives*: q filtered forward and backward by a
   Butterworth low-pass (order 4, cut-off ``cutoff_hz``, default :func:`select_cutoff`:
   from twice the motion's band up to a tenth of the sample rate, where the model explains
   the force best, so that it follows the motion, not the rate), then q̇ and q̈
   by central differences (MATLAB's ``diffcent``), :data:`BORDER` samples dropped at each end;
2. *decimation*: every column of φ and the force τ low-pass filtered and
   resampled by ``nd`` = round(fs/(4 ``cutoff_hz``)) (:func:`scipy.signal.decimate`,
   the order-8 Chebyshev filter run forward and backward as MATLAB's
   ``decimate``), which removes the force ripple the loop rejects;
3. θ̂ = argmin ‖y − Φ θ‖ (:func:`numpy.linalg.lstsq`).

The benchmark's quality figure is the *relative force error*
100·‖y − Φθ̂‖/‖y‖ [%] (:func:`force_error`), on the estimation data and
(cross-test) on data not used to estimate.

Intervals.  The classical standard deviations σ̂ √diag((ΦᵀΦ)⁻¹) assume a
white residual; the IDIM residual is not (model error: asymmetric friction,
flexibility).  :func:`hac_covariance` is the Newey-West
heteroscedasticity-and-autocorrelation-consistent sandwich (Bartlett weights)
with a bandwidth read from the residual's own autocorrelation
(:func:`hac_bandwidth`); the 95 % intervals use it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["ASYMMETRY_Z", "BORDER", "NAMES", "NAMES_ASYMMETRIC", "IdimResult",
           "asymmetry_threshold", "band_cutoff",
           "cross_test", "decimation_factor", "filtered_derivatives", "force_error",
           "hac_bandwidth", "hac_covariance", "idim_ls", "idim_system", "motion_band",
           "regressors", "select_cutoff", "staged_decimate", "viscous_asymmetry"]

#: Samples dropped at each end after the filters (their edge effects; EMPS: 50).
BORDER = 50
#: Order of the Butterworth low-pass of the position.
ORDER = 4
#: Parameter names of the regressor columns, in order (the gravity column only when asked).
NAMES = ("mass", "viscous_friction", "coulomb_friction", "offset", "gravity")
#: The same with the viscous friction split by direction (:func:`regressors`, asymmetric).
NAMES_ASYMMETRIC = ("mass", "viscous_friction_pos", "viscous_friction_neg", "coulomb_friction",
                    "offset", "gravity")


def _diffcent(y: np.ndarray, ts: float) -> np.ndarray:
    """Central differences [1/s]: (y[k+1] − y[k−1])/(2 ts), one-sided at the ends."""
    out = np.empty_like(y)
    out[1:-1] = (y[2:] - y[:-2]) / 2.0
    out[0] = y[1] - y[0]
    out[-1] = y[-1] - y[-2]
    return out / ts


def filtered_derivatives(y: np.ndarray, ts: float,
                         cutoff_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q̂, q̂̇, q̂̈) from the measured position ``y`` sampled every ``ts`` [s].

    Butterworth low-pass of order :data:`ORDER` at ``cutoff_hz`` [Hz], run
    forward and backward (no lag), then central differences.
    """
    from scipy.signal import butter, filtfilt

    b, a = butter(ORDER, cutoff_hz * 2.0 * ts)
    q = filtfilt(b, a, y)
    dq = _diffcent(q, ts)
    return q, dq, _diffcent(dq, ts)


#: The motion's band ends where the position's spectrum falls below this many times the
#: encoder's noise floor (its median density over the top half of the band).
BAND_SNR = 10.0


def band_cutoff(y: np.ndarray, ts: float) -> float:
    """The derivative filter's cut-off [Hz]: where the measured motion ``y`` leaves the noise.

    The highest frequency at which the position's Welch spectrum (4 s windows, linear trend
    removed) exceeds :data:`BAND_SNR` times its noise floor (the median density over the top
    half of the band), at most a tenth of the sample rate (the EMPS scripts' fs/10) and at
    least 20 bins of the log.  It follows the motion, not the sample rate: a 1 kHz log of a
    step and its 100 Hz down-sample get about the same filter (the fixed fs/10 gave
    100 Hz and 10 Hz, and inertias 40 % apart).
    """
    from scipy.signal import welch

    x = np.asarray(y, dtype=float)
    n = len(x)
    fs = 1.0 / ts
    if n < 64 or not np.all(np.isfinite(x)):
        return 0.1 * fs
    f, p = welch(x, fs, nperseg=min(n, int(round(4.0 * fs))), detrend="linear")
    floor = float(np.median(p[f >= 0.25 * fs]))
    above = np.flatnonzero(p[1:] > BAND_SNR * floor)
    band = float(f[1:][above[-1]]) if above.size and floor > 0 else 0.1 * fs
    return float(min(0.1 * fs, max(band, 20.0 * fs / n)))


#: The candidate cut-offs step down from a tenth of the sample rate by this factor.
CUTOFF_STEP = math.sqrt(2.0)
#: The written interval joins the HAC intervals of the candidate cut-offs within an octave
#: of the chosen one whose force error is within this factor of its own: how far the
#: estimate moves with the filter (model error in that band, which one filter's HAC
#: interval does not cover).
FILTER_SLACK = 1.25
#: The lowest candidate cut-off is this many times the motion's band (:func:`motion_band`):
#: the order-4 Butterworth run forward and backward keeps 99.6 % of the power there.
BAND_MARGIN = 2.0


def motion_band(parts: list[np.ndarray], ts: float, share: float = 0.9) -> float:
    """The frequency [Hz] below which ``share`` of the motion's energy lies, over the logs
    ``parts`` (positions).

    The velocity by first differences, its periodogram over the whole log (a step's velocity
    starts and ends at rest, so nothing leaks from the log's ends); a bin counts as motion
    where the position's periodogram (the velocity's over the difference's gain) exceeds
    :data:`BAND_SNR` times the encoder's noise floor (its median over the top half of the
    band; white noise passes that one bin in a thousand), so the noise does not stretch the
    band.

    Parameters
    ----------
    parts : list of ndarray
        The logs' positions [rad or m], one array per log.
    ts : float
        Sample period [s].
    share : float
        The share of the motion's energy below the band's top (0-1).

    Returns
    -------
    float
        The band's top [Hz], the largest over the logs (0 where nothing moved).
    """
    best = 0.0
    for y in parts:
        v = np.diff(np.asarray(y, dtype=float)) / ts
        if len(v) < 8 or not np.all(np.isfinite(v)):
            continue
        pv = np.abs(np.fft.rfft(v - v.mean())) ** 2
        f = np.fft.rfftfreq(len(v), ts)
        gain = (2.0 * np.sin(np.pi * f * ts) / ts) ** 2
        py = np.where(gain > 0, pv / np.where(gain > 0, gain, 1.0), 0.0)
        top = f >= 0.25 / ts
        floor = float(np.median(py[top])) if top.any() else 0.0
        signal = np.where(py > BAND_SNR * floor, py, 0.0)
        total = float(signal.sum())
        if total <= 0.0:
            continue
        k = int(np.searchsorted(np.cumsum(signal) / total, share))
        best = max(best, float(f[min(k, len(f) - 1)]))
    return best


def select_cutoff(force_error_at: Callable[[float], float], ts: float, band_hz: float,
                  shortest_s: float) -> tuple[float, tuple[float, ...]]:
    """The derivative filter's cut-off [Hz] for IDIM-LS, from the excitation's band up.

    Candidates step down from a tenth of the sample rate (the EMPS scripts' fs/10) by
    :data:`CUTOFF_STEP`, to :data:`BAND_MARGIN` × the motion's band ``band_hz`` (below it
    the filter would cut the motion) and to 20 periods of the shortest log ``shortest_s``.
    The cut-off is the candidate whose IDIM-LS explains the force best (lowest relative
    force error, ``force_error_at(cutoff)``): too high a cut-off lets the encoder's noise and
    vibration the model lacks into q̈ (errors in the variables pull the inertia towards 0);
    too low a one cuts the motion.  Both ends follow the motion, not the sample rate: a
    1 kHz step and its 100 Hz down-sample get about the same filter.

    Parameters
    ----------
    force_error_at : callable
        ``force_error_at(cutoff_hz) -> float``: IDIM-LS's relative force error with the
        filter at that cut-off (may raise ValueError or LinAlgError: the candidate is skipped).
    ts : float
        Sample period [s].
    band_hz : float
        The motion's band [Hz] (:func:`motion_band`).
    shortest_s : float
        The shortest log's length [s].

    Returns
    -------
    cutoff : float
        The chosen cut-off [Hz].
    around : tuple of float
        The candidates within an octave of it whose force error is within
        :data:`FILTER_SLACK` of its own (their intervals join the written one).
    """
    top = 0.1 / ts
    low = max(BAND_MARGIN * band_hz, 20.0 / max(shortest_s, ts))
    cands = [top]
    while cands[-1] / CUTOFF_STEP >= min(low, top / 4.0) * 0.999:
        cands.append(cands[-1] / CUTOFF_STEP)
    errors: dict[float, float] = {}
    for fc in cands:
        try:
            fe = float(force_error_at(fc))
        except (ValueError, np.linalg.LinAlgError):
            continue
        if math.isfinite(fe):
            errors[fc] = fe
    if not errors:
        return top, ()
    best = min(errors, key=lambda fc: errors[fc])
    around = tuple(fc for fc, fe in errors.items() if fc != best
                   and 0.5 * best * 0.999 <= fc <= 2.0 * best * 1.001
                   and fe <= FILTER_SLACK * errors[best])
    return best, around


def staged_decimate(x: np.ndarray, nd: int) -> np.ndarray:
    """:func:`scipy.signal.decimate` by ``nd`` along axis 0 (zero phase), in stages of at
    most 10 (scipy's advice for its IIR filter beyond 13)."""
    from scipy.signal import decimate

    stages = []
    rest = nd
    while rest > 10:
        f = next((f for f in range(10, 1, -1) if rest % f == 0), rest)
        stages.append(f)
        rest //= f
    stages.append(rest)
    for f in stages:
        if f > 1:
            x = decimate(x, f, axis=0, zero_phase=True)
    return x


#: Rows where the filtered speed is below this share of its peak are rest (left out).
MOVING_SHARE = 0.05
#: With fewer moving rows than this the log hardly moves and every row is kept.
MIN_MOVING_ROWS = 40
#: A candidate cut-off leaving fewer rows than this many per parameter is not chosen.
ROWS_PER_PARAMETER = 10
#: The decimated rate is this many times the cut-off (its Nyquist frequency twice the
#: cut-off: the filtered band is kept whole, whatever the log's rate).
DECIMATED_RATE = 4.0


def decimation_factor(ts: float, cutoff_hz: float, rate: float = DECIMATED_RATE) -> int:
    """nd = round(fs / (:data:`DECIMATED_RATE` · cutoff)), at least 1 (EMPS, 1 kHz with the
    scripts' 100 Hz cut-off: 2; the scripts' own nd = fs/cutoff = 10 left the decimated
    Nyquist frequency at half the cut-off, and a 100 Hz log of a 1 s step with ten rows)."""
    return max(1, int(round(1.0 / (ts * cutoff_hz * rate))))


def regressors(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
               gravity: bool = False, asymmetric: bool = False) -> np.ndarray:
    """The IDM's observation matrix φ: columns q̈, q̇, sign(q̇), 1 (and cos q with gravity).

    With ``asymmetric`` the viscous column is split by direction, q̇·[q̇ > 0] and
    q̇·[q̇ < 0] (:data:`NAMES_ASYMMETRIC`).  The Coulomb friction is not split: on a
    log that keeps moving, [q̇ > 0] and [q̇ < 0] add up to the offset's column of
    ones, so Fc+ − Fc− and twice the offset enter the force the same way and
    cannot be told apart (the split matrix is singular).
    """
    if asymmetric:
        pos = dq > 0.0
        cols = [ddq, np.where(pos, dq, 0.0), np.where(pos, 0.0, dq), np.sign(dq),
                np.ones_like(q)]
    else:
        cols = [ddq, dq, np.sign(dq), np.ones_like(q)]
    if gravity:
        cols.append(np.cos(q))
    return np.column_stack(cols)


def _decimate(x: np.ndarray, nd: int) -> np.ndarray:
    return x if nd == 1 else staged_decimate(x, nd)


def force_error(y: np.ndarray, yhat: np.ndarray) -> float:
    """The benchmark's relative force error 100·‖y − ŷ‖/‖y‖ [%]."""
    return float(100.0 * np.linalg.norm(y - yhat) / np.linalg.norm(y))


def hac_bandwidth(r: np.ndarray, threshold: float = 0.1) -> int:
    """Newey-West bandwidth [samples] from the residual ``r``'s autocorrelation.

    Twice the first lag at which |ρ| falls below ``threshold`` (the memory of
    the residual), at least the rule of thumb ⌊4 (N/100)^(2/9)⌋ and at most N/4.
    """
    n = len(r)
    rc = r - r.mean()
    spec = np.fft.rfft(rc, 2 * n)
    acf = np.fft.irfft(spec * np.conj(spec))[:n]
    acf = acf / acf[0] if acf[0] > 0 else acf
    below = np.flatnonzero(np.abs(acf) < threshold)
    memory = int(below[0]) if below.size else n
    rule = int(4.0 * (n / 100.0) ** (2.0 / 9.0))
    return int(min(max(2 * memory, rule), n // 4))


def hac_covariance(x: np.ndarray, r: np.ndarray, lags: int) -> np.ndarray:
    """Newey-West covariance of the least-squares estimate for regressors ``x`` (N×p),
    residual ``r`` (N), Bartlett weights 1 − l/(lags+1) up to ``lags``.

    (XᵀX)⁻¹ S (XᵀX)⁻¹ with S = Γ0 + Σ_l w_l (Γ_l + Γ_lᵀ), Γ_l = Σ_k g_k g_{k−l}ᵀ,
    g_k = x_k r_k.  The same function serves a nonlinear fit with ``x`` its
    Jacobian (rows: samples).
    """
    g = x * r[:, None]
    s = g.T @ g
    for lag in range(1, lags + 1):
        gamma = g[lag:].T @ g[:-lag]
        s += (1.0 - lag / (lags + 1.0)) * (gamma + gamma.T)
    bread = np.linalg.pinv(x.T @ x)
    return np.asarray(bread @ s @ bread)


@dataclass(frozen=True)
class IdimResult:
    """An IDIM-LS estimate.

    Attributes
    ----------
    names : tuple of str
        Parameter names (:data:`NAMES`, in the log's units: mass [kg] or inertia
        [kg·m²], viscous friction, Coulomb friction, offset [N or N·m]).
    values : ndarray
        θ̂.
    se_white : ndarray
        Classical standard errors σ̂ √diag((ΦᵀΦ)⁻¹) (the published ones; white residual).
    se_hac : ndarray
        Newey-West standard errors (:func:`hac_covariance`).
    bandwidth : int
        The Newey-West bandwidth [decimated samples].
    force_error : float
        Relative force error on the estimation data [%].
    condition : float
        Condition number of Φ.
    n : int
        Rows of Φ (decimated samples).
    decimation : int
        nd.
    cutoff_hz : float
        The Butterworth cut-off [Hz].
    max_autocorrelation : float
        Largest |ρ| of the residual over lags 1 … 20 (1 would be white noise's ±2/√n).
    cov_hac : ndarray or None
        The Newey-West covariance of θ̂ (p×p), whose square-rooted diagonal is ``se_hac``.
    ci_joined : ndarray or None
        p×2: the 95 % interval written for each parameter when the cut-off was chosen from
        the data -- this cut-off's HAC interval joined with those of the neighbouring
        cut-offs that explain the force about as well (``around_hz``,
        :func:`select_cutoff`): how far the estimate moves with the filter.  None: the
        HAC interval alone.
    around_hz : tuple of float
        Those neighbouring cut-offs [Hz].
    """

    names: tuple[str, ...]
    values: np.ndarray
    se_white: np.ndarray
    se_hac: np.ndarray
    bandwidth: int
    force_error: float
    condition: float
    n: int
    decimation: int
    cutoff_hz: float
    max_autocorrelation: float
    cov_hac: np.ndarray | None = None
    ci_joined: np.ndarray | None = None
    around_hz: tuple[float, ...] = ()

    @property
    def asymmetric(self) -> bool:
        """Whether the viscous friction is split by direction."""
        return "viscous_friction_pos" in self.names

    def value(self, name: str) -> float:
        """θ̂ of ``name``."""
        return float(self.values[self.names.index(name)])

    def ci95(self, name: str) -> tuple[float, float]:
        """The 95 % interval of ``name``: HAC, joined with the neighbouring cut-offs' when
        the cut-off was chosen from the data (``ci_joined``)."""
        i = self.names.index(name)
        if self.ci_joined is not None:
            return float(self.ci_joined[i, 0]), float(self.ci_joined[i, 1])
        half = 1.96 * float(self.se_hac[i])
        return float(self.values[i]) - half, float(self.values[i]) + half


def idim_system(y: np.ndarray, u: np.ndarray, ts: float, cutoff_hz: float | None = None,
                gravity: bool = False,
                asymmetric: bool = False, rate: float = DECIMATED_RATE,
                moving_only: bool = True) -> tuple[np.ndarray, np.ndarray, int, float]:
    """(Φ, y_F, nd, cutoff): the decimated observation matrix and force of one log.

    ``y`` the measured position, ``u`` the force/torque [N or N·m], ``ts`` [s];
    ``asymmetric`` splits the viscous column by direction (:func:`regressors`).
    With ``moving_only`` the rows where the axis is at rest (filtered speed below
    :data:`MOVING_SHARE` of its peak) are left out: there sign(q̇) is the sign of noise
    and the force is whatever static friction holds, so a rest carries no information
    about the model, only model error (a step followed by rest is fitted on the step).
    """
    cutoff = cutoff_hz if cutoff_hz is not None else band_cutoff(y, ts)
    q, dq, ddq = filtered_derivatives(y, ts, cutoff)
    keep = slice(BORDER - 1, len(y))  # as the EMPS script: samples n_border … N
    x = regressors(q, dq, ddq, gravity, asymmetric)[keep]
    nd = decimation_factor(ts, cutoff, rate)
    xd, fd = _decimate(x, nd), _decimate(u[keep], nd)
    if moving_only:
        speed = np.abs(_decimate(dq[keep], nd))
        moving = speed >= MOVING_SHARE * float(np.max(speed, initial=0.0))
        if moving.sum() >= MIN_MOVING_ROWS:  # (the same rows whatever the model's columns)
            xd, fd = xd[moving], fd[moving]
    return xd, fd, nd, cutoff


def idim_ls(parts: list[tuple[np.ndarray, np.ndarray]], ts: float,
            cutoff_hz: float | None = None, gravity: bool = False,
            asymmetric: bool = False, rate: float = DECIMATED_RATE,
            moving_only: bool = True, around: tuple[float, ...] = ()) -> IdimResult:
    """IDIM-LS over one or more logs (``parts``: (position, force) pairs), see the module.

    The logs' observation matrices are stacked (each filtered on its own);
    ``asymmetric`` fits the viscous friction of each direction
    (:data:`NAMES_ASYMMETRIC`).  Without ``cutoff_hz`` one filter for every log is chosen
    from the data (:func:`select_cutoff`) and the written intervals join those of the
    neighbouring cut-offs that explain the force about as well; ``around`` [Hz] gives such
    neighbours for a given cut-off (the same filter's estimate of another model).
    """
    if cutoff_hz is None:
        band = motion_band([y for y, _u in parts], ts)
        shortest = min(len(y) for y, _u in parts) * ts

        def fe_at(fc: float) -> float:
            est = _idim_fixed(parts, ts, fc, gravity, asymmetric, rate, moving_only)
            if est.n < ROWS_PER_PARAMETER * len(est.values):
                raise ValueError("too few rows")
            return est.force_error

        cutoff_hz, around = select_cutoff(fe_at, ts, band, shortest)
    est = _idim_fixed(parts, ts, cutoff_hz, gravity, asymmetric, rate, moving_only)
    if not around:
        return est
    lo = np.array([est.ci95(n)[0] for n in est.names])
    hi = np.array([est.ci95(n)[1] for n in est.names])
    for fc in around:
        other = _idim_fixed(parts, ts, fc, gravity, asymmetric, rate, moving_only)
        lo = np.minimum(lo, [other.ci95(n)[0] for n in other.names])
        hi = np.maximum(hi, [other.ci95(n)[1] for n in other.names])
    from dataclasses import replace

    return replace(est, ci_joined=np.column_stack([lo, hi]), around_hz=tuple(around))


def _idim_fixed(parts: list[tuple[np.ndarray, np.ndarray]], ts: float, cutoff_hz: float,
                gravity: bool, asymmetric: bool, rate: float,
                moving_only: bool) -> IdimResult:
    """IDIM-LS with one given cut-off (see :func:`idim_ls`)."""
    systems = [idim_system(y, u, ts, cutoff_hz, gravity, asymmetric, rate, moving_only)
               for y, u in parts]
    x = np.vstack([s[0] for s in systems])
    f = np.concatenate([s[1] for s in systems])
    theta, *_ = np.linalg.lstsq(x, f, rcond=None)
    r = f - x @ theta
    p = x.shape[1]
    s2 = float(r @ r) / max(len(f) - p, 1)
    se_white = np.sqrt(s2 * np.diag(np.linalg.pinv(x.T @ x)))
    lags = hac_bandwidth(r)
    cov = hac_covariance(x, r, lags)
    se_hac = np.sqrt(np.maximum(np.diag(cov), 0.0))
    rc = r - r.mean()
    denom = float(rc @ rc) or 1.0
    rho = max(abs(float(rc[:-k] @ rc[k:]) / denom) for k in range(1, 21))
    names = NAMES_ASYMMETRIC if asymmetric else NAMES
    return IdimResult(names[:p], theta, se_white, se_hac, lags, force_error(f, x @ theta),
                      float(np.linalg.cond(x)), len(f), systems[0][2], systems[0][3],
                      rho, cov)


#: |Fv+ − Fv−| beyond this many HAC standard errors keeps the asymmetric viscous friction
#: (two-sided 99 %: a symmetric axis keeps it one time in a hundred, and the symmetric
#: model is nested in it, so keeping it wrongly costs only width).
ASYMMETRY_Z = 2.576


def asymmetry_threshold(est: IdimResult) -> float:
    """The |z| beyond which the viscous asymmetry of ``est`` is kept: the two-sided 99 %
    point of Student's t with the HAC estimate's effective degrees of freedom (rows per
    bandwidth, less the parameters), :data:`ASYMMETRY_Z` on a long log.  With a few dozen
    correlated rows (a step's rise and its overshoot) the HAC standard error is itself
    uncertain and the normal 2.576 keeps an asymmetry that the Coulomb friction and the
    offset explain as well.

    Parameters
    ----------
    est : IdimResult
        The asymmetric estimate (its rows ``n``, HAC bandwidth and values).

    Returns
    -------
    float
        The threshold on |z| (≥ :data:`ASYMMETRY_Z`).
    """
    from scipy.stats import t as student

    dof = est.n / max(est.bandwidth, 1) - len(est.values)
    if dof >= 1000:
        return ASYMMETRY_Z
    return float(student.ppf(0.995, max(dof, 1.0)))


def viscous_asymmetry(est: IdimResult) -> tuple[float, float, float]:
    """(Fv+ − Fv−, its HAC standard error, z) of an asymmetric estimate (Wald test).

    The test is on the HAC covariance, valid with a coloured residual (a likelihood
    ratio would assume a white one).
    """
    i, j = est.names.index("viscous_friction_pos"), est.names.index("viscous_friction_neg")
    diff = float(est.values[i] - est.values[j])
    cov = est.cov_hac
    var = (float(cov[i, i] + cov[j, j] - 2.0 * cov[i, j]) if cov is not None
           else float(est.se_hac[i] ** 2 + est.se_hac[j] ** 2))
    se = math.sqrt(max(var, 0.0))
    return diff, se, (abs(diff) / se if se > 0 else math.inf)


def cross_test(y: np.ndarray, u: np.ndarray, ts: float, values: np.ndarray,
               cutoff_hz: float, gravity: bool = False, asymmetric: bool = False,
               rate: float = DECIMATED_RATE, moving_only: bool = True) -> float:
    """The relative force error [%] of parameters ``values`` on a log not used to estimate
    them (the benchmark's cross-test), with the same filters."""
    x, f, _nd, _c = idim_system(y, u, ts, cutoff_hz, gravity, asymmetric, rate, moving_only)
    return force_error(f, x @ values)

