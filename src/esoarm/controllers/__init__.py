"""Controllers: the control law from the estimate and the reference.

``flc``               kind "flc": the paper's feedback-linearization controller (eq. 14-17)
``computed_torque``   kind "computed-torque": the FLC on a URDF arm, M̂(α − ẑ3) per joint
"""
