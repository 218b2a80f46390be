"""A small seeded subset of the calibration study of ``esoarm identify`` (issue 30), run as a
user would: ``esoarm excite test-1 --twin`` then ``esoarm identify LOG --json``, each a
command of its own (:func:`esoarm.studies.identification.experiment.calibration.run_rig`).

* a twin that sticks most of its excitation (Coulomb friction 0.25 N·m above the
  multisine's 0.2 N·m RMS, no breakaway probe: stuck > 50 % of the samples) must not be
  written with exit 0 and an interval that misses its truth;
* seed 104 of the prior (50 Hz, a 3-sample delay beyond the default --max-delay 2, 0.42°
  of backlash, vibration, lag and stiction) must be answered, not refused: the code of
  main 105f283 refused it ("the log fits better without the scenario's disturbance",
  a likelihood-ratio test that the backlash and the delay beyond the search had inflated).
"""

from __future__ import annotations

from esoarm.studies.identification.experiment.calibration import (
    draw_rig,
    run_rig,
    sticking_rig,
    summary,
)


def test_a_twin_that_sticks_most_of_the_time_is_never_confidently_wrong(tmp_path):
    out = run_rig(sticking_rig(1), tmp_path)
    assert out.stuck_share > 0.5, out.stuck_share  # it does stick most of the time
    assert out.verdict in ("recovered", "flagged", "refused"), (out.verdict, out.missed,
                                                                out.params)
    if out.verdict == "flagged":  # the parameters it cannot support are named
        assert out.flagged


def test_a_delay_beyond_the_search_with_backlash_is_answered_not_refused(tmp_path):
    out = run_rig(draw_rig(104), tmp_path)
    assert out.verdict in ("recovered", "flagged"), (out.verdict, out.reason)
    assert not out.missed, out.params
    s = summary([out])
    assert s["wrong"] == 0 and s["coverage_percent"] == 100.0, s
