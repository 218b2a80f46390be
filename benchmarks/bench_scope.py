"""Cost of the live scope to the real-time loop: ``esoarm run`` with and without ``--scope``.

Each trial starts ``esoarm emulate SCENARIO`` (real time) and ``esoarm run ... --json``
against it, and reads the loop's own timing from the summary: host latency (sample in →
command out) p50/p99, period jitter p50/p99 and deadline misses.  Conditions, interleaved
and repeated:

- ``off``      no scope;
- ``idle``     ``--scope``, no page open;
- ``reader``   ``--scope`` with a plain Python client reading the event stream (the
  server's cost alone, without a browser's rendering on the same cores);
- ``flapping`` ``--scope`` with a client that connects, reads two events and hangs up,
  over and over (what closing and reopening pages does to the server);
- ``blank``    no scope, a headless Chromium showing an empty page (what a browser alone
  costs: its start-up and drawing compete for the same cores);
- ``page``     ``--scope`` with a headless Chromium started at the start of the run and
  showing the page to its end.

Browsers are started with ``nice -n 19``, as the docs advise on a machine that also runs a loop.

With ``--inprocess`` the same conditions (without the browser) are measured on the loop
itself, in one process and without a serial port or wall-clock pacing: ``run_rig`` drives an
in-process lockstep twin as fast as it can, and the per-sample host latency (sample in →
command out, the part of the loop the scope could slow down: the stream threads share the
interpreter with the loop) is read from the summary.  This isolates the scope's cost from the
scheduling noise of a shared machine.

Usage (writes a Markdown table on stdout)::

    python benchmarks/bench_scope.py [--rate 50] [--duration 10] [--repeat 3]
    python benchmarks/bench_scope.py --inprocess [--duration 200] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import select
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time

CLI = [sys.executable, "-c", "from esoarm.cli import main; main()"]
BROWSER = shutil.which("chromium") or shutil.which("/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run"]


def _first_line(proc: subprocess.Popen, prefix: str, timeout: float = 30.0) -> str:
    fd = proc.stdout.fileno()  # type: ignore[union-attr]
    buf = b""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.5)
        if ready:
            chunk = os.read(fd, 1)
            if not chunk:
                break
            buf += chunk
            if buf.endswith(b"\n"):
                line = buf.decode().strip()
                buf = b""
                if line.startswith(prefix):
                    return line
    raise RuntimeError(f"no line starting with {prefix!r}")


def _browse(url: str, stop: threading.Event, flap: float | None, profile: str) -> None:
    """Keep a page open on url (or open/close it every ``flap`` s) until ``stop``."""
    while not stop.is_set():
        nice = ["nice", "-n", "19"] if shutil.which("nice") else []
        proc = subprocess.Popen([*nice, BROWSER, *FLAGS, f"--user-data-dir={profile}", url],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        stop.wait(flap if flap else 1e9)
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


READER = """
import sys, time, urllib.request
url, hang = sys.argv[1], int(sys.argv[2])
while True:
    try:
        with urllib.request.urlopen(url + "events", timeout=5) as resp:
            events = 0
            for line in resp:
                events += line.startswith(b"data: ")
                if hang and events >= hang:
                    break
    except OSError:
        time.sleep(0.1)
"""


def _reader_process(url: str, hang_up_after: int) -> subprocess.Popen:
    """A client in its own process (as a browser is), killed by the caller."""
    return subprocess.Popen([sys.executable, "-c", READER, url, str(hang_up_after)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def trial(cond: str, scenario: str, sets: list[str], port: int) -> dict:
    emu = subprocess.Popen([*CLI, "emulate", scenario, "--once", *sets],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        path = _first_line(emu, "device: ", timeout=120).split(" ", 1)[1]
        scope = ["--scope", "--scope-port", str(port)] if cond not in ("off", "blank") else []
        run = subprocess.Popen([*CLI, "run", scenario, "--port", path, *sets, "--json", *scope],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stop = threading.Event()
        browser = None
        url = f"http://127.0.0.1:{port}/"
        reader = None
        if cond in ("reader", "flapping"):
            time.sleep(0.3)
            reader = _reader_process(url, 2 if cond == "flapping" else 0)
        if cond in ("page", "blank"):
            time.sleep(0.3)
            profile = tempfile.mkdtemp(prefix="esoarm-scope-bench-")
            browser = threading.Thread(target=_browse, args=(
                url if cond == "page" else "about:blank", stop, None, profile), daemon=True)
            browser.start()
        out, err = run.communicate(timeout=600)
        stop.set()
        if reader is not None:
            reader.kill()
            reader.wait()
        if browser is not None:
            browser.join(10)
        if run.returncode != 0:
            raise RuntimeError(f"run failed ({cond}): {err.strip()}")
        return json.loads(out)
    finally:
        if emu.poll() is None:
            emu.terminate()
            emu.wait(5)


class _LockstepLink:
    """A lockstep device in-process: the twin answers each TORQUE with the next sample."""

    def __init__(self, scn) -> None:  # type: ignore[no-untyped-def]
        from esoarm.hardware import protocol as P
        from esoarm.hardware.emulator import Twin

        self.P = P
        self.twin = Twin(scn)
        self.info = P.Info(1, P.FLAG_TORQUE | P.FLAG_LOCKSTEP, self.twin.counts_per_rev, 255,
                           round(1e6 * scn.sample_time))
        self.queue: list = []
        self.parser = P.Parser()
        self.rx_lost = 0
        self.stopped = False

    def handshake(self):  # type: ignore[no-untyped-def]
        return self.info

    def _emit(self) -> None:
        P, twin = self.P, self.twin
        payload = P.encode(P.SAMPLE, 0, twin.k, twin.k * 20000, twin.count())[5:-2]
        self.queue.append(P.Frame(P.SAMPLE, 0, payload))

    def send(self, kind, *fields) -> None:  # type: ignore[no-untyped-def]
        if kind == self.P.START:
            self._emit()
        elif kind == self.P.TORQUE:
            self.twin.advance(fields[1])
            self._emit()

    def receive(self, timeout):  # type: ignore[no-untyped-def]
        out, self.queue = self.queue, []
        if self.stopped and not out:
            return [self.P.Frame(self.P.STOPPED, 0, b"")]
        return out

    def stop(self) -> None:
        self.stopped = True


def inprocess(args: argparse.Namespace) -> None:
    from esoarm.hardware.realtime import run_rig
    from esoarm.hardware.scope import scope_for_run
    from esoarm.scenario import load_scenario

    scn = load_scenario(args.scenario, {"duration": args.duration,
                                        "sensor.rate_hz": args.rate})
    conds = ["off", "idle", "reader", "flapping"]
    results: dict[str, list[dict]] = {c: [] for c in conds}
    for r in range(args.repeat):
        for c in conds:
            scope = None if c == "off" else scope_for_run(scn.name, scn.sensor.rate_hz, 10.0, 0)
            reader = None
            if c in ("reader", "flapping"):
                assert scope is not None
                reader = _reader_process(scope.url, 2 if c == "flapping" else 0)
                time.sleep(0.5)
            t0 = time.perf_counter()
            s = run_rig(scn, _LockstepLink(scn), None,
                        monitor=scope.push if scope else None,
                        status=scope.set_status if scope else None)
            wall = time.perf_counter() - t0
            if reader is not None:
                reader.kill()
                reader.wait()
            if scope is not None:
                scope.close()
            results[c].append({**s.to_dict(), "wall_per_sample_us": wall / s.samples * 1e6})
            print(f"# run {r + 1} {c:9s} latency p50 {s.latency_p50_us:.1f} µs p99 "
                  f"{s.latency_p99_us:.1f} µs, wall {wall / s.samples * 1e6:.1f} µs/sample",
                  file=sys.stderr)
    # the loop's only work for the scope: one push per row (and a status dict 10 times a second)
    import timeit

    scope = scope_for_run(scn.name, scn.sensor.rate_hz, 10.0, 0)
    line = "1.0,0.5,0.5,0.0,0.1,0.5,0.0,0.0,50,1.0,1.0,4.5e-05,0,nan\n"
    n = 200_000
    push_ns = min(timeit.repeat(lambda: scope.push(line), number=n, repeat=5)) / n * 1e9
    scope.close()
    load = os.getloadavg()
    print(f"`python benchmarks/bench_scope.py --inprocess --duration {args.duration:g} "
          f"--repeat {args.repeat}`: {scn.n_samples} samples per run, in-process lockstep, "
          f"median over {args.repeat} runs per condition (interleaved); "
          f"{os.cpu_count()} cores, load average {load[0]:.1f}, "
          f"Python {platform.python_version()}.\n")
    print("| scope | host latency p50 [µs] | p99 [µs] | loop time per sample [µs] |")
    print("|---|---|---|---|")
    names = {"off": "off", "idle": "`--scope`, no page",
             "reader": "`--scope`, stream read by a client",
             "flapping": "`--scope`, a client connecting and hanging up every 0.2 s"}
    for c in conds:
        rs = results[c]
        med = {k: statistics.median(r[k] for r in rs)
               for k in ("latency_p50_us", "latency_p99_us", "wall_per_sample_us")}
        print(f"| {names[c]} | {med['latency_p50_us']:.1f} | {med['latency_p99_us']:.1f} | "
              f"{med['wall_per_sample_us']:.1f} |")
    print(f"\nScope.push (the loop's only call per sample): {push_ns:.0f} ns per row "
          f"(best of 5 × {n}).")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="test-1")
    ap.add_argument("--rate", type=float, default=50.0, help="sensor.rate_hz [Hz]")
    ap.add_argument("--duration", type=float, default=10.0, help="run length [s]")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--port", type=int, default=8799)
    ap.add_argument("--inprocess", action="store_true",
                    help="measure the loop in one process (lockstep, no port, no browser)")
    args = ap.parse_args()
    if args.inprocess:
        inprocess(args)
        return
    if BROWSER is None:
        sys.exit("needs Chromium for the 'page' conditions")
    sets = ["--set", f"sensor.rate_hz={args.rate:g}", "--set", f"duration={args.duration:g}"]
    conds = ["off", "idle", "reader", "flapping", "blank", "page"]
    results: dict[str, list[dict]] = {c: [] for c in conds}
    failures = dict.fromkeys(conds, 0)
    for r in range(args.repeat):
        for c in conds:
            try:
                results[c].append(trial(c, args.scenario, sets, args.port))
            except RuntimeError as exc:  # a run that faulted is a result too
                print(f"# run {r + 1} {c:9s} FAILED: {exc}", file=sys.stderr)
                failures[c] += 1
                continue
            s = results[c][-1]
            print(f"# run {r + 1} {c:9s} latency p50 {s['latency_p50_us']:.0f} µs p99 "
                  f"{s['latency_p99_us']:.0f} µs, jitter p99 {s['jitter_p99_us']:.0f} µs, "
                  f"misses {s['deadline_misses']}/{s['samples']}", file=sys.stderr)
    load = os.getloadavg()
    print(f"`python benchmarks/bench_scope.py --rate {args.rate:g} --duration {args.duration:g} "
          f"--repeat {args.repeat}`: {args.scenario}, real time at {args.rate:g} Hz, "
          f"{args.duration:g} s per run, median over {args.repeat} runs per condition "
          f"(interleaved); {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {load[0]:.1f} during the run, Python {platform.python_version()}.\n")
    print("| scope | host latency p50 [µs] | p99 [µs] | period jitter p50 [µs] | p99 [µs] | "
          "deadline misses per run | runs ended by a fault |")
    print("|---|---|---|---|---|---|---|")
    names = {"off": "off", "idle": "`--scope`, no page",
             "reader": "`--scope`, stream read by a Python client",
             "flapping": "`--scope`, a client connecting and hanging up every 0.2 s",
             "blank": "off, an empty page open in headless Chromium",
             "page": "`--scope`, page open in headless Chromium"}
    for c in conds:
        rs = results[c]
        if not rs:
            print(f"| {names[c]} | — | — | — | — | — | {failures[c]} of {args.repeat} |")
            continue

        def med(key: str, rs: list[dict] = rs) -> float:
            return statistics.median(r[key] for r in rs)

        misses = "/".join(str(r["deadline_misses"]) for r in rs)
        print(f"| {names[c]} | {med('latency_p50_us'):.0f} | {med('latency_p99_us'):.0f} | "
              f"{med('jitter_p50_us'):.0f} | {med('jitter_p99_us'):.0f} | {misses} of "
              f"{rs[0]['samples']} | {failures[c]} of {args.repeat} |")


if __name__ == "__main__":
    main()
