"""What a newcomer trips on: the first command, an unwritable home, hil outside the checkout,
Ctrl-C on hil, a run that was not real time, unbounded analyze, silent nonsense."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------------
# 1. `esoarm` alone prints the help, as --help does


def test_no_arguments_prints_the_help(run_esoarm):
    res = run_esoarm()
    assert res.exit_code == 0, res.stderr
    assert "\\n" not in res.stdout and "\\n" not in res.stderr
    assert res.stdout.startswith("Usage: esoarm")
    assert "Commands:" in res.stdout and "simulate" in res.stdout
    assert res.stderr == ""


def test_group_without_subcommand_prints_its_help(run_esoarm):
    res = run_esoarm("log")
    assert res.exit_code == 0, res.stderr
    assert res.stdout.startswith("Usage: esoarm log") and "import" in res.stdout


def test_missing_scenario_says_what_to_give(run_esoarm):
    res = run_esoarm("simulate")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert "SCENARIO" in line and "esoarm scenarios" in line and "TOML" in line


# ---------------------------------------------------------------------------
# 2. an unwritable home and a read-only install: a writable cache is found


def _env_without_caches(monkeypatch, home: Path) -> None:
    for var in ("ESOARM_CACHE_DIR", "ESOARM_CACHE", "XDG_CACHE_HOME", "NUMBA_CACHE_DIR"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(home))


def test_cache_dir_falls_back_when_home_is_not_writable(monkeypatch, tmp_path):
    from esoarm import _cache

    home = tmp_path / "home"
    home.mkdir()
    _env_without_caches(monkeypatch, home)
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    assert _cache.cache_dir() == home / ".cache" / "esoarm"  # writable: the usual place
    real = _cache.writable
    monkeypatch.setattr(_cache, "writable", lambda p: not str(p).startswith(str(home)) and real(p))
    got = _cache.cache_dir()
    assert got.parent == tmp_path / "tmp" and got.name.startswith(f"esoarm-{os.getuid()}")
    assert got.is_dir() and os.access(got, os.W_OK)
    assert (got.stat().st_mode & 0o777) == 0o700


def test_configure_numba_sets_a_cache_only_when_needed(monkeypatch, tmp_path):
    from esoarm import _cache

    home = tmp_path / "home"
    home.mkdir()
    _env_without_caches(monkeypatch, home)
    _cache.configure_numba()  # home writable: numba's own user-wide cache works
    assert "NUMBA_CACHE_DIR" not in os.environ
    real = _cache.writable
    # the home and the installed sources read-only (a service account, a root-owned install)
    monkeypatch.setattr(_cache, "writable", lambda p: not (
        str(p).startswith(str(home)) or str(p).startswith(str(_cache._PACKAGE))) and real(p))
    monkeypatch.setattr(_cache, "cache_dir", lambda: tmp_path / "cache")
    _cache.configure_numba()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "cache" / "numba")
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere/else")  # the user's choice stands
    _cache.configure_numba()
    assert os.environ["NUMBA_CACHE_DIR"] == "/somewhere/else"


def _non_root_user() -> str | None:
    """A non-root account that can run this Python (for the real unwritable-home check)."""
    if os.getuid() != 0 or shutil.which("runuser") is None:
        return None
    import pwd

    for name in ("ncuser", "nobody"):
        try:
            pwd.getpwnam(name)
        except KeyError:
            continue
        ok = subprocess.run(["runuser", "-u", name, "--", sys.executable, "-c", "pass"],
                            capture_output=True)
        if ok.returncode == 0:
            return name
    return None


@pytest.mark.slow
def test_unwritable_home_compiles_numba_kernels():
    """A non-root user whose HOME cannot be written, package sources read-only (root's)."""
    user = _non_root_user()
    if user is None:
        pytest.skip("needs root, runuser and a non-root account that can run this Python")
    if (ROOT / "src" / "esoarm").stat().st_uid != 0:
        pytest.skip("the sources are not root's: the other user may be able to write them")
    import tempfile

    base = Path(tempfile.mkdtemp(prefix="esoarm-newcomer-"))  # the other user can enter it
    base.chmod(0o755)
    home = base / "home"
    home.mkdir(mode=0o555)
    work = base / "work"
    work.mkdir()
    shutil.chown(work, user)
    try:
        _run_as(user, home, work)
    finally:
        shutil.rmtree(base, ignore_errors=True)


def _run_as(user: str, home: Path, work: Path) -> None:
    env = {"PATH": os.environ.get("PATH", ""), "HOME": str(home), "MPLBACKEND": "Agg",
           "PYTHONPATH": str(ROOT / "src"), "TMPDIR": str(work)}
    # numba refuses a cache=True kernel at its definition when it has nowhere to cache it
    code = "import os, esoarm.engines.batch; print(os.environ['NUMBA_CACHE_DIR'])"
    res = subprocess.run(["runuser", "-u", user, "--", "env", "-i", *(f"{k}={v}" for k, v in
                          env.items()), sys.executable, "-c", code],
                         capture_output=True, text=True, cwd=work, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "no locator" not in res.stderr
    assert res.stdout.strip().startswith(str(work / "esoarm-"))  # the fallback in TMPDIR


# ---------------------------------------------------------------------------
# 4. hil outside the checkout: the installed package carries the firmware sources


def _source_copy(tmp_path: Path) -> Path:
    """The checkout without its build output, to build from (pip builds in the tree)."""
    dest = tmp_path / "src-copy"
    shutil.copytree(ROOT, dest, ignore=shutil.ignore_patterns(
        ".git", "build", "dist", "site", "*.egg-info", "__pycache__", ".hypothesis",
        ".pytest_cache", ".ruff_cache", ".mypy_cache", "test-artifacts", "esoarm-results"))
    return dest


@pytest.mark.slow
def test_wheel_carries_the_firmware_sources(tmp_path):
    """setup.py's build_py copies firmware/ (not its build output) into the package."""
    import zipfile

    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                          str(tmp_path), str(_source_copy(tmp_path))],
                         capture_output=True, text=True, timeout=600)
    if res.returncode != 0 and "Could not" in res.stderr:  # no package index for the build deps
        pytest.skip(f"pip could not build the wheel here: {res.stderr.strip()[-200:]}")
    assert res.returncode == 0, res.stderr[-2000:]
    wheel, = tmp_path.glob("esoarm-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    fw = "esoarm/hardware/hil/firmware/"
    for need in ("Makefile", "sketch.mk", "esoarm_rig/esoarm_rig.ino",
                 "esoarm_rig/esoarm_protocol.h"):
        assert fw + need in names
    assert not any(n.startswith(fw + "build/") for n in names)


def test_installed_copy_is_found_and_built_into_the_cache(monkeypatch, tmp_path):
    from esoarm.hardware.hil import build

    packaged = tmp_path / "site" / "esoarm" / "hardware" / "hil" / "firmware"
    shutil.copytree(ROOT / "firmware", packaged, ignore=shutil.ignore_patterns("build"))
    monkeypatch.setattr(build, "packaged_firmware_dir", lambda: packaged)
    monkeypatch.setattr(build, "__file__", str(packaged.parent / "build.py"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ESOARM_CACHE_DIR", str(tmp_path / "cache"))
    assert build.default_firmware_dir() == packaged
    root = build.default_build_root(packaged)
    assert root.parent == tmp_path / "cache" and root.name.startswith("firmware-")
    # a change of the sources is a new build folder
    (packaged / "esoarm_rig" / "esoarm_rig.ino").write_text("// changed\n")
    assert build.default_build_root(packaged) != root


@pytest.mark.slow
def test_hil_builds_from_an_installed_copy_outside_the_checkout(tmp_path):
    """pip install --target, run from a directory that is not the checkout."""
    if shutil.which("avr-gcc") is None or not Path("/usr/share/arduino/Arduino.mk").exists():
        pytest.skip("the AVR toolchain is not installed (apt-get install gcc-avr avr-libc "
                    "arduino-core-avr arduino-mk)")
    site = tmp_path / "site"
    res = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                          "--target", str(site), str(_source_copy(tmp_path))],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    code = ("import esoarm.hardware.hil.build as b, sys; fw = b.default_firmware_dir(); "
            "print(fw); print(b.firmware_elf('l298n'))")
    env = dict(os.environ, PYTHONPATH=str(site), ESOARM_CACHE_DIR=str(tmp_path / "cache"))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path, env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    fw, elf = res.stdout.split()
    assert fw.startswith(str(site)) and Path(elf).is_file()
    assert elf.startswith(str(tmp_path / "cache"))


# ---------------------------------------------------------------------------
# 9. Ctrl-C on hil: exit 130, warnings prefixed


class _FakeServer:
    def __init__(self, scn, elf, **kw):
        self.path = "/dev/pts/fake"
        self.twin = SimpleNamespace(counts_per_rev=2400)
        self.log = SimpleNamespace(start_cycle=None)
        self.board = SimpleNamespace(isr_stats=lambda: {"n": 0}, cycle=0)
        self.slips, self.worst_slip, self.lags = 2, 0.05, 3
        self.samples_tracked, self.worst_lag = 10, 0.02

    def serve(self, until):
        raise KeyboardInterrupt

    def close(self):
        pass


def test_hil_ctrl_c_exits_130_with_prefixed_warnings(run_cli, monkeypatch, tmp_path):
    from esoarm.hardware.hil import server

    elf = tmp_path / "fw.elf"
    # the head of an AVR ELF (32-bit, little-endian, e_machine 83 = EM_AVR): --elf checks it
    elf.write_bytes(b"\x7fELF\x01\x01\x01" + bytes(9) + (2).to_bytes(2, "little")
                    + (83).to_bytes(2, "little"))
    monkeypatch.setattr(server, "HilServer", _FakeServer)
    res = run_cli("hil", "uno-rig", "--elf", str(elf))
    assert res.exit_code == 130, (res.stdout, res.stderr)
    assert "stopped: port closed" not in res.stdout
    warn = [ln for ln in res.stderr.splitlines() if "behind" in ln]
    assert len(warn) == 2 and all(ln.startswith("esoarm: warning: ") for ln in warn)
    assert res.stderr.strip().splitlines()[-1].startswith("esoarm: interrupted")


# ---------------------------------------------------------------------------
# 10. a 'real time' device that was not: the title says what was measured


def test_run_title_says_what_was_measured():
    from esoarm.cli.rig import _mode_title, _pace

    # 1000 samples = 20 s at 50 Hz
    fast = SimpleNamespace(samples=1000, mode="real time", stream_every=1, onboard=False)
    assert _pace(fast, 8.3, 0.02) is not None
    assert _mode_title(fast, 8.3, 0.02) == "not real time: 20.0 s of samples in 8.3 s"
    assert _pace(fast, 20.4, 0.02) is None
    assert _mode_title(fast, 20.4, 0.02).startswith("real time: 20.0 s")
    lock = SimpleNamespace(samples=1000, mode="lockstep", stream_every=1, onboard=False)
    assert _pace(lock, 1.0, 0.02) is None and _mode_title(lock, 1.0, 0.02).startswith("lockstep")


# ---------------------------------------------------------------------------
# 5. analyze --vary: a cap, and progress without a terminal


def test_analyze_vary_is_capped_before_any_work(run_cli, monkeypatch):
    from esoarm.studies.frequency import margins

    monkeypatch.setattr(margins, "analyze", lambda *a, **k: pytest.fail("work was started"))
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=geom:0.03:0.3:100000")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert "100,000 points" in line and "--max-points 1,000" in line and " h" in line
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.06,0.07",
                  "--max-points", "2")
    assert res.exit_code == 2 and "3 points" in res.stderr and "--max-points 2" in res.stderr
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05", "--max-points", "0")
    assert res.exit_code == 2 and "--max-points 0" in res.stderr


def test_analyze_vary_shows_progress_lines_without_a_terminal(run_cli, monkeypatch):
    from esoarm.cli import _common

    monkeypatch.setattr(_common, "PROGRESS_LINE_S", 0.0)  # a line at every point
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.09,0.2")
    assert res.exit_code == 0, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("esoarm: analyzing:")]
    assert [ln.split(":")[2].split(" points")[0].strip() for ln in lines] == [
        "1 of 3", "2 of 3", "3 of 3"]
    quiet = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.09", "-q")
    assert "analyzing" not in quiet.stderr


def test_progress_is_silent_for_short_work(run_cli):
    res = run_cli("analyze", "test-1", "--vary", "observer.eps=0.05,0.09")
    assert res.exit_code == 0 and "analyzing" not in res.stderr


# ---------------------------------------------------------------------------
# 6. analyze --theta0 beyond a turn


@pytest.mark.parametrize("value", ["1e300", "7", "-6.3"])
def test_analyze_theta0_beyond_a_turn_is_refused(run_cli, value):
    res = run_cli("analyze", "test-1", "--theta0", value)
    assert res.exit_code == 2
    assert "--theta0" in res.stderr and "±2π" in res.stderr


def test_analyze_theta0_within_a_turn_runs(run_cli):
    res = run_cli("analyze", "test-1", "--theta0", "-6.28", "--json")
    assert res.exit_code == 0, res.stderr


# ---------------------------------------------------------------------------
# 7. tune: no warning about a round-off "better" baseline inside the bounds


def _tune_result(best: float, base: float):
    from esoarm.studies.sweeps.tune import TuneResult

    return TuneResult(keys=("observer.eps",), best={"observer.eps": 0.09},
                      best_metrics={"objective": best},
                      baseline={"observer.eps": 0.09, "objective": base})


def test_tune_baseline_warning_ignores_round_off():
    from esoarm.studies.sweeps.tune import describe_baseline

    assert describe_baseline(_tune_result(0.055907 + 2e-16, 0.055907)) is None
    assert describe_baseline(_tune_result(0.06, 0.055907)) is not None


@pytest.mark.slow
def test_tune_never_reports_worse_than_the_scenario_inside_the_bounds():
    from esoarm.scenario import load_scenario
    from esoarm.studies.sweeps.tune import describe_baseline, parse_bound, tune

    base = load_scenario("test-1", {"duration": 2.0})
    res = tune(base, [parse_bound("observer.eps=0.03:0.3", base)], maxiter=1, popsize=3,
               seeds=1, workers=1)
    assert res.best_metrics["objective"] <= res.baseline["objective"]
    assert describe_baseline(res) is None


# ---------------------------------------------------------------------------
# 8. a NaN action in the Gymnasium environment is an error, not a diverged arm


@pytest.mark.parametrize("mode", ["torque", "residual"])
@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_env_refuses_a_non_finite_action(mode, bad):
    pytest.importorskip("gymnasium")
    import numpy as np

    from esoarm.envs.lever_arm import LeverArmEnv

    env = LeverArmEnv("test-1", action_mode=mode)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([bad]))
    # the episode goes on as if the bad action had not been given
    obs, reward, terminated, truncated, _ = env.step(np.array([0.0]))
    assert np.isfinite(reward) and not terminated and not truncated


# ---------------------------------------------------------------------------
# 11. smaller things


def test_csv_with_a_byte_order_mark_is_read(tmp_path):
    from esoarm.hardware.logfile import read_log_columns

    path = tmp_path / "bom.csv"
    path.write_text("t,theta,u\n0,0,0\n0.02,0.01,0.1\n", encoding="utf-8-sig")
    assert path.read_bytes()[:3] == b"\xef\xbb\xbf"
    names, data = read_log_columns(path, ["t", "theta", "u"], "need t, theta, u")
    assert names == ["t", "theta", "u"] and data.shape == (2, 3)


def test_simulate_interrupted_says_what_was_kept(run_cli, monkeypatch, tmp_path):
    import csv

    from esoarm.engines import simulation

    real = simulation.closed_loop

    def stop_half_way(log, x, noise, refs, sg, d, s):
        half = sg._replace(n=sg.n // 2)  # a NamedTuple (numba-friendly)
        real(log, x, noise, refs, half, d, s)
        raise KeyboardInterrupt

    monkeypatch.setattr(simulation, "closed_loop", stop_half_way)
    out = tmp_path / "run.csv"
    res = run_cli("simulate", "test-1", "--out", str(out))
    assert res.exit_code == 130
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith("esoarm: interrupted: at t = ") and "500 samples" in line
    assert str(out) in line
    with open(out, newline="") as fh:
        assert sum(1 for _ in csv.reader(fh)) == 1 + 500
    res = run_cli("simulate", "test-1")
    assert res.exit_code == 130 and "nothing written" in res.stderr and "--out" in res.stderr


def test_simulate_progress_lines_without_a_terminal(run_cli, monkeypatch):
    from esoarm.cli import _common

    monkeypatch.setattr(_common, "PROGRESS_LINE_S", 0.0)
    res = run_cli("simulate", "test-1", "--set", "duration=2")
    assert res.exit_code == 0, res.stderr
    last = [ln for ln in res.stderr.splitlines() if ln.startswith("esoarm: simulating:")][-1]
    assert "100 of 100 samples" in last


def test_long_run_warning_does_not_suggest_the_step_in_use(run_cli):
    res = run_cli("show", "test-1", "--set", "duration=200000")
    warn = [ln for ln in res.stderr.splitlines() if "RK4 steps" in ln]
    assert len(warn) == 1
    assert "Ts/20" not in warn[0] and "shorten duration" in warn[0]
    # a long run is streamed through the compiled engine by simulate itself (no sweep needed)
    assert "esoarm sweep" not in warn[0] and "h in esoarm simulate" in warn[0]
    res = run_cli("show", "test-1", "--set", "rig.step=1e-6", "--set", "duration=200")
    assert "Ts/20 = 0.001 s" in res.stderr


def test_fit_figure_shows_the_measured_trace_beside_the_fit():
    import numpy as np

    from esoarm.scenario import load_scenario
    from esoarm.studies.identification.plots import figure_identification

    t = np.arange(200) * 0.02
    y = np.sin(t)
    res = SimpleNamespace(curves={"fit": (t, y, y + 1e-4)}, fit_percent=99.9,
                          scenario=load_scenario("test-1"), segment_seconds=2.0,
                          validation={})
    fig = figure_identification(res)
    ax = fig.axes[0]
    measured, fitted = ax.get_lines()[:2]
    assert measured.get_label().startswith("measured")
    # drawn under the fit and wider than it, so both stay visible where they agree
    assert measured.get_zorder() < fitted.get_zorder()
    assert measured.get_linewidth() > 2 * fitted.get_linewidth()


def test_arm_ablation_torques_have_a_panel_each():
    import numpy as np

    from esoarm.plotting.arms import figure_arm_ablation

    t = np.arange(100) * 0.01

    def run(k):
        part = SimpleNamespace(t=t, error=np.sin(t) * k, u=np.cos(t) * k, rms_error=0.1 * k)
        return SimpleNamespace(per_joint=[part, part], joint_names=["a", "b"])

    fig = figure_arm_ablation({"one": run(1), "two": run(2), "three": run(3)}, "title")
    assert len(fig.axes) == 4 * 2  # error row + one torque row per variant, two joints
    torque_axes = [ax for ax in fig.axes if ax.get_ylabel() == "u [N·m]"]
    assert len(torque_axes) == 3
    assert all(len(ax.get_lines()) == 1 for ax in fig.axes[2:] if ax.get_title(loc="left"))


def test_sweep_heat_map_labels_every_row_or_a_regular_stride():
    from esoarm.studies.sweeps.plots import _tick_index

    assert _tick_index(12, 16) == list(range(12))
    idx = _tick_index(40, 16)
    assert len(idx) <= 16 and len({b - a for a, b in zip(idx, idx[1:], strict=False)}) == 1


@pytest.mark.slow
def test_identify_docs_show_what_the_command_prints(run_esoarm, tmp_path):
    """docs/identify.md's console block: the same samples and iterations as a fresh run."""
    import re

    text = (ROOT / "docs" / "identify.md").read_text(encoding="utf-8")
    head = re.search(r"identification of 'test-1' from excite\.csv \((\d+) samples fitted, "
                     r"segments of 2 s, (\d+) iterations, [\d.]+ s\)", text)
    assert head is not None
    res = run_esoarm("excite", "test-1", "--twin", "--log", "excite.csv", "--set",
                     "rig.inertia_scale=1.25", "--set", "rig.coulomb_friction=0.1", "-q",
                     cwd=tmp_path)
    assert res.exit_code == 0, res.stderr
    res = run_esoarm("identify", "excite.csv", "--scenario", "test-1", cwd=tmp_path)
    assert res.exit_code == 0, res.stderr
    got = re.search(r"\((\d+) samples fitted, segments of 2 s, (\d+) iterations", res.stdout)
    assert got is not None and got.groups() == head.groups()


# ---------------------------------------------------------------------------
# 3. a missing extra is a set-up problem named before any work


@pytest.mark.parametrize("args", [
    ("run", "test-1", "--port", "/dev/null"),
    ("excite", "test-1", "--port", "/dev/null", "--log", "x.csv"),
])
def test_missing_rig_extra_is_named(run_cli, monkeypatch, tmp_path, args):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "serial" else real(name, *a))
    monkeypatch.chdir(tmp_path)
    res = run_cli(*args)
    assert res.exit_code == 2, res.stderr
    line, = res.stderr.strip().splitlines()
    assert "pyserial" in line and "pip install 'esoarm[rig]'" in line
    assert not (tmp_path / "x.csv").exists()


def test_sweep_shows_progress_lines_in_a_log_at_normal_verbosity(run_cli, monkeypatch):
    from esoarm.cli import _common

    monkeypatch.setattr(_common, "PROGRESS_LINE_S", 0.0)
    res = run_cli("sweep", "test-1", "--vary", "observer.eps=0.05,0.09", "--set", "duration=1")
    assert res.exit_code == 0, res.stderr
    assert "esoarm: sweep: 2 of 2 runs" in res.stderr


def test_missing_choice_option_is_one_clean_line(run_esoarm):
    # click's own "Missing option ... Choose from:\n\t..." made one line (pil's --target is a
    # required click.Choice; codegen's --target is checked by the command, below)
    res = run_esoarm("pil", "test-1")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert "\\n" not in line and "\\t" not in line
    assert "--target" in line and "choose from: avr, " in line and "cortex-m4" in line
    res = run_esoarm("codegen", "test-1", "--out", "never-written")
    assert res.exit_code == 2
    line, = res.stderr.strip().splitlines()
    assert "--target is required" in line and "avr" in line and "cortex-m4" in line


def test_status_lines_for_logs(monkeypatch, capsys):
    from esoarm.cli import _common

    _common.reset_verbosity()
    say = _common.status_lines("identify")
    say("fitting")  # sooner than PROGRESS_LINE_S: nothing
    monkeypatch.setattr(_common, "PROGRESS_LINE_S", 0.0)
    say("trying delay 1 sample(s)")
    assert capsys.readouterr().err == "esoarm: identify: trying delay 1 sample(s)\n"
    _common._state["level"] = _common.QUIET
    say("quiet")
    assert capsys.readouterr().err == ""
    _common.reset_verbosity()


def test_fast_engine_and_hil_use_the_writable_cache(monkeypatch, tmp_path):
    from esoarm import _cache
    from esoarm.engines import fast
    from esoarm.hardware.hil import build

    for var in ("ESOARM_CACHE_DIR", "ESOARM_CACHE", "XDG_CACHE_HOME"):
        monkeypatch.delenv(var, raising=False)
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    real = _cache.writable
    monkeypatch.setattr(_cache, "writable", lambda p: not str(p).startswith(str(home)) and real(p))
    assert not str(fast.cache_dir()).startswith(str(home))
    assert not str(build._cache_dir()).startswith(str(home))
    monkeypatch.setenv("ESOARM_CACHE_DIR", str(tmp_path / "mine"))
    assert fast.cache_dir() == build._cache_dir() == tmp_path / "mine"
