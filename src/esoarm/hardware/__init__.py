"""Running esoarm on a rig: protocol, serial link, emulator, real-time loop, replay.

Modules (one concept each): :mod:`.protocol` (framing, parser),
:mod:`.link` (pyserial transport), :mod:`.controller` (ESO + FLC stepped per
sample), :mod:`.motor` (torque <-> PWM duty), :mod:`.loop` (real-time loop and
safety), :mod:`.emulator` (the twin as a device behind a pseudo-terminal),
:mod:`.device` (the pseudo-terminal and timed faults the emulator and ``hil`` share),
:mod:`.replay` (offline ESO over a log), :mod:`.logfile` (reading and
checking a run's CSV log).  See ``docs/protocol.md`` and ``docs/hardware.md``.
"""
