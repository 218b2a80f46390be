"""The generated C of every kind with C, held against the Python reference on the host.

The generated source is built with the host's gcc and stepped in lockstep with
the twin (:func:`esoarm.codegen.lockstep.lockstep`) beside the float64 Python
reference fed the same measurements: float64 must repeat the Python arithmetic
(max |Δu| ≤ 1e-12 N·m), float32 must hold 1e-4 of the torque limit with the
compensated observer sums.
"""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from esoarm.codegen import AGREEMENT, CodegenError, c_source, generate, scenario_hash
from esoarm.kinds import CONTROLLERS, OBSERVERS, PLANTS
from esoarm.scenario import load_scenario

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="not installed: gcc")

# every observer kind with C × discretization, every controller kind with C
OBS = [(m.KIND, d) for m in OBSERVERS if c_source(m) for d in ("euler", "zoh", "current")]
CTL = [(m.KIND, comp) for m in CONTROLLERS if c_source(m)
       for comp in (("eso", "model") if m.KIND == "flc" else (None,))]


def _scn(obs: tuple[str, str], ctl: tuple[str, str | None], **extra: object):
    over: dict[str, object] = {"observer.kind": obs[0], "observer.discretization": obs[1],
                               "controller.kind": ctl[0], "duration": 6.0, **extra}
    if ctl[1] is not None:
        over["controller.compensation"] = ctl[1]
    return load_scenario("test-1", over)


def _run(scn, precision: str, compensated: bool | None = None):
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep

    return lockstep(scn, HostChip(generate(scn, "host", precision, compensated)))


def test_every_kind_declares_c_or_is_refused() -> None:
    scn = load_scenario("test-1")
    for module in (*PLANTS, *OBSERVERS, *CONTROLLERS):
        name = getattr(module, "C_SOURCE", None)
        if name is not None:
            text = c_source(module)
            assert text and "static" in text, module.__name__
    urdf = load_scenario("test-1-urdf")
    with pytest.raises(CodegenError, match="plant.kind = 'urdf' has no C"):
        generate(urdf, "host", "float64")
    # the observer/controller kinds this issue covers all have C
    assert {k for k, _ in OBS} >= {"linear", "nonlinear"}
    assert {k for k, _ in CTL} >= {"flc", "pid"}
    assert generate(scn).source  # the default scenario generates


def test_header_names_scenario_and_hash_and_is_deterministic() -> None:
    scn = load_scenario("uno-rig")
    a, b = generate(scn, "avr", "float32"), generate(scn, "avr", "float32")
    assert a == b
    assert '"uno-rig"' in a.header and scenario_hash(scn) in a.header
    other = load_scenario("uno-rig", {"observer.eps": 0.05})
    assert scenario_hash(other) != scenario_hash(scn)
    assert "malloc" not in a.source and "free(" not in a.source


@pytest.mark.parametrize(("target", "precision"), [("avr", "float64"), ("pdp11", "float32"),
                                                   ("host", "float16")])
def test_bad_target_or_precision_refused(target: str, precision: str) -> None:
    with pytest.raises(CodegenError):
        generate(load_scenario("test-1"), target, precision)


@needs_gcc
@pytest.mark.parametrize("obs", OBS)
@pytest.mark.parametrize("ctl", CTL)
def test_float64_repeats_python(obs, ctl) -> None:
    run = _run(_scn(obs, ctl), "float64")
    assert run.steps == 300
    assert run.max_abs_du <= 1e-12, run.max_abs_du


@needs_gcc
@pytest.mark.parametrize("obs", OBS)
@pytest.mark.parametrize("ctl", CTL)
def test_float32_holds(obs, ctl) -> None:
    run = _run(_scn(obs, ctl), "float32")
    assert run.max_rel_du <= AGREEMENT, run.max_rel_du
    assert run.max_abs_du > 0.0  # float32 is not float64: the check can see a difference


@needs_gcc
@pytest.mark.slow
def test_full_twin_run_with_motor_at_1khz() -> None:
    """uno-rig (motor: torque -> duty) over its whole run at 1 kHz: float64 exact, float32
    within the agreement (measured 6.5e-7 N·m)."""
    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000})
    assert _run(scn, "float64").max_abs_du <= 1e-12
    comp = _run(scn, "float32")
    assert comp.steps == scn.n_samples
    assert comp.max_rel_du <= AGREEMENT
    # the chip closed the loop: the twin tracked the reference
    assert abs(comp.theta[-1] - comp.theta_ref[-1]) < 0.05


@needs_gcc
@pytest.mark.slow
def test_compensated_sums_hold_where_plain_sums_do_not() -> None:
    """ε = 0.01 s at 10 kHz (zoh): the plain float32 sums lose the increments (measured
    max |Δu| 4.6e-4 N·m over 5 s), the compensated ones hold (1.9e-6 N·m)."""
    scn = load_scenario("test-1", {"observer.eps": 0.01, "sensor.rate_hz": 10000,
                                   "rig.step": 1e-4, "observer.discretization": "zoh",
                                   "duration": 5.0})
    plain = _run(scn, "float32", compensated=False)
    comp = _run(scn, "float32", compensated=True)
    assert comp.max_rel_du <= AGREEMENT < plain.max_rel_du
    assert comp.max_abs_du < plain.max_abs_du / 20


@needs_gcc
def test_duty_ties_are_followed_and_counted() -> None:
    """At a duty rounding tie the float64 reference adopts the chip's duty (counted); the
    plain float32 sums at 1 kHz on uno-rig meet such ties."""
    scn = load_scenario("uno-rig", {"sensor.rate_hz": 1000, "duration": 8.0})
    run = _run(scn, "float32", compensated=False)
    assert run.duty_ties > 0
    assert run.max_rel_du <= AGREEMENT


@needs_gcc
def test_cli(tmp_path) -> None:
    out = tmp_path / "gen"
    res = subprocess.run([sys.executable, "-m", "esoarm", "codegen", "test-1", "--target",
                          "cortex-m4", "--out", str(out), "--plain-sums", "--set",
                          "observer.eps=0.01", "--set", "sensor.rate_hz=10000", "--set",
                          "rig.step=1e-4", "--set", "observer.discretization=zoh", "--set",
                          "duration=5"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 1, res.stderr  # one policy with `esoarm pil`: exit 1, files kept
    assert "float32 does not hold" in res.stderr and "kept" in res.stderr
    assert sorted(p.name for p in out.iterdir()) == ["esoarm_controller.c", "esoarm_controller.h",
                                                     "esoarm_reference.c", "esoarm_reference.h"]
    for args, word in ((["test-1", "--target", "avr", "--precision", "float64"], "float64"),
                       (["test-1-urdf", "--target", "host"], "urdf")):
        bad = tmp_path / "bad"
        res = subprocess.run([sys.executable, "-m", "esoarm", "codegen", *args, "--out", str(bad)],
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 2, res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and word in res.stderr
        assert not bad.exists()


@needs_gcc
@pytest.mark.parametrize("disc", ["euler", "zoh", "current"])
@pytest.mark.parametrize(("levels", "rate"), [(1, 50), (3, 50), (3, 1000)])
def test_cascade_float64_is_python_to_the_bit(disc: str, levels: int, rate: int) -> None:
    """The cascade ESO's float64 C repeats the Python step operation by operation: Δu = 0
    exactly (measured 0.0 for 1-3 levels, 50 Hz and 1 kHz, every discretization)."""
    scn = load_scenario("test-1", {"observer.kind": "cascade", "observer.levels": levels,
                                   "observer.discretization": disc, "sensor.rate_hz": rate,
                                   "duration": 4.0})
    gen = generate(scn, "host", "float64")
    assert f"#define ESOARM_OBS_NZ {6 * levels}\n" in gen.header  # z and carries per level
    run = _run(scn, "float64")
    assert run.steps == scn.n_samples
    assert run.max_abs_du == 0.0, run.max_abs_du


@needs_gcc
@pytest.mark.parametrize("disc", ["euler", "zoh", "current"])
def test_cascade_float32_compensated_at_1khz(disc: str) -> None:
    """Three levels at 1 kHz: the compensated float32 sums hold 1e-4 of the torque limit
    (measured 3.0e-7 to 3.2e-7 relative) and beat the plain sums (1.5e-6 to 7.0e-6)."""
    scn = load_scenario("test-1", {"observer.kind": "cascade", "observer.levels": 3,
                                   "observer.discretization": disc, "sensor.rate_hz": 1000,
                                   "duration": 6.0})
    comp = _run(scn, "float32", compensated=True)
    plain = _run(scn, "float32", compensated=False)
    assert comp.steps == plain.steps == scn.n_samples
    assert 0.0 < comp.max_rel_du <= AGREEMENT
    assert comp.max_abs_du < plain.max_abs_du / 3, (comp.max_abs_du, plain.max_abs_du)


@needs_gcc
@pytest.mark.slow
def test_cascade_needs_the_compensated_sums() -> None:
    """ε = 0.03 s at 1 kHz (zoh): level 2 measures level 1's angle, so its innovation is the
    difference of two nearly equal angles; in plain float32 it loses its digits (measured
    max |Δu| 6.4e-4 N·m over the 20 s run, 3.2e-4 of the limit), the compensated form, which
    carries each level's angle as stored value plus carried error, holds (5.2e-6 N·m)."""
    scn = load_scenario("test-1", {"observer.kind": "cascade", "observer.eps": 0.03,
                                   "sensor.rate_hz": 1000, "observer.discretization": "zoh"})
    plain = _run(scn, "float32", compensated=False)
    comp = _run(scn, "float32", compensated=True)
    assert comp.steps == plain.steps == scn.n_samples
    assert comp.max_rel_du <= AGREEMENT < plain.max_rel_du


def test_move_boundaries_are_the_python_references_samples() -> None:
    """float32 decides before / in / after a move on k: the first k with k·Ts ≥ t0 in float64,
    exactly as the Python reference tests t = k·Ts (checked against that test itself)."""
    import numpy as np

    from esoarm.codegen.generate import _first_sample

    rng = np.random.default_rng(7)
    for ts in (0.02, 0.001, 1e-4, 1.0 / 3.0):
        t = np.arange(200_001) * ts
        for bound in [0.0, ts, 1.0, 2.5, 3 * ts, *rng.uniform(0.0, t[-1], 50)]:
            assert _first_sample(ts, float(bound)) == int(np.argmax(t >= bound)), (ts, bound)


@needs_gcc
@pytest.mark.parametrize("extra", [
    {"actuator.pwm_bits": 8},
    {"actuator.pwm_bits": 4, "rig.backlash_deg": 1.5},
    {"sensor.noise_ar": [0.7], "sensor.vibration_deg": 0.05},
])
def test_float64_repeats_python_with_the_drive_and_noise_models(extra: dict) -> None:
    """The chip's actuator rounds to the PWM levels as esoarm.plants.actuator does; backlash
    and coloured noise live on the twin's side of the link."""
    run = _run(_scn(("linear", "euler"), ("flc", "eso"), **extra), "float64")
    assert run.steps == 300
    assert run.max_abs_du <= 1e-12, run.max_abs_du
