"""``esoarm pil``'s measurement: the generated step on an emulated chip, in lockstep with the twin.

:func:`run_pil` builds the PIL image for the target, runs it against the twin
(:func:`esoarm.codegen.lockstep.lockstep`) and summarizes agreement and timing
in a :class:`PilReport`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from esoarm.codegen import AGREEMENT
from esoarm.codegen.generate import Generated, generate
from esoarm.codegen.lockstep import Chip, LockstepRun, lockstep
from esoarm.scenario import Scenario

__all__ = ["PilReport", "open_chip", "run_pil"]


def open_chip(gen: Generated) -> Chip:
    """Start the emulated chip of ``gen.target`` (``host``: the host build, untimed)."""
    if gen.target == "avr":
        from esoarm.codegen.avr import AvrChip

        return AvrChip(gen)
    if gen.target == "cortex-m4":
        from esoarm.codegen.cortex_m4 import CortexM4Chip

        return CortexM4Chip(gen)
    if gen.target == "cortex-m0plus":
        from esoarm.codegen.cortex_m0 import CortexM0PlusChip

        return CortexM0PlusChip(gen)
    from esoarm.codegen.host import HostChip

    return HostChip(gen)


@dataclass(frozen=True)
class PilReport:
    """Agreement and timing of one PIL run.

    Attributes
    ----------
    run : LockstepRun
        The samples.
    gen : Generated
        What ran.
    timing : str
        What ``cycles`` counts (simavr cycles, or QEMU's instruction-count proxy).
    clock_hz : float
        The target's clock [Hz] (0 for the host).
    budget_cycles : int
        One sample period at that clock.
    flash_bytes, ram_bytes : int
        The PIL image.
    """

    run: LockstepRun
    gen: Generated
    timing: str
    clock_hz: float
    budget_cycles: int
    flash_bytes: int
    ram_bytes: int

    @property
    def cycles(self) -> dict[str, int] | None:
        """min, median, max of the per-step count (None when not timed)."""
        c = np.asarray(self.run.cycles)
        if c.size == 0:
            return None
        return {"min": int(c.min()), "median": int(np.median(c)), "max": int(c.max())}

    @property
    def fits(self) -> bool:
        """The worst step fits in one sample period (True when not timed)."""
        c = self.cycles
        return c is None or c["max"] <= self.budget_cycles

    @property
    def agrees(self) -> bool:
        """max |Δu| / torque_limit ≤ :data:`esoarm.codegen.AGREEMENT` over every sample."""
        return self.run.max_rel_du <= AGREEMENT

    @property
    def covers_motion(self) -> bool:
        """The run reached the moving part (:attr:`LockstepRun.covers_motion`): an agreement
        over a resting arm, before the first move, is not a check of the code."""
        return self.run.covers_motion

    def as_dict(self) -> dict[str, Any]:
        """The ``--json`` object."""
        return {
            "scenario": self.gen.scenario, "sha256": self.gen.digest,
            "target": self.gen.target, "precision": self.gen.precision,
            "observer_sums": "compensated" if self.gen.compensated else "plain",
            "steps": self.run.steps,
            "max_abs_du": self.run.max_abs_du, "max_rel_du": self.run.max_rel_du,
            "agreement_limit": AGREEMENT, "duty_ties": self.run.duty_ties,
            "cycles": self.cycles, "cycles_are": self.timing,
            "clock_hz": self.clock_hz, "budget_cycles": self.budget_cycles,
            "budget_used": (self.cycles["max"] / self.budget_cycles
                            if self.cycles and self.budget_cycles else None),
            "flash_bytes": self.flash_bytes, "ram_bytes": self.ram_bytes,
            "covers_motion": self.covers_motion, "first_move": self.run.first_move,
            "ok": self.fits and self.agrees and self.covers_motion,
        }


def run_pil(scn: Scenario, target: str, precision: str = "float32",
            compensated: bool | None = None, steps: int | None = None,
            stop_over_budget: bool = False,
            progress: Callable[[int], None] | None = None) -> PilReport:
    """Generate, build and run ``scn``'s controller on ``target`` in lockstep with the twin.

    Parameters
    ----------
    scn : Scenario
        One-joint scenario whose kinds have C.
    target : {"avr", "cortex-m0plus", "cortex-m4", "host"}
        The emulated chip.
    precision : {"float32", "float64"}
        Of the generated code.
    compensated : bool, optional
        Observer sums (default: compensated for float32).
    steps : int, optional
        Samples to run (default: the whole run).
    stop_over_budget : bool
        End the run at the first step that takes more than one sample period (the
        report then says it does not fit without running the rest).
    progress : callable, optional
        Called with the samples done, every 100 samples.

    Returns
    -------
    PilReport

    Raises
    ------
    esoarm.codegen.CodegenError
        The scenario, target or precision cannot be generated.
    esoarm.hardware.hil.build.ToolchainMissing
        A compiler or emulator is not installed.
    """
    gen = generate(scn, target, precision, compensated)
    chip = open_chip(gen)
    clock = float(getattr(chip, "clock_hz", 0.0))
    budget = round(clock * scn.sample_time)

    def over(k: int, c: Chip) -> bool:
        return bool(budget) and bool(c.cycles) and c.cycles[-1] > budget

    try:
        run = lockstep(scn, chip, steps, progress=progress,
                       stop=over if stop_over_budget else None)
    finally:
        chip.close()
    return PilReport(run, gen, chip.timing, clock, budget, chip.flash_bytes, chip.ram_bytes)
