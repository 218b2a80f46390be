"""analyze --bandwidth against a sweep optimum (docs/frequency.md states these numbers)."""

from __future__ import annotations

import pytest

from esoarm.studies.frequency.sweep_check import (
    DOC_GRID,
    Measured,
    check_recommendation,
    sweep_optimum,
)


def test_sweep_optimum_is_the_least_chatter_within_the_error_bound():
    pts = [Measured("linear", 0.03, 0.009, 0.4, 0.60),
           Measured("cascade", 0.04, 0.0105, 0.2, 0.15),
           Measured("cascade", 0.07, 0.03, 0.05, 0.03),
           Measured("linear", 0.045, 0.0117, 0.15, 0.21)]
    assert sweep_optimum(pts, 0.0117) == pts[1]  # 0.03 N·m is cheaper but tracks 3× worse
    assert sweep_optimum(pts, 0.0117 * 3) == pts[2]
    assert sweep_optimum(pts, 0.001) is None


@pytest.mark.slow
def test_bandwidth_recommendation_against_the_sweep_on_test_1_and_2():
    """W = 15 rad/s, 0.5° of noise, seeds 0-3: the budget predicts the recommendation's
    measured chatter within 10 %; the sweep optimum is the same kind at a smaller ε (the
    recommendation at its f → ẑ3 bandwidth tracks worse than the linear ESO at the same
    bandwidth), within a factor 1.2-2.1 of the recommended ε."""
    from esoarm.scenario import load_scenario

    for test in ("test-1", "test-2"):
        check = check_recommendation(load_scenario(test, ["sensor.noise_deg=0.5"]), 15.0,
                                     DOC_GRID)
        rec, at, opt = check.recommended, check.at_recommended, check.optimum
        assert at.kind == rec.kind and at.eps == rec.eps
        assert at.rms_du == pytest.approx(rec.budget.rms_du, rel=0.10)
        assert opt is not None and opt.rms_error <= check.error_limit
        assert check.same_kind and rec.kind == "cascade"
        assert 1.2 <= check.eps_ratio <= 2.1
        assert at.rms_error > check.error_limit  # equal bandwidth is not equal tracking
        assert opt.rms_du > at.rms_du


@pytest.mark.slow
def test_tracking_match_agrees_with_the_sweep_optimum():
    """``match_tracking`` (analyze --bandwidth W --tracking) on test-1 and test-2, W = 15 rad/s,
    0.5° of noise, seeds 0-3: the same kind as the sweep optimum over DOC_GRID × (linear,
    cascade), at an ε within 1.25× of the optimum's (the bandwidth-matched recommendation
    was 1.27-1.59× slow here), and within the bound it was matched to."""
    from esoarm.scenario import load_scenario
    from esoarm.studies.frequency.sweep_check import _measure, match_tracking

    for test in ("test-1", "test-2"):
        scn = load_scenario(test, ["sensor.noise_deg=0.5"])
        bound, matches = match_tracking(scn, 15.0)
        grid = _measure(scn, [(k, e) for k in ("linear", "cascade") for e in DOC_GRID],
                        (0, 1, 2, 3))
        opt = sweep_optimum(grid, bound)
        rec = matches[0]
        assert opt is not None and rec.kind == opt.kind == "cascade"
        assert 1 / 1.25 <= rec.eps / opt.eps <= 1.25
        assert rec.measured.rms_error <= bound
        assert rec.budget_du == pytest.approx(rec.measured.rms_du, rel=0.10)
