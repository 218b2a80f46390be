"""Controllers: the control law from the estimate and the reference.

``flc``   the paper's feedback-linearization controller (eq. 14-17)
"""
