"""The ESO of eq. 8 and its discretizations, against python-control and pyadrc."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from pyadrc import StateSpace

from esoarm.engines.simulation import prepare, simulate
from esoarm.observers.linear import (
    DISCRETIZATIONS,
    ExtendedStateObserver,
    continuous_error_matrix,
    continuous_gains,
    design_observer,
    discrete_error_matrix,
    eso_advance,
    eso_estimate,
    extended_plant,
)
from esoarm.observers.stability import characteristic_polynomial
from esoarm.plants.sensor import measure
from esoarm.scenario import load_scenario

EPS = [0.05, 0.09, 0.2, 0.013, 1.0]
TS = [0.02, 0.001, 0.005]
B0 = 1.0 / 0.0225


def _triple(p: float) -> np.ndarray:
    """Coefficients of (x − p)³, highest power first."""
    return np.array([1.0, -3.0 * p, 3.0 * p * p, -(p**3)])


@pytest.mark.parametrize("eps", EPS)
def test_continuous_gains_against_acker(eps):
    """Theorem 1: acker puts the three poles at −1/ε with β = (3/ε, 3/ε², 1/ε³)."""
    a, _, c = extended_plant(B0)
    gain = np.asarray(control.acker(a.T, c.reshape(3, 1), [-1.0 / eps] * 3)).ravel()
    np.testing.assert_allclose(continuous_gains(eps), gain, rtol=1e-12)
    np.testing.assert_allclose(continuous_gains(eps), [3 / eps, 3 / eps**2, 1 / eps**3],
                               rtol=1e-15)
    np.testing.assert_allclose(characteristic_polynomial(continuous_error_matrix(eps)),
                               _triple(-1.0 / eps), rtol=1e-12)


@pytest.mark.parametrize("ts", TS)
def test_zoh_matrices_against_sample_system(ts):
    a, b, c = extended_plant(B0)
    sysd = control.sample_system(control.ss(a, b.reshape(3, 1), c.reshape(1, 3), 0), ts,
                                 method="zoh")
    for disc in ("zoh", "current"):
        d = design_observer(0.09, ts, B0, disc)
        np.testing.assert_allclose(d.phi, sysd.A, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(d.gamma, np.asarray(sysd.B).ravel(), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("ts", TS)
@pytest.mark.parametrize("eps", EPS)
def test_discrete_gains_place_poles_at_exp(eps, ts):
    """Lp and Lc place the poles at e^{−Ts/ε}: python-control, char. polynomial, closed form.

    ``control.acker`` works on powers of Φ − pI with p close to 1 and loses
    digits as Ts/ε shrinks (3e-8 relative at Ts/ε = 0.001), hence its looser
    tolerance; the closed form, written with expm1, is checked to 1e-9.
    """
    p = math.exp(-ts / eps)
    one_minus_p = -math.expm1(-ts / eps)
    acker_rtol = 1e-9 if ts / eps >= 0.01 else 1e-6
    c = np.array([[1.0, 0.0, 0.0]])
    zoh = design_observer(eps, ts, B0, "zoh")
    cur = design_observer(eps, ts, B0, "current")
    lp = np.asarray(control.acker(zoh.phi.T, c.T, [p] * 3)).ravel()
    lc = np.asarray(control.acker(cur.phi.T, (c @ cur.phi).T, [p] * 3)).ravel()
    np.testing.assert_allclose(zoh.gain, lp, rtol=acker_rtol)
    np.testing.assert_allclose(cur.gain, lc, rtol=acker_rtol)
    # the closed-loop error matrices have characteristic polynomial (z − p)³
    np.testing.assert_allclose(characteristic_polynomial(zoh.phi - np.outer(zoh.gain, c)),
                               _triple(p), rtol=0, atol=1e-12)
    np.testing.assert_allclose(characteristic_polynomial(cur.phi - np.outer(cur.gain, c @ cur.phi)),
                               _triple(p), rtol=0, atol=1e-12)
    for disc in ("zoh", "current"):
        np.testing.assert_allclose(characteristic_polynomial(discrete_error_matrix(eps, ts, disc)),
                                   _triple(p), rtol=0, atol=1e-12)
    # Herbst's closed form of the current-form gains (as used by pyadrc)
    q = one_minus_p
    herbst = [q * (1 + p + p * p), 1.5 / ts * q**2 * (1 + p), q**3 / ts**2]
    np.testing.assert_allclose(cur.gain, herbst, rtol=1e-9)
    # the predictive gain is Φ·Lc (similar error matrices)
    np.testing.assert_allclose(zoh.gain, zoh.phi @ cur.gain, rtol=1e-9)


@pytest.mark.parametrize("eps", EPS)
def test_euler_design(eps):
    ts = 0.02
    d = design_observer(eps, ts, B0, "euler")
    a, b, _ = extended_plant(B0)
    np.testing.assert_array_equal(d.phi, np.eye(3) + ts * a)
    np.testing.assert_array_equal(d.gamma, ts * b)
    np.testing.assert_allclose(d.gain, ts * np.array(continuous_gains(eps)), rtol=1e-15)
    np.testing.assert_allclose(characteristic_polynomial(discrete_error_matrix(eps, ts, "euler")),
                               _triple(1 - ts / eps), rtol=0, atol=1e-12)


def test_euler_step_is_eq8():
    d = design_observer(0.09, 0.02, B0, "euler")
    z, y, u = (0.1, -0.3, 2.0), 0.15, 0.4
    b1, b2, b3 = continuous_gains(0.09)
    e = y - z[0]
    rhs = (z[1] + b1 * e, z[2] + B0 * u + b2 * e, b3 * e)
    new = eso_advance(*z, *z, y, u, d.vector)
    np.testing.assert_allclose(new, [z[i] + 0.02 * rhs[i] for i in range(3)], rtol=1e-15)
    assert eso_estimate(*z, y, d.vector) == z


@pytest.mark.parametrize("eps", [0.05, 0.09, 0.2])
def test_current_form_matches_pyadrc(eps):
    """Our "current" ESO and pyadrc's StateSpace give the same estimates.

    Index conventions, lined up from pyadrc's source (pyadrc.pyadrc.StateSpace):
    ``ctrl(y_k, u_{k-1}, r)`` updates x̂ ← (Ad − L C Ad) x̂ + (Bd − L C Bd) u_{k−1} + L y_k,
    i.e. prediction with u_{k−1} then correction with y_k: its x̂ after the
    call with (y_k, u_{k−1}) is our ẑ_k (the estimate the FLC uses at t_k).
    pyadrc's ``eso_init`` is the estimate *before* the first call, x̂_{−1};
    with u_{−1} = 0 its first prediction is Ad x̂_{−1}, and since Ad maps
    (a, 0, 0) to itself, ``eso_init = z_0 = (y_0, 0, 0)`` lines up with the sampled-data loop.
    pyadrc's observer poles are at exp(−k_eso·w_cl·Ts), so k_eso·w_cl = 1/ε.
    """
    ts = 0.02
    w_cl = 4.0
    rng = np.random.default_rng(3)
    n = 400
    y = np.cumsum(rng.normal(0, 0.01, n)) + 0.2 * np.sin(np.arange(n) * ts)
    u = rng.normal(0, 0.3, n)
    adrc = StateSpace(order=2, delta=ts, b0=B0, w_cl=w_cl, k_eso=1.0 / (eps * w_cl),
                      eso_init=(y[0], 0.0, 0.0))
    eso = ExtendedStateObserver(design_observer(eps, ts, B0, "current"), y[0])
    ours = np.empty((n, 3))
    theirs = np.empty((n, 3))
    u_prev = 0.0
    for k in range(n):
        ours[k] = eso.estimate(y[k])
        eso.update(u[k])
        adrc(y[k], u_prev, 0.0)
        theirs[k] = np.asarray(adrc.eso_states).ravel()
        u_prev = u[k]
    np.testing.assert_allclose(np.asarray(adrc.L).ravel(), eso.design.gain, rtol=1e-12)
    for i in range(3):
        scale = np.max(np.abs(theirs[:, i]))
        np.testing.assert_allclose(ours[:, i], theirs[:, i], rtol=0, atol=1e-10 * scale)
    # a one-sample shift of the inputs would not agree: the check is sharp
    assert np.max(np.abs(ours[1:, 2] - theirs[:-1, 2])) > 1e-3 * np.max(np.abs(theirs[:, 2]))


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_stateful_observer_replays_the_simulation(disc):
    """ExtendedStateObserver fed the run's (y_k, u_k) reproduces the logged ẑ_k exactly."""
    scn = load_scenario("test-2", {"observer.discretization": disc, "duration": 4.0})
    res = simulate(scn, warn=False)
    inp = prepare(scn)
    y = [measure(th, nk, inp.sigma, inp.q) for th, nk in zip(res.theta, inp.noise, strict=True)]
    eso = ExtendedStateObserver(design_observer(scn.observer.eps, scn.sample_time,
                                                1.0 / scn.plant.inertia, disc), y[0])
    replay = np.empty_like(res.z)
    for k in range(len(y)):
        replay[k] = eso.estimate(y[k])
        eso.update(res.u[k])
    assert np.array_equal(replay, res.z)


@pytest.mark.parametrize("disc", ("zoh", "current"))
def test_exact_discretizations_track_the_extended_plant(disc):
    """On the exact sampled extended plant (constant f), "zoh"/"current" converge to 0 error."""
    ts, eps = 0.02, 0.09
    d = design_observer(eps, ts, B0, disc)
    x = np.array([0.3, -0.2, 4.0])  # θ, θ̇, f (constant perturbation)
    eso = ExtendedStateObserver(d, 0.0)
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(300):
        zhat = eso.estimate(x[0])
        errors.append(np.max(np.abs(np.asarray(zhat) - x)))
        uk = float(rng.normal(0, 0.1))
        eso.update(uk)
        x = d.phi @ x + d.gamma * uk
    assert errors[0] > 1.0  # starts wrong (f = 4 unknown)
    # poles e^{−Ts/ε} ≈ 0.80: after 300 samples ~ 300² · 0.8^300 · 4 ≈ 1e-23
    assert errors[-1] < 1e-9


def test_design_rejects_bad_arguments():
    with pytest.raises(ValueError, match="eps"):
        continuous_gains(0.0)
    with pytest.raises(ValueError, match="eps"):
        design_observer(-0.1, 0.02, B0, "zoh")
    with pytest.raises(ValueError, match="ts"):
        design_observer(0.09, 0.0, B0, "zoh")
    with pytest.raises(ValueError, match="discretization"):
        design_observer(0.09, 0.02, B0, "rk4")


def test_design_vector_is_read_only():
    d = design_observer(0.09, 0.02, B0, "current")
    with pytest.raises(ValueError):
        d.vector[0] = 1.0
    with pytest.raises(ValueError):
        d.gain[0] = 1.0


def _continuous_eso(eps, y, u, t_end):
    """Eq. 8 integrated by scipy from z(0) = (y(0), 0, 0)."""
    from scipy.integrate import solve_ivp

    b1, b2, b3 = continuous_gains(eps)

    def rhs(t, z):
        e = y(t) - z[0]
        return [z[1] + b1 * e, z[2] + B0 * u(t) + b2 * e, b3 * e]

    sol = solve_ivp(rhs, (0.0, t_end), [y(0.0), 0.0, 0.0], method="DOP853", rtol=1e-12,
                    atol=1e-12)
    return sol.y[:, -1]


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_discretizations_converge_to_eq8_first_order(disc):
    """As Ts → 0 every discretization tends to the continuous ESO, with error O(Ts).

    Smooth y(t) and u(t); the discrete observers see y_k = y(t_k) and hold
    u_k = u(t_k), the continuous one sees both continuously, so all three
    carry an O(Ts) difference that halves with Ts.
    """
    eps, t_end = 0.09, 1.0

    def y(t):
        return 0.3 * math.sin(2.0 * t) + 0.1 * t

    def u(t):
        return 0.02 * math.cos(3.0 * t)

    exact = _continuous_eso(eps, y, u, t_end)
    errors = []
    for ts in (2e-3, 1e-3, 5e-4):
        n = int(round(t_end / ts))
        eso = ExtendedStateObserver(design_observer(eps, ts, B0, disc), y(0.0))
        for k in range(n):
            eso.estimate(y(k * ts))
            eso.update(u(k * ts))
        errors.append(np.max(np.abs(np.asarray(eso.z) - exact) / (1.0 + np.abs(exact))))
    assert errors[-1] < 0.02
    for coarse, fine in zip(errors, errors[1:], strict=False):
        assert 1.7 < coarse / fine < 2.3, errors
