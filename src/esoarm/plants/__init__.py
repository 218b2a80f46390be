"""Plants: the true system the loop drives (the lever-arm twin, its encoder and motor).

``model``       the paper's nominal lever-arm model (eq. 4-5), known to the controller
``lever_arm``   plant kind "lever-arm": the lever-arm rig, true dynamics, RK4 integration
``sensor``      the encoder: noise and quantization
``actuator``    saturation, motor, transport delay: what reaches the plant (every kind)
``motor``       the optional DC motor and driver (``[motor]``)
``urdf``        a serial arm from a URDF file: nominal and true models (Pinocchio)
``urdf_twin``   the URDF arm's twin: friction, disturbance, lag, RK4 around Pinocchio's ABA
"""
