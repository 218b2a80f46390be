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


@pytest.mark.slow
def test_wheel_carries_the_firmware_sources(tmp_path):
    """setup.py's build_py copies firmware/ (not its build output) into the package."""
    import zipfile

    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                          str(tmp_path), str(ROOT)], capture_output=True, text=True, timeout=600)
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
                          "--target", str(site), str(ROOT)],
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
    elf.write_bytes(b"\x7fELF")
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

    fast = SimpleNamespace(samples=1000, mode="real time")  # 20 s at 50 Hz
    assert _pace(fast, 8.3, 0.02) is not None
    assert _mode_title(fast, 8.3, 0.02) == "not real time: 20.0 s of samples in 8.3 s"
    assert _pace(fast, 20.4, 0.02) is None
    assert _mode_title(fast, 20.4, 0.02).startswith("real time: 20.0 s")
    lock = SimpleNamespace(samples=1000, mode="lockstep")
    assert _pace(lock, 1.0, 0.02) is None and _mode_title(lock, 1.0, 0.02).startswith("lockstep")
