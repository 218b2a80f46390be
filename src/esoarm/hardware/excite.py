"""Run an identification experiment (``esoarm excite``) on a rig or on the twin.

On a rig the experiment goes through :func:`esoarm.hardware.realtime.run_rig` with an
:class:`~esoarm.studies.identification.experiment.excitation.ExcitationController` in
place of the FLC, so it has every safety check of ``esoarm run`` (torque limit, angle limit, encoder
jump, watchdog, NaN guard, STOP on any fault) and the same streamed, flushed log.

On the twin (:func:`excite_twin`) the same controller drives the emulator's
device-side model (:class:`~esoarm.hardware.emulator.Twin`: the rig, actuator
lag and delay, encoder noise and counts, the optional motor) sample by sample,
with the same angle and torque checks, and writes the same columns plus the
true angle ``theta_true``.  The run is deterministic: noise from
``sensor.seed``, tone phases from the plan's seed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from esoarm.hardware.emulator import Twin
from esoarm.hardware.host_control import SampleController
from esoarm.hardware.realtime import LOG_COLUMNS, RunSummary, SafetyLimits, _LogWriter, _Stop
from esoarm.scenario import Scenario
from esoarm.studies.identification.experiment.excitation import ExcitationController, ExcitationPlan

__all__ = ["TWIN_LOG_COLUMNS", "ExcitationFault", "ExcitationInterrupted", "excite_twin",
           "finish_log"]

#: Columns of a twin excitation log: those of ``esoarm run`` plus the true angle [rad].
TWIN_LOG_COLUMNS = (*LOG_COLUMNS, "theta_true")


class ExcitationFault(RuntimeError):
    """The twin experiment hit a safety limit or its log failed; the log keeps every row written."""

    def __init__(self, message: str, summary: RunSummary) -> None:
        super().__init__(message)
        self.summary = summary


class ExcitationInterrupted(ExcitationFault):
    """Ctrl-C during the twin experiment; the message says how many rows were kept and where."""


def excite_twin(scn: Scenario, plan: ExcitationPlan | None, log_path: Path | None = None,
                limits: SafetyLimits | None = None,
                controller: SampleController | None = None,
                ) -> tuple[RunSummary, dict[str, float]]:
    """Run the experiment on the digital twin of ``scn``.

    Parameters
    ----------
    scn : Scenario
        The twin (rig, sensor, actuator, optional motor) and the observer.
    plan : ExcitationPlan or None
        The experiment (None with ``controller``).
    log_path : Path, optional
        CSV log (:data:`TWIN_LOG_COLUMNS`), one flushed row per sample.
    limits : SafetyLimits, optional
        Angle limit [rad] and encoder-jump limit [rad] as on a rig.
    controller : optional
        Another per-sample controller with the same interface, e.g. the
        scenario's ESO + FLC (:class:`~esoarm.hardware.host_control.DeploymentController`):
        the twin then logs a closed-loop run exactly as ``esoarm run`` would.

    Returns
    -------
    summary : RunSummary
        Rows logged, RMS of u [N·m].
    preview : dict
        ``max_abs_theta`` [rad], ``rms_u`` [N·m], ``saturated`` (fraction of samples);
        with a :class:`~esoarm.studies.identification.experiment.probe.ProbingExcitation` also
        ``probe``, its :class:`~esoarm.studies.identification.experiment.probe.ProbeReport`, which
        is then written as the log's first line as well (:func:`finish_log`).

    Raises
    ------
    ExcitationFault
        The measured angle left ±angle_limit, or the log could not be written (a
        full disk); the log keeps the rows written, each whole.
    """
    limits = limits or SafetyLimits()
    ctl: SampleController = (controller if controller is not None
                             else ExcitationController(scn, plan))  # type: ignore[arg-type]
    twin = Twin(scn)
    motor = twin.motor
    log = _LogWriter(log_path, TWIN_LOG_COLUMNS)
    n = ctl.n_samples
    u_log = np.zeros(n)
    theta_max = 0.0
    saturated = 0
    fmt = repr
    summary = RunSummary(mode="twin", log=str(log_path) if log_path else "")
    message = log_failed = None
    interrupted = False
    try:
        for k in range(n):
            theta = twin.theta
            y = twin.q * twin.count()
            if abs(y) > limits.angle_limit:
                message = (f"angle limit: measured θ = {y:.4g} rad at sample {k} "
                           f"(limit ±{limits.angle_limit:g} rad)")
                break
            u = ctl.step(k, y)
            z1, z2, z3 = ctl.zhat
            if motor is None:
                duty = "nan"
                u_applied = u
                twin.advance(u)
            else:
                d = motor.torque_to_duty(u, z2)
                duty = str(d)
                u_applied = motor.duty_to_torque(d, z2)
                twin.advance(twin.torque_of_duty(d))
            ctl.commit(u_applied)
            saturated += abs(u) >= ctl.torque_limit
            u_log[k] = u_applied
            theta_max = max(theta_max, abs(theta))
            ref = ctl.reference(k)
            try:
                log.write(f"{fmt(ctl.t[k])},{fmt(y)},{fmt(ref)},{fmt(y - ref)},{fmt(u_applied)},"
                          f"{fmt(z1)},{fmt(z2)},{fmt(z3)},{k},nan,nan,nan,0,{duty},{fmt(y)},"
                          f"{fmt(theta)}\n")
            except _Stop as exc:  # the log cannot be written (a full disk): stop, keep the rows
                log_failed = str(exc)
                break
    except KeyboardInterrupt:  # between two rows or inside one: the file ends at a whole row
        interrupted = True
    finally:
        log.close()
    rows = log.rows
    report = _finish(ctl, log_path if rows else None)
    summary.samples = rows
    if rows:
        summary.rms_u = float(np.sqrt(np.mean(u_log[:rows] ** 2)))
    preview: dict[str, Any] = {"max_abs_theta": theta_max, "rms_u": summary.rms_u,
                               "saturated": saturated / max(rows, 1)}
    if report is not None:
        preview["probe"] = report
    if interrupted:
        where = (f"the {rows:,} rows logged ({rows / scn.sensor.rate_hz:.4g} s of "
                 f"{n / scn.sensor.rate_hz:.4g} s) are in {log_path}, each row whole" if log_path
                 else "nothing logged")
        raise ExcitationInterrupted(f"twin experiment stopped at sample {rows:,} of {n:,}; "
                                    f"{where}", summary)
    if log_failed is not None:
        raise ExcitationFault(f"{log_failed}; {rows} rows kept", summary)
    if message is not None:
        kept = f"; {rows} rows in {log_path}" if log_path else ""
        raise ExcitationFault(f"{message}: motor off{kept}", summary)
    if not math.isfinite(summary.rms_u):
        summary.rms_u = 0.0
    return summary, preview


def finish_log(controller: object, log_path: Path | None) -> Any:
    """The probe's report of ``controller`` (None if it has none), written into the log's header.

    Called after a run on the twin or on a rig, whether it ended, faulted or was
    interrupted: the header then says what was measured up to the last row.
    """
    return _finish(controller, log_path)


def _finish(controller: object, log_path: Path | None) -> Any:
    finish = getattr(controller, "finish", None)
    if finish is None:
        return None
    report = finish()
    if log_path is not None and Path(log_path).exists():
        from esoarm.studies.identification.experiment.probe import write_header

        try:
            write_header(log_path, report)
        except OSError:
            pass  # the rows are kept as they are; only the summary line is missing
    return report
