"""Property tests over the scenario schema: load and run bounded, or one line naming the key.

Any generated scenario -- overrides of arbitrary keys (valid, misspelt, whole
tables) with arbitrary values (numbers of every size and sign, NaN, inf,
strings, booleans, lists, nested lists, tables) -- must either load and run
to a finite result (or stop as diverged, with one line and the rows kept), or
be rejected with :class:`ScenarioError`: one line naming a key.  Never any
other exception.  The same holds on the command line (exit 0 or 2, one line).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from esoarm.engines.simulation import SimulationDiverged, simulate
from esoarm.scenario import Scenario, ScenarioError, ScenarioWarning, load_scenario
from esoarm.scenario.schema import valid_keys

KEYS = valid_keys()
DEFAULTS = Scenario().to_dict()
#: Runs longer than this many RK4 steps are only loaded, not run (keeps the test quick).
MAX_STEPS = 40_000


def _default(key: str) -> Any:
    node: Any = DEFAULTS
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-1e3, max_value=1e3),
    st.floats(min_value=1e-6, max_value=10.0),
    st.integers(min_value=-10**20, max_value=10**20),
    st.integers(min_value=0, max_value=100),
)
scalars = st.one_of(numbers, st.booleans(), st.text(max_size=12),
                    st.sampled_from(["euler", "zoh", "current", "eso", "model", "sine",
                                     "quintic-steps", "multisine"]))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)),
    max_leaves=8)


@st.composite
def near_default(draw: st.DrawFn, key: str) -> Any:
    """A value of the key's own type, scaled or perturbed (finds range and consistency bugs)."""
    base = _default(key)
    if isinstance(base, bool) or base is None or isinstance(base, str):
        return draw(values)
    if isinstance(base, int):
        return draw(st.integers(min_value=-5, max_value=base * 10 + 50))
    if isinstance(base, float):
        factor = draw(st.sampled_from([0.0, -1.0, 1e-3, 0.5, 2.0, 10.0, 1e3, 1e9]))
        return base * factor if base else draw(st.floats(min_value=-1e9, max_value=1e9))
    if isinstance(base, list):
        return draw(st.lists(st.lists(st.floats(min_value=-50, max_value=50), min_size=0,
                                      max_size=4), max_size=3)
                    if base and isinstance(base[0], list)
                    else st.lists(st.floats(min_value=-50, max_value=50), max_size=3))
    return draw(values)


@st.composite
def overrides(draw: st.DrawFn) -> dict[str, Any]:
    n = draw(st.integers(min_value=1, max_value=5))
    out: dict[str, Any] = {}
    for _ in range(n):
        key = draw(st.one_of(
            st.sampled_from(KEYS),
            st.sampled_from(KEYS).map(lambda k: k[:-1] + "x"),  # misspelt
            st.sampled_from(["rig", "observer", "reference", "motor", "", "a.b.c"]),  # tables
        ))
        out[key] = draw(st.one_of(values, near_default(key)))
    if draw(st.booleans()):  # mostly short runs, so that most examples also run
        out.setdefault("duration", draw(st.sampled_from([0.1, 0.5, 2.0])))
    return out


@st.composite
def benign(draw: st.DrawFn, key: str) -> Any:
    """A value of the key's type, the default scaled by a modest factor."""
    base = _default(key)
    if isinstance(base, float) and not isinstance(base, bool):
        factor = draw(st.sampled_from([0.1, 0.5, 1.0, 2.0, 10.0]))
        return base * factor if base else draw(st.floats(min_value=-3.0, max_value=3.0))
    if isinstance(base, int) and not isinstance(base, bool):
        return draw(st.integers(min_value=0, max_value=max(3, base * 3)))
    return draw(near_default(key))


@st.composite
def plausible(draw: st.DrawFn) -> dict[str, Any]:
    """Valid keys with values of their own type near the defaults: most load and run."""
    keys = draw(st.lists(st.sampled_from([k for k in KEYS if not k.startswith("motor")]),
                         min_size=1, max_size=3, unique=True))
    out = {key: draw(st.one_of(benign(key), near_default(key))) for key in keys}
    out.setdefault("duration", draw(st.sampled_from([0.1, 0.5, 2.0])))
    return out


def _names_a_key(message: str, given_keys: list[str]) -> bool:
    return (any(k and k in message for k in [*given_keys, *KEYS]) or "empty key" in message
            or "scenario" in message)


@settings(max_examples=200)
@given(st.one_of(overrides(), plausible()))
def test_any_scenario_loads_and_runs_bounded_or_is_rejected_in_one_line(over):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", ScenarioWarning)  # warnings must be well-formed too
            try:
                scn = load_scenario("test-1", over)
            except ScenarioWarning:
                return
    except ScenarioError as exc:
        msg = str(exc)
        assert "\n" not in msg and msg.strip() == msg and msg
        assert _names_a_key(msg, list(over)), msg
        event("rejected")
        return
    assert isinstance(scn, Scenario)
    if scn.n_samples * scn.substeps > MAX_STEPS:
        event("loaded, too long to run here")
        return
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ScenarioWarning)
            result = simulate(scn)
    except SimulationDiverged as exc:
        assert "\n" not in str(exc)
        assert 1 <= len(exc.result.t) <= scn.n_samples
        event("ran, diverged")
        return
    assert len(result.t) == scn.n_samples
    assert all(math.isfinite(result.metrics[m]) for m in ("rms_error", "rms_u", "max_abs_error"))
    assert max(abs(result.u).max(), 0.0) <= scn.actuator.torque_limit
    event("ran")


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])  # run_cli is stateless
@given(key=st.one_of(st.sampled_from(KEYS), st.text(max_size=20)),
       raw=st.one_of(st.text(max_size=20), values.map(repr)))
def test_any_set_on_the_command_line_is_exit_0_or_one_line_exit_2(run_cli, key, raw):
    res = run_cli("show", "test-1", "--set", f"{key}={raw}")
    assert res.exception is None, res.exception
    if res.exit_code == 0:
        assert res.stdout.startswith("name = ")
        return
    assert res.exit_code == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("esoarm: error: "), res.stderr
