"""The live scope: local server, stream, page in headless Chromium, no effect on the loop."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import threading
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from esoarm.hardware.realtime import LOG_COLUMNS, run_rig
from esoarm.hardware.scope import Scope, ScopeError, run_panels, scope_for_run
from esoarm.scenario import load_scenario

from .rig_helpers import emulator, esoarm, needs_pty
from .test_loop import FakeLink

CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--no-first-run", "--disable-quic",
                  "--enable-logging=stderr", "--v=0", "--hide-scrollbars")


def _browser() -> str | None:
    for name in ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome"):
        if path := shutil.which(name):
            return path
    return None


def _events(url: str, n: int, timeout: float = 5.0) -> list[dict]:
    """Read ``n`` server-sent events from the scope's stream, then hang up."""
    out = []
    with urllib.request.urlopen(url + "events", timeout=timeout) as resp:
        assert resp.headers["Content-Type"] == "text/event-stream"
        for raw in resp:
            line = raw.decode()
            if line.startswith("data: "):
                out.append(json.loads(line[6:]))
                if len(out) >= n:
                    break
    return out


def _lockstep_run(scope: Scope | None, duration: float = 3.0):
    scn = load_scenario("test-1", {"duration": duration})
    link = FakeLink(scn)
    rows: list[str] = []

    def monitor(line: str) -> None:
        rows.append(line)
        if scope is not None:
            scope.push(line)

    summary = run_rig(scn, link, None, monitor=monitor,
                      status=scope.set_status if scope is not None else None)
    return summary, rows, link


def test_binds_to_localhost_only_and_serves_page_and_meta() -> None:
    scope = scope_for_run("test-1", 50.0, 5.0, 0)
    try:
        assert scope._server.server_address[0] == "127.0.0.1"
        assert scope.url.startswith("http://127.0.0.1:")
        page = urllib.request.urlopen(scope.url, timeout=5).read().decode()
        assert "<canvas" not in page or True  # canvases are created from /meta
        assert "http://" not in page and "https://" not in page  # nothing from the network
        meta = json.loads(urllib.request.urlopen(scope.url + "meta", timeout=5).read())
        assert [p["title"] for p in meta["panels"]] == [p.title for p in run_panels()]
        assert meta["window"] == 5.0
    finally:
        scope.close()


def test_port_in_use_is_a_clear_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        with pytest.raises(ScopeError, match="cannot listen"):
            Scope(("t",), (), 1.0, 50.0, s.getsockname()[1])


def test_stream_carries_the_logged_rows_and_keeps_the_window() -> None:
    scope = scope_for_run("test-1", 50.0, 2.0, 0)  # 2 s window
    try:
        summary, rows, _ = _lockstep_run(scope, duration=3.0)
        assert summary.samples == len(rows) == 150
        scope.end()
        events = _events(scope.url, 3)
        got = {}
        for ev in events:
            for col, vals in ev.get("rows", {}).items():
                got.setdefault(col, []).extend(vals)
        assert events[-1]["status"]["ended"]
        assert events[-1]["status"]["k"] == 149  # the status line ends with the last row
        # the ring keeps the last window (+ a margin); the page trims to the window
        log = np.array([[float(x) for x in r.split(",")] for r in rows])
        n = len(got["t"])
        assert 100 <= n <= 150
        np.testing.assert_array_equal(got["t"], log[-n:, 0])
        for col in ("theta", "theta_ref", "u", "z1", "z2", "z3"):
            np.testing.assert_array_equal(got[col], log[-n:, LOG_COLUMNS.index(col)])
        np.testing.assert_allclose(got["latency_ms"], log[-n:, LOG_COLUMNS.index("latency")] * 1e3)
    finally:
        scope.close()


def test_pages_coming_and_going_do_not_disturb_the_loop() -> None:
    """A lockstep run with clients connecting and hanging up is the run without a scope."""
    scope = scope_for_run("test-1", 50.0, 10.0, 0)
    stop = threading.Event()
    errors: list[BaseException] = []

    def flapping_client() -> None:
        while not stop.is_set():
            try:
                _events(scope.url, 2)
                with socket.create_connection(("127.0.0.1", scope.port)) as s:  # hang up early
                    s.sendall(b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
                    s.recv(10)
            except Exception as exc:  # noqa: BLE001 - collected and asserted below
                errors.append(exc)
                return

    threads = [threading.Thread(target=flapping_client, daemon=True) for _ in range(3)]
    try:
        for t in threads:
            t.start()
        with_scope, rows_scope, link_scope = _lockstep_run(scope, duration=4.0)
    finally:
        stop.set()
        for t in threads:
            t.join(10)
        scope.close()
    without, rows_plain, link_plain = _lockstep_run(None, duration=4.0)
    assert errors == []
    assert with_scope.samples == without.samples == 200
    assert link_scope.sent == link_plain.sent  # the same commands, bit for bit
    strip = [r.split(",")[:9] for r in rows_scope], [r.split(",")[:9] for r in rows_plain]
    assert strip[0] == strip[1]  # t … z3, k: identical (timing columns differ)
    assert scope.clients == 0


@pytest.mark.slow
def test_page_in_headless_chromium_shows_a_lockstep_run(tmp_path: Path) -> None:
    browser = _browser()
    if browser is None:
        pytest.skip("no Chromium on this machine: `apt-get install -y chromium` (.ci/run does)")
    scope = scope_for_run("test-1", 50.0, 10.0, 0)
    try:
        _, rows, _ = _lockstep_run(scope, duration=4.0)
        scope.end()
        env = {**os.environ, "HOME": str(tmp_path)}
        res = subprocess.run(
            [browser, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
             "--virtual-time-budget=5000", "--window-size=1200,1000", "--dump-dom", scope.url],
            capture_output=True, text=True, timeout=90, env=env, check=False)
    finally:
        scope.close()
    assert res.returncode == 0, res.stderr[-2000:]
    assert [ln for ln in res.stderr.splitlines() if ":CONSOLE" in ln] == []
    match = re.search(r'<pre id="scope-check">(.*?)</pre>', res.stdout, re.S)
    assert match, res.stdout[-2000:]
    check = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert check["errors"] == []
    assert check["received"] == len(rows) == 200
    last = [float(x) for x in rows[-1].split(",")]
    assert check["last"]["t"] == last[0]
    for col in ("theta", "theta_ref", "u", "z1", "z2", "z3"):
        assert check["drawn"][col] == 200, col
        assert check["last"][col] == last[LOG_COLUMNS.index(col)], col


@pytest.mark.slow
@needs_pty
def test_cli_run_and_emulate_with_scope_match_the_run_without(tmp_path: Path) -> None:
    logs = []
    for scope in (False, True):
        log = tmp_path / f"run-{scope}.csv"
        extra = ("--scope", "--scope-port", "0") if scope else ()
        with emulator("test-1", "--lockstep", "--once", "--set", "duration=1", *extra) as emu:
            res = esoarm("run", "test-1", "--port", emu.path, "--set", "duration=1", "--log",
                         str(log), "--json", *extra)
            assert res.returncode == 0, res.stderr
            out = emu.output()
            if scope:
                assert re.search(r"scope: http://127\.0\.0\.1:\d+/", res.stderr)
                assert re.search(r"scope: http://127\.0\.0\.1:\d+/", out)
        data = np.genfromtxt(log, delimiter=",", names=True)
        logs.append(np.column_stack([data[c] for c in LOG_COLUMNS[:9]]))
    np.testing.assert_array_equal(logs[0], logs[1])


def test_cli_bad_scope_options(tmp_path: Path) -> None:
    res = esoarm("run", "test-1", "--port", "/nonexistent", "--scope", "--scope-window", "0")
    assert res.returncode == 2 and "--scope-window" in res.stderr
    res = esoarm("emulate", "test-1", "--scope", "--scope-port", "70000")
    assert res.returncode == 2 and "--scope-port" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@needs_pty
def test_emulate_on_a_busy_scope_port_prints_no_device(tmp_path: Path) -> None:
    """The scope's port is bound before 'device:' is printed: a busy port is the error alone."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        res = esoarm("emulate", "test-1", "--scope", "--scope-port", str(s.getsockname()[1]))
    assert res.returncode == 2
    assert res.stdout == ""  # no 'device: PATH' to a port that is already gone
    assert len(res.stderr.strip().splitlines()) == 1 and "cannot listen" in res.stderr


def test_stream_resumes_after_reconnect() -> None:
    from esoarm.hardware.scope import Panel

    with pytest.raises(ValueError, match="theta_ref"):
        Scope(("t", "theta"), (run_panels()[0],), 10.0, 50.0, 0)
    scope = Scope(("t", "theta"), (Panel("angle", "rad", ("theta",), ("θ",)),), 10.0, 50.0, 0)
    try:
        for k in range(5):
            scope.push((k * 0.02, 0.1 * k))
        req = urllib.request.Request(scope.url + "events", headers={"Last-Event-ID": "3"})
        with urllib.request.urlopen(req, timeout=5) as resp:
            for raw in resp:
                if raw.startswith(b"data: "):
                    msg = json.loads(raw[6:])
                    break
        assert msg["rows"]["t"] == [0.06, 0.08]
    finally:
        scope.close()


def _js_function(source: str, name: str) -> str:
    """The text of ``function name(...) {...}`` in ``source`` (braces matched)."""
    start = source.index(f"function {name}(")
    depth = 0
    for i in range(source.index("{", start), len(source)):
        depth += {"{": 1, "}": -1}.get(source[i], 0)
        if depth == 0:
            return source[start:i + 1]
    raise AssertionError(f"unbalanced braces in {name}")


def test_axis_ticks_are_whole_multiples_of_the_step(tmp_path: Path) -> None:
    """The page's own niceTicks and fmt, run in Chromium over 24 000 axis ranges.

    Every tick is a multiple of its step, so a label of a tick at zero reads 0,
    never the running sum's rounding error (the page showed -5.6e-17).
    """
    browser = _browser()
    if browser is None:
        pytest.skip("no Chromium on this machine: `apt-get install -y chromium` (.ci/run does)")
    from importlib import resources

    page = resources.files("esoarm.hardware").joinpath("scope.html").read_text("utf-8")
    script = _js_function(page, "niceTicks") + "\n" + _js_function(page, "fmt") + """
    var out = { ranges: 0, ticks: 0, zero: 0, bad: [] };
    for (var a = 1; a <= 400; a++) { for (var b = 1; b <= 60; b++) {
      var lo = -a * 0.0137, hi = b * 0.0213, ticks = niceTicks(lo, hi, 4);
      var step = ticks[1] - ticks[0];
      out.ranges++;
      ticks.forEach(function (v) {
        out.ticks++;
        var label = fmt(v), q = Math.round(v / step);
        if (Math.abs(v / step - q) > 1e-9 || (q === 0 && label !== "0")) {
          if (out.bad.length < 5) { out.bad.push([lo, hi, label]); }
        }
        if (q === 0) { out.zero++; }
      });
    } }
    document.getElementById("out").textContent = JSON.stringify(out);
    """
    html = tmp_path / "ticks.html"
    html.write_text(f'<!DOCTYPE html><html><body><pre id="out">none</pre><script>{script}'
                    "</script></body></html>", "utf-8")
    env = {**os.environ, "HOME": str(tmp_path)}
    res = subprocess.run(
        [browser, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}", "--dump-dom",
         html.as_uri()], capture_output=True, text=True, timeout=90, env=env, check=False)
    assert res.returncode == 0, res.stderr[-2000:]
    match = re.search(r'<pre id="out">(.*?)</pre>', res.stdout, re.S)
    assert match, res.stdout[-2000:]
    out = json.loads(match.group(1).replace("&quot;", '"'))
    assert out["ranges"] == 24000 and out["ticks"] > 3 * 24000
    assert out["zero"] == 24000  # every range spans zero: one tick there each
    assert out["bad"] == []
