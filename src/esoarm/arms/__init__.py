"""Serial arms from URDF files: one ESO per joint, computed torque on the nominal model.

The lever arm's method joint by joint (see ``docs/arms.md``): the rigid-body
dynamics come from Pinocchio (the optional extra ``esoarm[arms]``, imported
lazily), the observers and the tracking law are the lever arm's own step
functions.

* :mod:`esoarm.arms.urdf` -- the nominal and true models from a URDF file;
* :mod:`esoarm.arms.twin` -- the digital twin, one ABA call per RK4 stage;
* :mod:`esoarm.arms.control` -- the per-joint observers and computed torque;
* :mod:`esoarm.arms.simulation` -- the sampled-data closed loop.
"""
