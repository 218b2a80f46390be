"""Identification of a prismatic or rotary axis (plant.kind = "axis"): the output-error fit
and the command that drives it."""
