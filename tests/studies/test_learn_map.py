"""esoarm learn-map: ẑ3 binned over the angle, the table written into the scenario, its use."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from esoarm.cli import cli as main
from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import load_scenario
from esoarm.studies.adrc.learn_map import eps_at_error, learn_map, map_at

COG = ["--set", "rig.cogging.amplitude=0.08", "--set", "rig.cogging.periods=6"]


def test_bins_recover_a_known_periodic_function() -> None:
    """A sampled 3·cos(2θ) + noise over a full turn comes back at the nodes within 0.05."""
    rng = np.random.default_rng(0)
    theta = rng.uniform(-10.0, 10.0, 200_000)
    z3 = 3.0 * np.cos(2.0 * theta) + rng.normal(0.0, 0.5, theta.size)
    lm = learn_map(theta, z3, 36)
    nodes = 2 * math.pi * np.arange(36) / 36
    # a bin averages over ±π/36 around its node: the mean of cos over it is sinc-shrunk
    shrink = math.sin(2 * math.pi / 36) / (2 * math.pi / 36)
    assert lm.visited == 36
    np.testing.assert_allclose(lm.table, 3.0 * shrink * np.cos(2 * nodes), atol=0.05)


def test_previous_table_is_added_and_unvisited_bins_kept() -> None:
    prev = np.arange(8.0)
    lm = learn_map(np.full(10, 0.01), np.full(10, 2.0), 8, previous=prev)
    assert lm.visited == 1 and lm.table[0] == 2.0 and np.array_equal(lm.table[1:], prev[1:])
    with pytest.raises(ValueError, match="--bins 8"):
        learn_map(np.zeros(3), np.zeros(3), 4, previous=prev)
    with pytest.raises(ValueError, match="at least 2"):
        learn_map(np.zeros(3), np.zeros(3), 1)


def test_map_at_matches_the_drive_rule() -> None:
    from esoarm.plants.actuator import actuator_vector, feedforward

    table = [0.3, -1.0, 2.0, 0.5, 0.0]
    a = actuator_vector(load_scenario("test-1", {"controller.feedforward_map": table}))
    for ang in (-7.0, -0.1, 0.0, 0.9, 3.3, 6.2, 12.0):
        assert feedforward(ang, a) == pytest.approx(-0.0225 * float(map_at(np.array(table),
                                                                           ang)), abs=1e-15)


def test_eps_at_error_interpolates() -> None:
    assert eps_at_error([0.1, 0.2], np.array([1.0, 3.0]), 2.0) == pytest.approx(0.15)
    assert eps_at_error([0.1, 0.2], np.array([1.0, 3.0]), 0.5) is None


def test_cli_writes_the_table_and_the_next_run_tracks_better(tmp_path: Path) -> None:
    """learn-map from a 20 s run with cogging; the table's run at the same ε tracks better."""
    log, out = tmp_path / "run.csv", tmp_path / "mapped.toml"
    runner = CliRunner()
    r = runner.invoke(main, ["simulate", "test-1", *COG, "--out", str(log)])
    assert r.exit_code == 0, r.output
    r = runner.invoke(main, ["learn-map", str(log), "test-1", *COG, "--bins", "72",
                             "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "72 bins" in r.output
    table = tomllib.loads(out.read_text())["controller"]["feedforward_map"]
    assert len(table) == 72 and any(v != 0.0 for v in table)
    mapped = load_scenario(str(out))
    plain = load_scenario("test-1", {"rig.cogging.amplitude": 0.08, "rig.cogging.periods": 6})
    e0 = run_reference(plain, prepare(plain)).metrics["rms_error"]
    e1 = run_reference(mapped, prepare(mapped)).metrics["rms_error"]
    assert e1 < 0.7 * e0


@pytest.mark.parametrize(("args", "word"), [
    (["--bins", "1"], "--bins"),
    (["--out", "x.csv"], "--out"),
    (["--set", "controller.kind=pid"], "controller.kind"),
])
def test_bad_input_is_one_line_exit_2(tmp_path: Path, args: list[str], word: str) -> None:
    log = tmp_path / "run.csv"
    log.write_text("t,z1,z3\n0,0,0\n0.02,0.1,1\n")
    base = ["learn-map", str(log), "test-1", "--out", str(tmp_path / "m.toml")]
    r = CliRunner().invoke(main, [*base, *args])
    assert r.exit_code == 2 and word in r.output
    assert not (tmp_path / "m.toml").exists()


def test_a_log_without_the_estimates_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "run.csv"
    log.write_text("t,theta\n0,0\n")
    r = CliRunner().invoke(main, ["learn-map", str(log), "test-1", "--out",
                                  str(tmp_path / "m.toml")])
    assert r.exit_code == 2 and "z1" in r.output


def test_codegen_carries_the_table() -> None:
    """The generated C applies the table (checked in lockstep: tests/codegen/test_map_c.py)."""
    from esoarm.codegen.generate import generate

    scn = load_scenario("test-1", {"controller.feedforward_map": [0.1, 0.2]})
    assert "#define ACT_FF_N 2" in generate(scn).source
