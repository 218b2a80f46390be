"""The delay predictor's nominal loop: the separation principle holds on an exact-model ESO.

The loop: the delayed double integrator θ̈ = b0 u_{k−N} (exact under a held input), the ESO's
analysis model (:func:`esoarm.observers.linear.linearization`, 3 + N states, the N commands
held being the plant's own delay line) and the FLC u = −k2 θ̂ − k1 θ̇̂ − f̂/b0 on the
estimate.  With the predictor on an ESO whose model is the exact held-input one ("zoh",
"current"), the loop's poles are the sampled FLC's on the true state, the ESO's error poles
and zeros, for every N: the prediction hands the FLC the state N samples ahead exactly.  On
the paper's Euler ESO the estimation error depends on u and the loop loses that margin as N
grows (docs/adrc.md, "A delay-aware ESO": unstable from N = 9 at ε = 0.03 s, 50 Hz).
"""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.observers import linear as lin

TS, B0, K1, K2 = 0.02, 44.0, 10.0, 25.0


def _loop(nd: int, eps: float, disc: str, form: str) -> np.ndarray:
    """The closed loop's matrix; state (θ, θ̇, z of the ESO with its N commands)."""
    params = lin.Params(eps=eps, discretization=disc, input_delay=nd, delay_form=form)
    m = lin.linearization(params, TS, B0)
    n = m.p.shape[0]
    c = np.zeros((1, 2 + n))
    c[0, 0] = 1.0  # y = θ
    zsel = np.hstack([np.zeros((n, 2)), np.eye(n)])
    est = m.hz @ zsel + m.hy @ c  # ẑ from the loop's state
    u = -(K2 * est[0] + K1 * est[1] + est[2]) / B0
    applied = zsel[3] if nd else u  # u_{k−N}: the first command the ESO holds
    acc = B0 * applied
    a = np.zeros((2 + n, 2 + n))
    a[0] = np.eye(2 + n)[0] + TS * np.eye(2 + n)[1] + 0.5 * TS * TS * acc
    a[1] = np.eye(2 + n)[1] + TS * acc
    a[2:] = m.p @ zsel + m.q @ c + m.gamma @ u[None, :]
    return a


def _flc_poles() -> np.ndarray:
    a = np.array([[1.0 - 0.5 * TS * TS * K2, TS - 0.5 * TS * TS * K1],
                  [-TS * K2, 1.0 - TS * K1]])
    return np.linalg.eigvals(a)


@pytest.mark.parametrize("disc", ["zoh", "current"])
@pytest.mark.parametrize("nd", [1, 4, 8, 12])
def test_predictor_keeps_the_flc_poles_on_an_exact_model_eso(disc: str, nd: int) -> None:
    eps = 0.03
    ev = np.linalg.eigvals(_loop(nd, eps, disc, "predictor"))
    eso = lin.design_observer(eps, TS, B0, disc).poles
    want = np.concatenate([_flc_poles(), eso, np.zeros(nd)])
    # the triple ESO pole and the zeros split at round-off^(1/3): compare the polynomials
    np.testing.assert_allclose(np.poly(ev), np.poly(want), atol=1e-9)
    assert np.max(np.abs(ev)) == pytest.approx(np.max(np.abs(_flc_poles())), abs=1e-9)


def test_without_the_prediction_the_loop_degrades() -> None:
    """The same ESO fed u_{k−N} but handing over ẑ_k: the FLC acts on a state N samples old
    and the loop oscillates (the test fails if the prediction is disabled)."""
    radius = np.max(np.abs(np.linalg.eigvals(_loop(8, 0.03, "current", "input"))))
    assert radius > np.max(np.abs(_flc_poles())) + 0.02


def test_euler_eso_loses_the_separation() -> None:
    """The paper's Euler ESO under the same predictor: poorly damped at N = 8, unstable from 9
    (ε = 0.03 s, 50 Hz) where the exact-model ESO keeps the FLC's radius."""
    flc = np.max(np.abs(_flc_poles()))
    radius = {nd: np.max(np.abs(np.linalg.eigvals(_loop(nd, 0.03, "euler", "predictor"))))
              for nd in (8, 9)}
    assert radius[8] > flc + 0.05
    assert radius[9] > 1.0


def test_the_predictor_on_the_euler_eso_is_warned_of() -> None:
    from esoarm.observers.linear import warnings
    from esoarm.scenario import load_scenario

    scn = load_scenario("test-1", {"observer.input_delay": 3, "observer.delay_form": "predictor"})
    assert any("'predictor' with discretization 'euler'" in w
               for w in warnings(scn.observer, scn.sample_time))
    for disc in ("current", "zoh"):
        ok = load_scenario("test-1", {"observer.input_delay": 3, "observer.delay_form": "predictor",
                                      "observer.discretization": disc})
        assert not any("predictor" in w for w in warnings(ok.observer, ok.sample_time))
