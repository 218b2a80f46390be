"""A URDF arm asks the registry which observer kinds take its joints (esoarm.kinds.observers_for),
it keeps no list of names: a kind registered at run time is accepted or refused by what its
design does."""

from __future__ import annotations

import types

import numpy as np
import pytest

from esoarm import kinds
from esoarm.scenario import ScenarioError, load_scenario
from kinds_extra import reduced


def _one_joint_only() -> types.ModuleType:
    """``reduced`` as another kind whose design refuses more than one joint (ValueError)."""
    from typing import Literal

    from pydantic import Field, create_model

    from esoarm.contract import ComponentDesign, read_only

    mod = types.ModuleType("one_joint_eso")
    mod.__dict__.update({k: v for k, v in vars(reduced).items() if not k.startswith("__")})
    mod.KIND, mod.CODE = "one-joint-eso", 9
    mod.Params = create_model("Params", __base__=reduced.Params,
                              kind=(Literal["one-joint-eso"], Field("one-joint-eso")))

    def design(scn, plant, ts):  # type: ignore[no-untyped-def]
        if plant.n_joints > 1:
            raise ValueError("one joint only")
        d = reduced.design(scn, plant, ts)
        return ComponentDesign(read_only(np.concatenate([[9.0], d.vector[1:]])), d.n_state)

    mod.design = design
    return mod


def test_a_registered_per_joint_observer_runs_a_two_link_arm():
    kinds.register("observer", reduced)
    try:
        assert "reduced" in kinds.observers_for(2)
        scn = load_scenario("two-link", {"observer.kind": "reduced"})
        assert scn.observer.kind == "reduced"
    finally:
        kinds.unregister("observer", reduced)


def test_an_observer_whose_design_takes_one_joint_is_refused_in_one_line():
    one = _one_joint_only()
    kinds.register("observer", one)
    try:
        assert "one-joint-eso" in kinds.observers_for(1)
        assert "one-joint-eso" not in kinds.observers_for(2)
        with pytest.raises(ScenarioError) as err:
            load_scenario("two-link", {"observer.kind": "one-joint-eso"})
        msg = str(err.value)
        assert "observer.kind" in msg and "designed for one joint" in msg
        assert "'linear'" in msg and "one-joint-eso" not in msg.split("use one of")[1]
    finally:
        kinds.unregister("observer", one)
