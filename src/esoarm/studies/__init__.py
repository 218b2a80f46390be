"""Studies built on the engines: the paper's reproduction and its report, sweeps,
tuning, and the observer/controller analysis (poles, Theorem 1 and 2 bounds).
"""
