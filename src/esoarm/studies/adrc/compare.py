"""The observer/controller forms of linear ADRC on one scenario, measured on the twin.

A *form* is a named set of scenario keys (:data:`FORMS`): the paper's ESO + FLC, the
half-gain observer, the delay-aware ESO and its predictor, the error-based and the
transfer-function ADRC, the PID alone and with the ESO's compensation.  For each form
:func:`compare` runs the scenario over seeds on the batch engine and reports RMS error and
RMS Δu (means over the seeds); :func:`delay_tolerance` finds the largest transport delay
(``actuator.delay_samples``) whose RMS error stays within ``factor`` × the delay-free run of
the reference form, the delay-aware forms told the delay (``observer.input_delay`` = the
delay).  Everything runs through the registry's kinds: a form is only keys.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from esoarm.scenario import Scenario, load_scenario

__all__ = ["DELAY_AWARE", "FORMS", "PREVIEW", "ChipResult", "FormResult", "compare",
           "delay_tolerance", "form_keys", "on_chip"]

#: The forms by name: the scenario keys each sets.
FORMS: dict[str, dict[str, Any]] = {
    "eso+flc": {},
    "half-gain": {"observer.tuning": "half-gain"},
    "delay-input": {"observer.delay_form": "input"},
    "delay-predictor": {"observer.delay_form": "predictor"},
    "adrc-tf": {"controller.kind": "adrc-tf"},
    "adrc-error": {"controller.kind": "adrc-error"},
    "pid": {"controller.kind": "pid"},
    "pid+eso": {"controller.kind": "pid", "controller.compensation": "eso"},
}

#: Forms told the transport delay (observer.input_delay = actuator.delay_samples).
DELAY_AWARE = ("delay-input", "delay-predictor", "delay-predictor+preview",
               "delay-model+preview")

FORMS["delay-predictor+preview"] = {"observer.delay_form": "predictor"}
#: the model-based predictor on the exact-model ESO (its friction: observer.model_* of --set)
FORMS["delay-model+preview"] = {"observer.delay_form": "model",
                                "observer.discretization": "current"}
#: Forms that see the reference N samples ahead (the moves started N·Ts earlier; the error is
#: measured against the reference itself).
PREVIEW = ("delay-predictor+preview", "delay-model+preview")


def form_keys(form: str, base: Scenario, delay: int = 0) -> dict[str, Any]:
    """The keys of ``form`` on ``base`` with a transport delay of ``delay`` samples.

    The controller kinds with their own ESO take the observer's ε, discretization and
    tuning, so that every form observes with the same bandwidth.

    Parameters
    ----------
    form : str
        A name of :data:`FORMS`.
    base : Scenario
        The scenario the form is applied to.
    delay : int
        actuator.delay_samples [samples].

    Returns
    -------
    dict
        Dotted keys and values.

    Raises
    ------
    ValueError
        If ``form`` is not one of :data:`FORMS`.
    """
    if form not in FORMS:
        raise ValueError(f"form must be one of {', '.join(FORMS)}; got {form!r}")
    keys: dict[str, Any] = {**FORMS[form], "actuator.delay_samples": delay}
    if form in DELAY_AWARE:
        keys["observer.input_delay"] = delay
    if form in PREVIEW and delay:
        moves = getattr(base.reference, "moves", None)
        if moves is None:
            raise ValueError(f"form {form!r} shifts the reference's moves: "
                             f"reference.kind = {base.reference.kind!r} has none")
        lead = delay * base.sample_time
        keys["reference.moves"] = [[t0 - lead, dur, target] for t0, dur, target in moves]
    if keys.get("controller.kind") in ("adrc-tf", "adrc-error"):
        ob = base.observer
        for key in ("eps", "discretization", "tuning"):
            if hasattr(ob, key):
                keys[f"controller.{key}"] = getattr(ob, key)
        if hasattr(base.controller, "k1"):
            keys["controller.k1"] = base.controller.k1
            keys["controller.k2"] = base.controller.k2
    return keys


@dataclass(frozen=True)
class FormResult:
    """One form on one scenario, means over the seeds.

    Attributes
    ----------
    form : str
        The form's name.
    rms_error : float
        RMS tracking error [rad].
    rms_du : float
        RMS of u_k − u_{k−1} [N·m].
    rms_u : float
        RMS command [N·m].
    diverged : float
        Fraction of the runs that diverged.
    """

    form: str
    rms_error: float
    rms_du: float
    rms_u: float
    diverged: float


def _scenario(base: Scenario | str, over: Mapping[str, Any]) -> Scenario:
    return load_scenario(base, dict(over))


def _run(points: Sequence[Scenario], seeds: Sequence[int]) -> np.ndarray:
    from esoarm.engines.batch import run_metrics
    from esoarm.engines.metrics import METRICS

    tab = run_metrics(list(points), list(seeds))
    vals = tab.values.reshape(len(points), len(seeds), len(METRICS))
    return vals


def compare(base: Scenario | str, forms: Sequence[str], seeds: Sequence[int] = (0, 1, 2, 3),
            extra: Mapping[str, Any] | None = None) -> list[FormResult]:
    """Every form of ``forms`` on ``base`` (with ``extra`` keys), means over ``seeds``.

    Parameters
    ----------
    base : Scenario or str
        The scenario (or a built-in name).
    forms : sequence of str
        Names of :data:`FORMS`.
    seeds : sequence of int
        sensor.seed of the runs.
    extra : mapping, optional
        Keys set on every form (e.g. ``{"sensor.noise_deg": 0.5}``).

    Returns
    -------
    list of FormResult
        One per form, in order.
    """
    from esoarm.engines.metrics import METRICS

    scn = _scenario(base, extra or {})
    points = [_scenario(scn, form_keys(f, scn)) for f in forms]
    vals = _run(points, seeds)
    col = {m: i for i, m in enumerate(METRICS)}
    out = []
    for i, f in enumerate(forms):
        v = vals[i]
        ok = v[:, col["diverged"]] == 0.0
        mean = v[ok].mean(axis=0) if ok.any() else np.full(len(METRICS), np.inf)
        out.append(FormResult(f, float(mean[col["rms_error"]]), float(mean[col["rms_du"]]),
                              float(mean[col["rms_u"]]), float(1.0 - ok.mean())))
    return out


def delay_tolerance(base: Scenario | str, forms: Sequence[str], delays: Sequence[int],
                    seeds: Sequence[int] = (0, 1), factor: float = 2.0,
                    reference: str = "eso+flc") -> tuple[float, dict[str, int], np.ndarray]:
    """The largest transport delay each form holds: RMS error ≤ factor × the delay-free run.

    A form holds delay d when its mean RMS error over the seeds (no run diverged) is within
    ``factor`` times the reference form's at delay 0, at d and at every smaller delay of
    ``delays``.

    Parameters
    ----------
    base : Scenario or str
        The scenario (its ε, rate, ...).
    forms : sequence of str
        Names of :data:`FORMS`.
    delays : sequence of int
        Increasing delays [samples], starting at 0.
    seeds : sequence of int
        sensor.seed of the runs.
    factor : float
        The tolerance on the RMS error.
    reference : str
        The form whose delay-free RMS error is the yardstick.

    Returns
    -------
    (float, dict, ndarray)
        The yardstick's RMS error [rad]; per form the largest delay held [samples] (−1: not
        even the first); the mean RMS errors, shape (forms, delays) (inf: a run diverged).
    """
    from esoarm.engines.metrics import METRICS

    scn = _scenario(base, {})
    col = {m: i for i, m in enumerate(METRICS)}
    names = [reference, *forms]
    plain = [f for f in names if f not in PREVIEW]
    points = [_scenario(scn, form_keys(f, scn, d)) for f in plain for d in delays]
    vals = _run(points, seeds).reshape(len(plain), len(delays), len(seeds), len(METRICS))
    err_plain = vals[..., col["rms_error"]].mean(axis=2)
    bad = (vals[..., col["diverged"]] != 0.0).any(axis=2)
    err_plain = np.where(bad, np.inf, err_plain)
    err = np.empty((len(names), len(delays)))
    for i, f in enumerate(names):
        err[i] = (err_plain[plain.index(f)] if f in plain
                  else _preview_errors(scn, f, delays, seeds))
    yard = float(err[0, 0])
    held: dict[str, int] = {}
    for i, f in enumerate(forms, start=1):
        ok = err[i] <= factor * yard
        last = -1
        for j, d in enumerate(delays):
            if not ok[j]:
                break
            last = d
        held[f] = last
    return yard, held, err[1:]


def _preview_errors(scn: Scenario, form: str, delays: Sequence[int],
                    seeds: Sequence[int]) -> np.ndarray:
    """Mean RMS of θ − θd (the scenario's own reference) of ``form`` at each delay."""
    from esoarm.engines.batch import simulate_many
    from esoarm.engines.simulation import SimulationDiverged, prepare

    theta_ref = np.asarray(prepare(scn).theta_ref).ravel()
    out = np.empty(len(delays))
    for j, d in enumerate(delays):
        keys = form_keys(form, scn, d)
        rms = []
        for seed in seeds:
            point = _scenario(scn, {**keys, "sensor.seed": seed})
            try:
                (res,) = simulate_many([point])
            except SimulationDiverged:
                rms.append(math.inf)
                continue
            theta = np.asarray(res.theta).ravel()
            rms.append(float(np.sqrt(np.mean((theta - theta_ref[:len(theta)]) ** 2))))
        out[j] = float(np.mean(rms))
    return out


@dataclass(frozen=True)
class ChipResult:
    """One form's generated controller on an emulated chip (processor in the loop).

    Attributes
    ----------
    form : str
        The form's name.
    median, maximum : int
        Cycles (AVR) or executed instructions (Cortex-M4) per step.
    flash, ram : int
        The PIL image's flash and static RAM [bytes].
    max_rel_du : float
        max |u_chip − u_ref| / torque limit.
    """

    form: str
    median: int
    maximum: int
    flash: int
    ram: int
    max_rel_du: float


def on_chip(base: Scenario | str, forms: Sequence[str], target: str = "avr",
            steps: int | None = None) -> list[ChipResult]:
    """Each form's generated C on ``target`` in lockstep with the twin (``esoarm pil``).

    Parameters
    ----------
    base : Scenario or str
        The scenario.
    forms : sequence of str
        Names of :data:`FORMS`.
    target : {"avr", "cortex-m4"}
        The emulated chip.
    steps : int, optional
        Samples to run (default: the whole run).

    Returns
    -------
    list of ChipResult
        One per form, in order.
    """
    from esoarm.codegen.pil import run_pil

    scn = _scenario(base, {})
    out = []
    for f in forms:
        rep = run_pil(_scenario(scn, form_keys(f, scn)), target, steps=steps)
        data = rep.as_dict()
        out.append(ChipResult(f, int(data["cycles"]["median"]), int(data["cycles"]["max"]),
                              int(data["flash_bytes"]), int(data["ram_bytes"]),
                              float(data["max_rel_du"])))
    return out
