"""What every plant, observer and controller kind hands to the engines.

A *kind* is one module (``esoarm.plants.lever_arm``, ``esoarm.observers.linear``,
``esoarm.controllers.flc``, ...) registered in :mod:`esoarm.kinds`.  It provides

* ``KIND`` (the tag written in the scenario), ``CODE`` (a small integer, unique
  within its component, stored in element 0 of its parameter vector) and
  ``JIT`` (whether its step functions compile with numba);
* ``Params``: its validated scenario table, a :class:`esoarm._schema.Section`
  with a ``kind`` literal;
* ``design(scn, ...)``: the scenario turned into what its step functions need,
  one of the frozen records below (a read-only float vector plus sizes);
* plain step functions on array-valued state, called as Python by the
  reference engine and compiled by the batch engine (see docs/contract.md for
  their signatures);
* optionally ``C_SOURCE``: the name of a ``.c`` file beside the module with the
  same step in C99 for the generated controller (:mod:`esoarm.codegen`); a kind
  without it is refused by ``esoarm codegen``.

Array conventions (n joints): the plant state ``x`` holds the angles in
``x[:n]`` and the rates in ``x[n:2n]`` (further states after them); the
observer's estimate ``zhat`` holds (angle, rate, total perturbation) of joint
j in ``zhat[3j:3j+3]``; measurements ``y`` and commands ``u`` have length n.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeAlias

import numpy as np

__all__ = ["ComponentDesign", "PlantDesign", "Vector", "read_only"]

#: A parameter vector as the step functions take it: a NumPy array, or a tuple of
#: floats (the compiled engine hands vectors over as tuples, which live in registers).
Vector: TypeAlias = np.ndarray | tuple[float, ...]


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` as float64, flagged read-only (designs are immutable)."""
    out = np.array(array, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class PlantDesign:
    """What a plant kind's ``design`` returns.

    Attributes
    ----------
    vector : ndarray
        Parameters of the plant's step functions; ``vector[0]`` is the kind's CODE.
    x0 : ndarray
        Initial state (angles, then rates, then any further states).
    n_joints : int
        Number of joints n (inputs and measured angles).
    b0 : ndarray, shape (n,)
        Nominal input gain per joint [1/(kg·m²)], the b0 of the observer model
        and of the logged total perturbation f = θ̈ − b0 u.
    """

    vector: np.ndarray
    x0: np.ndarray
    n_joints: int
    b0: np.ndarray


@dataclass(frozen=True)
class ComponentDesign:
    """What an observer or controller kind's ``design`` returns.

    Attributes
    ----------
    vector : ndarray
        Parameters of the step functions; ``vector[0]`` is the kind's CODE.
    n_state : int
        Length of the component's own state array (≥ 1; unused entries are fine).
    """

    vector: np.ndarray
    n_state: int
