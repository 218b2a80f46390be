"""Hardware in the loop: the Uno firmware on a simulated ATmega328P, the twin on its pins.

- :mod:`~esoarm.hardware.hil.build`: compile the simavr harness and the firmware
- :mod:`~esoarm.hardware.hil.board`: the simulated Uno (ctypes over ``harness.c``)
- :mod:`~esoarm.hardware.hil.twin`: the twin's physics behind encoder and driver pins
- :mod:`~esoarm.hardware.hil.server`: the loop behind a pseudo-terminal (``esoarm hil``)
"""
