"""Analysis of the loop, in one import.

- Frequency domain: :func:`to_control` gives the loop linearized at an
  operating angle and sampled at Ts as python-control ``StateSpace`` systems
  (``.plant``, ``.controller``, ``.loop``; needs ``pip install 'esoarm[analyze]'``);
  :func:`analyze` computes margins, sensitivities and bandwidths
  (:mod:`esoarm.studies.frequency`, :mod:`esoarm.studies.linearization`).
- Observer and tracking bounds: gains, poles, Theorem 1 and 2
  (:mod:`esoarm.studies.analysis`).

Example
-------
>>> import control
>>> from esoarm.analysis import to_control
>>> sys = to_control("test-1", {"observer.eps": 0.05})
>>> gm, pm, _, _, wgc, _ = control.stability_margins(sys.loop)
>>> closed = control.feedback(sys.loop, 1)        # the closed loop, broken at the plant input
>>> bool(max(abs(closed.poles())) < 1)
True
"""

from esoarm.studies.analysis import (
    CONTINUOUS,
    ObserverAnalysis,
    analyze_observer,
    observer_gains,
    observer_poles,
    observer_warnings,
    theorem1_bound,
    theorem2_bound,
    tracking_l1_gain,
)
from esoarm.studies.frequency import FrequencyAnalysis, Margins, analyze, margins
from esoarm.studies.linearization import ControlLoop, LinearLoop, linearize, to_control

__all__ = [
    "CONTINUOUS",
    "ControlLoop",
    "FrequencyAnalysis",
    "LinearLoop",
    "Margins",
    "ObserverAnalysis",
    "analyze",
    "analyze_observer",
    "linearize",
    "margins",
    "observer_gains",
    "observer_poles",
    "observer_warnings",
    "theorem1_bound",
    "theorem2_bound",
    "to_control",
    "tracking_l1_gain",
]
