"""Reference engine: one closed-loop run in plain Python, the readable statement of the loop.

:func:`prepare` resolves a scenario into plain arrays and the designs of its
plant, observer and controller kinds (:mod:`esoarm.kinds`);
:func:`run_reference` runs :func:`esoarm.engines.loop.closed_loop` -- the one
sample loop every engine uses -- as ordinary Python with the kinds' step
functions.  The compiled batch engine runs the same loop and is tested
against this one bit for bit.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from esoarm.contract import ComponentDesign, PlantDesign
from esoarm.engines.loop import DIVERGENCE_LIMIT, closed_loop, within_limits
from esoarm.engines.metrics import METRICS, NROW, SAT, MetricsTable
from esoarm.engines.sample import Designs, Sampling, Steps, steps_of
from esoarm.kinds import Kinds, hook, kinds_of
from esoarm.plants.actuator import actuator_vector, motor_refused
from esoarm.plants.noise import draws, noise_model, sequence_scale
from esoarm.reference import reference_rows
from esoarm.result import SimResult
from esoarm.scenario import (
    Scenario,
    ScenarioError,
    ScenarioWarning,
    load_scenario,
    scenario_warnings,
)

__all__ = [
    "reference_metrics",
    "DIVERGENCE_LIMIT",
    "RunInputs",
    "SimulationDiverged",
    "SimulationInterrupted",
    "diverged_message",
    "joint_limits",
    "prepare",
    "prepare_designs",
    "run_reference",
    "simulate",
    "within_limits",
]


class SimulationDiverged(RuntimeError):
    """A run left the finite range; ``result`` holds every row logged before."""

    def __init__(self, message: str, result: SimResult) -> None:
        super().__init__(message)
        self.result = result


class SimulationInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run; ``result`` holds every row logged before (a KeyboardInterrupt)."""

    def __init__(self, result: SimResult) -> None:
        super().__init__()
        self.result = result


@dataclass(frozen=True)
class RunInputs:
    """Everything one run needs, as plain arrays and designs (shared by every engine).

    Attributes
    ----------
    t : ndarray (N,)
        Sample times t_k = k·Ts [s].
    refs : ndarray (3·joints, N)
        θd, θ̇d, θ̈d per joint at t_k [rad, rad/s, rad/s²].
    noise : ndarray (N·joints,)
        The noise sequence (:func:`esoarm.plants.noise.draws`): standard-normal draws n_k for
        white noise (zeros without noise), the disturbance w_k [rad] for coloured noise.
    sigma, q : float
        Scale of the noise sequence (:func:`esoarm.plants.noise.sequence_scale`: the noise
        std dev σ [rad] for white noise, 1 for coloured) and quantization step [rad].
    kinds : Kinds
        The scenario's plant, observer and controller kind modules.
    plant : PlantDesign
        Plant design (parameter vector, initial state, joints, b0).
    observer, controller : ComponentDesign
        Observer and controller designs.
    actuator : ndarray
        :func:`esoarm.plants.actuator.actuator_vector`.
    ts, h : float
        Sample period and RK4 step [s].
    nsub : int
        RK4 steps per sample.
    delay : int
        Transport delay [samples].
    """

    t: np.ndarray
    refs: np.ndarray
    noise: np.ndarray
    sigma: float
    q: float
    kinds: Kinds
    plant: PlantDesign
    observer: ComponentDesign
    controller: ComponentDesign
    actuator: np.ndarray
    ts: float
    h: float
    nsub: int
    delay: int

    @property
    def sampling(self) -> Sampling:
        """Samples, timing and sensor as the sample functions take them."""
        return Sampling(len(self.t), self.ts, self.h, self.nsub, self.delay, self.sigma, self.q)

    @property
    def designs(self) -> Designs:
        """The parameter vectors as the sample functions take them."""
        return Designs(self.plant.b0, self.plant.vector, self.observer.vector,
                       self.controller.vector, self.actuator, self.observer.n_state,
                       self.controller.n_state)

    @property
    def steps(self) -> Steps:
        """The kinds' own step functions (plain Python)."""
        return steps_of(self.kinds)

    @property
    def theta0(self) -> float:
        """Initial angle of joint 0 [rad]."""
        return float(self.plant.x0[0])

    @property
    def theta_ref(self) -> np.ndarray:
        """θd(t_k) of joint 0 [rad]."""
        row: np.ndarray = self.refs[0]
        return row

    @property
    def omega_ref(self) -> np.ndarray:
        """θ̇d(t_k) of joint 0 [rad/s]."""
        row: np.ndarray = self.refs[1]
        return row

    @property
    def accel_ref(self) -> np.ndarray:
        """θ̈d(t_k) of joint 0 [rad/s²]."""
        row: np.ndarray = self.refs[2]
        return row


def prepare(scn: Scenario, *, draw_noise: bool = True) -> RunInputs:
    """Resolve a scenario into the arrays and designs every engine consumes.

    ``draw_noise=False`` leaves ``noise`` empty, for engines that draw the
    noise of each seed once for many runs (:mod:`esoarm.engines.batch`).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.
    draw_noise : bool
        Draw the sensor's standard-normal sequence (N·joints values) for ``sensor.seed``.

    Returns
    -------
    RunInputs
        Sample times [s], reference rows [rad, rad/s, rad/s²], noise, sensor σ and
        quantization step [rad], the kinds and their designs, the actuator vector, timing.

    Raises
    ------
    ScenarioError
        A ``[motor]`` table with a plant kind that does not model a motor.
    """
    n = scn.n_samples
    t = np.arange(n) * scn.sample_time
    bare = prepare_designs(scn)
    refs = reference_rows(scn.reference, t, bare.plant.n_joints, joint_limits(scn, bare.kinds))
    noise = noise_model(scn)
    return RunInputs(
        t=t,
        refs=refs,
        noise=(draws(noise, scn.sensor.seed, n * bare.plant.n_joints, bare.plant.n_joints)
               if draw_noise else np.empty(0)),
        sigma=bare.sigma, q=bare.q, kinds=bare.kinds, plant=bare.plant,
        observer=bare.observer, controller=bare.controller, actuator=bare.actuator,
        ts=bare.ts, h=bare.h, nsub=bare.nsub, delay=bare.delay,
    )


def joint_limits(scn: Scenario, kinds: Kinds) -> tuple[np.ndarray, np.ndarray] | None:
    """The plant kind's joint limits (lower, upper) [rad or m], or None if it has none.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.
    kinds : Kinds
        Its kind modules.

    Returns
    -------
    (ndarray, ndarray) or None
        Lower and upper limits per joint (the ``range`` reference needs them).
    """
    limits = hook(kinds.plant, "joint_limits")  # the documented optional hook
    return None if limits is None else limits(scn)


def prepare_designs(scn: Scenario) -> RunInputs:
    """:func:`prepare` without the per-sample arrays: empty ``t``, ``refs`` and ``noise``.

    For engines that make the sample times, the reference and the noise block by block
    (:mod:`esoarm.engines.stream`); memory does not grow with the run's length.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    RunInputs
        The kinds, their designs, the actuator vector, timing and the sensor's σ and
        quantization step [rad]; ``t``, ``refs`` and ``noise`` empty.

    Raises
    ------
    ScenarioError
        A ``[motor]`` table with a plant kind that does not model a motor.
    """
    ts = scn.sample_time
    kinds = kinds_of(scn)
    if not getattr(kinds.plant, "MOTOR", False) and scn.motor is not None:
        # a plant kind that neither models a motor nor refuses one in its check
        raise ScenarioError(str(motor_refused(scn, kinds.plant.KIND)))
    plant = kinds.plant.design(scn)
    return RunInputs(
        t=np.empty(0),
        refs=np.empty((3 * plant.n_joints, 0)),
        noise=np.empty(0),
        sigma=sequence_scale(noise_model(scn)),
        q=math.radians(scn.sensor.resolution_deg),
        kinds=kinds,
        plant=plant,
        observer=kinds.observer.design(scn, plant, ts),
        controller=kinds.controller.design(scn, plant, ts),
        actuator=actuator_vector(scn),
        ts=ts,
        h=scn.rig.step,
        nsub=scn.substeps,
        delay=scn.actuator.delay_samples,
    )


def simulate(
    scenario: Scenario | str | Path = "test-1",
    overrides: dict[str, Any] | list[str] | None = None,
    *,
    warn: bool = True,
    progress: Callable[[int], None] | None = None,
) -> SimResult:
    """Simulate one closed-loop run with the reference engine (the sampled-data loop).

    Parameters
    ----------
    scenario : Scenario, str or Path
        A scenario, a built-in name or a TOML path.
    overrides : dict or list of str, optional
        Dotted-key overrides, e.g. ``{"observer.eps": 0.05}``.
    warn : bool
        Emit :class:`~esoarm.scenario.ScenarioWarning` for risky settings.
    progress : callable, optional
        Called from a watcher thread, about twice a second, with the number of
        samples logged since the last call (for a progress display).

    Returns
    -------
    SimResult
        Time series and metrics.

    Raises
    ------
    SimulationDiverged
        The state left the finite range; the exception holds the partial result.
    SimulationInterrupted
        Ctrl-C (a KeyboardInterrupt) during the run; it holds the partial result.

    Examples
    --------
    >>> res = simulate("test-1", {"duration": 2.0})
    >>> len(res.t), round(res.metrics["rms_error"], 3) < 0.05
    (100, True)
    >>> res.table().shape  # t, theta, theta_ref, error, u, z1, z2, z3, f_true, y, saturated
    (100, 11)
    """
    scn = load_scenario(scenario, overrides) if overrides or not isinstance(
        scenario, Scenario) else scenario
    if warn:
        for msg in scenario_warnings(scn):
            warnings.warn(msg, ScenarioWarning, stacklevel=2)
    return run_reference(scn, prepare(scn), progress=progress)


def run_reference(scn: Scenario, inp: RunInputs,
                  progress: Callable[[int], None] | None = None) -> SimResult:
    """The closed loop over prepared inputs, as plain Python (one sample at a time).

    ``progress`` (optional) receives the samples logged since its last call, from a
    watcher thread; Ctrl-C raises :class:`SimulationInterrupted` with the rows logged.

    Parameters
    ----------
    scn : Scenario
        The scenario (kept in the result).
    inp : RunInputs
        Its prepared inputs (:func:`prepare`).
    progress : callable, optional
        Called with the number of samples logged since the last call.

    Returns
    -------
    SimResult
        Time series and metrics of the N samples.

    Raises
    ------
    SimulationDiverged
        The state left the finite range; the exception holds the partial result.
    SimulationInterrupted
        Ctrl-C during the run; it holds the partial result.
    """
    n = len(inp.t)
    nj = inp.plant.n_joints
    log = np.full((NROW * nj, n), np.nan)
    x = np.array(inp.plant.x0)
    watcher = _Watcher(log, progress) if progress is not None else None
    try:
        rows = closed_loop(log, x, inp.noise, inp.refs, inp.sampling, inp.designs, inp.steps)
    except (ArithmeticError, ValueError):  # e.g. cos(inf) inside a step: out of range too
        rows = -max(_logged(log), 1)
    except KeyboardInterrupt:
        k = _logged(log)
        raise SimulationInterrupted(
            SimResult.from_log(scn, inp.t[:k], log[:, :k], diverged=False)) from None
    finally:
        if watcher is not None:
            watcher.stop()
    k = abs(rows)
    result = SimResult.from_log(scn, inp.t[:k], log[:, :k], diverged=rows < 0)
    if rows < 0:
        raise SimulationDiverged(
            diverged_message(scn.name, float(inp.t[k - 1]), k - 1, result), result)
    return result


def _logged(log: np.ndarray) -> int:
    """Samples logged so far: the columns are filled in order, unwritten ones all NaN."""
    written = ~np.isnan(log).all(axis=0)
    return int(np.argmin(written)) if not written.all() else log.shape[1]


class _Watcher:
    """A daemon thread reporting the samples logged, about twice a second."""

    def __init__(self, log: np.ndarray, report: Callable[[int], None]) -> None:
        import threading

        self._log, self._report, self._done = log, report, 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _count(self) -> None:
        # the first unwritten column of the saturation flag (0/1 once written): a
        # bisection, the columns fill in order
        row = self._log[SAT]
        lo, hi = self._done, row.shape[0]
        while lo < hi:
            mid = (lo + hi) // 2
            if np.isnan(row[mid]):
                hi = mid
            else:
                lo = mid + 1
        if lo > self._done:
            self._report(lo - self._done)
            self._done = lo

    def _run(self) -> None:
        while not self._stop.wait(0.5):
            self._count()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self._count()


def diverged_message(name: str, tk: float, k: int, result: SimResult | None = None) -> str:
    """The one-line message of a run that left the finite range at sample k (t_k [s]).

    With the partial ``result`` it says which quantity left the range first
    and names the likely causes in the scenario (:mod:`esoarm.engines.diagnosis`).

    Parameters
    ----------
    name : str
        The scenario's name.
    tk : float
        Time t_k of the last logged sample [s].
    k : int
        Index of the last logged sample.
    result : SimResult, optional
        The partial result (rows 0 … k); without it the message is generic.

    Returns
    -------
    str
        One line: where it diverged, what left the range, the likely cause.

    Examples
    --------
    >>> diverged_message("demo", 0.5, 25).startswith(
    ...     "simulation of 'demo' diverged at t = 0.5 s (sample 25): the state left")
    True
    """
    head = f"simulation of '{name}' diverged at t = {tk:.4g} s (sample {k}): "
    from esoarm.kinds import units

    unit = units(result.scenario if result is not None else None).position
    bound = f"|θ|, |ẑ1| < {DIVERGENCE_LIMIT:g} {unit}, all finite"
    if result is None or len(result.t) == 0:
        return (f"{head}the state left the finite range ({bound}); check observer.eps "
                "against the sample rate")
    from esoarm.engines.diagnosis import divergence_causes, what_left

    z = np.asarray(result.z).reshape(len(result.t), -1)
    left = what_left(float(np.ravel(result.theta)[-1]), float(z[-1, 0]), float(z[-1, 1]),
                     float(z[-1, 2]), float(np.ravel(result.u)[-1]), DIVERGENCE_LIMIT,
                     units(result.scenario))
    causes = divergence_causes(result.scenario, DIVERGENCE_LIMIT)
    if causes:
        why = "likely cause: " + causes[0] + (f" (also {'; '.join(causes[1:])})"
                                              if len(causes) > 1 else "")
    else:
        why = ("nothing in the scenario stands out; check observer.eps against the sample "
               "rate, the gains and the disturbance")
    return f"{head}{left} left the finite range ({bound}); {why}"


def reference_metrics(
    points: Sequence[Scenario],
    seeds: Sequence[int] | None = None,
    *,
    progress: Callable[[int], None] | None = None,
    **_ignored: object,
) -> MetricsTable:
    """Metrics of every point (× every seed) from the plain-Python reference engine.

    Same arguments and result as :func:`esoarm.engines.batch.run_metrics`, and
    the same numbers; about 0.1 s per 20 s run, so meant for a handful of runs
    (no compiled kernel to load).

    Parameters
    ----------
    points : sequence of Scenario
        Validated scenarios.
    seeds : sequence of int, optional
        Noise seeds run at every point (seed fastest); default each point's own.
    progress : callable, optional
        Called with 1 after each run.
    **_ignored : object
        The batch engine's other keywords (``workers``, ``chunk``, ...), accepted and unused.

    Returns
    -------
    MetricsTable
        One row per run, columns :data:`esoarm.engines.metrics.METRICS`; a diverged run
        has its partial metrics and ``diverged`` = 1.
    """
    if seeds is None:
        runs = [scn for scn in points]
    else:
        runs = [scn.with_overrides({"sensor.seed": int(s)}) if s != scn.sensor.seed else scn
                for scn in points for s in seeds]
    out = np.empty((len(runs), len(METRICS)))
    for i, scn in enumerate(runs):
        try:
            res = run_reference(scn, prepare(scn))
        except SimulationDiverged as exc:  # the partial run's metrics, diverged = 1
            res = exc.result
        out[i] = [res.metrics[name] for name in METRICS]
        if progress is not None:
            progress(1)
    return MetricsTable(out)
