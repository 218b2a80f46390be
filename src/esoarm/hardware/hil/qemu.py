"""``esoarm hil --onboard --target cortex-m4``: the on-board firmware on QEMU's mps2-an386.

The chip (:func:`esoarm.codegen.cortex_m_onboard.m4_onboard_firmware`) runs the
generated observer and controller and speaks the rig protocol on its UART1,
which this server passes to a new pseudo-terminal for ``esoarm run SCENARIO
--port PATH --onboard``.  QEMU models no encoder and no motor pins, so the
arm's side is the chip's UART0, the *pin link*, in lockstep with the digital
twin (:class:`esoarm.hardware.emulator.Twin`, the physics of every engine):

1. the chip asks for sample k (``'S'`` k u32) -- once after START, then after each step;
2. the twin answers (k u32, count i32), the count of θ(t_k) with the scenario's
   sensor noise, drawn as :mod:`esoarm.plants.sensor` does (k = 0 sets the arm
   back to ``rig.theta0``, at rest);
3. the chip steps on y_k = q·count_k and answers ``'U'`` drive f32, duty i16, on u8;
4. the twin holds the drive torque (with a ``[motor]`` table: the torque of the
   duty, :meth:`~esoarm.hardware.emulator.Twin.torque_of_duty`) over [t_k, t_k+1).

Step 4 is the zero-order hold of ``esoarm simulate``, so a run commands the u
sequence of the simulator up to the chip's float32 arithmetic.

Pacing: sample k is answered no earlier than k·Ts of wall clock after sample 0
(where the machine cannot keep up the run is slower than real time, never
faster: counted in ``lags``, ``worst_lag``), and not while the host's last
HEARTBEAT is more than :data:`HOST_LEAD_S` of samples behind -- unless the host
has been silent for :data:`HOST_SILENT_S`.  A host slowed by a loaded machine is
waited for (the chip's 100 ms heartbeat watchdog, counted in its samples, would
otherwise trip on the simulation's scheduling, measured: at sample 910 of 5000
at a load of 18 on 2 cores); a host that is gone is not, and the chip's watchdog
stops the motor 100 ms of its samples after the last heartbeat.
"""

from __future__ import annotations

import math
import os
import select
import socket
import struct
import subprocess
import tempfile
import time
from collections.abc import Callable

from esoarm.codegen.cortex_m_onboard import M4Firmware
from esoarm.codegen.toolchain import tool
from esoarm.hardware import protocol as P
from esoarm.hardware.device import PtyDevice
from esoarm.hardware.emulator import Twin
from esoarm.scenario import Scenario

__all__ = ["QemuError", "QemuOnboardServer"]

_REQUEST = struct.Struct("<cI")      # 'S', k
_ANSWER = struct.Struct("<Ii")       # k, count
_COMMAND = struct.Struct("<cfhB")    # 'U', drive [N·m], duty [counts], motor on
#: how far behind the wall clock a sample may be answered before it is counted [s]
LAG_S = 0.005
#: the twin waits while the host's newest heartbeat is this far behind [s of samples] ...
HOST_LEAD_S = 0.05
#: ... unless the host has sent nothing for this long [s of wall clock]
HOST_SILENT_S = 0.3


class QemuError(RuntimeError):
    """QEMU could not be started, or the chip stopped answering; one line."""


def _connect(path: str, proc: subprocess.Popen[bytes], timeout: float = 10.0) -> socket.socket:
    deadline = time.monotonic() + timeout
    while True:
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            s.connect(path)
            s.setblocking(False)
            return s
        except OSError:
            s.close()
            if proc.poll() is not None or time.monotonic() > deadline:
                err = proc.stderr.read().decode(errors="replace").strip() if proc.stderr else ""
                raise QemuError("qemu-system-arm did not start"
                                + (f": {err.splitlines()[-1]}" if err else "")) from None
            time.sleep(0.02)


class QemuOnboardServer:
    """The on-board firmware in QEMU behind a new pseudo-terminal, the twin on its pin link.

    Parameters
    ----------
    scn : Scenario
        The twin (rig, sensor, motor) and the run's rate.
    firmware : M4Firmware
        From :func:`~esoarm.codegen.cortex_m_onboard.m4_onboard_firmware` (of ``scn``).
    echo : callable
        Receives one-line status messages.
    """

    def __init__(self, scn: Scenario, firmware: M4Firmware,
                 echo: Callable[[str], None] = print) -> None:
        self.scn = scn
        self.firmware = firmware
        self.echo = echo
        self.twin = Twin(scn)
        self.ts = scn.sample_time
        self._dir = tempfile.TemporaryDirectory(prefix="esoarm-qemu-")
        pins, link = (os.path.join(self._dir.name, n) for n in ("pins", "link"))
        cmd = [tool("qemu-system-arm"), "-M", "mps2-an386", "-display", "none", "-monitor",
               "none", "-icount", "shift=8",
               "-chardev", f"socket,id=pins,path={pins},server=on,wait=off",
               "-chardev", f"socket,id=link,path={link},server=on,wait=off",
               "-serial", "chardev:pins", "-serial", "chardev:link",
               "-kernel", str(firmware.elf)]
        self.proc: subprocess.Popen[bytes] = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            self.pins = _connect(pins, self.proc)
            self.link = _connect(link, self.proc)
        except QemuError:
            self.proc.kill()
            self.proc.wait()
            self._dir.cleanup()
            raise
        self.port = PtyDevice()
        self.path = self.port.path
        self.closed = False
        self.rx_parser = P.Parser()   # host -> chip (watched)
        self.tx_parser = P.Parser()   # chip -> host (watched)
        self._pin_buf = b""
        self._due: tuple[float, int] | None = None  # (wall time, k) of a requested sample
        self._t0 = 0.0
        self.samples = 0              # samples the twin served in the current run
        self.lags = 0
        self.worst_lag = 0.0
        self.run_started = False
        self.stop_seen = False
        self.motor_on = False
        self.device_faults: list[str] = []
        self._last_host_wall = -math.inf
        self._host_k = 0        # the sample of the host's newest HEARTBEAT (0 at START)
        self._beat_twin_k = 0   # the twin's sample when that heartbeat went to the chip
        self._lead = max(1, round(HOST_LEAD_S / self.ts))
        self.host_waits = 0     # samples held back for a slow host

    # -- the pin link -----------------------------------------------------------------
    def _on_pins(self, data: bytes) -> None:
        self._pin_buf += data
        while self._pin_buf:
            tag = self._pin_buf[:1]
            if tag == b"S":
                if len(self._pin_buf) < _REQUEST.size:
                    return
                _, k = _REQUEST.unpack_from(self._pin_buf)
                self._pin_buf = self._pin_buf[_REQUEST.size:]
                if k == 0:  # a new run: the arm back at theta0, at rest
                    self.twin.reset()
                    self._t0 = time.perf_counter()
                    self.samples = 0
                elif k != self.twin.k:
                    raise QemuError(f"the chip asked for sample {k}, the twin is at "
                                    f"{self.twin.k}")
                self._due = (self._t0 + k * self.ts, k)
            elif tag == b"U":
                if len(self._pin_buf) < _COMMAND.size:
                    return
                _, drive, duty, on = _COMMAND.unpack_from(self._pin_buf)
                self._pin_buf = self._pin_buf[_COMMAND.size:]
                if self.motor_on and not on:
                    since = (self.twin.k - self._beat_twin_k) * self.ts * 1e3
                    self.echo(f"motor off at t = {self.twin.time:.4g} s ({since:.0f} ms of the "
                              "chip's samples after the host's last heartbeat)")
                self.motor_on = bool(on)
                if on:  # the answer to sample twin.k: hold it over [t_k, t_k+1)
                    u = float(drive) if self.firmware.torque else self.twin.torque_of_duty(duty)
                    self.twin.advance(u)
                    self.samples += 1
            else:
                raise QemuError(f"the chip wrote {tag!r} on its pin link (expected S or U)")

    def _answer_due(self) -> None:
        if self._due is None:
            return
        due, k = self._due
        now = time.perf_counter()
        if now < due:
            return
        if k > 0 and k - self._host_k > self._lead and not self.host_quiet(HOST_SILENT_S):
            self.host_waits += 1
            return  # a slow host: wait for its heartbeat (select wakes on its bytes)
        lag = now - due
        if lag > LAG_S and k > 0:
            self.lags += 1
            self.worst_lag = max(self.worst_lag, lag)
            self._t0 += lag  # carry on from now: never race to catch up
        self._due = None
        self.pins.sendall(_ANSWER.pack(k, self.twin.count()))

    # -- the protocol link ------------------------------------------------------------
    def _on_chip(self, data: bytes) -> None:
        for f in self.tx_parser.feed(data):
            if f.kind == P.FAULT:
                code, detail = f.fields()
                name = {P.FAULT_WATCHDOG: "watchdog", P.FAULT_OVERRUN: "overrun",
                        P.FAULT_BAD_COMMAND: "bad command"}.get(code, f"code {code}")
                self.device_faults.append(name)
                self.echo(f"device fault: {name} (detail {detail}) at t = {self.twin.time:.4g} s")
        self.port.write(data)

    def _on_host(self, data: bytes) -> None:
        self._last_host_wall = time.perf_counter()
        for f in self.rx_parser.feed(data):
            if f.kind == P.START:
                self.run_started, self.stop_seen = True, False
                self._host_k = self._beat_twin_k = 0
            elif f.kind == P.HEARTBEAT:
                self._host_k = max(self._host_k, int(f.fields()[0]))
                self._beat_twin_k = self.twin.k
            elif f.kind == P.STOP:
                self.stop_seen = True
        self.link.sendall(data)

    def host_quiet(self, seconds: float) -> bool:
        """True when no byte came from the host for ``seconds`` of wall time."""
        return time.perf_counter() - self._last_host_wall > seconds

    def serve(self, until: Callable[[], bool] = lambda: False) -> None:
        """Pass bytes and serve the twin until ``until()`` is true or QEMU exits."""
        pins, link = self.pins.fileno(), self.link.fileno()
        while not self.closed and not until():
            if self.proc.poll() is not None:
                raise QemuError(f"QEMU exited (status {self.proc.returncode})")
            timeout = 0.05
            if self._due is not None:
                left = self._due[0] - time.perf_counter()
                # past due: waiting for a slow host, whose bytes wake the select
                timeout = min(timeout, left) if left > 0 else 0.005
            host = None if self.port.closed else self.port.master
            ready, _, _ = select.select([pins, link] + ([host] if host is not None else []), [],
                                        [], timeout)
            if pins in ready:
                data = self._recv(self.pins)
                self._on_pins(data)
            if link in ready:
                self._on_chip(self._recv(self.link))
            if host is not None and host in ready:
                data = self.port.read(0.0)
                if data:
                    self._on_host(data)
            self._answer_due()

    @staticmethod
    def _recv(sock: socket.socket) -> bytes:
        try:
            data = sock.recv(65536)
        except BlockingIOError:
            return b""
        if not data:
            raise QemuError("QEMU closed a serial port")
        return data

    def close(self) -> None:
        """Stop QEMU and close the pseudo-terminal."""
        if self.closed:
            return
        self.closed = True
        self.port.close()
        for s in (self.pins, self.link):
            s.close()
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        if self.proc.stderr is not None:
            self.proc.stderr.close()
        self._dir.cleanup()

    def __enter__(self) -> QemuOnboardServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
