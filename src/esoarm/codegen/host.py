"""The generated controller compiled for the host (gcc) and stepped through ctypes.

:class:`HostChip` is the host "target" of the processor-in-the-loop check: the
same generated source the chips run, built with the host's gcc (``-O2
-ffp-contract=off``: no fused multiply-add, so float64 repeats the Python
step's rounding), stepped one sample at a time.
"""

from __future__ import annotations

import ctypes

from esoarm.codegen.generate import HEADER, SOURCE, Generated
from esoarm.codegen.toolchain import build

__all__ = ["HostChip"]

_WRAPPER = """#include "esoarm_controller.h"
static esoarm_state S;
void pil_init(void) { esoarm_init(&S); }
void pil_step(const double in[4], double out[6])
{
    esoarm_step(&S, (esoarm_real)in[0], (esoarm_real)in[1], (esoarm_real)in[2],
                (esoarm_real)in[3]);
    out[0] = S.u; out[1] = S.drive; out[2] = S.duty;
    out[3] = S.zhat[0]; out[4] = S.zhat[1]; out[5] = S.zhat[2];
}
"""


class HostChip:
    """The generated controller in a shared library on the host.

    Parameters
    ----------
    gen : Generated
        Sources for target ``host``.

    Attributes
    ----------
    cycles : list of int
        Empty: the host is not timed (wall-clock timing belongs in benchmarks/).
    last : tuple of float
        (u, drive, duty, ẑ1, ẑ2, ẑ3) of the latest step.
    """

    timing = "none"

    def __init__(self, gen: Generated) -> None:
        self.target, self.precision = "host", gen.precision
        if gen.prefix != "esoarm":
            raise ValueError("HostChip needs code generated with the default prefix")
        lib = build("gcc", {HEADER: gen.header, SOURCE: gen.source, "pil_host.c": _WRAPPER},
                    ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                     "-shared", "-fPIC"], "controller.so", "esoarm-codegen-host", ["-lm"])
        self._lib = ctypes.CDLL(str(lib))
        self._lib.pil_step.argtypes = [ctypes.POINTER(ctypes.c_double),
                                       ctypes.POINTER(ctypes.c_double)]
        self._lib.pil_step.restype = None
        self._out = (ctypes.c_double * 6)()
        self._in = (ctypes.c_double * 4)()
        self._lib.pil_init()
        self.cycles: list[int] = []
        self.flash_bytes = 0
        self.ram_bytes = 0
        self.last: tuple[float, ...] = ()

    def step(self, y: float, ref: tuple[float, float, float] = (0.0, 0.0, 0.0)
             ) -> tuple[float, float, float]:
        """One sample: y_k [rad] and (θd, θ̇d, θ̈d) -> (u_k [N·m], drive [N·m], duty)."""
        self._in[0], self._in[1], self._in[2], self._in[3] = float(y), *map(float, ref)
        self._lib.pil_step(self._in, self._out)
        self.last = tuple(self._out)
        return self._out[0], self._out[1], self._out[2]

    def close(self) -> None:
        """Nothing to release (the library stays loaded)."""
