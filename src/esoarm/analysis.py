"""Analysis of the loop, in one import.

- Frequency domain: :func:`to_control` gives the loop linearized at an
  operating angle and sampled at Ts as python-control ``StateSpace`` systems
  (``.plant``, ``.controller``, ``.loop``; needs ``pip install 'esoarm[analyze]'``);
  :func:`analyze` computes margins, sensitivities and bandwidths
  (:mod:`esoarm.studies.frequency.margins`, :mod:`esoarm.studies.frequency.linearization`).
- Observer and tracking bounds: gains, poles, Theorem 1 and 2
  (:mod:`esoarm.observers.stability`).

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

from esoarm.observers.stability import (
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
from esoarm.studies.frequency.linearization import ControlLoop, LinearLoop, linearize, to_control
from esoarm.studies.frequency.margins import FrequencyAnalysis, Margins, analyze, margins

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
