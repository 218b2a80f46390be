"""The rig a commissioning talks to: a serial port, or the simulated Uno (``--hil``).

On ``--hil`` the board is ``esoarm hil``'s simavr Uno with the scenario's twin on its pins
(:class:`esoarm.hardware.hil.server.HilServer`), run in a child process so that the
host loop (``esoarm.hardware.realtime.run_rig``) and the simulated chip do not share an
interpreter: ``python -m esoarm.studies.commission.board --elf FILE SCENARIO [--set
KEY=VALUE ...]`` prints ``device: PATH`` and serves one run (it exits once the host
sent STOP, or went quiet for 5 s).  The scenario given to it is the *rig* (the twin
the person commissions); the firmware may carry a controller generated from another
scenario (the identified design), as a flashed board would.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["SimulatedBoard", "main"]


class SimulatedBoard:
    """One run of ``elf`` on the simulated Uno with the twin of ``scenario`` (a child process).

    Parameters
    ----------
    scenario : str
        Built-in name or TOML path of the rig.
    overrides : sequence of str
        ``KEY=VALUE`` as given to ``--set``.
    elf : Path
        The firmware (host-controlled, or built with a generated controller on board).
    log : Path
        Where the child's output goes (kept for the report).
    """

    def __init__(self, scenario: str, overrides: list[str] | tuple[str, ...], elf: Path,
                 log: Path) -> None:
        sets = [a for kv in overrides for a in ("--set", kv)]
        self.log = log
        self._fh = open(log, "w", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "esoarm.studies.commission.board", "--elf", str(elf),
             scenario, *sets], stdout=subprocess.PIPE, stderr=self._fh, text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"})
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line.startswith("device: "):
            self.close()
            raise RuntimeError("the simulated board did not start: "
                               + (log.read_text(encoding="utf-8").strip().splitlines() or
                                  ["no output"])[-1])
        self.path = line.split(": ", 1)[1].strip()

    def close(self, timeout: float = 30.0) -> None:
        """Wait for the board to finish its run (at most ``timeout`` s), then stop it."""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.terminate()
            self.proc.wait(10)
        if self.proc.stdout is not None:
            rest = self.proc.stdout.read()
            self._fh.write(rest)
            self.proc.stdout.close()
        self._fh.close()

    def __enter__(self) -> SimulatedBoard:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def main(argv: list[str] | None = None) -> int:
    """Serve one run of a firmware on the simulated Uno (see the module docstring)."""
    from esoarm.hardware.hil.server import HilServer
    from esoarm.scenario import load_scenario

    ap = argparse.ArgumentParser(prog="python -m esoarm.studies.commission.board")
    ap.add_argument("scenario")
    ap.add_argument("--elf", required=True)
    ap.add_argument("--set", dest="sets", action="append", default=[])
    args = ap.parse_args(argv)
    scn = load_scenario(args.scenario, args.sets)
    server = HilServer(scn, Path(args.elf), echo=lambda s: print(s, file=sys.stderr, flush=True))
    print(f"device: {server.path}", flush=True)
    t0 = time.monotonic()

    def done() -> bool:
        if server.log.start_cycle is None:  # nobody started a run within 5 minutes
            return time.monotonic() - t0 > 300
        return server.motor_duty == 0 and (
            server.host_quiet(5.0) or server.stop_seen and server.host_quiet(0.3))

    try:
        server.serve(until=done)
    finally:
        server.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
