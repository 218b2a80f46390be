"""Commissioning a rig in one command (``esoarm commission``): excite, identify, design,
generate, flash, run on board, and one report of predicted against measured."""

from esoarm.studies.commission.steps import (
    AGREEMENT,
    STEPS,
    Commission,
    CommissionOptions,
    CommissionRefused,
    check_options,
)

__all__ = ["AGREEMENT", "STEPS", "Commission", "CommissionOptions", "CommissionRefused",
           "check_options"]
