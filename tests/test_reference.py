"""Reference trajectories: quintic rest-to-rest moves and multisines."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from esoarm.reference import Multisine, QuinticSteps, evaluate_reference


def _fd_check(ref, t, h=1e-5):
    p, v, a = evaluate_reference(ref, t)
    pp, vp, _ = evaluate_reference(ref, t + h)
    pm, vm, _ = evaluate_reference(ref, t - h)
    np.testing.assert_allclose(v, (pp - pm) / (2 * h), rtol=0, atol=1e-7)
    np.testing.assert_allclose(a, (vp - vm) / (2 * h), rtol=0, atol=1e-6)


def test_quintic_defaults_hold_and_move():
    ref = QuinticSteps()
    t = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 11.0, 12.0, 20.0])
    p, v, a = evaluate_reference(ref, t)
    np.testing.assert_array_equal(p[[0, 1, 2]], 0.0)
    assert p[3] == pytest.approx(0.5)  # half way through the first move (symmetric)
    np.testing.assert_array_equal(p[[4, 5, 6]], 1.0)
    assert p[7] == pytest.approx(0.5)
    np.testing.assert_array_equal(p[[8, 9]], 0.0)
    np.testing.assert_array_equal(v[[0, 4, 5, 8, 9]], 0.0)
    assert v[3] == pytest.approx(1.0 * 30 / 16 / 2.0)  # peak rate of the quintic: 15/8 · Δ/T
    np.testing.assert_array_equal(a[[0, 4, 5, 8, 9]], 0.0)


def test_quintic_derivatives_are_consistent():
    ref = QuinticSteps(start=0.2, moves=[[0.5, 1.5, -0.4], [3.0, 0.7, 1.1]])
    t = np.linspace(0.51, 3.69, 400)
    t = t[(np.abs(t - 2.0) > 1e-3) & (np.abs(t - 3.0) > 1e-3)]  # away from the move ends
    _fd_check(ref, t)


@given(start=st.floats(-3, 3), t0=st.floats(0, 10), dur=st.floats(0.01, 5),
       target=st.floats(-3, 3), s=st.floats(0, 1))
def test_quintic_rest_to_rest(start, t0, dur, target, s):
    ref = QuinticSteps(start=start, moves=[[t0, dur, target]])
    p, v, a = evaluate_reference(ref, np.array([t0, t0 + s * dur, t0 + dur, t0 + dur + 1.0]))
    assert p[0] == pytest.approx(start, abs=1e-12) and v[0] == 0.0 and a[0] == 0.0
    assert p[2] == target and p[3] == target and v[2] == 0.0 and a[2] == 0.0
    lo, hi = min(start, target), max(start, target)
    assert lo - 1e-12 <= p[1] <= hi + 1e-12  # no overshoot
    assert v[1] * (target - start) >= -1e-12  # moves towards the target


def test_quintic_continuous_at_move_ends():
    ref = QuinticSteps()
    for edge in (1.0, 3.0, 10.0, 12.0):
        p, v, a = evaluate_reference(ref, np.array([edge - 1e-9, edge + 1e-9]))
        assert abs(p[1] - p[0]) < 1e-8 and abs(v[1] - v[0]) < 1e-7 and abs(a[1] - a[0]) < 1e-6


def test_multisine():
    ref = Multisine(amplitudes=[0.5, 0.1], frequencies=[0.5, 3.0], phases=[0.2, -1.0],
                    offset=0.3)
    t = np.linspace(0, 20, 300)
    p, v, a = evaluate_reference(ref, t)
    np.testing.assert_allclose(
        p, 0.3 + 0.5 * np.sin(0.5 * t + 0.2) + 0.1 * np.sin(3.0 * t - 1.0), rtol=0, atol=1e-15)
    _fd_check(ref, t)


def test_multisine_default_is_test2():
    t = np.linspace(0, 20, 50)
    p, v, a = evaluate_reference(Multisine(), t)
    np.testing.assert_allclose(p, 0.5 * np.sin(0.5 * t), rtol=0, atol=1e-16)
    np.testing.assert_allclose(v, 0.25 * np.cos(0.5 * t), rtol=0, atol=1e-16)
    np.testing.assert_allclose(a, -0.125 * np.sin(0.5 * t), rtol=0, atol=1e-16)


def test_scalar_time():
    p, v, a = evaluate_reference(Multisine(), 1.0)
    assert p.shape == (1,) and p[0] == pytest.approx(0.5 * np.sin(0.5))
