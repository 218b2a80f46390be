"""Sweeps at scale: rows streamed to CSV in grid order, memory independent of the runs."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from esoarm.cli import cli
from esoarm.engines.metrics import METRICS
from esoarm.scenario import load_scenario
from esoarm.studies.sweeps import sweep
from esoarm.studies.sweeps.output import SweepWriter

SHORT = {"duration": 2.0}


def _grid(points: int = 6, seeds: int = 3):  # type: ignore[no-untyped-def]
    return sweep.build_grid(load_scenario("test-1", SHORT),
                            [f"observer.eps=geom:0.03:0.3:{points}"], seeds=seeds)


def _rows(path: Path) -> list[list[str]]:
    with path.open(newline="") as fh:
        return list(csv.reader(fh))


def test_writer_out_of_order_chunks_give_the_in_order_csv(tmp_path: Path) -> None:
    grid = _grid()
    result = sweep.run_sweep(grid, chunk=6)  # 2 points per chunk
    expected = tmp_path / "expected.csv"
    result.write_csv(expected)
    chunks = list(sweep.iter_sweep(grid, chunk=6))
    writer = SweepWriter(grid, tmp_path / "streamed.csv")
    for first, values in reversed(chunks):  # as a cluster might deliver them
        writer.add(first, values)
    assert writer.close() == grid.n_runs
    assert (tmp_path / "streamed.csv").read_text() == expected.read_text()
    assert writer.best(3) == result.best(3)
    assert writer.n_done == grid.n_runs and writer.diverged == 0


def test_rows_reach_the_file_as_chunks_finish(tmp_path: Path) -> None:
    grid = _grid()
    writer = SweepWriter(grid, tmp_path / "s.csv")
    first, values = next(sweep.iter_sweep(grid, chunk=6))
    writer.add(first, values)
    assert writer._tmp is not None
    assert len(_rows(writer._tmp)) == 1 + 6  # header and the first chunk, before closing
    assert not (tmp_path / "s.csv").exists()  # the named file appears when closed
    writer.close(complete=False)
    assert len(_rows(tmp_path / "s.csv")) == 7


def test_interrupted_writer_keeps_rows_held_behind_a_gap(tmp_path: Path) -> None:
    grid = _grid()
    chunks = list(sweep.iter_sweep(grid, chunk=6))
    writer = SweepWriter(grid, tmp_path / "gap.csv")
    writer.add(*chunks[2])  # the first two chunks never came
    assert writer.close(complete=False) == 6
    rows = _rows(tmp_path / "gap.csv")
    assert rows[0] == ["observer.eps", "seed", *METRICS] and len(rows) == 7
    assert float(rows[1][0]) == grid.vary[0].values[4]


@pytest.mark.slow
def test_memory_does_not_grow_with_the_runs(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The CLI holds no per-run array: 10× the runs, the same peak (synthetic rows)."""

    def synthetic(grid, *, chunk=None, **_kw):  # type: ignore[no-untyped-def]
        size = chunk or 1000
        row = np.array([0.01, 0.1, 0.02, 0.3, 1.0, 1000.0, 0.0])
        for start in range(0, grid.n_runs, size):
            n = min(size, grid.n_runs - start)
            yield start, np.tile(row, (n, 1))

    monkeypatch.setattr(sweep, "iter_sweep", synthetic)

    def peak(points: int) -> int:
        out = tmp_path / f"{points}.csv"
        tracemalloc.start()
        res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary",
                                       f"observer.eps=geom:0.03:0.3:{points}", "--seeds", "100",
                                       "--chunk", "1000", "--out", str(out)])
        size = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert res.exit_code == 0, res.output
        assert len(_rows(out)) == points * 100 + 1
        return size

    small, large = peak(20), peak(200)  # 2,000 and 20,000 runs
    assert large < small + 2_000_000, (small, large)


@pytest.mark.slow
@pytest.mark.skipif(os.name != "posix", reason="signals are POSIX-specific")
def test_sigterm_keeps_a_valid_csv(tmp_path: Path) -> None:
    out = tmp_path / "term.csv"
    cmd = [sys.executable, "-c", "from esoarm.cli import main; main()", "sweep", "test-1",
           "--vary", "observer.eps=geom:0.03:0.3:400", "--seeds", "10", "--chunk", "40",
           "--workers", "1", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    tmp = out.with_name(f".{out.name}.{proc.pid}.tmp")
    while time.monotonic() < deadline and proc.poll() is None:
        if tmp.exists() and len(tmp.read_text().splitlines()) > 1:
            break  # at least one chunk written
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "finished rows are in" in err
    rows = _rows(out)
    assert rows[0] == ["observer.eps", "seed", *METRICS]
    assert 1 < len(rows) < 4001
    assert all(len(r) == 2 + len(METRICS) and r[-1] in ("0", "1") for r in rows[1:])
    assert not tmp.exists()
