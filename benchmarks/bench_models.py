"""The continuous-time closed loop as a python-control system (benchmark (b))."""

from __future__ import annotations


def continuous_loop(scn):  # type: ignore[no-untyped-def]
    """The continuous-time closed loop as a python-control nonlinear system.

    States (θ, θ̇, z1, z2, z3): the rig (no lag), the eq. 8 ESO fed y = θ, and the
    saturated FLC -- built from esoarm's own physics functions.  No sampling,
    noise or quantization, so its numbers differ from the sampled loop by design.
    """
    import control as ct

    from esoarm.controllers.flc import FLCParams, flc_control
    from esoarm.observers.linear import continuous_gains, eso_rhs
    from esoarm.plants.lever_arm import RigParams, rig_acceleration
    from esoarm.plants.model import input_gain
    from esoarm.reference import evaluate_reference

    rig = RigParams.from_scenario(scn).vector
    ctl = FLCParams.from_scenario(scn).vector
    b0 = input_gain(scn.plant.inertia)
    beta = continuous_gains(scn.observer.eps)
    ref = scn.reference

    def update(t, x, u, params):  # type: ignore[no-untyped-def]
        r, dr, ddr = (float(v[0]) for v in evaluate_reference(ref, t))
        uc = flc_control(x[2], x[3], x[4], r, dr, ddr, ctl)
        acc = rig_acceleration(x[0], x[1], uc, t, rig)
        return [x[1], acc, *eso_rhs(x[2], x[3], x[4], x[0], uc, b0, *beta)]

    return ct.nlsys(update, lambda t, x, u, params: x[0], states=5, inputs=0, outputs=1,
                    name="closed_loop")
