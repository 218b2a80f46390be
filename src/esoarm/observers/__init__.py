"""Observers: estimate the state and the total perturbation from the measured angle.

``linear``   the paper's linear extended state observer (eq. 8) and its discretizations
"""
