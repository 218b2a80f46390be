"""Streaming engine: one long run in blocks of samples, in memory that does not grow with it.

The reference engine (:mod:`esoarm.engines.simulation`) keeps the whole log, the
sample times, the reference and the noise of a run: about 200 bytes per sample,
13.7 GB for the documented maximum of 10⁸ samples.  Here the run is cut into
blocks of :data:`BLOCK` samples; each block's reference, noise and log are made,
used and dropped, while the state that carries from one sample to the next (the
plant's x, the observer's z, the controller's c, the drives still in the transport
delay) is carried from block to block.  The metrics are accumulated as the blocks
go (:class:`_Sums`), and each block's rows can be handed to a sink (the CSV writer
of ``esoarm simulate --out``).

Each sample is the one of :func:`esoarm.engines.loop.closed_loop` -- the same
sample functions of :mod:`esoarm.engines.sample`, the same arithmetic, so the
same bits (tested): only the arrays are indexed within the block.  Where the
scenario's kinds compile (``JIT``), a block runs compiled (numba, cached on
disk like the batch kernels); otherwise it runs as plain Python with the kinds'
own step functions.

The metrics equal the reference engine's to round-off: the sums of squares are
taken per block in NumPy's pairwise order and the block sums added exactly
(:func:`math.fsum`), where the reference sums the whole run pairwise.
"""

from __future__ import annotations

import math
import signal
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from esoarm import _limits
from esoarm.engines.metrics import (
    ERR,
    METRICS,
    NROW,
    OM,
    SAT,
    Z2,
    Z3,
    F,
    MetricsTable,
    U,
    combine_joints,
)
from esoarm.engines.sample import Sampling
from esoarm.engines.stream.block import stream_block
from esoarm.plants.noise import NoiseStream, noise_model
from esoarm.reference import reference_rows
from esoarm.result import SimResult
from esoarm.scenario import Scenario

__all__ = ["BLOCK", "PYTHON_BLOCK", "STREAM_SAMPLES", "StreamInterrupted", "StreamedRun",
           "stream", "stream_block", "streamed_metrics", "with_long_runs", "worth_compiling"]

#: Samples per block when the block runs compiled (~0.1 s at 1-2 µs per sample).
BLOCK = 1 << 16
#: Samples per block when it runs as plain Python (~0.4 s at ~100 µs per sample): Ctrl-C
#: and the progress display act between blocks.
PYTHON_BLOCK = 1 << 12
#: ``esoarm simulate`` streams runs of more samples than this (memory: the reference engine
#: keeps ~200 bytes per sample; time: the compiled blocks are ~50 times quicker).
STREAM_SAMPLES = _limits.STREAM_SAMPLES


# ---------------------------------------------------------------------------
# metrics accumulated block by block


class _Sums:
    """Per joint: the sums, maxima and counts behind :data:`esoarm.engines.metrics.METRICS`."""

    _SQUARES = ("rms_error", "rms_u", "rms_f_error", "rms_rate_error", "rms_du")

    def __init__(self, joints: int) -> None:
        self.joints = joints
        self.parts: list[dict[str, list[float]]] = [
            {name: [] for name in (*self._SQUARES, "saturated")} for _ in range(joints)]
        self.peak = [{"max_abs_error": -math.inf, "max_abs_u": -math.inf}
                     for _ in range(joints)]
        self.last_u: list[float | None] = [None] * joints
        self.n = 0

    def add(self, log: np.ndarray) -> None:
        """Add the rows of a block's log (columns = samples, in order)."""
        m = log.shape[1]
        if m == 0:
            return
        for j in range(self.joints):
            r = j * NROW
            e, u = log[r + ERR], log[r + U]
            part = self.parts[j]
            part["rms_error"].append(float(np.sum(e**2)))
            part["rms_u"].append(float(np.sum(u**2)))
            part["rms_f_error"].append(float(np.sum((log[r + Z3] - log[r + F]) ** 2)))
            part["rms_rate_error"].append(float(np.sum((log[r + Z2] - log[r + OM]) ** 2)))
            du = np.diff(u)
            last = self.last_u[j]
            part["rms_du"].append(float(np.sum(du**2))
                                  + (0.0 if last is None else (float(u[0]) - last) ** 2))
            part["saturated"].append(float(np.sum(log[r + SAT])))
            self.last_u[j] = float(u[-1])
            peak = self.peak[j]
            peak["max_abs_error"] = max(peak["max_abs_error"], float(np.max(np.abs(e))))
            peak["max_abs_u"] = max(peak["max_abs_u"], float(np.max(np.abs(u))))
        self.n += m

    def metrics(self, diverged: bool) -> tuple[dict[str, float], list[dict[str, float]]]:
        """The run's metrics and each joint's (as :func:`esoarm.engines.metrics.series_metrics`)."""
        n = self.n
        joints = []
        for j in range(self.joints):
            out = dict.fromkeys(METRICS, math.nan)
            out["samples"] = float(n)
            out["diverged"] = 1.0 if diverged else 0.0
            if n:
                part = self.parts[j]
                for name in ("rms_error", "rms_u", "rms_f_error", "rms_rate_error"):
                    out[name] = math.sqrt(math.fsum(part[name]) / n)
                out["rms_du"] = math.sqrt(math.fsum(part["rms_du"]) / (n - 1)) if n > 1 else 0.0
                out["saturated_fraction"] = math.fsum(part["saturated"]) / n
                out.update(self.peak[j])
            joints.append(out)
        return combine_joints(joints), joints


# ---------------------------------------------------------------------------
# the run


@dataclass(frozen=True)
class StreamedRun:
    """The outcome of a streamed run: its metrics, not its series.

    Attributes
    ----------
    scenario : Scenario
        The scenario run.
    metrics : dict of str to float
        :data:`esoarm.engines.metrics.METRICS` over every sample (and joint).
    joint_metrics : tuple of dict
        Each joint's metrics (one entry for one joint).
    joint_names : tuple of str
        An arm's joint names (empty for one joint).
    samples : int
        Samples run.
    diverged : bool
        The run left the finite range (it stopped there).
    compiled : bool
        The blocks ran compiled (numba); False: as plain Python.
    series : SimResult or None
        Every ``stride``-th sample (k = 0, stride, …) when asked for (``figure_rows``), with
        the run's metrics; for a figure.
    stride : int
        Samples per row of ``series``.
    """

    scenario: Scenario
    metrics: dict[str, float]
    joint_metrics: tuple[dict[str, float], ...]
    joint_names: tuple[str, ...] = ()
    samples: int = 0
    diverged: bool = False
    compiled: bool = False
    series: SimResult | None = field(default=None, repr=False)
    stride: int = 1

    def summary(self) -> dict[str, Any]:
        """Metrics plus the identifying settings, JSON-ready (as :meth:`SimResult.summary`).

        Returns
        -------
        dict
            The same keys as :meth:`esoarm.result.SimResult.summary`.
        """
        from esoarm.result import JOINT_KEYS, run_settings

        out = {**run_settings(self.scenario), **self.metrics, "samples": self.samples}
        if self.joint_names:
            out["joints"] = [{"name": name, **{k: m[k] for k in JOINT_KEYS}}
                             for name, m in zip(self.joint_names, self.joint_metrics,
                                                strict=True)]
        return out


class StreamInterrupted(KeyboardInterrupt):
    """Ctrl-C during a streamed run: it stopped after ``samples`` samples (all handed on)."""

    def __init__(self, samples: int, t_end: float) -> None:
        super().__init__()
        self.samples = samples
        self.t_end = t_end


class _Noise:
    """The run's noise draws, block by block: the values of :func:`esoarm.plants.noise.draws`."""

    def __init__(self, scn: Scenario, joints: int) -> None:
        model = noise_model(scn)
        self.joints = joints
        self.zero = model.white and not model.sigma > 0.0
        self.white = model.white
        self.rng = np.random.default_rng(scn.sensor.seed)
        self.stream = None if model.white else NoiseStream(model, scn.sensor.seed, joints)

    def block(self, m: int, off: int) -> np.ndarray:
        out = np.zeros((off + m) * self.joints)
        if self.zero:
            return out
        if self.white:
            out[off * self.joints:] = self.rng.standard_normal(m * self.joints)
        else:
            assert self.stream is not None
            nxt = self.stream.next
            out[off * self.joints:] = [nxt() for _ in range(m * self.joints)]
        return out


def _compiled_runner(scn: Scenario, inp: Any) -> Callable[..., int] | None:
    """The compiled block for these inputs, or None where the kinds do not compile.

    In a process that has not loaded numba yet, the block is compiled (the first
    time) by a child process and loaded here from numba's cache
    (:mod:`esoarm.engines.stream.prepare`: compiling peaks far above loading).
    """
    if not inp.kinds.jit:
        return None
    from esoarm.engines.stream import prepare

    try:
        selected = prepare.apart(scn, inp)
    except KeyboardInterrupt:
        raise StreamInterrupted(0, 0.0) from None
    if selected:
        from esoarm import kinds as _kinds

        _kinds.compile_only([inp.kinds])
    from esoarm.engines.stream import kernels

    return kernels.runner(inp)


class _SigintFlag:
    """Ctrl-C sets a flag (checked between blocks) instead of raising mid-block; a second
    Ctrl-C raises KeyboardInterrupt at once."""

    def __init__(self) -> None:
        self.hit = False
        self._old: Any = None

    def __enter__(self) -> _SigintFlag:
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._set)
        return self

    def _set(self, signum: int, frame: Any) -> None:
        if self.hit:  # a second Ctrl-C: at once (a block being compiled takes a minute)
            raise KeyboardInterrupt
        self.hit = True

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


def stream(scn: Scenario, *, sink: Callable[[SimResult], None] | None = None,
           progress: Callable[[int], None] | None = None, compiled: bool | None = None,
           block: int | None = None, figure_rows: int = 0) -> StreamedRun:
    """Run ``scn`` block by block; memory stays flat whatever the number of samples.

    Parameters
    ----------
    scn : Scenario
        A validated scenario.
    sink : callable, optional
        Called with each block's rows as a :class:`~esoarm.result.SimResult` (t_k the
        run's), in order; e.g. a CSV writer.
    progress : callable, optional
        Called with the samples of each block once it is done.
    compiled : bool, optional
        Run the blocks compiled (default: where the scenario's kinds compile); False:
        plain Python.
    block : int, optional
        Samples per block (default :data:`BLOCK` compiled, :data:`PYTHON_BLOCK` Python).
    figure_rows : int
        Keep at most about this many evenly spaced samples for a figure
        (:attr:`StreamedRun.series`); 0 keeps none.

    Returns
    -------
    StreamedRun
        The metrics (equal to the reference engine's to round-off).

    Raises
    ------
    esoarm.engines.simulation.SimulationDiverged
        The state left the finite range; its ``result`` holds the rows of the last block
        (the earlier ones went to ``sink``), its ``metrics`` those of the whole run.
    StreamInterrupted
        Ctrl-C: the run stopped at the end of a block; every row up to it went to ``sink``.
    """
    from esoarm.engines.sample import steps_of
    from esoarm.engines.simulation import (
        SimulationDiverged,
        diverged_message,
        joint_limits,
        prepare_designs,
    )

    inp = prepare_designs(scn)
    n = scn.n_samples
    nj = inp.plant.n_joints
    runner = _compiled_runner(scn, inp) if compiled is not False else None
    if compiled and runner is None:
        raise ValueError(f"the kinds of '{scn.name}' do not compile")
    m_block = max(int(block or (BLOCK if runner else PYTHON_BLOCK)), inp.delay + 1, 1)
    limits = joint_limits(scn, inp.kinds)
    nz, nc = max(inp.observer.n_state, 1), max(inp.controller.n_state, 1)
    work = [np.empty(nj) for _ in range(8)] + [np.zeros(nz), np.zeros(nz), np.zeros(nc)]
    hist = np.zeros((inp.delay + m_block) * nj)
    x = np.array(inp.plant.x0, dtype=float)
    sg = Sampling(n, inp.ts, inp.h, inp.nsub, inp.delay, inp.sigma, inp.q)
    d, steps = inp.designs, steps_of(inp.kinds)
    noise = _Noise(scn, nj)
    sums = _Sums(nj)
    names = _joint_names(scn, nj)
    k0 = 0
    stride = max(1, math.ceil(n / figure_rows)) if figure_rows > 0 else 0
    kept: list[np.ndarray] = []
    with _SigintFlag() as sigint:
        while k0 < n:
            if sigint.hit:
                raise StreamInterrupted(k0, k0 * inp.ts)
            m = min(m_block, n - k0)
            off = 0 if k0 == 0 else 1
            if k0:  # the last `delay` drives of the previous block to the front
                end = (m_block if k0 == m_block else m_block + inp.delay) * nj
                hist[: inp.delay * nj] = hist[end - inp.delay * nj: end]
            t = np.arange(k0 - off, k0 + m) * inp.ts
            refs = np.ascontiguousarray(reference_rows(scn.reference, t, nj, limits))
            log = np.full((NROW * nj, off + m), np.nan)
            args: tuple[Any, ...] = (log, x, noise.block(m, off), refs, k0, off, m, *work, hist)
            try:
                rows = (runner(*args) if runner is not None
                        else stream_block(*args, sg, d, steps))  # type: ignore[call-arg]
            except (ArithmeticError, ValueError):  # out of range inside a step
                rows = -max(int((~np.isnan(log[SAT, off:])).sum()), 1)
            done = abs(rows)
            part = SimResult.from_log(scn, t[off: off + done], log[:, off: off + done],
                                      diverged=rows < 0)
            sums.add(log[:, off: off + done])
            if rows < 0:
                kd = k0 + done - 1
                exc = SimulationDiverged(diverged_message(scn.name, kd * inp.ts, kd, part),
                                         part)
                exc.metrics = sums.metrics(True)[0]  # type: ignore[attr-defined]
                raise exc
            if sink is not None:
                sink(part)
            if stride:
                first = (-k0) % stride
                kept.append(log[:, off + first: off + m: stride].copy())
            k0 += m
            if progress is not None:
                progress(m)
    metrics, joints = sums.metrics(False)
    series = None
    if stride:
        import dataclasses

        every = np.concatenate(kept, axis=1) if kept else np.empty((NROW * nj, 0))
        series = dataclasses.replace(
            SimResult.from_log(scn, np.arange(every.shape[1]) * stride * inp.ts, every),
            metrics=metrics)
    return StreamedRun(scn, metrics, tuple(joints), names, sums.n, False, runner is not None,
                       series, max(stride, 1))


def _joint_names(scn: Scenario, nj: int) -> tuple[str, ...]:
    from esoarm.result import _joint_names as names

    return names(scn, nj) if nj > 1 else ()


def streamed_metrics(scn: Scenario) -> dict[str, float]:
    """:data:`~esoarm.engines.metrics.METRICS` of one run, streamed (a diverged run does not
    raise: its metrics up to the divergence, ``diverged`` = 1).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    dict of str to float
        The run's metrics.
    """
    from esoarm.engines.simulation import SimulationDiverged

    try:
        return stream(scn, compiled=worth_compiling(scn)).metrics
    except SimulationDiverged as exc:
        return dict(exc.metrics)  # type: ignore[attr-defined]


def with_long_runs(run_metrics: Callable[..., MetricsTable], points: Sequence[Scenario],
                   seeds: Sequence[int] | None = None, **kwargs: Any) -> MetricsTable:
    """``run_metrics(points, seeds, **kwargs)``, every run longer than
    :data:`STREAM_SAMPLES` samples streamed instead (:func:`streamed_metrics`).

    An engine's kernel keeps a run's whole log (~90 bytes a sample); a long run here is
    run block by block in constant memory, with the same metrics.  The engines do not
    call this module themselves (it is above them: it runs their step functions), so a
    caller that may meet long runs (a sweep, a tune) routes its engine through here.

    Parameters
    ----------
    run_metrics : callable
        An engine's ``run_metrics(points, seeds, **kwargs)`` (the exact, reference or
        fast engine's), used for the runs that are not long.
    points : sequence of Scenario
        Validated scenarios.
    seeds : sequence of int, optional
        Noise seeds for each point (point-major, seed fastest); default each point's own.
    **kwargs
        Passed on to ``run_metrics``; ``progress`` (if given) is also called with 1 after
        each streamed run.

    Returns
    -------
    MetricsTable
        One row per run, columns :data:`~esoarm.engines.metrics.METRICS`, in the order
        ``run_metrics`` gives.
    """
    long = [scn.n_samples > STREAM_SAMPLES for scn in points]
    if not any(long):
        return run_metrics(points, seeds, **kwargs)
    seed_list: list[int | None] = [None] if seeds is None else [int(s) for s in seeds]
    per = len(seed_list)
    out = np.empty((len(points) * per, len(METRICS)))
    short = [i for i, is_long in enumerate(long) if not is_long]
    if short:
        values = run_metrics([points[i] for i in short], seeds, **kwargs).values
        for j, i in enumerate(short):
            out[i * per:(i + 1) * per] = values[j * per:(j + 1) * per]
    progress = kwargs.get("progress")
    for i, is_long in enumerate(long):
        if not is_long:
            continue
        for k, seed in enumerate(seed_list):
            scn = points[i]
            if seed is not None and seed != scn.sensor.seed:
                scn = scn.with_overrides({"sensor.seed": seed})
            got = streamed_metrics(scn)
            out[i * per + k] = [got[name] for name in METRICS]
            if progress is not None:
                progress(1)
    return MetricsTable(out)


def worth_compiling(scn: Scenario) -> bool | None:
    """None (compiled where the kinds allow it) for a run of more than
    :data:`esoarm._limits.COMPILED_STREAM_SAMPLES` samples, else False (plain Python: compiling
    the block the first time would take longer than the run).

    Parameters
    ----------
    scn : Scenario
        A validated scenario.

    Returns
    -------
    bool or None
        The ``compiled`` argument of :func:`stream`.
    """
    return None if scn.n_samples > _limits.COMPILED_STREAM_SAMPLES else False
