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
    """Round x to the nearest multiple of q (halves up); identity for q = 0."""
    if q > 0.0:
        return q * math.floor(x / q + 0.5)
    return x


@jitable
def measure(theta: float, noise: float, sigma: float, q: float) -> float:
    """Encoder reading Q(θ + σ n) [rad]."""
    return quantize(theta + sigma * noise, q)


def noise_sequence(seed: int, n_samples: int, noise_deg: float) -> np.ndarray:
    """Standard-normal draws n_0 … n_{N−1} of one run (zeros when noise_deg = 0).

    Exactly ``numpy.random.default_rng(seed).standard_normal(N)`` (the sampled-data loop),
    so every engine and independent implementation sees the same noise.
    """
    if noise_deg > 0:
        return np.random.default_rng(seed).standard_normal(n_samples)
    return np.zeros(n_samples)
