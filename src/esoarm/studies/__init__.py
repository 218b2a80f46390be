"""Studies built on the twin and the rig: identification experiments and fits."""
