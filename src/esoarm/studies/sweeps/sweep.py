"""Parameter sweeps: grids of scenarios × noise seeds on the compiled batch engine.

A sweep varies dotted scenario keys over value lists (``--vary KEY=SPEC``) and
runs the cross product of all of them, in the order given (first key slowest),
each grid point with ``sensor.seed`` = 0 … K−1 (seed fastest).  SPEC is

* a comma list ``0.05,0.09,0.2`` (each item a TOML value, else a string:
  ``euler,zoh,current``),
* ``lin:START:STOP:NUM`` -- ``numpy.linspace(START, STOP, NUM)``,
* ``geom:START:STOP:NUM`` -- ``numpy.geomspace(START, STOP, NUM)``.

Only metrics are kept (:data:`esoarm.engines.metrics.METRICS`), so memory does not grow
with runs × samples.  The work is cut into chunks of whole grid points; chunks
run in this process on all cores (numba threads) or, given a scheduler
address, as tasks on a Dask distributed cluster.  Every run is independent and
deterministic, so the results are identical whatever the backend, the
chunking and the number of workers.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from esoarm.engines.metrics import MetricsTable, NoiseCache
from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.sweeps.grid import SweepGrid, VarySpec, build_grid, parse_vary
from esoarm.studies.sweeps.output import SweepResult, SweepWriter

__all__ = [
    "ENGINES",
    "SweepGrid",
    "SweepResult",
    "SweepWriter",
    "VarySpec",
    "build_grid",
    "iter_sweep",
    "parse_vary",
    "run_sweep",
]

#: Default runs per chunk in this process (about 1-2 s of work on 2 cores).
LOCAL_CHUNK = 1024
#: Default runs per Dask task.
DASK_CHUNK = 256
#: How long to try reaching a Dask scheduler.
CONNECT_TIMEOUT = "10s"


# ---------------------------------------------------------------------------
# running


def _chunks(grid: SweepGrid, chunk_runs: int) -> list[tuple[int, int]]:
    """Point ranges [start, stop) holding about ``chunk_runs`` runs each."""
    per_point = max(len(grid.seeds), 1)
    size = max(1, chunk_runs // per_point)
    n = len(grid.points)
    return [(i, min(i + size, n)) for i in range(0, n, size)]


_CHUNK_LOCK = threading.Lock()

#: Engines a sweep (or a tuning run) can use: "exact" (the default, bit-identical
#: to the reference engine) and "fast" (vectorized, agrees to round-off; see
#: :mod:`esoarm.engines.fast`).
ENGINES: tuple[str, ...] = ("exact", "fast")


#: Up to this many runs the exact engine runs on the reference loop (same
#: numbers): loading numba and the compiled kernels costs more than the runs.
#: Measured, whole commands (test-1, 20 s runs, tanh/cos in C): 4 runs 0.65 s on
#: the reference loop against 0.80 s compiled; 8 runs 1.00 s against 0.77 s.
REFERENCE_RUNS = 5


def _same_bits(scn: Scenario) -> bool:
    """The compiled engine gives the reference engine's bits for ``scn``'s kinds.

    Not for a URDF arm (Pinocchio in the reference engine, the compiled rigid body in
    the batch engine: equal to rounding), whose sweeps always use the compiled
    engine, so that a run's row does not depend on the size of the sweep.
    """
    from esoarm.kinds import kinds_of

    return all(getattr(kind, "COMPILED_EXACT", True) for kind in kinds_of(scn))


def _run_exact(points: Sequence[Scenario], seeds: Sequence[int] | None = None,
               **kwargs: Any) -> MetricsTable:
    from esoarm.engines.stream import with_long_runs  # a long run: in constant memory

    runs = len(points) * (len(seeds) if seeds is not None else 1)
    if runs <= REFERENCE_RUNS and all(_same_bits(scn) for scn in points):
        from esoarm.engines.simulation import reference_metrics  # no compiled kernel to load

        return with_long_runs(
            lambda pts, sds, **kw: reference_metrics(pts, sds, progress=kw.get("progress")),
            points, seeds, **kwargs)
    from esoarm.engines.batch import run_metrics

    return with_long_runs(run_metrics, points, seeds, **kwargs)


def metrics_runner(engine: str = "exact") -> Callable[..., MetricsTable]:
    """The ``run_metrics`` function of an engine (``"exact"`` or ``"fast"``).

    "exact" is :func:`esoarm.engines.batch.run_metrics`, except that a call of
    at most :data:`REFERENCE_RUNS` runs uses the reference engine (identical
    numbers, no compiled kernel to load).

    Parameters
    ----------
    engine : {"exact", "fast"}
        A name of :data:`ENGINES`.

    Returns
    -------
    callable
        ``run_metrics(points, seeds, *, workers, ...)`` giving a
        :class:`~esoarm.engines.metrics.MetricsTable`.

    Raises
    ------
    ValueError
        An unknown engine.
    """
    if engine == "exact":
        return _run_exact
    if engine == "fast":
        from esoarm.engines.fast import run_metrics as run_fast

        return run_fast
    raise ValueError(f"engine must be one of {', '.join(ENGINES)}; got {engine!r}")


def _run_chunk(points: Sequence[Scenario], seeds: Sequence[int] | None,
               threads: int | None, engine: str = "exact") -> np.ndarray:
    """One chunk's metrics: the Dask task.

    A worker process runs one chunk at a time (on ``threads`` numba threads):
    numba's parallel kernels must not be launched from several threads at
    once with every threading layer.  Give Dask workers ``--nthreads 1`` and
    one process per core, or fewer processes and ``--workers N``.
    """
    with _CHUNK_LOCK:
        return metrics_runner(engine)(points, seeds if seeds else None, workers=threads).values


def iter_sweep(
    grid: SweepGrid,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    chunk: int | None = None,
    engine: str = "exact",
) -> Iterator[tuple[int, np.ndarray]]:
    """Run the sweep chunk by chunk; yield (first run index, metrics rows).

    In this process chunks come in grid order; from a Dask cluster in the
    order they finish.  Stopping the iteration (or Ctrl-C while waiting)
    cancels the chunks not yet finished.

    Parameters
    ----------
    grid : SweepGrid
        From :func:`build_grid`.
    workers : int, optional
        In this process: threads (cores), default all.  On Dask: numba
        threads per task (default 1; Dask's own worker threads give the
        parallelism).
    scheduler : str, optional
        Address of a Dask distributed scheduler, e.g. ``tcp://10.0.0.5:8786``.
    chunk : int, optional
        Runs per chunk (rounded to whole grid points); default
        :data:`LOCAL_CHUNK` or :data:`DASK_CHUNK`.
    engine : {"exact", "fast"}
        :data:`ENGINES`; "fast" agrees with "exact" to round-off (:mod:`esoarm.engines.fast`).

    Yields
    ------
    tuple
        (index of the chunk's first run, its metric rows (runs, len(METRICS))).
    """
    run_metrics = metrics_runner(engine)
    per_point = max(len(grid.seeds), 1)
    seeds = list(grid.seeds) or None
    if scheduler is None:
        ranges = _chunks(grid, chunk or LOCAL_CHUNK)
        noise_cache = NoiseCache()  # each seed's noise drawn once for the whole sweep
        for lo, hi in ranges:
            table = run_metrics(grid.points[lo:hi], seeds, workers=workers,
                                _noise_cache=noise_cache)
            yield lo * per_point, table.values
        return
    yield from _iter_dask(grid, scheduler, workers or 1, chunk or DASK_CHUNK, engine)


class ClusterError(RuntimeError):
    """The Dask cluster could not be used (unreachable, lost, or not installed)."""


#: How long to wait for a TCP answer from the scheduler before giving up [s].
PROBE_TIMEOUT = 5.0


def parse_scheduler(address: str) -> tuple[str, str, int]:
    """Split ``[tcp://|tls://]HOST:PORT`` into (scheme, host, port).

    Parameters
    ----------
    address : str
        A Dask scheduler's address (no scheme: tcp).

    Returns
    -------
    tuple of (str, str, int)
        The scheme, the host and the port.

    Raises
    ------
    ScenarioError
        Not an address of that form (one line, exit status 2 on the command line).
    """
    shown = f"scheduler '{address}'"
    scheme, sep, rest = address.strip().partition("://")
    if not sep:
        scheme, rest = "tcp", address.strip()
    if scheme not in ("tcp", "tls"):
        raise ScenarioError(f"{shown}: scheme '{scheme}://' is not supported; "
                            "expected tcp://HOST:PORT or tls://HOST:PORT")
    host, colon, port_text = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not colon or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ScenarioError(f"{shown}: expected tcp://HOST:PORT with a port 1-65535, "
                            "e.g. tcp://127.0.0.1:8786")
    return scheme, host, int(port_text)


def probe_scheduler(address: str, timeout: float = PROBE_TIMEOUT) -> None:
    """Check within ``timeout`` seconds that something at ``address`` answers like Dask.

    Done before a Dask client is made: a client that cannot connect takes
    tens of seconds to give up and complains again when garbage-collected,
    and one connected to a server that never answers waits for ever.  Over
    tcp:// the scheduler must send the first bytes of its handshake (it does
    on accepting); over tls:// only the connection is checked.

    Parameters
    ----------
    address : str
        ``[tcp://|tls://]HOST:PORT`` (:func:`parse_scheduler`).
    timeout : float
        The longest wait [s] for the connection and for the first bytes.

    Raises
    ------
    ScenarioError
        The address is malformed.
    ClusterError
        The host is unknown, nothing accepts connections there, or what does
        sends nothing.
    """
    import socket

    scheme, host, port = parse_scheduler(address)
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except socket.gaierror as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: unknown host "
                           f"'{host}' ({exc.strerror})") from None
    except TimeoutError:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: no answer within "
                           f"{timeout:g} s") from None
    except OSError as exc:
        raise ClusterError(f"cannot reach the Dask scheduler at {address}: "
                           f"{exc.strerror or exc} (is 'dask scheduler' running there?)") from None
    with sock:
        if scheme != "tcp":  # TLS: the client speaks first
            return
        # a Dask scheduler sends its handshake as soon as it accepts; a server that accepts
        # and stays silent would keep distributed's Client waiting for ever (its handshake
        # read has no timeout)
        try:
            first = sock.recv(1)
        except TimeoutError:
            raise ClusterError(f"cannot use the Dask scheduler at {address}: something accepts "
                               f"connections there but sends nothing within {timeout:g} s (not a "
                               "Dask scheduler, or a hung one)") from None
        except OSError as exc:
            raise ClusterError(f"cannot use the Dask scheduler at {address}: "
                               f"{exc.strerror or exc}") from None
        if not first:
            raise ClusterError(f"cannot use the Dask scheduler at {address}: the connection was "
                               "closed at once (not a Dask scheduler?)")


def _iter_dask(grid: SweepGrid, address: str, threads: int,
               chunk: int, engine: str = "exact") -> Iterator[tuple[int, np.ndarray]]:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise ClusterError(
            "a Dask scheduler needs Dask distributed: pip install 'esoarm[cluster]'"
        ) from None
    per_point = max(len(grid.seeds), 1)
    seeds = list(grid.seeds)
    probe_scheduler(address)

    class _QuietClient(Client):  # type: ignore[misc, valid-type]
        """A client that, when its constructor failed, is dropped quietly and at once.

        (distributed's own ``__del__`` would wait twice the connect timeout and
        print a traceback after the one-line error.)
        """

        _esoarm_ok = False

        def __del__(self) -> None:
            if self._esoarm_ok:
                super().__del__()
                return
            try:
                self.close(timeout=0.5)
            except BaseException:  # noqa: S110 - best effort on a client that never worked
                pass

    try:
        client = _QuietClient(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except Exception as exc:  # noqa: BLE001 - anything here means: no usable scheduler
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if isinstance(exc, MemoryError):
            reason = "something answers there, but not a Dask scheduler"
        raise ClusterError(f"cannot use the Dask scheduler at {address}: {reason}") from None
    client._esoarm_ok = True
    ranges = iter(_chunks(grid, chunk))
    futures: dict[Any, int] = {}

    def submit() -> Any:
        # chunks are submitted as others finish, a few per worker thread, so
        # the scenarios in flight (and in memory) do not grow with the sweep
        lo, hi = next(ranges)
        fut = client.submit(_run_chunk, grid.points[lo:hi], seeds, threads, engine, pure=False)
        futures[fut] = lo
        return fut

    try:
        slots = max(2, 2 * sum(client.nthreads().values()))
        first = []
        for _ in range(slots):
            try:
                first.append(submit())
            except StopIteration:
                break
        pending = as_completed(first, loop=client.loop)
        for fut in pending:
            try:
                values = fut.result()
            except Exception as exc:  # a worker died or the task failed
                raise ClusterError(f"a sweep chunk failed on the cluster: {exc}") from None
            lo = futures.pop(fut)
            try:
                pending.add(submit())
            except StopIteration:
                pass
            yield lo * per_point, values
    finally:
        for fut in futures:
            if not fut.done():
                fut.cancel()
        client.close()


def run_sweep(
    grid: SweepGrid,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    chunk: int | None = None,
    progress: Callable[[int], None] | None = None,
    result: SweepResult | None = None,
    engine: str = "exact",
) -> SweepResult:
    """Run a whole sweep and collect it (see :func:`iter_sweep` for the options).

    Pass your own ``result`` (from :meth:`SweepResult.empty`) to keep the
    finished rows if the run is interrupted (``KeyboardInterrupt``) or fails.

    Parameters
    ----------
    grid : SweepGrid
        From :func:`build_grid`.
    workers, scheduler, chunk, engine
        As for :func:`iter_sweep`.
    progress : callable, optional
        Called with the number of runs finished after each chunk.
    result : SweepResult, optional
        Where the rows go (default a new one).

    Returns
    -------
    SweepResult
        Every run's metrics, in grid order.
    """
    result = result if result is not None else SweepResult.empty(grid)
    start = time.perf_counter()
    try:
        for first, values in iter_sweep(grid, workers=workers, scheduler=scheduler, chunk=chunk,
                                        engine=engine):
            result.add(first, values)
            if progress is not None:
                progress(len(values))
    finally:
        result.seconds = time.perf_counter() - start
    return result
