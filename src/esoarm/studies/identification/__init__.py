"""Identification of a rig from logs: data, fit, report, figures, excitation."""
