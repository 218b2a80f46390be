"""Sweeps and tuning: grids of scenarios on the batch engine, their output and figures."""
