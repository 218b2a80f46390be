"""The identification experiment: the excitation plan and its guard loop, the breakaway probe
and the motion it measures, and the calibration study of the estimator (seeded twins)."""
