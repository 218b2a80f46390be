"""The linear ADRC forms' FLC equivalent (the kind contract's ``flc_equivalent``), through
which ``analyze`` models adrc-tf and adrc-error: the FLC (compensation "eso") with the
linear ESO of the form's own keys closes the same loop y → u.  adrc-tf commands that FLC's
u on any reference; adrc-error the same u at rest and a different one on a move (its
reference path), so the claim is the loop's, not the tracking's."""

from __future__ import annotations

import json

import numpy as np
import pytest

from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import load_scenario
from esoarm.studies.frequency.linearization import loop_scenario
from esoarm.studies.frequency.margins import analyze

FORMS = [(d, t) for d in ("euler", "zoh", "current") for t in ("bandwidth", "half-gain")]
REST = {"reference.moves": [[1.0, 2.0, 0.0]]}  # a "move" from 0 to 0: the arm held at rest


def _pair(kind: str, disc: str, tuning: str, extra: dict) -> tuple[np.ndarray, np.ndarray]:
    adrc = load_scenario("test-1", {"duration": 6.0, **extra, "controller.kind": kind,
                                    "controller.eps": 0.05, "controller.discretization": disc,
                                    "controller.tuning": tuning})
    flc = loop_scenario(adrc)
    assert flc.controller.kind == "flc" and flc.observer.kind == "linear"
    return run_reference(adrc, prepare(adrc)).u, run_reference(flc, prepare(flc)).u


@pytest.mark.parametrize("disc, tuning", FORMS)
def test_adrc_tf_commands_its_equivalents_u(disc: str, tuning: str) -> None:
    u_tf, u_flc = _pair("adrc-tf", disc, tuning, {})
    assert np.max(np.abs(u_tf - u_flc)) <= 1e-9 * np.max(np.abs(u_flc))  # measured ≤ 2e-12


@pytest.mark.parametrize("disc, tuning", FORMS)
def test_adrc_error_closes_the_same_loop(disc: str, tuning: str) -> None:
    u_err, u_flc = _pair("adrc-error", disc, tuning, REST)
    assert np.max(np.abs(u_err - u_flc)) <= 1e-12  # measured ≤ 2e-16: the same loop y → u
    u_err, u_flc = _pair("adrc-error", disc, tuning, {})
    assert np.max(np.abs(u_err - u_flc)) > 1e-3  # a move: the reference path differs


def test_analysis_of_a_form_is_its_equivalents() -> None:
    for kind in ("adrc-tf", "adrc-error"):
        adrc = load_scenario("test-1", {"controller.kind": kind, "controller.eps": 0.05,
                                        "controller.discretization": "current"})
        flc = load_scenario("test-1", {"controller.kind": "flc", "controller.compensation": "eso",
                                       "observer.eps": 0.05, "observer.discretization": "current"})
        a, b = analyze(adrc).to_dict(), analyze(flc).to_dict()
        assert a["gain_margin"] == b["gain_margin"] and a["phase_margin"] == b["phase_margin"]
        assert a["noise_to_control_peak"] == b["noise_to_control_peak"]


def test_analyze_runs_the_forms_and_says_how(run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("analyze", "test-1", "--set", "controller.kind=adrc-error", "--json")
    assert res.exit_code == 0, res.stderr
    assert "analyzed as the loop it closes" in res.stderr
    assert json.loads(res.stdout)["gain_margin"] > 1.0
    res = run_cli("analyze", "test-1", "--set", "controller.kind=adrc-tf", "--vary",
                  "controller.eps=0.05,0.09", "--json")
    assert res.exit_code == 0 and "analyzed as the loop it closes" in res.stderr, res.stderr
    gm = [p["gain_margin"] for p in json.loads(res.stdout)["points"]]
    assert gm[0] != gm[1]  # each point is its own form's loop
    res = run_cli("analyze", "test-1", "--set", "controller.kind=adrc-tf", "--bandwidth", "10")
    assert res.exit_code == 2 and "controller.eps" in res.stderr
    res = run_cli("analyze", "test-1", "--set", "controller.kind=pid")
    assert res.exit_code == 2 and "'pid'" in res.stderr  # no equivalent: refused as before
