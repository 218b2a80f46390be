"""The lockstep serve loop that ``esoarm hil`` runs for each simulated chip (simavr, QEMU)."""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import Any

from esoarm.cli._common import Interrupted, RunFailure


def say(line: str) -> None:
    """A line of the board's report on stdout, flushed (the host reads 'device: PATH').

    Parameters
    ----------
    line : str
        The line, without its newline.
    """
    print(line, flush=True)


def serve_until(server: Any, done: Callable[[], bool], errors: tuple[type[BaseException], ...],
                simulator: str, close: Callable[[], None]) -> bool:
    """Serve the simulated board until ``done()`` or SIGTERM; Ctrl-C ends it too.

    Parameters
    ----------
    server : HilServer or QemuOnboardServer
        The board and its twin (``serve(until=...)``).
    done : callable
        True when the run is over (the ``--once`` rule of the chip).
    errors : tuple of exception types
        The simulator's faults: a run-time failure (exit 1) named ``simulator: ...``.
    simulator : str
        ``simavr`` or ``qemu``.
    close : callable
        Called once the loop ends, however it ends (closes the server).

    Returns
    -------
    bool
        True if Ctrl-C ended it (the caller prints its summary, then :func:`finish`).
    """
    terminated: list[int] = []

    def on_term(signum, frame) -> None:  # type: ignore[no-untyped-def]
        terminated.append(signum)

    old = signal.signal(signal.SIGTERM, on_term)
    interrupted = False
    try:
        server.serve(until=lambda: bool(terminated) or done())
    except KeyboardInterrupt:
        interrupted = True
    except errors as exc:
        raise RunFailure(f"{simulator}: {exc}") from None
    finally:
        signal.signal(signal.SIGTERM, old)
        close()
    return interrupted


def finish(interrupted: bool) -> None:
    """The last line: 'stopped: port closed', or exit status 130 after Ctrl-C.

    Parameters
    ----------
    interrupted : bool
        True when the serving ended with Ctrl-C.

    Raises
    ------
    Interrupted
        After Ctrl-C (the command exits with status 130, saying the port was closed).
    """
    if interrupted:
        raise Interrupted("simulated board stopped, port closed")
    say("stopped: port closed")
