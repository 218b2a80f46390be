"""``esoarm codegen SCENARIO --project stm32 --out DIR``: a firmware project around the C."""

from __future__ import annotations

from pathlib import Path

from esoarm.cli._common import BadInput, note, output_dir, resolve_scenario


def write_project(scenario: str, overrides: tuple[str, ...], project: str, out: str,
                  target: str | None, precision: str | None, plain_sums: bool) -> None:
    """Write the ``project`` (``stm32``) of ``scenario`` into ``out``; bad input exits 2.

    Parameters
    ----------
    scenario : str
        A built-in scenario's name or a TOML file.
    overrides : tuple of str
        ``KEY=VALUE`` items of ``--set``.
    project : str
        The project kind (``stm32``: a register-level Makefile project for the STM32F401RE).
    out : str
        The project's folder.
    target : str, optional
        ``--target``: none or ``cortex-m4``.
    precision : str, optional
        ``--precision``: none or ``float32`` (the FPU is single precision).
    plain_sums : bool
        Sum the observer's increments without compensation.
    """
    from esoarm.codegen import CodegenError
    from esoarm.codegen.stm32_project import write_stm32_project
    from esoarm.scenario import ScenarioError

    if target not in (None, "cortex-m4"):
        raise BadInput(f"--project {project} is for the Cortex-M4F: drop --target {target}")
    if precision == "float64":
        raise BadInput(f"--project {project}: float32 (the STM32F4's FPU is single precision)")
    folder = output_dir(out, "--out")
    scn = resolve_scenario(scenario, overrides)
    try:
        paths = write_stm32_project(scn, Path(folder), False if plain_sums else None)
    except (CodegenError, ScenarioError) as exc:
        raise BadInput(str(exc)) from None
    note(f"wrote the STM32F401RE project of scenario '{scn.name}' into {folder} "
         f"({len(paths)} files): build it with 'make -C {folder}'")
