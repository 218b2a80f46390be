"""Plants: the true system the loop drives (the lever-arm twin, its encoder and motor).

``model``       the paper's nominal lever-arm model (eq. 4-5), known to the controller
``lever_arm``   plant kind "lever-arm": the lever-arm rig, true dynamics, RK4 integration
``sensor``      the encoder: noise and quantization
``actuator``    saturation, motor, transport delay: what reaches the plant (every kind)
``motor``       the optional DC motor and driver (``[motor]``)
``noise``       coloured measurement noise: AR encoder noise, arm vibration
``backlash``    gear backlash (the twin's dead zone)
``elementary``  tanh, cos and exp(−x) in plain arithmetic: the same bits in every engine
``axis``        plant kind "axis": any single rotary or prismatic axis
``arms``        serial arms from URDF files (plant kind "urdf"): models, twin, compiled rigid body
"""
