"""The ADRC controller forms against the output-based form where the papers say they agree.

- ``adrc-tf`` (Herbst's minimum-footprint transfer-function form, δ operator) is the same
  input-output map as the linear ESO + FLC: the same commands, closed loop, on any reference,
  with saturation, for every discretization and tuning.
- ``adrc-error`` (the ESO driven by e = θd − y) equals the output-based form while the
  reference advances by the observer's own model (a set point; a ramp for Euler, a parabola
  for the exact discretizations) and the initial states correspond; along test-1's quintic
  moves it does not (measured here).
- ``pid`` + ``compensation = "eso"`` adds −ẑ3/b0 and beats the PID alone on test-2.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from esoarm.contract import PlantDesign
from esoarm.controllers import adrc_error, adrc_tf, flc, pid
from esoarm.engines.simulation import prepare, run_reference
from esoarm.observers import linear
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.scenario import load_scenario

from .lockstep import host_commands

TS, B0 = 0.02, 1.0 / 0.0225


def _plant() -> PlantDesign:
    return PlantDesign(np.zeros(1), np.zeros(3), 1, np.array([B0]))


def _run(over: dict[str, object]):  # type: ignore[no-untyped-def]
    scn = load_scenario("test-1", over)
    return run_reference(scn, prepare(scn))


def _pair(kind: str, disc: str, tuning: str, **extra: object):  # type: ignore[no-untyped-def]
    """The output-based run (linear ESO + FLC) and the same settings in the form ``kind``."""
    out = _run({"observer.discretization": disc, "observer.tuning": tuning,
                "observer.eps": 0.07, **extra})
    other = _run({"controller.kind": kind, "controller.discretization": disc,
                  "controller.tuning": tuning, "controller.eps": 0.07, **extra})
    return out, other


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("tuning", ["bandwidth", "half-gain"])
def test_tf_form_commands_what_the_state_space_form_commands(disc: str, tuning: str) -> None:
    """Closed loop on test-1 (quintic moves, encoder noise, friction): u to round-off."""
    out, tf = _pair("adrc-tf", disc, tuning, duration=8.0)
    np.testing.assert_allclose(tf.u, out.u, rtol=0, atol=1e-9)
    assert tf.metrics["rms_error"] == pytest.approx(out.metrics["rms_error"], rel=1e-7)


def test_tf_form_holds_under_saturation() -> None:
    """A torque limit the moves hit: the TF form is fed u_lim as the ESO is (same commands)."""
    out, tf = _pair("adrc-tf", "zoh", "bandwidth", duration=8.0,
                    **{"actuator.torque_limit": 0.06})
    assert out.metrics["saturated_fraction"] > 0.05  # saturated often
    np.testing.assert_allclose(tf.u, out.u, rtol=0, atol=1e-9)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_tf_start_is_the_state_space_start(disc: str) -> None:
    """initialize gives c_0 = K ẑ_0 = I0 k2 y_0, and the state is a fixed point at rest."""
    scn = load_scenario("test-1", {"controller.kind": "adrc-tf",
                                   "controller.discretization": disc})
    d = adrc_tf.design(scn, _plant(), TS)
    c = np.zeros(3)
    y0 = 0.37
    adrc_tf.initialize(c, np.array([y0]), d.vector)
    v = d.vector[1:]
    assert v[adrc_tf.D] * y0 + c[0] == pytest.approx(25.0 / B0 * y0, rel=1e-12)
    start = c.copy()
    u = adrc_tf.adrc_tf_command(c, y0, y0, 0.0, 0.0, v)
    assert u == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(c, start, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_error_form_equals_output_form_at_a_set_point(disc: str) -> None:
    """From θ0 = 0.3 rad to the set point 0 (no move until 6 s): the same commands to
    round-off; once the quintic move starts (θ⃛d ≠ 0) the forms part."""
    extra = {"duration": 8.0, "rig.theta0": 0.3,
             "reference.moves": [[6.0, 1.5, 0.5]]}
    out, err = _pair("adrc-error", disc, "bandwidth", **extra)
    before = out.t < 6.0
    np.testing.assert_allclose(err.u[before], out.u[before], rtol=0, atol=1e-9)
    assert np.max(np.abs(err.u[~before] - out.u[~before])) > 1e-3


@pytest.mark.parametrize(("disc", "degree"), [("euler", 1), ("zoh", 2), ("current", 2)])
def test_error_eso_is_reference_minus_output_eso(disc: str, degree: int) -> None:
    """Open loop on arbitrary (y, u): with w = (r, ṙ, r̈) a polynomial of the degree the
    discretization integrates exactly and z^e_0 = w_0 − z_0, the error ESO's commands equal
    the output ESO + FLC's with the reference's derivatives."""
    scn = load_scenario("test-1", {"controller.kind": "adrc-error",
                                   "controller.discretization": disc})
    vec = adrc_error.design(scn, _plant(), TS).vector[1:]
    oscn = load_scenario("test-1", {"observer.discretization": disc})
    ovec = linear.design(oscn, _plant(), TS).vector
    fvec = flc.design(oscn, PlantDesign(np.zeros(1), np.zeros(3), 1, np.array([B0])),
                      TS).vector[1:]
    rng = np.random.default_rng(4)
    n = 200
    t = np.arange(n) * TS
    coef = (0.2, 0.5, 0.3 if degree == 2 else 0.0)
    r = coef[0] + coef[1] * t + coef[2] * t**2
    rd = coef[1] + 2 * coef[2] * t
    rdd = np.full(n, 2 * coef[2])
    y = r + 0.02 * np.sin(3 * t) + 0.002 * rng.standard_normal(n)
    # output-based: ESO on (y, u), FLC with the reference's derivatives
    z = np.zeros(linear.design(oscn, _plant(), TS).n_state)
    zh = np.zeros_like(z)
    linear.initialize(z, y[:1], ovec)
    c = np.array([r[0] - y[0], rd[0], rdd[0]])  # z^e_0 = w_0 − z_0
    for k in range(n):
        linear.estimate(z, y[k:k + 1], ovec, zh)
        want = flc.flc_command(zh[0], zh[1], zh[2], r[k], rd[k], rdd[k], fvec)
        # the error form: k + 1 so that its k == 0 start does not overwrite the state
        got = adrc_error.adrc_error_command(c, r[k] - y[k], k + 1, vec)
        assert abs(want) < 1.0  # the limit (2 N·m) is far: both ESOs see the same command
        assert got == pytest.approx(want, abs=1e-9)
        ua = np.array([want])
        linear.advance(z, zh, y[k:k + 1], ua, ovec)


def test_error_form_on_test1_without_reference_derivatives() -> None:
    """On test-1's moves the error form (no θ̇d, θ̈d) tracks worse than the output form at the
    same ε; both are stable (the numbers of docs/adrc.md)."""
    out, err = _pair("adrc-error", "euler", "bandwidth")
    assert err.metrics["diverged"] == 0.0
    assert out.metrics["rms_error"] < err.metrics["rms_error"] < 3 * out.metrics["rms_error"]


def test_pid_compensation_adds_minus_z3_over_b0() -> None:
    scn = load_scenario("test-1", {"controller.kind": "pid"})
    scn_c = load_scenario("test-1", {"controller.kind": "pid", "controller.compensation": "eso"})
    p0, p1 = pid.design(scn, _plant(), TS).vector, pid.design(scn_c, _plant(), TS).vector
    refs = np.array([[0.3], [0.0], [0.0]])
    zhat = np.array([0.1, 0.0, 2.5])
    c0, c1 = np.zeros(3), np.zeros(3)
    u0, u1 = np.zeros(1), np.zeros(1)
    pid.control(c0, zhat, np.array([0.1]), refs, 0, p0, u0)
    pid.control(c1, zhat, np.array([0.1]), refs, 0, p1, u1)
    assert u1[0] - u0[0] == pytest.approx(-2.5 / B0, rel=1e-12)


def test_pid_with_eso_rejects_test2_disturbance_better() -> None:
    scn = load_scenario("test-2", {"controller.kind": "pid"})
    alone = run_reference(scn, prepare(scn))
    scn = load_scenario("test-2", {"controller.kind": "pid", "controller.compensation": "eso"})
    comp = run_reference(scn, prepare(scn))
    assert comp.metrics["rms_error"] < 0.8 * alone.metrics["rms_error"]


# -- on the chip ------------------------------------------------------------------------

_MISSING = [tool for tool, ok in (
    ("avr-gcc (gcc-avr)", shutil.which("avr-gcc")),
    ("libsimavr-dev", Path("/usr/include/simavr/sim_avr.h").exists()),
    ("gcc", shutil.which("gcc")),
) if not ok]
if _MISSING and os.environ.get("ESOARM_REQUIRE_HIL"):
    raise RuntimeError(f"ESOARM_REQUIRE_HIL is set but not installed: {', '.join(_MISSING)}")


@pytest.mark.slow
@pytest.mark.hil
@pytest.mark.skipif(bool(_MISSING), reason=f"not installed: {', '.join(_MISSING)}")
@pytest.mark.parametrize("sets", [
    ("controller.kind=adrc-error",),
    ("controller.kind=adrc-tf",),
    ("observer.tuning=half-gain",),
    ("observer.input_delay=2",),
    ("observer.input_delay=2", "observer.delay_form=predictor", "actuator.delay_samples=2"),
    ("controller.kind=pid", "controller.compensation=eso"),
    ("controller.kind=switch", "controller.switch_at=2", "controller.switch_back=6"),
])
def test_pil_on_avr(sets: tuple[str, ...]) -> None:
    """esoarm pil test-1 --target avr agrees to 1e-4 of the torque limit within the budget."""
    args = [a for s in sets for a in ("--set", s)]
    res = subprocess.run([sys.executable, "-m", "esoarm", "pil", "test-1", "--target", "avr",
                          "--steps", "400", *args, "--json"],
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert data["ok"] and data["max_rel_du"] <= 1e-4
    assert data["cycles"]["max"] < data["budget_cycles"]


# -- esoarm compare --------------------------------------------------------------------


def test_compare_refuses_an_unknown_form(run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("compare", "test-1", "--kinds", "eso+flc,lqr")
    assert res.exit_code == 2
    assert "--kinds: unknown form lqr" in res.stderr and "Traceback" not in res.stderr
    res = run_cli("compare", "test-1", "--delays", "1:4")
    assert res.exit_code == 2 and "--delays" in res.stderr


@pytest.mark.slow
def test_compare_runs_the_forms(run_cli) -> None:  # type: ignore[no-untyped-def]
    """Two seconds of test-1: the TF form commands what the ESO + FLC does (same metrics);
    the delay search answers for every form."""
    res = run_cli("compare", "test-1", "--set", "duration=2", "--seeds", "1", "--kinds",
                  "eso+flc,adrc-tf,delay-input", "--delays", "0,1,2", "--json")
    assert res.exit_code == 0, res.stderr
    data = json.loads(res.stdout)
    rows = {r["form"]: r for r in data["forms"]}
    assert rows["adrc-tf"]["rms_error"] == pytest.approx(rows["eso+flc"]["rms_error"], rel=1e-6)
    assert all(r["delay_held"] >= 0 for r in data["forms"])


# -- PID → ESO + FLC and back, bumpless ---------------------------------------------------

_SWITCH = {"controller.kind": "switch", "controller.switch_at": 2.0,
           "controller.switch_back": 11.0}


def test_switch_is_bumpless_both_ways() -> None:
    """Mid-move (test-1's first move runs 1-3 s): the command does not jump at either switch
    with the bumpless transfer, and does with the hard one; before the switch the kind is the
    PID, bit for bit."""
    bump = _run({**_SWITCH, "controller.transfer": "bumpless"})
    hard = _run({**_SWITCH, "controller.transfer": "hard",
                 "sensor.noise_deg": 0.0})
    ks, kb = 100, 550
    u = np.asarray(bump.u)
    assert u[ks] == u[ks - 1]  # the FLC entered from the PID's last command
    assert abs(u[kb] - u[kb - 1]) < 1e-12  # the PID restarted from the FLC's last command
    uh = np.asarray(hard.u)
    assert abs(uh[ks] - uh[ks - 1]) > 0.03 and abs(uh[kb] - uh[kb - 1]) > 0.03
    pid_alone = _run({"controller.kind": "pid"})
    np.testing.assert_array_equal(u[:ks], np.asarray(pid_alone.u)[:ks])


def test_switch_over_the_emulated_device() -> None:
    """The rig loop's host controller (esoarm run's) over the emulated device commands what
    simulate does, through both switches."""
    scn = load_scenario("test-1", {**_SWITCH, "controller.switch_at": 0.5,
                                   "controller.switch_back": 1.5, "duration": 2.0})
    ref = run_reference(scn, prepare(scn))
    assert np.array_equal(host_commands(scn), ref.u)


def test_run_switch_at_is_checked(run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("run", "test-1", "--port", "/dev/null", "--switch-at", "-1")
    assert res.exit_code == 2 and "--switch-at" in res.stderr


def test_kind_switch_does_not_carry_a_key_of_another_meaning() -> None:
    """The FLC's compensation = "eso" (β̂ = ẑ3) is not the PID's; "none" is no FLC value."""
    assert load_scenario("test-1", {"controller.kind": "pid"}).controller.compensation == "none"
    pid = load_scenario("test-1", {"controller.kind": "pid", "controller.compensation": "eso"})
    assert pid.controller.compensation == "eso"
    back = load_scenario(load_scenario("test-1", {"controller.kind": "pid"}),
                         {"controller.kind": "flc"})
    assert back.controller.compensation == "eso"  # the FLC's default, not the PID's "none"
    tf = load_scenario("test-1", {"controller.k1": 12.0, "controller.kind": "adrc-tf"})
    assert tf.controller.k1 == 12.0  # same meaning: carried


@pytest.mark.slow
@pytest.mark.hil
@pytest.mark.skipif(bool(_MISSING), reason=f"not installed: {', '.join(_MISSING)}")
def test_compare_on_the_chip(run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("compare", "test-1", "--set", "duration=2", "--seeds", "1", "--kinds",
                  "eso+flc,adrc-tf", "--chip", "avr", "--json")
    assert res.exit_code == 0, res.stderr
    rows = {r["form"]: r for r in json.loads(res.stdout)["forms"]}
    for r in rows.values():
        assert r["chip"]["max_rel_du"] <= 1e-4 and r["chip"]["median"] > 0
    assert rows["adrc-tf"]["chip"]["flash_bytes"] > 0
