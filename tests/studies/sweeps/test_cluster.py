"""Sweeps on a Dask distributed cluster started on 127.0.0.1 by the test.

A ``dask scheduler`` and a ``dask worker`` (two single-threaded worker
processes) run as subprocesses on loopback only; the sweep through them must
give exactly the rows of the in-process sweep.  Skipped, with the reason, only
when distributed is not installed or the processes cannot start.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("distributed", reason="the 'cluster' extra (dask[distributed]) is needed")

from esoarm.cli import cli  # noqa: E402
from esoarm.scenario import load_scenario  # noqa: E402
from esoarm.studies.sweeps import sweep  # noqa: E402

pytestmark = pytest.mark.slow  # end to end (see pyproject: the fast tier is -m 'not slow')

START_TIMEOUT = 60.0


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    from distributed import Client

    tmp = tmp_path_factory.mktemp("dask")
    info = tmp / "scheduler.json"
    logs = [open(tmp / name, "w") for name in ("scheduler.log", "worker.log")]  # noqa: SIM115
    procs: list[subprocess.Popen] = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
            stdout=logs[0], stderr=subprocess.STDOUT, cwd=tmp))
        deadline = time.monotonic() + START_TIMEOUT
        while not info.exists() and time.monotonic() < deadline and procs[0].poll() is None:
            time.sleep(0.2)
        if not info.exists():
            log = (tmp / "scheduler.log").read_text()[-300:]
            pytest.skip(f"dask scheduler did not start: {log}")
        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:"), address
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address, "--host", "127.0.0.1",
             "--nworkers", "2", "--nthreads", "1", "--no-dashboard", "--memory-limit", "2GiB"],
            stdout=logs[1], stderr=subprocess.STDOUT, cwd=tmp))
        with Client(address, timeout="20s") as client:
            try:
                client.wait_for_workers(2, timeout=START_TIMEOUT)
            except TimeoutError:
                log = (tmp / "worker.log").read_text()[-300:]
                pytest.skip(f"dask workers did not start: {log}")
        yield address
    finally:
        for proc in reversed(procs):
            _stop(proc)
        for fh in logs:
            fh.close()


def test_dask_rows_identical_to_in_process(scheduler: str) -> None:
    base = load_scenario("test-1", {"duration": 3.0})
    grid = sweep.build_grid(base, ["observer.eps=geom:0.03:0.3:9",
                                   "observer.discretization=euler,current"], seeds=3)
    local = sweep.run_sweep(grid)
    remote = sweep.run_sweep(grid, scheduler=scheduler, chunk=8)  # 6 points... many tasks
    assert remote.complete
    np.testing.assert_array_equal(remote.values, local.values)
    remote2 = sweep.run_sweep(grid, scheduler=scheduler, chunk=1000, workers=2)  # one task
    np.testing.assert_array_equal(remote2.values, local.values)


def test_arm_sweep_on_dask_same_rows(scheduler: str) -> None:
    """A URDF arm's sweep (compiled engine) on the cluster: the in-process rows exactly."""
    pytest.importorskip("pinocchio")
    base = load_scenario("two-link", {"duration": 1.0})
    grid = sweep.build_grid(base, ["observer.eps=0.02,0.03,0.05"], seeds=2)
    local = sweep.run_sweep(grid)
    remote = sweep.run_sweep(grid, scheduler=scheduler, chunk=2)
    assert remote.complete
    np.testing.assert_array_equal(remote.values, local.values)


@pytest.mark.parametrize("engine", ["exact", "fast"])
def test_cli_scheduler_same_csv(scheduler: str, tmp_path: Path, engine: str) -> None:
    args = ["sweep", "test-2", "--vary", "observer.eps=0.05,0.09,0.2", "--seeds", "4",
            "--set", "duration=2.0", "--engine", engine]
    here, there = tmp_path / "here.csv", tmp_path / "there.csv"
    r1 = CliRunner().invoke(cli, [*args, "--out", str(here)])
    r2 = CliRunner().invoke(cli, [*args, "--out", str(there), "--scheduler", scheduler,
                                  "--chunk", "4"])
    assert r1.exit_code == 0, r1.output
    assert r2.exit_code == 0, r2.output
    assert here.read_text() == there.read_text()


def test_unreachable_scheduler_is_a_one_line_failure(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import socket

    monkeypatch.setattr(sweep, "CONNECT_TIMEOUT", "1s")
    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "x.csv"
    res = CliRunner().invoke(cli, ["sweep", "test-1", "--vary", "observer.eps=0.1",
                                   "--set", "duration=1.0", "--scheduler",
                                   f"tcp://127.0.0.1:{port}", "--out", str(out)])
    assert res.exit_code == 1, res.output
    lines = [ln for ln in res.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1 and "cannot reach the Dask scheduler" in lines[0], lines
    assert len(out.read_text().splitlines()) == 1  # the header: no run finished


# -- schedulers that do not answer: one line, no traceback after it ------------------


def _esoarm(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", "import sys; from esoarm.cli import main; main(sys.argv[1:])",
         *args], capture_output=True, text=True, timeout=120)


SWEEP = ("sweep", "test-1", "--vary", "observer.eps=0.05", "--set", "duration=0.2")


@pytest.mark.parametrize("address", ["notanaddress", "tcp://host", "tcp://h:0", "ftp://h:1",
                                     "tcp://h:99999", "tcp://:8786"])
def test_malformed_scheduler_address_is_bad_input(address: str) -> None:
    proc = _esoarm(*SWEEP, "--scheduler", address)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1 and f"--scheduler '{address}'" in lines[0], proc.stderr


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_nothing_listening_is_one_line_exit_1() -> None:
    proc = _esoarm(*SWEEP, "--scheduler", f"tcp://127.0.0.1:{_free_port()}")
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1 and "cannot reach the Dask scheduler" in lines[0], proc.stderr
    assert "refused" in lines[0]


def test_a_server_that_is_not_dask_is_one_line_exit_1() -> None:
    """Something accepts the connection but does not speak Dask: no __del__ traceback."""
    import socket
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"HTTP/1.0 400 Bad Request\r\n\r\n" * 4)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        port = server.getsockname()[1]
        proc = _esoarm(*SWEEP, "--scheduler", f"tcp://127.0.0.1:{port}")
    finally:
        stop.set()
        thread.join(5)
        server.close()
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1 and "Dask scheduler at tcp://127.0.0.1:" in lines[0], proc.stderr
    assert "Exception ignored" not in proc.stderr


def test_a_server_that_accepts_and_stays_silent_is_one_line_within_seconds() -> None:
    """distributed's Client waits for ever for the handshake of a server that accepts and
    says nothing (a hung scheduler, an HTTP server): the probe gives up after its timeout."""
    import socket

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)  # the backlog accepts the connection; nothing is ever sent
    try:
        port = server.getsockname()[1]
        start = time.monotonic()
        proc = _esoarm(*SWEEP, "--scheduler", f"tcp://127.0.0.1:{port}")
        seconds = time.monotonic() - start
    finally:
        server.close()
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if "warning:" not in ln]
    assert len(lines) == 1 and "sends nothing within 5 s" in lines[0], proc.stderr
    assert seconds < 60  # hung for ever before (the subprocess timeout is 120 s)
