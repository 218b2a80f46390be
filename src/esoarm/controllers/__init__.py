"""Controllers: the control law from the estimate and the reference.

``flc``               controller kind "flc": feedback linearization (paper eq. 14-17)
``computed_torque``   its n-joint form: one ESO per joint, computed torque on the nominal model
"""
