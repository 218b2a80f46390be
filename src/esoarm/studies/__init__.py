"""Studies built on the engines: the paper's reproduction and its report, sweeps,
tuning, the observer/controller analysis (poles, Theorem 1 and 2 bounds), and
the identification of a rig from its logs (experiments and grey-box fits).
"""
