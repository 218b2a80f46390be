"""Scenario files: defaults, built-ins, overrides, validation, TOML round trip."""

from __future__ import annotations

import math
import tomllib

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from esoarm.scenario import (
    Scenario,
    ScenarioError,
    builtin_names,
    load_scenario,
    parse_override,
    to_toml,
)

# the scenario format, typed again from the specification.
SPEC_DEFAULTS = {
    "name": "test-1",
    "duration": 20.0,
    "plant.m1": 0.5, "plant.m2": 0.55, "plant.l1": 0.15, "plant.l2": 0.14,
    "plant.inertia": 0.0225, "plant.g": 9.81,
    "rig.inertia_scale": 1.1, "rig.coulomb_friction": 0.05, "rig.friction_velocity": 0.01,
    "rig.viscous_friction": 0.01, "rig.step": 0.001, "rig.theta0": 0.0,
    "rig.disturbance.kind": "sine", "rig.disturbance.amplitude": 0.2,
    "rig.disturbance.frequency": 0.5,
    "sensor.rate_hz": 50.0, "sensor.resolution_deg": 0.05, "sensor.noise_deg": 0.2,
    "sensor.seed": 0,
    "actuator.torque_limit": 2.0, "actuator.lag": 0.0, "actuator.delay_samples": 0,
    "observer.eps": 0.09, "observer.discretization": "euler",
    "controller.k1": 10.0, "controller.k2": 25.0, "controller.compensation": "eso",
    "reference.kind": "quintic-steps", "reference.start": 0.0,
    "reference.moves": [[1.0, 2.0, 1.0], [10.0, 2.0, 0.0]],
}


def _get(scn: Scenario, dotted: str):
    node = scn
    for part in dotted.split("."):
        node = getattr(node, part)
    return node


def test_builtin_names():
    assert builtin_names() == ["dc-motor-eso", "emps", "test-1", "test-1-urdf", "test-2",
                               "two-link", "uno-rig"]
    assert builtin_names(plant="lever-arm") == ["test-1", "test-2", "uno-rig"]


@pytest.mark.parametrize("key", list(SPEC_DEFAULTS))
def test_test1_is_exactly_the_spec_defaults(key):
    scn = load_scenario("test-1")
    assert _get(scn, key) == SPEC_DEFAULTS[key]
    assert type(_get(scn, key)) is type(SPEC_DEFAULTS[key])


def test_test1_equals_schema_defaults():
    assert load_scenario("test-1") == Scenario()


def test_test2_differs_only_in_reference_and_name():
    one, two = load_scenario("test-1").to_dict(), load_scenario("test-2").to_dict()
    assert two["name"] == "test-2"
    assert two["reference"] == {"kind": "multisine", "amplitudes": [0.5], "frequencies": [0.5],
                                "phases": [], "offset": 0.0}
    for key in one:
        if key not in ("name", "reference"):
            assert one[key] == two[key], key


def test_derived_quantities():
    scn = load_scenario("test-1")
    assert scn.sample_time == 0.02
    assert scn.n_samples == 1000
    assert scn.substeps == 20
    assert load_scenario("test-1", {"duration": 0.03}).n_samples == 2  # round(1.5) -> 2


def test_scenario_is_frozen():
    scn = load_scenario("test-1")
    with pytest.raises(ValidationError):
        scn.observer.eps = 0.05  # type: ignore[misc]
    with pytest.raises(ValidationError):
        scn.duration = 1.0  # type: ignore[misc]


def test_overrides_dict_list_and_method_agree():
    a = load_scenario("test-1", {"observer.eps": 0.05, "observer.discretization": "zoh"})
    b = load_scenario("test-1", ["observer.eps=0.05", "observer.discretization=zoh"])
    c = load_scenario("test-1").with_overrides({"observer.eps": 0.05,
                                                "observer.discretization": "zoh"})
    d = load_scenario(load_scenario("test-1"), ["observer.eps=0.05",
                                                "observer.discretization=\"zoh\""])
    assert a == b == c == d
    assert a.observer.eps == 0.05 and a.observer.discretization == "zoh"
    assert load_scenario("test-1").observer.eps == 0.09  # the original is untouched


def test_override_switches_reference_kind_with_its_defaults():
    scn = load_scenario("test-1", ["reference.kind=multisine"])
    assert scn.reference.kind == "multisine"
    assert scn.reference.amplitudes == [0.5] and scn.reference.frequencies == [0.5]
    back = load_scenario("test-2", ["reference.kind=quintic-steps"])
    assert back.reference == load_scenario("test-1").reference


def test_int_accepted_for_float_but_not_the_reverse():
    assert load_scenario("test-1", ["duration=5"]).duration == 5.0
    with pytest.raises(ScenarioError, match="sensor.seed"):
        load_scenario("test-1", ["sensor.seed=1.0"])


def test_file_with_only_differences(tmp_path):
    path = tmp_path / "my-run.toml"
    path.write_text("[observer]\neps = 0.2\n[sensor]\nseed = 3\n", encoding="utf-8")
    scn = load_scenario(path)
    assert scn.name == "my-run"  # from the file name when not given
    assert scn.observer.eps == 0.2 and scn.sensor.seed == 3
    assert scn.with_overrides({"name": "test-1", "observer.eps": 0.09, "sensor.seed": 0}) == \
        load_scenario("test-1")
    assert load_scenario(str(path), ["observer.eps=0.05"]).observer.eps == 0.05


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        (["observer.eps=0"], "observer.eps"),
        (["observer.esp=1"], "did you mean 'observer.eps'"),
        (["rig.step=0.003"], "rig.step"),
        (["reference.moves=[[3.0, 1.0, 1.0], [1.0, 1.0, 0.0]]"], "reference.moves[1]"),
        (["sensor.noise_deg=nan"], "finite"),
        # a whole table: it exists, it is not a leaf (was "unknown key 'rig.disturbance'")
        (['rig.disturbance={kind="sine"}'], "key 'rig.disturbance' is a table; set its keys "
         "one at a time (rig.disturbance.amplitude, rig.disturbance.frequency, "
         "rig.disturbance.kind)"),
        ({"observer": {"eps": 0.05}}, "override: key 'observer' is a table"),
    ],
)
def test_errors_are_one_line_scenario_errors(overrides, fragment):
    with pytest.raises(ScenarioError) as info:
        load_scenario("test-1", overrides)
    msg = str(info.value)
    assert fragment in msg and "\n" not in msg
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("name", "overrides", "message"),
    [
        ("test-1", {"observer.eps": [0.05, -1]},
         "override: key 'observer.eps[1]' (joint 1, counting from 0) = -1: Input should be "
         "greater than 0"),
        ("two-link", {"controller.k1": [20.0, "a"]},
         "override: key 'controller.k1[1]' (joint 1, counting from 0) = 'a': input should be "
         "a valid number"),
        ("two-link", {"observer.eps": [math.inf, 0.02]},
         "override: key 'observer.eps[0]' (joint 0, counting from 0) = inf: must be a finite "
         "number (no NaN or inf)"),
        # a lever arm has one joint: a list of two was an internal error in the observer
        ("test-1", {"observer.eps": [0.05, 0.09]},
         "key 'observer.eps': 2 entries, but plant kind 'lever-arm' has one joint"),
        # an empty list was an internal error (min of nothing) in the computability check
        ("test-1", {"observer.eps": []},
         "key 'observer.eps': 0 entries, but plant kind 'lever-arm' has one joint"),
        ("two-link", {"observer.eps": []}, "key 'observer.eps': 0 entries, but 'two-link.urdf'"),
        # a plain number keeps its message
        ("test-1", {"observer.eps": "a"},
         "override: key 'observer.eps' = 'a': input should be a valid number"),
    ],
    ids=["negative-entry", "text-entry", "inf-entry", "lever-two", "lever-empty", "arm-empty",
         "number"],
)
def test_per_joint_list_errors_name_the_joint(name, overrides, message):
    if name == "two-link":
        pytest.importorskip("pinocchio")
    with pytest.raises(ScenarioError) as info:
        load_scenario(name, overrides)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert load_scenario("test-1", {"observer.eps": [0.05]}).observer.eps == [0.05]


def test_toml_syntax_error_names_file_and_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("duration = 5.0\n\n[sensor\nseed = 1\n", encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert str(path) in msg and "line 3" in msg and "\n" not in msg


def test_unknown_scenario_suggests():
    with pytest.raises(ScenarioError, match="did you mean 'test-1'"):
        load_scenario("tset-1")


# ---------------------------------------------------------------------------
# TOML output and round trip


@pytest.mark.parametrize("name", builtin_names())
def test_to_toml_round_trip_builtins(name, tmp_path):
    scn = load_scenario(name)
    text = scn.to_toml()
    assert tomllib.loads(text) == {k: v for k, v in scn.to_dict().items() if v is not None}
    path = tmp_path / "x.toml"
    path.write_text(text, encoding="utf-8")
    assert load_scenario(path) == scn


def test_round_trip_with_per_joint_references(tmp_path, run_cli):
    """Tables inside a list (reference.joints) are written inline; `show` printed an internal
    error for them ('cannot write dict as TOML')."""
    over = ["reference.kind=per-joint",
            'reference.joints=[{kind = "multisine", amplitudes = [0.3, 0.1], '
            'frequencies = [2.0, 5.0], phases = [0.0, 1.5]}]']
    scn = load_scenario("test-1", over)
    text = scn.to_toml()
    assert tomllib.loads(text) == {k: v for k, v in scn.to_dict().items() if v is not None}
    path = tmp_path / "pj.toml"
    path.write_text(text, encoding="utf-8")
    assert load_scenario(path) == scn
    res = run_cli("show", "test-1", *(a for o in over for a in ("--set", o)))
    assert res.exit_code == 0 and res.stdout == text, res.stderr


def test_round_trip_with_optional_motor_section(tmp_path):
    scn = load_scenario("test-1", ["motor.supply_voltage=24.0"])
    path = tmp_path / "m.toml"
    path.write_text(scn.to_toml(), encoding="utf-8")
    assert load_scenario(path) == scn


finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
positive = st.floats(min_value=1e-6, max_value=1e6, allow_nan=False)


@given(eps=positive, amp=finite, theta0=finite, phases=st.lists(finite, min_size=1, max_size=1),
       name=st.text(max_size=20), seed=st.integers(min_value=0, max_value=2**62))
def test_round_trip_property(eps, amp, theta0, phases, name, seed):
    scn = load_scenario("test-2", {"observer.eps": eps, "rig.disturbance.amplitude": amp,
                                   "rig.theta0": theta0, "reference.phases": phases,
                                   "name": name, "sensor.seed": seed})
    back = Scenario.model_validate(tomllib.loads(to_toml(scn.to_dict())))
    assert back == scn


# ---------------------------------------------------------------------------
# --set parsing


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_parse_override_floats(value):
    key, parsed = parse_override(f"observer.eps={value!r}")
    assert key == "observer.eps" and parsed == value


@given(st.integers(min_value=-(2**63), max_value=2**63 - 1))
def test_parse_override_ints(value):
    assert parse_override(f"sensor.seed={value}") == ("sensor.seed", value)


@given(st.text(alphabet=st.characters(codec="utf-8", exclude_characters="\n\r\"'[{#"),
               min_size=1, max_size=30))
def test_parse_override_bare_strings(text):
    """A VALUE that is not TOML is taken as the string itself (stripped)."""
    key, parsed = parse_override(f"name={text}")
    try:
        expected = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        expected = text.strip()
    assert key == "name" and parsed == expected


def test_parse_override_examples():
    assert parse_override("observer.discretization=zoh") == ("observer.discretization", "zoh")
    assert parse_override('name="a b"') == ("name", "a b")
    assert parse_override("reference.moves=[[1.0, 2.0, 1.0]]") == (
        "reference.moves", [[1.0, 2.0, 1.0]])
    assert parse_override(" duration = 5 ") == ("duration", 5)
    assert parse_override("x=a=b") == ("x", "a=b")
    v = parse_override("observer.eps=nan")[1]
    assert isinstance(v, float) and math.isnan(v)
    with pytest.raises(ScenarioError, match="KEY=VALUE"):
        parse_override("observer.eps")


# -- messages of the library speak of its own arguments, the CLI of its options -----


@pytest.mark.parametrize(
    ("overrides", "fragments"),
    [
        ({"observer.epsilon": 0.05}, ["override", "unknown key 'observer.epsilon'",
                                      "did you mean 'observer.eps'"]),
        ({"observer.eps": 0}, ["override", "observer.eps"]),
        ({"reference.moves": [[2.0, 1.0, 1.0], [1.0, 1.0, 0.0]]}, ["override",
                                                                   "reference.moves[1]"]),
        (["observer.eps"], ["override 'observer.eps'", "KEY=VALUE"]),
        ({1: 2}, ["override 1", "dotted string"]),
        ("observer.eps=0.05", ["overrides", "dict"]),
    ],
    ids=["unknown-key", "out-of-range", "moves-order", "no-equals", "non-string-key", "a-string"],
)
def test_api_errors_speak_of_the_override_not_the_cli(overrides, fragments):
    with pytest.raises(ScenarioError) as info:
        load_scenario("test-1", overrides)
    msg = str(info.value)
    assert "--set" not in msg and "\n" not in msg
    for fragment in fragments:
        assert fragment in msg


def test_cli_words_the_same_error_for_its_option(run_cli):
    res = run_cli("show", "test-1", "--set", "observer.epsilon=0.05")
    assert res.exit_code == 2
    assert res.stderr.strip() == ("esoarm: error: --set: unknown key 'observer.epsilon'; "
                                  "did you mean 'observer.eps'?")
    res = run_cli("show", "test-1", "--set", "observer.eps=0")
    assert res.stderr.startswith("esoarm: error: --set: key 'observer.eps' = 0")


def test_library_study_errors_name_arguments_not_options():
    from esoarm.studies.sweeps import sweep, tune
    from esoarm.studies.sweeps.sweep import parse_scheduler

    base = load_scenario("test-1")
    calls = [
        lambda: sweep.build_grid(base, []),
        lambda: sweep.build_grid(base, ["observer.eps=0.1"], seeds=0),
        lambda: sweep.build_grid(base, ["observer.eps=0.1"], max_runs=0),
        lambda: sweep.parse_vary("observer.eps"),
        lambda: parse_scheduler("nope"),
        lambda: tune.Objective("rms_error +", 1.0),
        lambda: tune.parse_bound("observer.eps=3", base),
    ]
    for call in calls:
        with pytest.raises(ScenarioError) as info:
            call()
        assert not str(info.value).startswith("--"), str(info.value)


# -- settings that silently do nothing (or less than asked) are warned about -------


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        ({"actuator.delay_samples": 1000}, "no command ever reaches the arm"),
        ({"reference.moves": [[30.0, 1.0, 1.0]]}, "reference.moves[0] starts at 30 s"),
        ({"duration": 0.03}, "not a whole number of sample periods"),
    ],
    ids=["delay-longer-than-run", "move-after-the-end", "duration-rounded"],
)
def test_ineffective_settings_warn(overrides, fragment):
    from esoarm.scenario import scenario_warnings

    msgs = scenario_warnings(load_scenario("test-1", overrides))
    assert any(fragment in m for m in msgs), msgs
    assert all("\n" not in m for m in msgs)


def test_aliased_multisine_reference_warns():
    from esoarm.scenario import scenario_warnings

    msgs = scenario_warnings(load_scenario("test-2", {"reference.frequencies": [200.0]}))
    assert any("reference.frequencies[0]" in m and "Nyquist" in m for m in msgs), msgs


@pytest.mark.parametrize("name", builtin_names())
def test_builtins_have_no_timing_warnings(name):
    from esoarm.scenario import timing_warnings

    assert timing_warnings(load_scenario(name)) == []


@pytest.mark.parametrize(
    ("overrides", "key"),
    [({"observer.eps": 1e-110}, "observer.eps"), ({"observer.eps": 1e200}, "observer.eps"),
     ({"rig.friction_velocity": 1e-320}, "rig.friction_velocity"),
     ({"actuator.lag": 1e-320}, "actuator.lag"),
     ({"rig.inertia_scale": 1e-320}, "rig.inertia_scale")],
    ids=["eps-tiny", "eps-huge", "vs-subnormal", "lag-subnormal", "inertia-underflow"],
)
def test_values_whose_derived_quantities_overflow_are_rejected(overrides, key):
    with pytest.raises(ScenarioError, match=f"key '{key}': out of the range double precision"):
        load_scenario("test-1", overrides)


def test_a_run_of_hours_is_warned_about():
    from esoarm.scenario import timing_warnings

    msgs = timing_warnings(load_scenario("test-1", {"rig.step": 1e-9, "duration": 2.0}))
    assert any("20,000,000 RK4 steps per sample" in m for m in msgs), msgs
