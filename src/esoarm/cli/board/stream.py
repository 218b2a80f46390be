"""The on-board firmware's stream options, shared by ``hil --onboard``, ``flash`` and
``codegen --arduino-library``: ``--stream-every N``, ``--baud BITS/S``, ``--stream-polled``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click


def stream_options(when: str) -> Callable[[Any], Any]:
    """The three options as one decorator; ``when`` starts each help text ("With --onboard").

    Parameters
    ----------
    when : str
        The condition under which the options apply, e.g. ``"With --onboard"``.

    Returns
    -------
    callable
        A decorator adding ``every`` (int or None), ``baud`` (int or None) and ``polled``
        (bool) to a click command.
    """
    options = [
        click.option("--stream-every", "every", type=click.IntRange(1, 65535), default=None,
                     metavar="N",
                     help=f"{when}: the chip streams every N-th sample to the host (one "
                     "CHIP_SAMPLE frame per N samples) and still controls at every sample "
                     "[default: the fewest the line carries, 1 at 1 kHz and 1 Mbit/s]. At "
                     "1 kHz, --stream-every 10 --baud 115200 --stream-polled leaves the Uno 35 % "
                     "of its period free at p99 while the arm moves (docs/on-the-chip.md); "
                     "'esoarm run --onboard' then logs every N-th sample and says so."),
        click.option("--baud", type=int, default=None, metavar="BITS/S",
                     help=f"{when}: the firmware's line rate [bit/s; default: 1000000], one the "
                     "ATmega328P makes within 2.5 % at 16 MHz (115200, 250000, 500000, "
                     "1000000, ...); a real board's host needs the same 'esoarm run --baud'."),
        click.option("--stream-polled", "polled", is_flag=True,
                     help=f"{when}: feed the line from loop() a byte at a time, each frame "
                     "built as it goes, instead of the transmit interrupt: a frame's cost "
                     "spreads over the samples it spans (with --stream-every 10 at 115200 "
                     "bit/s)."),
    ]

    def apply(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return apply


def stream_given(every: int | None, baud: int | None, polled: bool) -> list[str]:
    """The stream options given on the command line, by name (empty: none).

    Parameters
    ----------
    every : int or None
        ``--stream-every``.
    baud : int or None
        ``--baud``.
    polled : bool
        ``--stream-polled``.

    Returns
    -------
    list of str
    """
    return [name for name, given in (("--stream-every", every is not None),
                                     ("--baud", baud is not None),
                                     ("--stream-polled", polled)) if given]
