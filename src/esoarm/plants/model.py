"""The lever-arm model of the paper (eq. 4-5) and the lumped perturbation (eq. 7).

Sign conventions: θ [rad] is the arm angle, positive in the direction of
positive motor torque u [N·m].  The gravity torque enters the dynamics as

    I0 θ̈ + G(θ) = u,      G(θ) = (m1 l1 − m2 l2) g cos θ          (eq. 4)

so with the state x1 = θ, x2 = θ̇ (eq. 5)

    ẋ1 = x2,   ẋ2 = −G(x1)/I0 + u/I0 + d.

All functions are plain float arithmetic so the compiled batch engine can
reuse them (see :mod:`esoarm._jit`).
"""

from __future__ import annotations

from esoarm._jit import jitable
from esoarm.plants.elementary import cos


@jitable
def gravity_coefficient(m1: float, m2: float, l1: float, l2: float, g: float) -> float:
    """Amplitude of the gravity torque, (m1 l1 − m2 l2) g [N·m] (eq. 4).

    Parameters
    ----------
    m1 : float
        Mass on the motor side of the pivot [kg].
    m2 : float
        Counterweight mass on the other side [kg].
    l1 : float
        Distance of m1 from the pivot [m].
    l2 : float
        Distance of m2 from the pivot [m].
    g : float
        Gravitational acceleration [m/s²], positive.

    Returns
    -------
    float
        gcoef = (m1 l1 − m2 l2) g [N·m]; positive when the m1 side is heavier.

    Examples
    --------
    >>> gravity_coefficient(1.0, 0.5, 0.2, 0.2, 10.0)
    1.0
    """
    return (m1 * l1 - m2 * l2) * g


@jitable
def gravity_torque(theta: float, gcoef: float) -> float:
    """Gravity torque G(θ) = gcoef · cos θ [N·m] (eq. 4).

    Parameters
    ----------
    theta : float
        Arm angle θ [rad].
    gcoef : float
        (m1 l1 − m2 l2) g [N·m], from :func:`gravity_coefficient`.

    Returns
    -------
    float
        G(θ) [N·m]; it enters as I0 θ̈ + G(θ) = u, so a positive G pulls θ̈ negative.
    """
    return gcoef * cos(theta)


@jitable
def input_gain(inertia: float) -> float:
    """Nominal input gain b0 = 1/I0 [1/(kg·m²)] of eq. 5 and eq. 8.

    Parameters
    ----------
    inertia : float
        Moment of inertia I0 about the pivot [kg·m²], positive.

    Returns
    -------
    float
        b0 = 1/I0 [1/(kg·m²)].

    Examples
    --------
    >>> input_gain(0.25)
    4.0
    """
    return 1.0 / inertia
