"""Helpers for end-to-end tests: the emulator and the host CLI as subprocesses."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import pytest

CLI = [sys.executable, "-c", "from esoarm.cli import main; main()"]


def _have_pty() -> bool:
    try:
        master, slave = os.openpty()
    except OSError:
        return False
    os.close(master)
    os.close(slave)
    return True


#: skip marker for tests that need a pseudo-terminal (the emulator's port)
needs_pty = pytest.mark.skipif(not _have_pty(), reason="no pseudo-terminals (os.openpty failed)")


@dataclass
class EmulatorProcess:
    proc: subprocess.Popen
    path: str
    lines: list[str] = field(default_factory=list)

    def output(self, wait: float = 1.0) -> str:
        """Everything printed so far (waits up to ``wait`` s for more)."""
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + wait
        while (left := deadline - time.monotonic()) > 0:
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                break
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            self.lines.extend(chunk.decode().splitlines())
        return "\n".join(self.lines)


@contextmanager
def emulator(*args: str) -> Iterator[EmulatorProcess]:
    """Start ``esoarm emulate ARGS``; yield once it has printed ``device: PATH``."""
    proc = subprocess.Popen([*CLI, "emulate", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        fd = proc.stdout.fileno()
        before: list[str] = []  # scenario warnings (stderr) may come first
        while True:
            ready, _, _ = select.select([fd], [], [], 60.0)
            assert ready, "emulator printed nothing"
            first = b""
            while not first.endswith(b"\n"):
                byte = os.read(fd, 1)
                assert byte, f"emulator exited: {first!r}"
                first += byte
            line = first.decode().strip()
            if not line.startswith("esoarm: warning: "):
                break
            before.append(line)
        assert line.startswith("device: "), line
        yield EmulatorProcess(proc, line.split(" ", 1)[1], [*before, line])
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        proc.stdout.close()


@contextmanager
def served(*args: str, wait: float = 60.0) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """Start ``esoarm ARGS`` (``hil`` or ``emulate``, serving a device); yield (the process,
    its port) once it has printed ``device: PORT`` as its first line.  Leaving the block
    normally waits up to ``wait`` s for it to exit (a ``--once`` server ends with the run),
    then terminates it; leaving on an error terminates it at once."""
    dev = subprocess.Popen([sys.executable, "-m", "esoarm", *args], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    ok = False
    try:
        assert dev.stdout is not None and dev.stderr is not None
        first = dev.stdout.readline()
        assert first.startswith("device: "), (first, "" if first else dev.stderr.read())
        yield dev, first.split(": ", 1)[1].strip()
        ok = True
    finally:
        if ok and dev.poll() is None:
            try:
                dev.wait(wait)
            except subprocess.TimeoutExpired:
                pass
        if dev.poll() is None:
            dev.terminate()
            dev.wait(10)


def esoarm(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    """Run the esoarm CLI; capture stdout/stderr as text."""
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=timeout)
