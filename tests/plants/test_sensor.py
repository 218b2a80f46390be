"""Encoder model: quantizer properties (hypothesis), noise sequence (loop step 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from esoarm.plants.sensor import measure, noise_sequence, quantize

angles = st.floats(min_value=-100.0, max_value=100.0, allow_nan=False)
steps = st.floats(min_value=1e-6, max_value=1.0, allow_nan=False)


@given(angles, steps)
def test_quantize_error_at_most_half_a_step(x, q):
    assert abs(quantize(x, q) - x) <= 0.5 * q * (1 + 1e-9)


@given(angles, steps)
def test_quantize_gives_multiples_of_q(x, q):
    n = quantize(x, q) / q
    assert abs(n - round(n)) < 1e-6


@given(angles, steps)
def test_quantize_idempotent(x, q):
    y = quantize(x, q)
    assert quantize(y, q) == y


@given(angles, angles, steps)
def test_quantize_monotone(x, y, q):
    lo, hi = min(x, y), max(x, y)
    assert quantize(lo, q) <= quantize(hi, q)


@given(angles)
def test_zero_resolution_is_identity(x):
    assert quantize(x, 0.0) == x


@pytest.mark.parametrize("n", [-3, -1, 0, 1, 2, 7])
def test_halves_round_up(n):
    q = 0.25  # exact in binary
    assert quantize((n + 0.5) * q, q) == (n + 1) * q
    assert quantize((n + 0.49) * q, q) == n * q


def test_encoder_resolution_example():
    q = math.radians(0.05)
    assert quantize(math.radians(0.12), q) == pytest.approx(math.radians(0.10), rel=1e-12)


@given(angles, st.floats(min_value=-5, max_value=5), st.floats(min_value=0, max_value=0.1),
       steps)
def test_measure_is_quantized_noisy_angle(theta, n, sigma, q):
    assert measure(theta, n, sigma, q) == quantize(theta + sigma * n, q)


def test_noise_sequence_is_default_rng_standard_normal():
    np.testing.assert_array_equal(noise_sequence(7, 500, 0.2),
                                  np.random.default_rng(7).standard_normal(500))
    np.testing.assert_array_equal(noise_sequence(7, 500, 0.0), np.zeros(500))
    assert not np.array_equal(noise_sequence(1, 50, 0.2), noise_sequence(2, 50, 0.2))
    np.testing.assert_array_equal(noise_sequence(3, 10, 0.2), noise_sequence(3, 10, 5.0))
