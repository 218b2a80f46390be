"""Output files: unwritable paths are bad input, a full disk is one line, nothing half-written.

Every command that writes checks its paths before any work (exit 2, one line
naming the user's path), and every file goes through ``esoarm._io.atomic_path``
(a full disk or a file-size limit: exit 1, one line, no partial file and no
temporary file left behind).
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from esoarm import _io
from esoarm.engines.simulation import simulate
from esoarm.scenario import load_scenario

SHORT = ["--set", "duration=1.0"]
LINUX = sys.platform.startswith("linux")


def _one_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    assert "Traceback" not in text
    return lines[0]


@pytest.fixture
def log_csv(tmp_path: Path) -> Path:
    """A short run written as CSV: has the t, theta, u columns replay needs."""
    path = tmp_path / "log.csv"
    simulate(load_scenario("test-1", {"duration": 1.0})).to_csv(path)
    return path


def _commands(log_csv: Path, target: str, directory: str) -> list[list[str]]:
    return [
        ["simulate", "test-1", *SHORT, "--out", target],
        ["simulate", "test-1", *SHORT, "--plot", target.replace(".csv", ".png")],
        ["sweep", "test-1", "--vary", "observer.eps=0.05", *SHORT, "--out", target],
        ["sweep", "test-1", "--vary", "observer.eps=0.05,0.09", *SHORT, "--plot",
         target.replace(".csv", ".png")],
        ["tune", "test-1", "--vary", "observer.eps=0.05:0.1", *SHORT, "--out", target],
        ["replay", str(log_csv), "--out", target],
        ["replay", str(log_csv), "--plot", target.replace(".csv", ".png")],
        ["run", "test-1", "--port", "/nonexistent/port", "--log", target],
        ["reproduce", "--out", directory],
        ["analyze", "test-1", "--plot", target.replace(".csv", ".png")],
        ["excite", "test-1", "--twin", "--duration", "1", "--log", target],
        ["identify", str(log_csv), "--out", target.replace(".csv", ".toml")],
        ["identify", str(log_csv), "--plot", target.replace(".csv", ".png")],
        ["arm-study", "two-link", "--set", "duration=0.1", "--eps", "0.02", "--out", directory],
    ]


@pytest.mark.skipif(not LINUX or not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_unwritable_paths_are_bad_input_before_any_work(run_cli, log_csv, tmp_path):
    """/proc accepts no new files: every output option says so in one line, exit 2."""
    for args in _commands(log_csv, "/proc/esoarm-x.csv", "/proc/esoarm-results"):
        res = run_cli(*args)
        line = _one_line(res.stderr)
        assert res.exit_code == 2 and res.exception is None, (args, res.stderr)
        assert line.startswith("esoarm: error: --"), line
        assert "/proc/esoarm-" in line and ".tmp" not in line, line


def test_parent_that_is_a_file_is_bad_input(run_cli, log_csv, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x", encoding="utf-8")
    for args in _commands(log_csv, str(afile / "r.csv"), str(afile / "res")):
        res = run_cli(*args)
        line = _one_line(res.stderr)
        assert res.exit_code == 2 and res.exception is None, (args, res.stderr)
        assert str(afile) in line and "not a directory" in line, line
    assert afile.read_text(encoding="utf-8") == "x"


def test_arm_study_checks_out_before_the_runs_and_writes_all_or_nothing(run_cli, tmp_path,
                                                                       monkeypatch):
    """arm-study's DIR: bad input before any run (was an internal error after them), and a
    write failing halfway leaves DIR as it was (files staged, moved in at the end)."""
    from esoarm.studies import arms as arm_study

    def no_runs(*args, **kwargs):
        raise AssertionError("the runs started before --out was checked")

    monkeypatch.setattr(arm_study, "run_arm_study", no_runs)
    afile = tmp_path / "afile"
    afile.write_text("x", encoding="utf-8")
    res = run_cli("arm-study", "two-link", "--out", str(afile / "res"))
    assert res.exit_code == 2 and "not a directory" in _one_line(res.stderr)
    monkeypatch.undo()
    pytest.importorskip("pinocchio")

    real_write = arm_study.write_arm_study

    def write_then_fail(study, out, fmt="png"):
        real_write(study, out, fmt)
        raise _io.OutputError(Path(out) / "report.html", "no space left on the device")

    monkeypatch.setattr(arm_study, "write_arm_study", write_then_fail)
    out = tmp_path / "study"
    res = run_cli("arm-study", "two-link", "--set", "duration=0.2", "--eps", "0.02",
                  "--workers", "1", "--out", str(out), "--quiet")
    # esoarm.cli.main prints an OutputError as one line, exit 1 (test_file_size_limit_...)
    assert isinstance(res.exception, _io.OutputError), res
    assert str(res.exception) == (f"cannot write '{out / 'report.html'}': "
                                  "no space left on the device")
    assert list(tmp_path.iterdir()) == [afile]  # no DIR, no temporary directory


def test_empty_out_directory_is_bad_input(run_cli, tmp_path, monkeypatch):
    """--out '' is not the current directory (reproduce wrote its files there)."""
    monkeypatch.chdir(tmp_path)
    for args in (["reproduce", "--out", ""], ["arm-study", "two-link", "--out", ""]):
        res = run_cli(*args)
        assert res.exit_code == 2 and "give a directory name" in _one_line(res.stderr), args
    with pytest.raises(_io.OutputError, match="empty path"):
        _io.check_writable("")
    assert list(tmp_path.iterdir()) == []


def test_a_name_too_long_is_bad_input(run_cli, log_csv, tmp_path):
    long = "a" * 300
    for args in _commands(log_csv, str(tmp_path / f"{long}.csv"), str(tmp_path / long / "res")):
        res = run_cli(*args)
        line = _one_line(res.stderr)
        assert res.exit_code == 2 and res.exception is None, (args, res.stderr)
        assert "too long" in line and "at most" not in line or "255" in line, line
    _io.check_writable(tmp_path / ("b" * 255 + ".csv")[-255:])  # the longest name fits
    with _io.atomic_path(tmp_path / ("c" * 251 + ".csv")) as tmp:  # its temporary one too
        tmp.write_text("x", encoding="utf-8")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith("c")] == ["c" * 251 + ".csv"]


@pytest.mark.skipif(not LINUX, reason="FIFOs and /dev/null")
def test_a_fifo_or_a_device_is_not_replaced_by_a_file(run_cli, log_csv, tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    for args in _commands(log_csv, str(fifo), str(tmp_path / "res"))[:1] + [
            ["sweep", "test-1", "--vary", "observer.eps=0.05", *SHORT, "--out", str(fifo)]]:
        res = run_cli(*args)
        assert res.exit_code == 2 and "a FIFO (named pipe)" in _one_line(res.stderr), args
    for path in (fifo, Path("/dev/null")):
        with pytest.raises(_io.OutputError, match="not a regular file"), _io.atomic_path(path):
            raise AssertionError("not reached")
    assert fifo.exists() and not fifo.is_file()
    assert Path("/dev/null").is_char_device()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "pipe.csv"]


def test_a_symbolic_link_keeps_pointing_at_the_written_file(run_cli, tmp_path):
    """An output path that is a link: its target is written, the link stays (as with >)."""
    data = tmp_path / "data"
    data.mkdir()
    for args, name in ((["simulate", "test-1", *SHORT], "run.csv"),
                       (["sweep", "test-1", "--vary", "observer.eps=0.05,0.09", *SHORT],
                        "sweep.csv")):
        link = tmp_path / name
        link.symlink_to(data / name)  # dangling until written
        res = run_cli(*args, "--out", str(link), "--quiet")
        assert res.exit_code == 0, res.stderr
        assert link.is_symlink() and (data / name).is_file()
        assert link.read_text(encoding="utf-8").startswith(("t,", "observer.eps,"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "run.csv", "sweep.csv"]
    assert sorted(p.name for p in data.iterdir()) == ["run.csv", "sweep.csv"]
    dead = tmp_path / "dead.csv"
    dead.symlink_to("/proc/esoarm-nowhere.csv")
    res = run_cli("simulate", "test-1", *SHORT, "--out", str(dead))
    assert res.exit_code == 2 and str(dead) in _one_line(res.stderr)


def test_reproduce_out_that_is_a_file(run_cli, tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x", encoding="utf-8")
    res = run_cli("reproduce", "--out", str(afile))
    assert res.exit_code == 2 and "not a directory" in _one_line(res.stderr)


# -- the library: OutputError naming the user's path --------------------------------


@pytest.mark.skipif(not LINUX or not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_api_writers_raise_output_error_naming_the_path(tmp_path):
    from esoarm.hardware.replay import ReplayResult
    from esoarm.studies.sweeps.sweep import build_grid, run_sweep

    res = simulate(load_scenario("test-1", {"duration": 0.2}))
    grid = build_grid(load_scenario("test-1", {"duration": 0.2}), ["observer.eps=0.05"])
    writers = [
        lambda p: res.to_csv(p),
        lambda p: res.plot(p.with_suffix(".png")),
        lambda p: run_sweep(grid).write_csv(p),
        lambda p: ReplayResult(res.t, res.theta, res.u, res.z, 0.02).to_csv(p),
    ]
    for write in writers:
        with pytest.raises(_io.OutputError) as info:
            write(Path("/proc/esoarm-api.csv"))
        assert "/proc/esoarm-api" in str(info.value) and ".tmp" not in str(info.value)
        assert isinstance(info.value, OSError)  # callers catching OSError still work
    afile = tmp_path / "afile"
    afile.write_text("x", encoding="utf-8")
    with pytest.raises(_io.OutputError) as info:  # was "File exists"
        res.to_csv(afile / "sub" / "r.csv")
    assert str(info.value) == f"cannot write '{afile / 'sub' / 'r.csv'}': '{afile}' is a file, " \
        "not a directory"


def test_atomic_path_cleans_up_on_a_failed_write(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old", encoding="utf-8")
    with pytest.raises(_io.OutputError, match="no space left"), _io.atomic_path(target) as tmp:
        tmp.write_text("partial", encoding="utf-8")
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert target.read_text(encoding="utf-8") == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def _tree(root: Path) -> dict[str, str]:
    """Every file under root (hidden ones too) -> its text."""
    return {str(p.relative_to(root)): p.read_text(encoding="utf-8")
            for p in sorted(root.rglob("*")) if p.is_file()}


def _write_some(out: Path, fail_after: int | None = None) -> None:
    """Write a.csv, runs/r1.csv, runs/r2.csv, report.html through atomic_path; OSError
    (a full disk) instead of the file number ``fail_after``."""
    for i, name in enumerate(("a.csv", "runs/r1.csv", "runs/r2.csv", "report.html")):
        with _io.atomic_path(out / name) as tmp:
            if i == fail_after:
                tmp.write_text("par", encoding="utf-8")
                raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
            tmp.write_text(f"new {name}", encoding="utf-8")


def test_staged_dir_appears_only_complete(tmp_path):
    out = tmp_path / "sub" / "res"
    with _io.staged_dir(out) as staging:
        assert staging != out and staging.is_dir() and not out.exists()
        _write_some(staging)
        assert not out.exists()  # nothing under DIR before the end
    assert _tree(out) == {n: f"new {n}" for n in ("a.csv", "report.html", "runs/r1.csv",
                                                  "runs/r2.csv")}
    assert [p.name for p in out.parent.iterdir()] == ["res"]  # no temporary directory left


@pytest.mark.parametrize("fail_after", [0, 2, 3])
def test_staged_dir_failing_halfway_leaves_no_directory(tmp_path, fail_after):
    out = tmp_path / "res"
    with pytest.raises(_io.OutputError) as info, _io.staged_dir(out) as staging:
        _write_some(staging, fail_after)
    name = ("a.csv", "runs/r1.csv", "runs/r2.csv", "report.html")[fail_after]
    assert str(info.value) == f"cannot write '{out / name}': no space left on the device"
    assert list(tmp_path.iterdir()) == []


def test_staged_dir_over_earlier_results_replaces_them_only_when_complete(tmp_path):
    out = tmp_path / "res"
    (out / "runs").mkdir(parents=True)
    old = {"a.csv": "old a", "runs/r1.csv": "old r1", "runs/mine.txt": "keep",
           "notes.txt": "keep"}
    for name, text in old.items():
        (out / name).write_text(text, encoding="utf-8")
    with pytest.raises(_io.OutputError, match="runs/r2.csv"), _io.staged_dir(out) as staging:
        assert staging.parent == out  # inside DIR: the renames stay on one file system
        _write_some(staging, fail_after=2)
    assert _tree(out) == old
    with _io.staged_dir(out) as staging:
        _write_some(staging)
    assert _tree(out) == {"a.csv": "new a.csv", "notes.txt": "keep", "report.html":
                          "new report.html", "runs/mine.txt": "keep",
                          "runs/r1.csv": "new runs/r1.csv", "runs/r2.csv": "new runs/r2.csv"}


def test_staged_dir_on_ctrl_c_and_plain_os_errors(tmp_path):
    out = tmp_path / "res"
    with pytest.raises(KeyboardInterrupt), _io.staged_dir(out) as staging:
        _write_some(staging, fail_after=None)
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(_io.OutputError) as info, _io.staged_dir(out):
        raise OSError(errno.EFBIG, "File too large")  # a writer that names no file
    assert str(info.value).startswith(f"cannot write '{out}': file too large")
    assert list(tmp_path.iterdir()) == []


def test_atomic_path_cleans_up_on_ctrl_c(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(KeyboardInterrupt), _io.atomic_path(target) as tmp:
        tmp.write_text("partial", encoding="utf-8")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_check_writable_leaves_nothing_behind(tmp_path):
    _io.check_writable(tmp_path / "a" / "b" / "c.csv")
    _io.check_writable(tmp_path / "x" / "y", directory=True)
    _io.check_writable(tmp_path / "f.csv")
    assert list(tmp_path.iterdir()) == []


# -- a full disk: one line, exit 1, no partial and no temporary file -----------------

FSIZE = 40_000  # bytes: more than any script needs, less than the outputs below


def _limited(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    import resource

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (FSIZE, FSIZE))

    return subprocess.run(
        [sys.executable, "-c", "import sys; from esoarm.cli import main; main(sys.argv[1:])",
         *args], capture_output=True, text=True, timeout=300, cwd=cwd, preexec_fn=limit)


@pytest.mark.skipif(not LINUX, reason="RLIMIT_FSIZE and SIGXFSZ semantics")
@pytest.mark.parametrize("kind", ["simulate-csv", "simulate-plot", "sweep-csv", "replay-csv",
                                  "reproduce"])
@pytest.mark.slow
def test_file_size_limit_is_one_line_exit_1(kind, tmp_path, log_csv):
    out = tmp_path / "out"
    out.mkdir()
    args = {
        "simulate-csv": ["simulate", "test-1", "--set", "duration=20", "--out", "run.csv"],
        "simulate-plot": ["simulate", "test-1", "--set", "duration=20", "--plot", "run.svg"],
        "sweep-csv": ["sweep", "test-1", "--vary", "observer.eps=geom:0.03:0.3:400",
                      "--set", "duration=0.5", "--out", "sweep.csv"],
        "replay-csv": ["replay", str(log_csv), "--set", "observer.eps=0.05", "--out", "r.csv"],
        "reproduce": ["reproduce", "--out", "res"],
    }[kind]
    if kind == "replay-csv":  # a log long enough to exceed the limit
        simulate(load_scenario("test-1", {"duration": 20.0})).to_csv(log_csv)
    proc = _limited([*args, "--quiet"], out)  # --quiet: warnings off, the error still shown
    line = _one_line(proc.stderr)
    assert proc.returncode == 1, proc.stderr
    assert line.startswith("esoarm: failed: cannot write '") and "file too large" in line
    assert ".tmp" not in line
    left = [p for p in out.rglob("*") if p.is_file()]
    if kind == "reproduce":  # the files finished before the limit are whole; no temporary
        assert not any(p.name.endswith(".tmp") for p in left), left
    else:
        assert left == [], left


@pytest.mark.skipif(not LINUX, reason="RLIMIT_FSIZE and SIGXFSZ semantics")
def test_excite_twin_log_on_a_full_disk_keeps_whole_rows(tmp_path):
    """The streamed log of 'excite --twin': one line, exit 1, whole rows kept (was an
    internal error)."""
    proc = _limited(["excite", "test-1", "--twin", "--duration", "20", "--log", "ex.csv",
                     "--quiet"], tmp_path)
    line = _one_line(proc.stderr)
    assert proc.returncode == 1, proc.stderr
    assert line.startswith("esoarm: failed: cannot write the log 'ex.csv': file too large")
    assert "rows kept" in line and "internal error" not in line
    lines = (tmp_path / "ex.csv").read_text(encoding="utf-8").splitlines()
    width = len(lines[0].split(","))
    assert 10 < len(lines) < 1000 and all(len(ln.split(",")) == width for ln in lines)
    assert f"{len(lines) - 1} rows kept" in line
    assert [p.name for p in tmp_path.iterdir()] == ["ex.csv"]


@pytest.mark.skipif(not LINUX or os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_full_tmpfs_is_one_line_exit_1(tmp_path):
    """A really full disk (a 64 kB tmpfs), not only a file-size limit."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)],
                             capture_output=True, check=False)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        proc = subprocess.run(
            [sys.executable, "-c", "import sys; from esoarm.cli import main; main(sys.argv[1:])",
             "simulate", "test-1", "--set", "duration=20", "--out", str(mnt / "run.csv")],
            capture_output=True, text=True, timeout=120)
        line = _one_line(proc.stderr)
        assert proc.returncode == 1 and "no space left on the device" in line, proc.stderr
        assert str(mnt / "run.csv") in line
        assert list(mnt.iterdir()) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=False)


def test_run_log_that_cannot_be_written_stops_the_run_cleanly(tmp_path):
    """The streamed rig log: a failed write is a fault; the file keeps whole rows only."""
    from esoarm.hardware import realtime as loop

    path = tmp_path / "log.csv"
    log = loop._LogWriter(path)
    for k in range(3):
        log.write(f"{k},1,2,3,4,5,6,7,8,9,10,11,12,13\n")

    class Full:
        def write(self, text: str) -> None:
            raise OSError(errno.ENOSPC, "No space left on device")

        def close(self) -> None:
            pass

    assert log._fh is not None
    log._fh.flush()
    with path.open("a", encoding="utf-8") as fh:  # a half row reached the disk
        fh.write("3,1,2")
    log._fh = Full()  # type: ignore[assignment]
    with pytest.raises(loop._Stop, match="cannot write the log .*no space left"):
        log.write("3,1,2,3,4,5,6,7,8,9,10,11,12,13\n")
    log.close()
    lines = path.read_text(encoding="utf-8").splitlines()
    assert len(lines) == 4 and lines[0].startswith("t,") and log.rows == 3
    assert np.loadtxt(path, delimiter=",", skiprows=1).shape == (3, 14)


def test_a_suffix_without_a_name_is_bad_input(run_cli):
    res = run_cli("simulate", "test-1", "--out", ".csv")
    assert res.exit_code == 2
    assert "give a file name before the suffix" in _one_line(res.stderr)
