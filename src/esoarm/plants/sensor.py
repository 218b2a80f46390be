"""Encoder model: Gaussian noise then quantization (the sampled-data loop, step 1).

    y_k = Q(θ(t_k) + σ n_k),    Q(x) = q · floor(x/q + 1/2)

with n = numpy.random.default_rng(seed).standard_normal(N) drawn once per run
(only when σ > 0) and q the resolution in rad (q = 0: no quantization).
"""

from __future__ import annotations

import math

import numpy as np

from esoarm._jit import jitable

__all__ = ["measure", "noise_sequence", "quantize"]


@jitable
def quantize(x: float, q: float) -> float:
    """Round x to the nearest multiple of q (halves up); identity for q = 0.

    Parameters
    ----------
    x : float
        Value to quantize [rad].
    q : float
        Resolution [rad]; q ≤ 0 disables quantization.

    Returns
    -------
    float
        q · floor(x/q + 1/2) [rad], or x itself when q ≤ 0.

    Examples
    --------
    >>> quantize(0.26, 0.5), quantize(0.25, 0.5), quantize(-0.25, 0.5), quantize(0.3, 0.0)
    (0.5, 0.5, 0.0, 0.3)
    """
    if q > 0.0:
        return q * math.floor(x / q + 0.5)
    return x


@jitable
def measure(theta: float, noise: float, sigma: float, q: float) -> float:
    """Encoder reading Q(θ + σ n) [rad].

    Parameters
    ----------
    theta : float
        True angle θ(t_k) [rad].
    noise : float
        Standard-normal draw n_k of this sample (from :func:`noise_sequence`).
    sigma : float
        Noise standard deviation σ [rad].
    q : float
        Encoder resolution [rad]; 0 for none.

    Returns
    -------
    float
        The measured angle y_k [rad].
    """
    return quantize(theta + sigma * noise, q)


def noise_sequence(seed: int, n_samples: int, noise_deg: float) -> np.ndarray:
    """Standard-normal draws n_0 … n_{N−1} of one run (zeros when noise_deg = 0).

    Exactly ``numpy.random.default_rng(seed).standard_normal(N)`` (the sampled-data loop),
    so every engine and independent implementation sees the same noise.

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``.
    n_samples : int
        Number of draws N (samples × joints, joint index fastest, for the engines).
    noise_deg : float
        Noise standard deviation [deg]; only its sign matters here (0: no draws).

    Returns
    -------
    ndarray, shape (n_samples,)
        Dimensionless standard-normal draws (scaled by σ in :func:`measure`).

    Examples
    --------
    >>> noise_sequence(1, 3, 0.0).tolist()
    [0.0, 0.0, 0.0]
    """
    if noise_deg > 0:
        return np.random.default_rng(seed).standard_normal(n_samples)
    return np.zeros(n_samples)
