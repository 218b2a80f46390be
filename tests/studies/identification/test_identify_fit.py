"""The least-squares problem of an identification: the parallel Jacobian against one
simulation at a time, the prediction cache, the fit order's shortcuts."""

from __future__ import annotations

import numpy as np
import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.plants.motor import MotorParams
from esoarm.scenario import load_scenario
from esoarm.studies.identification.data import read_ident_log, simulate_segments
from esoarm.studies.identification.experiment.excitation import ExcitationPlan
from esoarm.studies.identification.fit import PARAMS, Problem
from esoarm.studies.identification.identify import _values


@pytest.fixture(scope="module", params=["torque", "motor"])
def problem(request, tmp_path_factory):
    sets = ["motor.torque_constant=0.02"] if request.param == "motor" else []
    scn = load_scenario("test-1", [*sets, "actuator.lag=0.02", "rig.stiction=0.1"])
    path = tmp_path_factory.mktemp("fit") / "ex.csv"
    excite_twin(scn, ExcitationPlan(duration=6.0), path)
    log = read_ident_log(path, 2.0, MotorParams.from_scenario(scn))
    free = [k for k in PARAMS if scn.motor is not None or k != "motor.torque_constant"]
    prob = Problem(scn, [log], 50, 1, 1, free, _values(scn))
    x = np.concatenate([[_values(scn)[k] * 1.03 for k in free], prob.initial_states()])
    return prob, x, (scn, log)


def _one_at_a_time(prob, x):
    """The Jacobian as the sequential definition: one simulate_segments call per column."""
    def sim(xx):
        plant, src = prob.design(xx)
        out = np.zeros(len(prob.y))
        simulate_segments(out, plant, src, prob.t, prob.seg_start, prob.seg_len,
                          np.ascontiguousarray(xx[prob.n_phys:]), prob.h, prob.nsub)
        return out

    base = sim(x)
    cols = np.zeros((len(prob.y), len(x)))
    scales = prob.scales()
    for i in range(prob.n_phys):
        step = 1e-6 * max(abs(x[i]), scales[i])
        if x[i] + step > PARAMS[prob.free[i]][3][1]:
            step = -step
        xp = x.copy()
        xp[i] += step
        cols[:, i] = (sim(xp) - base) / step
    seg_of = np.repeat(np.arange(prob.n_seg), prob.seg_len)
    rows = np.concatenate([np.arange(s, s + n) for s, n in zip(prob.seg_start, prob.seg_len,
                                                               strict=True)])
    for j, step in ((0, 1e-6), (1, 1e-5)):
        xp = x.copy()
        xp[prob.n_phys + j::2] += step
        cols[rows, prob.n_phys + 2 * seg_of + j] = ((sim(xp) - base) / step)[rows]
    return base, cols[prob.mask]


def test_parallel_jacobian_is_the_sequential_one_bit_for_bit(problem):
    prob, x, _ = problem
    base, want = _one_at_a_time(prob, x)
    got = prob.jacobian(x)
    assert got.shape == want.shape == (int(prob.mask.sum()), len(x))
    assert np.array_equal(got, want)
    assert np.array_equal(prob.predict(x)[prob.mask], base[prob.mask])


def test_prediction_cache_is_keyed_on_the_parameters(problem):
    _, _, (scn, log) = problem
    prob = Problem(scn, [log], 50, 1, 1, ["rig.inertia_scale"], _values(scn))
    x = np.concatenate([[1.2], prob.initial_states()])
    a = prob.predict(x)
    assert prob.predict(x.copy()) is a  # the same point: not simulated again
    other = x.copy()
    other[0] *= 1.01
    b = prob.predict(other)
    assert b is not a and not np.array_equal(a[prob.mask], b[prob.mask])
    assert not a.flags.writeable  # shared with the cache: nobody may change it
    held = prob.with_fixed({"rig.viscous_friction": 0.05})  # a held value: another model
    assert not np.array_equal(held.predict(other)[prob.mask], b[prob.mask])


def test_lag_and_delay_fit_simulates_no_more_than_it_needs(tmp_path, monkeypatch):
    """A twin with lag and delay: the scenario's delay (0) is not fitted to the end before
    the others are tried, and the Jacobian's columns reuse the accepted prediction.  The
    work is counted in simulations of the log (timings belong to benchmarks/): 448 for
    this log before, 178 after; the fit finds the twin back either way.  Since issue 20's
    case 6 a log shorter than two periods of the scenario's disturbance (this one: 15 s of
    fitting data, 25 s) also gets a few iterations without d(t): 282 in all.  Since issue 30
    the neighbouring delays are always retried from the converged fit (a delay decided by a
    cost ratio alone was confidently wrong on sticking twins): 318.  Since the delay search
    goes one past the longest delay tried while the best is there (here the lag makes delay 2
    look best before the lag is fitted: +31) and the stiction fit is screened after 10
    iterations (260 -> 100 here): 392.  With excite's guard loop since raised for the delay
    (main a5e5dc8) the log differs, and its lag fit takes more iterations: 535.  The
    neighbouring delays tried again with the final model (lag, stiction): 601.  The
    delay's profile walked with the final model (each delay also from the best model as
    it is, the walk going on from a new best and past delays inside the threshold): 654."""
    from esoarm.studies.identification import fit as identify_fit
    from esoarm.studies.identification.identify import identify

    truth = load_scenario("test-1", ["actuator.lag=0.03", "actuator.delay_samples=1",
                                     "rig.inertia_scale=1.25", "rig.coulomb_friction=0.08"])
    path = tmp_path / "ld.csv"
    excite_twin(truth, ExcitationPlan(duration=20.0), path)
    count = [0]
    one, many = identify_fit.simulate_segments_parallel, identify_fit.simulate_columns

    def counted_one(*args):
        count[0] += 1
        return one(*args)

    def counted_many(outs, *args):
        count[0] += outs.shape[0]
        return many(outs, *args)

    monkeypatch.setattr(identify_fit, "simulate_segments_parallel", counted_one)
    monkeypatch.setattr(identify_fit, "simulate_columns", counted_many)
    res = identify(load_scenario("test-1"), [read_ident_log(path, 2.0)])
    assert count[0] <= 680, count[0]
    assert res.value("actuator.delay_samples") == 1
    for key, true in (("actuator.lag", 0.03), ("rig.inertia_scale", 1.25),
                      ("rig.coulomb_friction", 0.08)):
        lo, hi = res.estimates[key].ci95
        assert lo <= true <= hi, (key, res.estimates[key])
