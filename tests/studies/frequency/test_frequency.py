"""Frequency-domain analysis: the linear loop against independent references.

- margins against python-control's ``stability_margins`` (polynomial/FRD
  method, independent of ours) and against a direct marginal-stability test
  (eigenvalues of the closed loop with the gain scaled by the gain margin; the
  plant rediscretized with the delay margin added as a true input delay);
- the linear plant against the nonlinear rig's RK4 step (finite differences),
  the linear controller against the ESO/FLC step functions the simulators run;
- the ESO's transfer functions against Theorem 1's closed forms;
- the predicted disturbance response against a nonlinear simulation;
- all of these with a ``[motor]`` table too (uno-rig): its back-EMF damping and the
  host's back-EMF compensation are in the linear loop.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import esoarm
from esoarm.engines.simulation import prepare
from esoarm.observers.linear import DISCRETIZATIONS
from esoarm.plants.actuator import LIMIT, MOTOR_BLOCK, actuate, saturate
from esoarm.plants.lever_arm import design, rig_advance
from esoarm.plants.motor import PWM_MAX, MotorParams
from esoarm.scenario import Scenario, builtin_names, load_scenario
from esoarm.studies.frequency import linearization as L
from esoarm.studies.frequency import margins as F

control = pytest.importorskip("control")

#: uno-rig's [motor] table as overrides of test-1 (back-EMF damping 0.1215 N·m·s/rad)
UNO_MOTOR = {"motor.supply_voltage": 12.0, "motor.resistance": 2.4,
             "motor.torque_constant": 0.018, "motor.gear_ratio": 30.0, "motor.deadband": 0.06}

LOOPS = [
    {},
    UNO_MOTOR,
    {**UNO_MOTOR, "actuator.lag": 0.02, "actuator.delay_samples": 1},
    {"actuator.lag": 0.01},
    {"actuator.delay_samples": 2},
    {"actuator.lag": 0.02, "actuator.delay_samples": 1},
    {"controller.compensation": "model"},
    {"observer.eps": 0.05, "sensor.rate_hz": 100.0},
]


def _cases() -> list[tuple[str, dict]]:
    return [(d, {"observer.discretization": d, **extra}) for d in DISCRETIZATIONS
            for extra in LOOPS]


@pytest.mark.parametrize("disc, over", _cases())
def test_margins_against_python_control_and_direct_tests(disc: str, over: dict) -> None:
    scn = load_scenario("test-1", over)
    lin = L.linearize(scn, theta0=0.3)
    m = F.margins(lin)
    sys = L.to_control(scn, theta0=0.3)
    with _quiet():
        gm, pm, _sm, wpc, wgc, _ = control.stability_margins(sys.loop)
    assert m.gain_margin == pytest.approx(gm, rel=1e-6)
    assert m.phase_margin == pytest.approx(pm, rel=1e-6)
    assert m.phase_crossover == pytest.approx(wpc, rel=1e-6)
    assert m.gain_crossover == pytest.approx(wgc, rel=1e-6)
    # direct test 1: the loop gain scaled by the gain margin is marginally stable
    assert L.closed_loop_radius(lin.plant, lin.controller) < 1.0
    assert L.closed_loop_radius(lin.plant, lin.controller, m.gain_margin) == pytest.approx(
        1.0, abs=1e-6)
    # direct test 2: the delay margin added as a true (fractional) input delay of the
    # sampled-data loop makes it marginally stable, to 1 %
    crit = L.critical_delay(scn, 0.3)
    assert crit == pytest.approx(m.delay_margin, rel=0.01)
    radius = L.closed_loop_radius(L.sampled_plant(scn, 0.3, "viscous", m.delay_margin),
                                  lin.controller)
    assert radius == pytest.approx(1.0, abs=0.01)


class _quiet:
    """python-control warns when it falls back to its FRD method; not our concern here."""

    def __enter__(self) -> None:
        import warnings

        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("ignore")

    def __exit__(self, *exc: object) -> None:
        self._cm.__exit__(*exc)


@pytest.mark.parametrize("name", builtin_names(plant="lever-arm"))
def test_to_control_objects(name: str) -> None:
    scn = load_scenario(name)
    sys = L.to_control(name)
    for part in (sys.plant, sys.controller, sys.loop, sys.observer):
        assert isinstance(part, control.StateSpace)
        assert part.dt == scn.sample_time
    cl = control.feedback(sys.loop, 1)
    lin = L.linearize(name)
    want = np.sort_complex(np.linalg.eigvals(L.closed_loop_matrix(lin.plant, lin.controller)))
    got = np.sort_complex(cl.poles())
    # closed-loop poles of a multiple eigenvalue agree only to ~cube root of round-off
    assert np.max(np.abs(np.abs(got) - np.abs(want))) < 1e-4
    w = np.array([0.1, 1.0, 10.0, 100.0])
    z = np.exp(1j * w * scn.sample_time)
    series = sys.controller * sys.plant
    np.testing.assert_allclose(sys.loop(z), series(z), rtol=1e-10)
    np.testing.assert_allclose(sys.loop(z), lin.response("loop", w), rtol=1e-10)


@pytest.mark.parametrize("base", ["test-1", "uno-rig"])
@pytest.mark.parametrize("lag", [0.0, 0.02])
@pytest.mark.parametrize("friction", ["viscous", "slope", "none"])
def test_plant_matches_the_rig_step(lag: float, friction: str, base: str) -> None:
    """Finite differences of the nonlinear rig over one sample give the plant matrices.

    The rig is the one the simulators integrate (the plant kind's design): with
    uno-rig's ``[motor]``, the back-EMF damping (N·Kt)²/R is part of it.
    """
    over = {"actuator.lag": lag, "rig.disturbance.amplitude": 0.0}
    if friction == "slope":
        over["rig.stiction"] = 0.03  # Stribeck: its slope at rest adds Fst/vs
        over["rig.step"] = 1e-4  # a pole near −320 1/s: a finer RK4 step for the reference
    else:
        over["rig.coulomb_friction"] = 0.0
    if friction == "none":
        over["rig.viscous_friction"] = 0.0
    scn = load_scenario(base, over)
    theta0 = 0.7
    rig = design(scn).vector[1:]  # (code, rig vector): the rig the simulators integrate
    assert (scn.motor is not None) == (base == "uno-rig")
    u0 = rig[1] * math.cos(theta0)  # gravity torque: an equilibrium
    ad, bd, _, _ = L.sampled_plant(scn, theta0, friction)
    n = ad.shape[0]
    x0 = np.array([theta0, 0.0, u0][:n])

    def step(x: np.ndarray, u: float) -> np.ndarray:
        tau = x[2] if n == 3 else 0.0
        out = rig_advance(x[0], x[1], tau, u, 0.0, scn.rig.step, scn.substeps, rig)
        return np.array(out[:n])

    h = 1e-7
    jac = np.column_stack([(step(x0 + h * e, u0) - step(x0 - h * e, u0)) / (2 * h)
                           for e in np.eye(n)])
    jb = (step(x0, u0 + h) - step(x0, u0 - h)) / (2 * h)
    # RK4 (1 ms; 0.1 ms for "slope") against the exact matrix exponential
    np.testing.assert_allclose(jac, ad, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(jb, bd[:, 0], rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("comp", ["eso", "model"])
@pytest.mark.parametrize("kind", ["linear", "nonlinear"])
@pytest.mark.parametrize("base", ["test-1", "uno-rig"])
def test_controller_matches_the_step_functions(disc: str, comp: str, kind: str,
                                               base: str) -> None:
    """K(z) reproduces the observer and controller kinds' step functions on a random y.

    For the nonlinear ESO the innovations stay within fal's linear zone (|e| ≤ δ =
    0.1 rad), where K(z) is exact too.  With uno-rig's ``[motor]`` the output is the
    torque that drives the plant, from the actuator the simulators run (the host's
    back-EMF compensation with ẑ2, the deadband and its pre-compensation), and the
    observer is updated with the torque the host believes it applies; the duty's
    resolution is raised to 1e12 counts so that PWM rounding (left out of the linear
    loop) is below the tolerance.
    """
    theta0 = 0.4
    scn = load_scenario(base, {"observer.kind": kind, "observer.discretization": disc,
                               "controller.compensation": comp,
                               "actuator.torque_limit": 1e9})
    inp = prepare(scn)
    _, observer, controller = inp.kinds
    op, cp = inp.observer.vector, inp.controller.vector
    ap = np.array(inp.actuator)
    ap[MOTOR_BLOCK + PWM_MAX] = 1e12 if scn.motor is not None else 0.0
    ak, bk, ck, dk = L.controller_matrices(scn, theta0)
    rng = np.random.default_rng(1)
    dy = 1e-3 * rng.standard_normal(60)
    refs = np.array([[theta0], [0.0], [0.0]])
    z, zhat, c, u, y = np.zeros(3), np.zeros(3), np.zeros(1), np.zeros(1), np.array([theta0])

    def sample(yk: float) -> float:  # steps 3 and 5 of the loop, with the kinds' functions
        y[0] = yk
        observer.estimate(z, y, op, zhat)
        controller.control(c, zhat, y, refs, 0, cp, u)
        u[0], drive, _ = actuate(saturate(u[0], ap[LIMIT]), zhat[1], ap)
        observer.advance(z, zhat, y, u, op)
        return float(drive)

    observer.initialize(z, y, op)
    for _ in range(3000):  # settle the observer on y = θ0: the operating point
        u_eq = sample(theta0)
    xk = np.zeros(ak.shape[0])
    for k in range(len(dy)):
        u_k = sample(theta0 + dy[k])
        u_lin = -(ck @ xk + dk[:, 0] * dy[k])[0]
        xk = ak @ xk + bk[:, 0] * dy[k]
        tol = 1e-9 if comp == "eso" else 1e-6  # "model": cos linearized
        assert u_k - u_eq == pytest.approx(u_lin, abs=tol)
    if scn.motor is not None:  # the compensation is a visible part of the output
        plain = L.controller_matrices(_without_motor(scn), theta0)
        assert np.allclose(plain[0], ak) and not np.allclose(plain[2], ck)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("eps", [0.05, 0.09, 0.2])
def test_eso_transfer_functions_against_theorem1(disc: str, eps: float) -> None:
    """At ω Ts ≪ 1 the discrete ESO's transfers approach the continuous closed forms.

    From y (and the perturbation f → ẑ3) the relative error is O(ω Ts) for every
    discretization; from u the exact ("zoh", "current") designs also differ by
    O(Ts/ε), so those are checked at a high sample rate.
    """
    for rate in (50.0, 2000.0):
        scn = load_scenario("test-1", {"observer.discretization": disc,
                                       "observer.eps": eps, "sensor.rate_hz": rate,
                                       "rig.step": 0.5 / rate})
        ts = scn.sample_time
        b0 = 1.0 / scn.plant.inertia
        w = np.array([0.01, 0.1, 1.0])
        z = np.exp(1j * w * ts)
        closed = L.eso_closed_forms(eps, b0, 1j * w)
        a, b, c, d = L.observer_system(scn)
        bound = 1.5 * w * ts
        for i in range(3):
            for j, inp in enumerate("yu"):
                got = L.freqresp((a, b[:, j:j + 1], c[i:i + 1], d[i:i + 1, j:j + 1]), z)
                ref = closed[f"z{i + 1}_{inp}"]
                rel = np.abs(got - ref) / np.abs(ref)
                if inp == "u" and disc != "euler" and i < 2:
                    if rate < 1000:
                        continue
                    assert np.all(rel < bound + 2 * ts / eps), (i, inp, rel)
                else:
                    assert np.all(rel < bound), (i, inp, rel)
        got = L.freqresp(L.perturbation_estimate(scn), z)
        assert np.all(np.abs(got - closed["f"]) / np.abs(closed["f"]) < bound)


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
def test_disturbance_response_against_nonlinear_simulation(disc: str) -> None:
    """The sine disturbance's steady-state error amplitude, linear prediction vs the twin."""
    scn = load_scenario("test-1", {
        "sensor.noise_deg": 0.0, "sensor.resolution_deg": 0.0, "rig.coulomb_friction": 0.0,
        "reference.kind": "multisine", "reference.amplitudes": [0.0],
        "reference.frequencies": [0.5], "duration": 40.0, "observer.discretization": disc})
    result = esoarm.simulate(scn)
    a = F.analyze(scn, over_range=False, n_freq=400)
    period = round(2 * math.pi / scn.rig.disturbance.frequency / scn.sample_time)
    tail = result.error[-period:]
    assert (tail.max() - tail.min()) / 2 == pytest.approx(a.scenario_disturbance_error, rel=1e-3)
    assert abs(a.disturbance_dc) < 1e-9  # the ESO's integral action


def _without_motor(scn: Scenario) -> Scenario:
    """The same scenario with an ideal torque source (no ``[motor]`` table)."""
    return scn.model_copy(update={"motor": None})


@pytest.mark.parametrize("disc", DISCRETIZATIONS)
@pytest.mark.parametrize("freq", [0.5, 3.0])
def test_motor_disturbance_response_against_nonlinear_simulation(disc: str, freq: float) -> None:
    """With a ``[motor]`` the linear loop predicts the twin's disturbance response.

    uno-rig drives the arm through its motor model (back-EMF damping, the host's
    compensation with ẑ2, deadband and its pre-compensation, PWM duty counts).  The
    linear loop leaves out the PWM rounding: at pwm_max = 255 one count is 11 mN·m at
    the arm, twice the scenario's 5 mN·m disturbance, so the check uses the finest
    duty the scenario allows (32767 counts, 0.09 mN·m per count) and a disturbance of
    0.5 N·m, within the supply's 2.7 N·m (no saturation).  3 rad/s is near the peak
    of the disturbance transfer, where the motor's damping changes it most.
    """
    scn = load_scenario("uno-rig", {
        "sensor.noise_deg": 0.0, "sensor.resolution_deg": 0.0, "rig.coulomb_friction": 0.0,
        "reference.kind": "multisine", "reference.amplitudes": [0.0],
        "reference.frequencies": [0.5], "duration": 40.0, "observer.discretization": disc,
        "motor.pwm_max": 32767, "rig.disturbance.amplitude": 20.0,
        "rig.disturbance.frequency": freq})
    motor = MotorParams.from_scenario(scn)
    assert motor is not None
    result = esoarm.simulate(scn)
    # the duty the host asks for, (u + Dm ẑ2)/stall, stays well inside ±1 (no supply limit)
    duty = (result.u + motor.damping * result.z[:, 1]) / motor.stall_gain
    assert np.max(np.abs(duty)) < 0.5 and not np.any(result.saturated)
    a = F.analyze(scn, over_range=False, n_freq=400)
    period = round(2 * math.pi / freq / scn.sample_time)
    tail = result.error[-4 * period:]
    assert (tail.max() - tail.min()) / 2 == pytest.approx(a.scenario_disturbance_error, rel=1e-3)
    assert abs(a.disturbance_dc) < 1e-9
    # the check tells the motor's part apart: without it the prediction is off by more
    # than 5 times the tolerance (0.9-1.2 % at 0.5 rad/s, 24-31 % at 3 rad/s)
    plain = F.analyze(_without_motor(scn), over_range=False, n_freq=400)
    assert abs(plain.scenario_disturbance_error / a.scenario_disturbance_error - 1) > (
        5e-3 if freq < 1 else 0.2)


def test_motor_changes_the_loop_and_is_named(run_cli) -> None:  # type: ignore[no-untyped-def]
    """uno-rig is test-1 plus a motor (and an encoder): its margins must differ."""
    uno, t1 = F.analyze("uno-rig"), F.analyze("test-1")
    assert uno.motor["damping"] == pytest.approx((30.0 * 0.018) ** 2 / 2.4, rel=1e-12)
    assert uno.motor["pwm_step"] == pytest.approx(30 * 0.018 * 12 / 2.4 / (0.94 * 255))
    assert uno.motor["left_out"] == ["deadband", "pwm_quantization", "supply_saturation"]
    assert t1.motor == {}
    # more damping at the plant input: larger gain, phase and delay margins
    assert uno.gain_margin > 1.3 * t1.gain_margin
    assert uno.phase_margin > t1.phase_margin + 10
    assert uno.delay_margin > t1.delay_margin
    res = run_cli("analyze", "uno-rig")
    assert res.exit_code == 0, res.stderr
    notes = [ln for ln in res.stdout.splitlines() if ln.startswith("motor:")]
    assert len(notes) == 1
    for word in ("0.1215", "deadband", "PWM quantization", "supply saturation"):
        assert word in notes[0]
    out = json.loads(run_cli("analyze", "uno-rig", "--json").stdout)
    assert out["gain_margin"] == pytest.approx(uno.gain_margin)
    assert out["motor"]["left_out"] == uno.motor["left_out"]
    res = run_cli("analyze", "uno-rig", "--vary", "motor.resistance=2.4,4")
    assert res.exit_code == 0, res.stderr
    assert sum(ln.startswith("motor:") for ln in res.stdout.splitlines()) == 1
    assert "motor:" not in run_cli("analyze", "test-1").stdout


def test_eps_trade_off_in_the_frequency_domain() -> None:
    """Smaller ε: better disturbance rejection, more noise into the control, less delay margin."""
    res = [F.analyze("test-1", {"observer.eps": e}, over_range=False, n_freq=600)
           for e in (0.05, 0.09, 0.2)]
    assert res[0].disturbance_peak < res[1].disturbance_peak < res[2].disturbance_peak
    assert res[0].noise_to_control_peak > res[1].noise_to_control_peak > \
        res[2].noise_to_control_peak
    assert res[0].delay_margin < res[1].delay_margin < res[2].delay_margin
    assert all(r.observer_bandwidth < r.nyquist for r in res)


def test_unstable_loop_is_reported() -> None:
    a = F.analyze("test-1", {"observer.eps": 0.008}, over_range=False, n_freq=300)
    assert not a.stable and a.closed_loop_radius > 1


def test_cli_json(run_cli) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("analyze", "test-1", "--json")
    assert res.exit_code == 0, res.stderr
    out = json.loads(res.stdout)
    lin = L.linearize("test-1")
    m = F.margins(lin)
    assert out["gain_margin"] == pytest.approx(m.gain_margin)
    assert out["phase_margin"] == pytest.approx(m.phase_margin)
    assert out["delay_margin"] == pytest.approx(m.delay_margin)
    assert out["gain_margin"] > 1 and 0 < out["delay_margin"] < 1
    assert out["range"]["theta_max"] == pytest.approx(1.0)


@pytest.mark.slow
def test_cli_vary_and_plot(run_cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    fig = tmp_path / "m.png"
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.2", "--plot", str(fig),
                  "--json")
    assert res.exit_code == 0, res.stderr
    out = json.loads(res.stdout)
    assert [p["value"] for p in out["points"]] == [0.05, 0.2]
    assert out["points"][0]["eps"] == 0.05
    assert fig.stat().st_size > 10_000
    res = run_cli("analyze", "test-2", "--plot", str(tmp_path / "b.svg"))
    assert res.exit_code == 0 and "phase margin" in res.stdout


@pytest.mark.parametrize("args, word", [
    (("--vary", "observer.eps=0,1"), "observer.eps"),
    (("--vary", "observer.epz=1"), "observer.epz"),
    (("--plot", "x.txt"), "--plot"),
    (("--theta0", "nan"), "--theta0"),
    # a second --vary replaced the first without a word (click keeps the last)
    (("--vary", "observer.eps=0.05,0.1", "--vary", "controller.k1=5,10"),
     "--vary given 2 times"),
])
def test_cli_bad_input(run_cli, args, word, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.chdir(tmp_path)
    res = run_cli("analyze", "test-1", *args)
    assert res.exit_code == 2
    assert word in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("args, word", [
    (("two-link",), "plant.kind"),
    (("test-1", "--set", "controller.kind=pid"), "controller.kind"),
    (("test-1", "--vary", "controller.kind=flc,computed-torque"), "controller.kind"),
])
def test_cli_refuses_kinds_it_does_not_model(run_cli, args, word) -> None:  # type: ignore[no-untyped-def]
    res = run_cli("analyze", *args)
    assert res.exit_code == 2, res.stderr
    assert word in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_nonlinear_eso_is_analyzed_in_its_linear_zone() -> None:
    """fal's slope δ^(α−1) scales the 2nd and 3rd gains; α = 1 is the linear ESO exactly."""
    lin = F.analyze("test-1")
    same = F.analyze("test-1", {"observer.kind": "nonlinear", "observer.alpha": [1.0, 1.0]})
    # the pole frequency of the nonlinear kind comes from eigenvalues, which for the
    # linear ESO's triple pole are accurate to ~eps^(1/3); everything else is the same bits
    pole = "observer_pole_frequency"
    assert same.observer_pole_frequency == pytest.approx(lin.observer_pole_frequency, rel=1e-4)
    assert {**same.to_dict(), pole: None} == {**lin.to_dict(), "observer": "nonlinear",
                                              "observer_label": same.observer_label, pole: None}
    assert same.observer_label.startswith("fal-ESO") and lin.observer_label == "ESO"
    fal = F.analyze("test-1", {"observer.kind": "nonlinear"})
    assert fal.observer == "nonlinear" and fal.phase_margin != lin.phase_margin
    p_lin, q_lin, *_ = L.observer_matrices(load_scenario("test-1"))
    p_nl, q_nl, *_ = L.observer_matrices(load_scenario("test-1", {"observer.kind": "nonlinear"}))
    delta, (a2, a3) = 0.1, (0.5, 0.25)  # the kind's defaults
    assert q_nl[:, 0] == pytest.approx(q_lin[:, 0] * [1.0, delta ** (a2 - 1), delta ** (a3 - 1)],
                                       rel=1e-15)


def test_cli_usage_error_is_one_line(run_esoarm, tmp_path) -> None:  # type: ignore[no-untyped-def]
    res = run_esoarm("analyze", "test-1", "--friction", "dry", cwd=tmp_path)
    assert res.exit_code == 2 and "--friction" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_docstring_examples() -> None:
    import doctest

    import esoarm.analysis
    from esoarm.studies.frequency import linearization

    for mod in (esoarm.analysis, linearization):
        res = doctest.testmod(mod, raise_on_error=False)
        assert res.attempted > 0 and res.failed == 0, mod.__name__


def test_report_section_states_the_trade_off_from_the_numbers() -> None:
    from esoarm.studies.frequency.report import frequency_section

    class Rep:  # the two things the section reads from a reproduction
        scenarios = {"test-1/eso": load_scenario("test-1")}

        @staticmethod
        def metric(test: str, eps: float, key: str) -> float:
            return {0.05: 0.3, 0.2: 0.1}[eps]

    html = frequency_section(Rep(), eps_values=(0.05, 0.2))  # type: ignore[arg-type]
    lo = F.analyze("test-1", {"observer.eps": 0.05}, over_range=False, n_freq=800)
    hi = F.analyze("test-1", {"observer.eps": 0.2}, over_range=False, n_freq=800)
    assert f"{lo.noise_to_control_peak:.3g} to {hi.noise_to_control_peak:.3g}" in html
    assert f"{lo.disturbance_peak:.3g} to {hi.disturbance_peak:.3g}" in html
    assert f"<td>{lo.gain_margin:.2f}</td>" in html and "<td>0.3000</td>" in html
    assert html.count("data:image/png;base64,") == 1
