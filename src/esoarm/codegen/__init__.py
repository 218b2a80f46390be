"""Generated C for a scenario's observer and controller, and its processor-in-the-loop check.

- :mod:`esoarm.codegen.generate`: the C99 generator driven by the kinds' ``C_SOURCE``;
- :mod:`esoarm.codegen.host`: the generated code built for the host and stepped by ctypes;
- :mod:`esoarm.codegen.lockstep`: a chip in the loop with the twin, held against the
  Python float64 reference;
- :mod:`esoarm.codegen.avr` and :mod:`esoarm.codegen.cortex_m4`: the emulated chips
  (simavr's ATmega328P, QEMU's Cortex-M4).
"""

from esoarm.codegen.generate import (
    PRECISIONS,
    TARGETS,
    CodegenError,
    Generated,
    c_source,
    generate,
    scenario_hash,
    write_sources,
)

__all__ = ["PRECISIONS", "TARGETS", "AGREEMENT", "CodegenError", "Generated", "c_source",
           "generate", "scenario_hash", "write_sources"]

#: The agreement a generated controller must hold: max |u_chip − u_ref| / torque_limit.
AGREEMENT = 1e-4
