"""excite's guard loop and the rig's transport delay (issue 30: with a delay of 2-3 samples
at 50 Hz and little friction the default plan swung the arm past its angle limit; 9 of 35
calibration rigs never reached identify)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from esoarm.hardware.excite import excite_twin
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.identification.experiment.excitation import (
    GUARD_MARGIN_DEG,
    ExcitationPlan,
    guard_kd,
    guard_margin,
    plan_text,
)

LITTLE_FRICTION = ["rig.coulomb_friction=0", "rig.viscous_friction=0.001"]


def test_guard_margin_against_python_control():
    """The phase margin against python-control's, the delay as a 10th-order Padé."""
    import control

    for kp, kd, inertia, b, tau in ((1.0, 0.05, 0.02475, 0.001, 0.05),
                                    (1.0, 0.2, 0.02475, 0.01, 0.03),
                                    (2.0, 0.1, 0.1, 0.05, 0.0)):
        s = control.tf("s")
        loop = (kp + kd * s) / (inertia * s**2 + b * s)
        if tau > 0:
            num, den = control.pade(tau, 10)
            loop = loop * control.tf(num, den)
        _gm, pm, _wg, _wp = control.margin(loop)
        assert guard_margin(kp, kd, inertia, b, tau) == pytest.approx(pm, abs=0.2)


@pytest.mark.parametrize("delay", [2, 3])
def test_the_guard_keeps_a_delayed_arm_within_its_limit(delay):
    """Before: the angle limit at sample 607 (delay 2) / 193 (delay 3), motor off.  Now kd is
    raised until the loop has its phase margin back, and the 60 s run ends inside ±π."""
    scn = load_scenario("test-1", [f"actuator.delay_samples={delay}", *LITTLE_FRICTION])
    plan = ExcitationPlan(duration=60.0)
    inertia = scn.plant.inertia * scn.rig.inertia_scale
    tau = (delay + 0.5) * scn.sample_time
    assert guard_margin(plan.kp, plan.kd, inertia, 0.001, tau) < GUARD_MARGIN_DEG
    kd = guard_kd(scn, plan)
    assert kd > plan.kd and guard_margin(plan.kp, kd, inertia, 0.001, tau) >= 20.0
    _summary, preview = excite_twin(scn, plan, None)
    assert preview["max_abs_theta"] < 0.6 * math.pi
    assert "kd raised from 0.05" in plan_text(plan, scn)


def test_a_plan_without_delay_is_unchanged():
    scn = load_scenario("test-1")
    plan = ExcitationPlan()
    assert guard_kd(scn, plan) == plan.kd
    assert "kd raised" not in plan_text(plan, scn)


def test_a_delay_no_kd_can_hold_is_refused_in_words():
    scn = load_scenario("test-1", ["actuator.delay_samples=4", *LITTLE_FRICTION])
    with pytest.raises(ScenarioError, match=r"kp 1: the guard loop cannot be kept stable with "
                                            r"a delay of 4 sample\(s\).*lower kp"):
        guard_kd(scn, ExcitationPlan())
    # a weaker kp holds it
    assert np.isfinite(guard_kd(scn, ExcitationPlan(kp=0.2)))
