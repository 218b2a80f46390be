"""The host controller of ``esoarm run`` driving the emulator's twin in lockstep (shared by
the controller tests that compare it with the reference engine)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from esoarm.scenario import Scenario

if TYPE_CHECKING:
    from esoarm.hardware.host_control import DeploymentController


def lockstep(scn: Scenario) -> tuple[list[float], DeploymentController]:
    """:class:`~esoarm.hardware.host_control.DeploymentController` fed the encoder counts of
    :class:`~esoarm.hardware.emulator.Twin`, as ``esoarm run`` over the emulated device.

    Parameters
    ----------
    scn : Scenario
        The scenario (its sensor noise is the twin's).

    Returns
    -------
    u : list of float
        u_k [N·m], one per sample.
    controller : DeploymentController
        The host controller after the last sample.
    """
    from esoarm.hardware.emulator import Twin
    from esoarm.hardware.host_control import DeploymentController

    ctl, twin = DeploymentController(scn), Twin(scn)
    q = math.radians(scn.sensor.resolution_deg)
    u_log = []
    for k in range(ctl.n_samples):
        u, _ = ctl.actuate(ctl.step(k, q * twin.count()))
        ctl.commit(u)
        twin.advance(u)
        u_log.append(u)
    return u_log, ctl


def host_commands(scn: Scenario) -> list[float]:
    """The command of each sample of :func:`lockstep`: u_k [N·m]."""
    return lockstep(scn)[0]
