"""Observers: estimate the state and the total perturbation from the measured angle.

``linear``   observer kind "linear": the paper's ESO (eq. 8) and its discretizations
"""
