"""Figures of runs (numerics never import this package; results forward to it)."""
