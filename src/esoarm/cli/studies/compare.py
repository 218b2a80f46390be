"""``esoarm compare``: the ADRC forms side by side on one scenario (twin, seeded)."""

from __future__ import annotations

import json
import math

import click

from esoarm.cli._common import (
    BadInput,
    RunFailure,
    bad_input_guard,
    resolve_scenario,
    scenario_argument,
    set_option,
)

_DEFAULT_FORMS = "eso+flc,half-gain,adrc-tf,adrc-error,pid,pid+eso"


@click.command()
@scenario_argument
@set_option
@click.option("--kinds", "forms", default=_DEFAULT_FORMS, show_default=True,
              help="Comma-separated forms: eso+flc (the paper's ESO + FLC), half-gain, "
              "delay-input, delay-predictor (told actuator.delay_samples), "
              "delay-predictor+preview (also the reference's moves started N·Ts earlier), "
              "delay-model+preview (the same with observer.delay_form = 'model' on the "
              "'current' ESO; give the friction with --set observer.model_coulomb=...), "
              "adrc-tf, adrc-error, pid, pid+eso.")
@click.option("--seeds", type=click.IntRange(1, 64), default=4, show_default=True,
              help="Noise seeds per form (sensor.seed 0 … N−1); means are reported.")
@click.option("--delays", default=None,
              help="Also find the largest actuator.delay_samples each form holds (RMS error ≤ "
              "2× the paper's ESO without delay), over these delays, e.g. 0:12 or 0,2,4,8.")
@click.option("--chip", type=click.Choice(["avr", "cortex-m4"]), default=None,
              help="Also run each form's generated C on this emulated chip (esoarm pil): "
              "median and max cycles (AVR) or instructions (Cortex-M4) per step, flash, RAM.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@bad_input_guard
def compare(scenario: str, overrides: tuple[str, ...], forms: str, seeds: int,
            delays: str | None, chip: str | None, as_json: bool) -> None:
    """Run the ADRC forms on SCENARIO: RMS error and RMS Δu, means over the seeds.

    A form is a set of scenario keys on top of SCENARIO and --set: the controller kinds
    with their own ESO take the observer's ε, discretization and tuning, so every form
    observes with the same bandwidth.  With --delays, the largest transport delay each
    form holds is searched (batch engine).
    """
    from esoarm.studies.adrc.compare import FORMS, delay_tolerance, on_chip
    from esoarm.studies.adrc.compare import compare as run_compare

    names = [f.strip() for f in forms.split(",") if f.strip()]
    bad = [f for f in names if f not in FORMS]
    if bad or not names:
        raise BadInput(f"--kinds: unknown form {', '.join(bad) or '(none)'}; allowed: "
                       f"{', '.join(FORMS)}")
    ds: list[int] | None = None
    if delays is not None:
        try:
            if ":" in delays:
                lo, hi = (int(x) for x in delays.split(":"))
                ds = list(range(lo, hi + 1))
            else:
                ds = [int(x) for x in delays.split(",")]
        except ValueError:
            raise BadInput(f"--delays: {delays!r} is not N:M or a comma-separated list of "
                           "integers") from None
        if not ds or ds[0] != 0 or any(b <= a for a, b in zip(ds, ds[1:], strict=False)) \
                or ds[-1] > 200:
            raise BadInput("--delays: increasing delays from 0, at most 200 samples")
    scn = resolve_scenario(scenario, overrides)
    seed_list = list(range(seeds))
    try:
        rows = run_compare(scn, names, seed_list)
        held = None
        if ds is not None:
            yard, held, _ = delay_tolerance(scn, names, ds, seed_list[:2])
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    chips = None
    if chip is not None:
        from esoarm.codegen import CodegenError
        from esoarm.hardware.hil.build import ToolchainMissing

        try:
            chips = {c.form: c for c in on_chip(scn, names, chip)}
        except CodegenError as exc:
            raise BadInput(str(exc)) from None
        except (ToolchainMissing, RuntimeError) as exc:
            raise RunFailure(f"{chip}: {exc}") from None
    if as_json:
        data = {"scenario": scn.name, "seeds": seeds,
                "forms": [{"form": r.form,
                           **{k: (v if math.isfinite(v) else None) for k, v in
                              (("rms_error", r.rms_error), ("rms_du", r.rms_du),
                               ("rms_u", r.rms_u), ("diverged", r.diverged))},
                           **({"delay_held": held[r.form]} if held is not None else {}),
                           **({"chip": {"target": chip, "median": chips[r.form].median,
                                        "max": chips[r.form].maximum,
                                        "flash_bytes": chips[r.form].flash,
                                        "ram_bytes": chips[r.form].ram,
                                        "max_rel_du": chips[r.form].max_rel_du}}
                              if chips is not None else {})}
                          for r in rows]}
        click.echo(json.dumps(data))
        return
    click.echo(f"scenario '{scn.name}', means over {seeds} seed(s)")
    from esoarm.kinds import units

    un = units(scn)  # rad and N·m; m and N on a prismatic axis; rad/s and V on a DC motor
    head = (f"{'form':<24} {f'RMS error [{un.position}]':>16} {f'RMS Δu [{un.force}]':>13} "
            f"{f'RMS u [{un.force}]':>12}")
    if held is not None:
        head += f" {'delay held':>11}"
    if chips is not None:
        unit = "cycles" if chip == "avr" else "instr."
        head += f" {f'{chip} median/max {unit}':>28} {'flash [B]':>10} {'RAM [B]':>8}"
    click.echo(head)
    for r in rows:
        line = f"{r.form:<24} {r.rms_error:>16.5f} {r.rms_du:>13.4f} {r.rms_u:>12.4f}"
        if held is not None:
            h = held[r.form]
            line += f" {('none' if h < 0 else str(h)):>11}"
        if chips is not None:
            c = chips[r.form]
            line += f" {f'{c.median} / {c.maximum}':>28} {c.flash:>10} {c.ram:>8}"
        if r.diverged:
            line += f"  ({100 * r.diverged:.0f} % of the runs diverged)"
        click.echo(line)
