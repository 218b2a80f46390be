"""A live scope in the browser for ``esoarm run --scope`` and ``esoarm emulate --scope``.

The control loop must never wait for the page, so the design puts nothing on
the loop's path but one append under an uncontended lock:

- the loop calls :meth:`Scope.push` with each row it logs (the CSV line it
  writes, or a tuple of floats), and :meth:`Scope.set_status` with the status
  line's counters (about ten times a second);
- a ``ThreadingHTTPServer`` from the standard library, bound to 127.0.0.1 only,
  serves one static page (``scope.html``, a hand-written canvas plot: no CDN,
  no script from the network, works offline) and a server-sent-events stream
  ``/events`` in its own daemon threads; every 100 ms each stream takes the
  rows it has not sent yet from the ring buffer (the last ``window`` seconds),
  parses and encodes them there, and writes one event;
- a page that closes, reloads or stalls only ends or slows its own stream
  thread (a broken pipe ends it); the loop never sees it.

The measured cost to the loop, with and without a page open, is in the docs
(``benchmarks/bench_scope.py``).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

__all__ = ["EMULATOR_COLUMNS", "Panel", "Scope", "ScopeError", "emulator_panels", "run_panels",
           "scope_for_emulator", "scope_for_run"]

#: How often a stream sends what arrived [s].
PERIOD = 0.1
#: Host the server binds to (never another interface).
HOST = "127.0.0.1"
#: Columns computed in the server thread: name -> (source column, scale).
DERIVED = {"latency_ms": ("latency", 1e3)}


class ScopeError(RuntimeError):
    """The scope's server could not start (e.g. the port is taken)."""


@dataclass(frozen=True)
class Panel:
    """One plot of the page: a title with its unit and the columns drawn in it."""

    title: str
    unit: str
    columns: tuple[str, ...]
    labels: tuple[str, ...]


def run_panels() -> tuple[Panel, ...]:
    """Panels of ``esoarm run`` (columns of :data:`esoarm.hardware.realtime.LOG_COLUMNS`)."""
    return (
        Panel("angle", "rad", ("theta", "theta_ref", "z1"), ("θ measured", "θd", "ẑ1")),
        Panel("control", "N·m", ("u",), ("u",)),
        Panel("rate estimate", "rad/s", ("z2",), ("ẑ2",)),
        Panel("perturbation estimate", "rad/s²", ("z3",), ("ẑ3",)),
        Panel("host latency", "ms", ("latency_ms",), ("sample in → command out",)),
    )


def emulator_panels() -> tuple[Panel, ...]:
    """Panels of ``esoarm emulate``: what the device knows (true and measured angle, torque)."""
    return (
        Panel("angle", "rad", ("theta", "theta_measured"), ("θ true", "θ encoder")),
        Panel("applied torque", "N·m", ("u",), ("u applied",)),
        Panel("rate", "rad/s", ("omega",), ("θ̇ true",)),
    )


class Scope:
    """Ring buffer + local HTTP server for the live page.

    Parameters
    ----------
    columns : sequence of str
        Names of the fields of each pushed row (a CSV line or a tuple), in order.
    panels : sequence of Panel
        What the page draws; derived columns ``latency_ms`` (from ``latency`` [s])
        are computed in the server thread.
    window : float
        Seconds of data kept and shown [s] (by the column ``t``).
    rate_hz : float
        Sample rate, to size the ring buffer.
    port : int
        TCP port on 127.0.0.1 (0: any free port).
    title : str
        Shown at the top of the page.
    """

    def __init__(self, columns: Sequence[str], panels: Sequence[Panel], window: float,
                 rate_hz: float, port: int = 0, title: str = "esoarm") -> None:
        if not (math.isfinite(window) and window > 0):
            raise ValueError(f"window must be a finite number > 0, got {window!r}")
        self.columns = tuple(columns)
        self.panels = tuple(panels)
        self.window = float(window)
        self.title = title
        self._rows: deque[tuple[int, Any]] = deque(maxlen=max(16, int(window * rate_hz) + 64))
        self._seq = 0
        self._lock = threading.Lock()
        self._status: dict[str, Any] = {}
        self._ended = False
        self.clients = 0
        self.served = 0
        self._index = {c: i for i, c in enumerate(self.columns)}
        self._shown = ["t"]
        for p in self.panels:
            self._shown.extend(c for c in p.columns if c not in self._shown)
        unknown = [c for c in self._shown if c not in self._index and c not in DERIVED]
        if unknown:
            raise ValueError(f"scope panels name columns not in the rows: {', '.join(unknown)}")
        page = resources.files("esoarm.hardware").joinpath("scope.html").read_bytes()
        self._page = page
        scope = self

        class Handler(_Handler):
            owner = scope

        try:
            self._server = _QuietServer((HOST, port), Handler)
        except OSError as exc:
            raise ScopeError(f"scope: cannot listen on {HOST}:{port}: {exc.strerror or exc}"
                             ) from None
        self._server.daemon_threads = True
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        kwargs={"poll_interval": 0.2}, daemon=True,
                                        name="esoarm-scope")
        self._thread.start()

    @property
    def url(self) -> str:
        """Address of the page."""
        return f"http://{HOST}:{self.port}/"

    # -- the loop's side: O(1), never blocks on the network ---------------------
    def push(self, row: str | Sequence[float]) -> None:
        """Add one row (a CSV line of ``columns``, or a tuple of floats)."""
        with self._lock:
            self._seq += 1
            self._rows.append((self._seq, row))

    status_source: Callable[[], dict[str, Any]] | None = None
    """Optional: polled by the streams for the counters (instead of :meth:`set_status`)."""

    def set_status(self, status: dict[str, Any]) -> None:
        """Replace the counters shown in the page's status line."""
        self._status = status

    def end(self, message: str = "run ended") -> None:
        """Tell connected pages the run is over (they keep the data on screen)."""
        self._status = {**self._status, "ended": message}
        self._ended = True

    def close(self) -> None:
        """Stop the server (connected pages show 'disconnected')."""
        self.end()
        time.sleep(PERIOD * 1.5)  # let the streams send the last rows and the end
        self._server.shutdown()
        self._server.server_close()

    # -- the server's side -------------------------------------------------------
    def _since(self, seq: int) -> tuple[int, list[Any]]:
        with self._lock:
            if not self._rows or self._rows[-1][0] <= seq:
                return seq, []
            rows = list(self._rows)
        first = rows[0][0]
        start = max(0, seq + 1 - first)
        return rows[-1][0], [r for _, r in rows[start:]]

    def _encode(self, rows: list[Any]) -> dict[str, list[float | None]]:
        out: dict[str, list[float | None]] = {c: [] for c in self._shown}
        index = self._index
        for row in rows:
            fields = row.rstrip("\n").split(",") if isinstance(row, str) else row
            for name in self._shown:
                if name in DERIVED:
                    src, scale = DERIVED[name]
                    v = _num(fields[index[src]]) if src in index else None
                    out[name].append(None if v is None else v * scale)
                else:
                    out[name].append(_num(fields[index[name]]))
        return out

    def meta(self) -> dict[str, Any]:
        """What the page needs to lay itself out."""
        return {"title": self.title, "window": self.window,
                "panels": [{"title": p.title, "unit": p.unit, "columns": list(p.columns),
                            "labels": list(p.labels)} for p in self.panels]}


class _QuietServer(ThreadingHTTPServer):
    """A page's broken connection is its own business: no traceback on the terminal."""

    def handle_error(self, request: Any, client_address: Any) -> None:
        return


def _num(text: Any) -> float | None:
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


class _Handler(BaseHTTPRequestHandler):
    owner: Scope
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - quiet
        return

    def _send(self, code: int, ctype: str, body: bytes) -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path = self.path.split("?", 1)[0]
        scope = self.owner
        try:
            if path in ("/", "/index.html"):
                self._send(200, "text/html; charset=utf-8", scope._page)
            elif path == "/meta":
                self._send(200, "application/json", json.dumps(scope.meta()).encode())
            elif path == "/events":
                self._stream(scope)
            elif path == "/favicon.ico":
                self._send(204, "image/x-icon", b"")
            else:
                self._send(404, "text/plain", b"not found")
        except (BrokenPipeError, ConnectionResetError, TimeoutError, OSError):
            return  # the page went away: only this thread ends

    def _stream(self, scope: Scope) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.send_header("Connection", "close")
        self.end_headers()
        self.close_connection = True
        scope.clients += 1
        try:  # a reconnecting page resumes where it left off
            seq = int(self.headers.get("Last-Event-ID") or 0)
        except ValueError:
            seq = 0
        try:
            while True:
                seq, rows = scope._since(seq)
                ended = scope._ended
                source = scope.status_source
                status = {**source(), **scope._status} if source is not None else scope._status
                msg: dict[str, Any] = {"status": status}
                if rows:
                    msg["rows"] = scope._encode(rows)
                self.wfile.write(f"id: {seq}\ndata: ".encode()
                                 + json.dumps(msg, separators=(",", ":")).encode() + b"\n\n")
                self.wfile.flush()
                scope.served += len(rows)
                if ended:
                    return
                time.sleep(PERIOD)
        finally:
            scope.clients -= 1


#: Columns of the rows the emulator pushes (see :attr:`esoarm.hardware.emulator.Emulator.monitor`).
EMULATOR_COLUMNS = ("t", "theta", "theta_measured", "omega", "u")


def scope_for_run(name: str, rate_hz: float, window: float, port: int) -> Scope:
    """The scope of ``esoarm run``: rows are the run log's CSV lines."""
    from esoarm.hardware.realtime import LOG_COLUMNS

    return Scope(LOG_COLUMNS, run_panels(), window, rate_hz, port, title=f"esoarm run {name}")


def scope_for_emulator(emu: Any, name: str, window: float, port: int) -> Scope:
    """The scope of ``esoarm emulate``: the twin's own signals and the device counters."""
    scope = Scope(EMULATOR_COLUMNS, emulator_panels(), window, 1.0 / emu.twin.ts, port,
                  title=f"esoarm emulate {name}")

    def counters() -> dict[str, Any]:
        return {"t": emu.twin.time, "k": emu.twin.k,
                "state": "running" if emu.running else "idle",
                "frames lost": emu.frames_lost, "bad commands": emu.bad_commands,
                "faults": ",".join(sorted(emu.active)) or "none"}

    scope.status_source = counters
    emu.monitor = scope.push
    return scope
