"""Sweeps: SPEC parsing, grid order, CSV, CLI behaviour, interruption, figures."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from esoarm.cli import cli
from esoarm.engines import batch
from esoarm.engines.simulation import prepare, run_reference
from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.sweeps import sweep

SHORT = ["--set", "duration=2.0"]


@pytest.fixture()
def base():  # type: ignore[no-untyped-def]
    return load_scenario("test-1", {"duration": 2.0})


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


# -- SPEC parsing ------------------------------------------------------------


def test_parse_vary_forms(base) -> None:  # type: ignore[no-untyped-def]
    assert sweep.parse_vary("observer.eps=0.05,0.09,0.2").values == (0.05, 0.09, 0.2)
    # an arm's per-joint lists: commas inside [...] (or quotes) do not split the list
    assert sweep.parse_vary("observer.eps=[0.02,0.03], [0.04,0.06]").values == (
        [0.02, 0.03], [0.04, 0.06])
    assert sweep.parse_vary('name="a,b",c').values == ("a,b", "c")
    assert sweep.parse_vary("observer.discretization=euler,zoh,current").values == (
        "euler", "zoh", "current")
    lin = sweep.parse_vary("controller.k1=lin:5:15:3")
    assert lin.values == (5.0, 10.0, 15.0) and lin.spacing == "lin"
    geom = sweep.parse_vary("observer.eps=geom:0.03:0.3:3")
    np.testing.assert_allclose(geom.values, [0.03, 0.03 * 10**0.5, 0.3], rtol=1e-15)
    ints = sweep.parse_vary("actuator.delay_samples=lin:0:4:5", base)
    assert ints.values == (0, 1, 2, 3, 4) and all(type(v) is int for v in ints.values)


@pytest.mark.parametrize(
    ("item", "needle"),
    [
        ("observer.eps", "expected KEY=SPEC"),
        ("observer.eps=", "empty value"),
        ("observer.eps=lin:0:1", "lin:START:STOP:NUM"),
        ("observer.eps=lin:a:1:3", "must be numbers"),
        ("observer.eps=geom:0:1:3", "non-zero"),
        ("observer.eps=lin:0.1:1:0", "NUM must be >= 1"),
        ("observer.eps=0.1,,0.2", "empty item"),
    ],
)
def test_parse_vary_errors_name_the_key(item: str, needle: str) -> None:
    with pytest.raises(ScenarioError) as exc:
        sweep.parse_vary(item)
    assert needle in str(exc.value)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(
    ("vary", "needle"),
    [
        (["observer.epss=0.1"], "unknown key 'observer.epss'; did you mean 'observer.eps'"),
        (["observer.eps=-0.1,0.1"], "observer.eps"),
        (["observer.discretization=euler,rk9"], "observer.discretization"),
        (["observer.eps=0.1", "observer.eps=0.2"], "given more than once"),
        ([], "at least one"),
    ],
)
def test_build_grid_rejects_bad_input(base, vary: list[str], needle: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ScenarioError) as exc:
        sweep.build_grid(base, vary, seeds=2)
    assert needle in str(exc.value)
    assert str(exc.value).startswith("vary")  # the library names its argument


def test_grid_order_first_key_slowest_seed_fastest(base) -> None:  # type: ignore[no-untyped-def]
    grid = sweep.build_grid(base, ["observer.eps=0.05,0.1", "controller.k1=8,12,16"], seeds=2)
    assert grid.n_runs == 12
    values = list(grid.point_values())
    assert values[:4] == [(0.05, 8), (0.05, 12), (0.05, 16), (0.1, 8)]
    assert [(p.observer.eps, p.controller.k1) for p in grid.points] == values
    result = sweep.run_sweep(grid, chunk=5)
    rows = list(result.rows())
    assert [(r[0], r[1], r[2]) for r in rows[:3]] == [(0.05, 8, 0), (0.05, 8, 1), (0.05, 12, 0)]
    # the row of (eps 0.1, k1 12, seed 1) is exactly that reference run
    scn = base.with_overrides({"observer.eps": 0.1, "controller.k1": 12, "sensor.seed": 1})
    ref = run_reference(scn, prepare(scn))
    row = next(r for r in rows if r[:3] == [0.1, 12, 1])
    assert row[3:6] == [ref.metrics["rms_error"], ref.metrics["rms_u"],
                        ref.metrics["max_abs_error"]]


def test_sensor_seed_as_a_grid_key(base, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    grid = sweep.build_grid(base, ["sensor.seed=3,5"])
    result = sweep.run_sweep(grid)
    assert result.complete and grid.n_runs == 2
    assert [r[:2] for r in result.rows()] == [[3, 3], [5, 5]]
    one = base.with_overrides({"sensor.seed": 5})
    assert result.values[1, 0] == run_reference(one, prepare(one)).metrics["rms_error"]
    with pytest.raises(ScenarioError, match="number of noise seeds"):
        sweep.build_grid(base, ["sensor.seed=3,5"], seeds=2)


def test_identical_whatever_chunking_and_workers(base) -> None:  # type: ignore[no-untyped-def]
    grid = sweep.build_grid(base, ["observer.eps=geom:0.03:0.3:7"], seeds=3)
    a = sweep.run_sweep(grid, chunk=1, workers=1)
    b = sweep.run_sweep(grid, chunk=4, workers=2)
    c = sweep.run_sweep(grid)
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(a.values, c.values)
    direct = batch.run_metrics(grid.points, seeds=range(3))
    np.testing.assert_array_equal(a.values, direct.values)


def test_csv_round_trips_exactly(base, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    grid = sweep.build_grid(base, ["observer.discretization=euler,zoh"], seeds=2)
    result = sweep.run_sweep(grid)
    path = tmp_path / "s.csv"
    assert result.write_csv(path) == 4
    rows = _read_csv(path)
    assert list(rows[0]) == ["observer.discretization", "seed", *batch.METRICS]
    assert [r["observer.discretization"] for r in rows] == ["euler", "euler", "zoh", "zoh"]
    got = np.array([[float(r[m]) for m in batch.METRICS] for r in rows])
    np.testing.assert_array_equal(got, result.values)
    assert rows[0]["samples"] == "100" and rows[0]["diverged"] == "0"


# -- command line ------------------------------------------------------------


def test_cli_sweep_json_and_outputs(tmp_path: Path) -> None:
    out, fig = tmp_path / "eps.csv", tmp_path / "eps.png"
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.05,0.09,0.2",
                                   "--seeds", "2", *SHORT, "--out", str(out), "--plot",
                                   str(fig), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert summary["runs"] == summary["finished"] == 6
    assert summary["best"][0]["observer.eps"] in (0.05, 0.09, 0.2)
    assert len(_read_csv(out)) == 6
    assert fig.stat().st_size > 10_000


def test_cli_two_keys_heatmap(tmp_path: Path) -> None:
    fig = tmp_path / "heat.png"
    res = CliRunner().invoke(cli, ["sweep", "test-2", "--vary", "observer.eps=geom:0.04:0.2:3",
                                   "--vary", "observer.discretization=euler,zoh", *SHORT,
                                   "--plot", str(fig)])
    assert res.exit_code == 0, res.output
    assert fig.stat().st_size > 10_000
    assert "observer.eps" in res.stdout


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--vary", "observer.epss=0.1"], "unknown key 'observer.epss'"),
        (["--vary", "observer.eps=geom:0:1:3"], "--vary observer.eps"),
        (["--vary", "observer.eps=0.1", "--set", "controller.k9=1"], "controller.k9"),
        (["--vary", "observer.eps=0.1", "--seeds", "0"], "--seeds"),
        (["--vary", "observer.eps=0.1", "--workers", "0"], "--workers"),
        (["--vary", "observer.eps=0.1", "--out", "x.txt"], "--out"),
        (["--vary", "observer.eps=0.1", "--vary", "controller.k1=5", "--vary",
          "controller.k2=9", "--plot", "p.png"], "one or two varied keys"),
    ],
)
def test_cli_bad_input_exit_2_one_line(tmp_path: Path, args: list[str], needle: str) -> None:
    out = tmp_path / "never.csv"
    res = CliRunner().invoke(cli, ["sweep", "test-1", *args, "--out", str(out)]
                             if "--out" not in args else ["sweep", "test-1", *args])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], res.stderr
    assert "Traceback" not in res.output
    assert not out.exists()


def test_diverged_runs_are_rows_with_a_warning(tmp_path: Path) -> None:
    out = tmp_path / "d.csv"
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.004,0.09",
                                   *SHORT, "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "1 of 2 runs diverged" in res.stderr
    assert "unstable" in res.stderr  # the scenario warning for eps = 0.004 with Euler
    assert [r["diverged"] for r in _read_csv(out)] == ["1", "0"]
    (line,) = [x for x in res.stderr.splitlines() if "runs diverged" in x]
    assert "at 1 of 2 grid points (observer.eps = 0.004)" in line
    assert "likely cause at the first: observer.eps = 0.004 s, an unstable observer" in line


def test_divergence_warning_names_the_first_points_in_grid_order(base) -> None:  # type: ignore[no-untyped-def]
    from esoarm.engines.metrics import METRICS
    from esoarm.studies.sweeps.output import DIVERGED_SHOWN, SweepWriter

    grid = sweep.build_grid(base, ["observer.eps=0.01,0.02,0.03,0.04,0.05,0.06"], 2)
    writer = SweepWriter(grid)
    assert writer.divergence_warning() is None
    diverged = {1: 2, 2: 1, 4: 1, 5: 2}  # grid point -> diverged seeds
    for first in (8, 4, 0):  # chunks of two points, finishing out of order (as on Dask)
        values = np.zeros((4, len(METRICS)))
        for k in range(4):
            p, j = divmod(first + k, 2)
            values[k, -1] = j < diverged.get(p, 0)
        writer.add(first, values)
    assert writer.diverged == 6 and writer.diverged_points == 4
    assert writer.first_diverged == [(1, 2), (2, 1), (4, 1)][:DIVERGED_SHOWN]
    line = writer.divergence_warning()
    assert line is not None and line.startswith("6 of 12 runs diverged, at 4 of 6 grid points "
                                                "(observer.eps = 0.02 (2 of 2 seeds); "
                                                "observer.eps = 0.03 (1 of 2 seeds); "
                                                "observer.eps = 0.05 (1 of 2 seeds); and 1 more)")
    assert "nothing in the scenario of the first stands out" in line  # eps = 0.02 is stable


def test_interrupt_keeps_finished_rows(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    real = sweep.iter_sweep

    def first_chunk_then_ctrl_c(*args, **kwargs):  # type: ignore[no-untyped-def]
        for i, item in enumerate(real(*args, **kwargs)):
            if i == 2:
                raise KeyboardInterrupt
            yield item

    monkeypatch.setattr(sweep, "iter_sweep", first_chunk_then_ctrl_c)
    out = tmp_path / "part.csv"
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=geom:0.03:0.3:10",
                                   "--seeds", "2", *SHORT, "--chunk", "4", "--out", str(out)])
    assert res.exit_code == 130, res.output
    assert "interrupted: 8 of 20 runs finished; the 8 finished rows are in" in res.stderr
    rows = _read_csv(out)
    assert len(rows) == 8 and rows[0]["seed"] == "0" and rows[-1]["seed"] == "1"
    grid = sweep.build_grid(load_scenario("test-1", {"duration": 2.0}),
                            ["observer.eps=geom:0.03:0.3:10"], seeds=2)
    full = sweep.run_sweep(grid)
    got = np.array([[float(r[m]) for m in batch.METRICS] for r in rows])
    np.testing.assert_array_equal(got, full.values[:8])


@pytest.mark.slow
@pytest.mark.skipif(os.name != "posix", reason="SIGINT delivery is POSIX-specific")
def test_real_ctrl_c_exits_130_with_a_valid_csv(tmp_path: Path) -> None:
    """Ctrl-C once the first chunk is done (a condition, not a time: robust under load)."""
    out = tmp_path / "sig.csv"
    # SIGINT as in a terminal: a job started in the background by a non-interactive shell
    # (nohup, `cmd &` in a script) inherits SIGINT ignored, and Python then raises no
    # KeyboardInterrupt; Ctrl-C is only meaningful with the default handler.
    child = ("import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
             "from esoarm.cli import main; main()")
    cmd = [sys.executable, "-c", child, "sweep", "test-1",
           "--vary", "observer.eps=geom:0.03:0.3:400", "--seeds", "10", "--chunk", "40",
           "--workers", "1", "--out", str(out), "--verbose"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = []
    try:
        assert proc.stderr is not None
        for line in proc.stderr:  # --verbose: one progress line per finished chunk (≤ 1/s)
            seen.append(line)
            if line.startswith("esoarm: sweep: "):
                break
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = "".join(seen) + err
    assert any(ln.startswith("esoarm: sweep: ") for ln in seen), err
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "finished rows are in" in err
    rows = _read_csv(out)  # header plus whole rows only
    assert 40 <= len(rows) < 4000
    assert all(len(r) == 2 + len(batch.METRICS) and r["diverged"] in ("0", "1") for r in rows)


# -- the size of a grid: checked before anything is built -----------------------------


def test_grid_over_the_limit_is_refused_before_allocating(base) -> None:  # type: ignore[no-untyped-def]
    # 10**12 values would not fit in memory: refused from NUM alone
    with pytest.raises(ScenarioError, match=r"1,000,000,000,000 runs.*--max-runs"):
        sweep.build_grid(base, ["observer.eps=geom:0.01:0.3:1000000000000"])
    with pytest.raises(ScenarioError, match=r"this sweep is 12 runs.*limit of 10\b"):
        sweep.build_grid(base, ["observer.eps=0.05,0.1", "controller.k1=8,12,16"], seeds=2,
                         max_runs=10)
    grid = sweep.build_grid(base, ["observer.eps=0.05,0.1", "controller.k1=8,12,16"], seeds=2,
                            max_runs=12)
    assert grid.n_runs == 12


def test_build_grid_reports_progress(base) -> None:  # type: ignore[no-untyped-def]
    calls: list[int] = []
    sweep.build_grid(base, ["observer.eps=geom:0.03:0.3:250"], progress=calls.append)
    assert sum(calls) == 250 and len(calls) == 3


def test_cli_grid_too_large_is_one_line(tmp_path: Path) -> None:
    out = tmp_path / "big.csv"
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary",
                                   "observer.eps=geom:0.01:0.3:100000000", "--out", str(out)])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "100,000,000 runs" in lines[0] and "--max-runs" in lines[0]
    assert not out.exists()
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.05,0.1",
                                   "--seeds", "3", "--max-runs", "5", *SHORT])
    assert res.exit_code == 2 and "limit of 5" in res.stderr
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.05,0.1",
                                   "--seeds", "3", "--max-runs", "6", *SHORT, "--json"])
    assert res.exit_code == 0 and json.loads(res.stdout)["runs"] == 6


def test_verbose_progress_lines_without_a_terminal_and_json_stays_pure() -> None:
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.004,0.05,0.1",
                                   *SHORT, "--json", "--verbose"])
    assert res.exit_code == 0, res.output
    json.loads(res.stdout)  # nothing but the JSON object on stdout
    assert "esoarm: checking grid: 3 of 3 points" in res.stderr
    assert "esoarm: sweep: 3 of 3 runs" in res.stderr
    assert "warning:" in res.stderr  # eps = 0.004 is unstable with Euler
    quiet = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.004,0.05",
                                     *SHORT, "--json", "--quiet"])
    assert quiet.exit_code == 0 and quiet.stderr == ""
    assert json.loads(quiet.stdout)["runs"] == 2


def test_best_points_rank_a_diverged_point_last(run_cli) -> None:  # type: ignore[no-untyped-def]
    """ε = 0.2 ms diverges early with a smaller RMS error than ε = 0.09 s: it is not 'best'."""
    res = run_cli("sweep", "test-1", "--vary", "observer.eps=0.0002,0.09", "--set",
                  "duration=2", "-q")
    assert res.exit_code == 0, res.stderr
    rows = [line for line in res.stdout.splitlines() if line.startswith("│")]
    assert rows[0].split("│")[1].strip() == "0.09"
    assert "(diverged)" in rows[1] and "(diverged)" not in rows[0]
