"""Serial arms from URDF files: plant kind ``"urdf"``, its models, twin and compiled rigid body.

``urdf``        plant kind "urdf": a serial arm from a URDF file, the kind's step functions
``model``       loading a URDF: the nominal and true models (Pinocchio), built-in robots
``twin``        the arm's twin: friction, disturbance, lag, RK4 around Pinocchio's ABA
``rigid_body``  the rigid body compiled (numba): RNEA, CRBA, forward dynamics, per run and per block
``compiled``    the twin's step functions on the compiled rigid body (the batch engine's)
"""
