"""The streamed block compiled the first time by a child process (esoarm.engines.stream.prepare):
the first long ``simulate`` after install stays under 300 MB peak resident memory."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from esoarm.engines.simulation import prepare_designs
from esoarm.engines.stream import prepare
from esoarm.scenario import load_scenario

SRC = str(Path(prepare.__file__).resolve().parents[3])


def test_a_process_that_has_numba_compiles_in_place(tmp_path, monkeypatch):
    monkeypatch.setenv("ESOARM_CACHE_DIR", str(tmp_path))
    pytest.importorskip("numba")
    scn = load_scenario("test-1")
    assert "numba" in sys.modules
    assert prepare.apart(scn, prepare_designs(scn)) is False
    assert not (tmp_path / "stream").exists()


def test_the_marker_is_per_kinds(tmp_path, monkeypatch):
    monkeypatch.setenv("ESOARM_CACHE_DIR", str(tmp_path))
    a = prepare.marker(prepare_designs(load_scenario("test-1")))
    b = prepare.marker(prepare_designs(load_scenario("test-1", {"observer.kind": "nonlinear"})))
    assert a != b and a.parent == b.parent == tmp_path / "stream"


#: A small parent for the measured command: the peak resident set that ``wait4`` reports for
#: a child includes the image it was forked from (Linux records the old image's high-water
#: mark at ``exec``), so a child forked from this test process -- over 1 GB after a whole
#: suite -- would report pytest's size, not its own.
_WRAP = ("import json, os, subprocess, sys\n"
         "p = subprocess.Popen(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,"
         " text=True)\n"
         "out = p.stdout.read()\n"
         "_, status, usage = os.wait4(p.pid, 0)\n"
         "print(json.dumps({'out': out, 'code': os.waitstatus_to_exitcode(status),"
         " 'mb': usage.ru_maxrss / 1024}))\n")


def _simulate(env: dict[str, str], cwd: Path) -> tuple[dict, float]:
    """``esoarm simulate test-1`` of 6·10⁵ samples (streamed, compiled): (JSON, peak RSS MB)."""
    proc = subprocess.run([sys.executable, "-c", _WRAP, sys.executable, "-m", "esoarm",
                           "simulate", "test-1", "--set", "duration=1.2e4", "--json"],
                          cwd=cwd, env=env, capture_output=True, text=True, check=True)
    res = json.loads(proc.stdout)
    assert res["code"] == 0
    return json.loads(res["out"]), res["mb"]


@pytest.mark.slow
def test_the_first_long_run_with_cold_caches_stays_under_300_mb(tmp_path):
    env = {**os.environ, "PYTHONPATH": SRC, "ESOARM_CACHE_DIR": str(tmp_path / "esoarm"),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    cold, cold_mb = _simulate(env, tmp_path)
    assert list((tmp_path / "esoarm" / "stream").iterdir())  # the child ran
    warm, warm_mb = _simulate(env, tmp_path)
    # the largest process (the child that compiled, or this one): measured 275 MB cold,
    # 199 MB warm (before: 357-387 MB cold, compiled in the process itself)
    assert cold_mb < 300, cold_mb
    assert warm_mb < 250, warm_mb
    assert cold == warm  # the same numbers whichever process compiled the block
