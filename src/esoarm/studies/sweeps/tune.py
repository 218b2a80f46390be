"""Gain and observer tuning: a SciPy optimizer on top of the batch engine.

``esoarm tune`` looks for the values of some scenario keys (typically
``observer.eps``, ``controller.k1``, ``controller.k2``) inside given bounds
that minimize an objective over the run metrics.

Objective
    An arithmetic expression over the metric names of
    :data:`esoarm.engines.metrics.METRICS` -- ``rms_error`` [rad], ``rms_u`` [N·m],
    ``max_abs_error`` [rad], ``max_abs_u`` [N·m], ``rms_f_error`` [rad/s²] --
    the weight ``w`` (``--weight``, default :data:`DEFAULT_WEIGHT` rad/(N·m)),
    numbers, ``+ - * / **``, parentheses and ``abs, sqrt, log, exp, min, max``.
    The default is :data:`DEFAULT_OBJECTIVE`, ``rms_error + w*rms_u``: RMS
    tracking error plus the RMS control torque priced at w rad per N·m.  The
    metrics are first averaged over the noise seeds (``--seeds K``: seeds
    0 … K−1) and, with ``--robust``, over the sampled rig uncertainty; the
    expression is evaluated on those means.  A candidate any of whose runs
    diverged scores :data:`DIVERGED_PENALTY`, and so does one at which the
    expression is not a finite number (``log(rms_u - 0.1)`` with rms_u <
    0.1 N·m): :attr:`TuneResult.nonfinite` counts those, for a warning.  An
    expression that is inf or nan whatever the metrics (``1/0``,
    ``log(-rms_error)``) is bad input, found before any run; one that is not
    finite at any candidate whose runs did not diverge is bad input too, found
    after the search (nothing is written then).

Robustness
    ``--robust KEY=LOW:HIGH`` (repeatable) draws ``--samples M`` values of each
    such key by Latin hypercube sampling (seeded with ``--seed``), once: every
    candidate is scored on the same M rig variants and the same K seeds
    (common random numbers), so the objective is a deterministic function.

Optimizer
    :func:`scipy.optimize.differential_evolution`, seeded, with the whole
    population scored in one batch (``vectorized=True``) so each generation
    runs on all cores.  Keys whose bounds are both positive and a decade or
    more apart (ε, the gains) are searched on a log scale.  Whole-number keys
    (``actuator.delay_samples``) are searched as integers.

Every candidate scored is kept (:attr:`TuneResult.evaluations`): its values,
mean metrics and objective; the Pareto front of RMS error against RMS control
over them is the trade-off figure.
"""

from __future__ import annotations

import ast
import math
import operator
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from esoarm.engines.metrics import METRICS
from esoarm.scenario import Scenario, ScenarioError
from esoarm.studies.sweeps.grid import _apply, _lookup
from esoarm.studies.sweeps.sweep import metrics_runner

__all__ = [
    "DEFAULT_OBJECTIVE",
    "DEFAULT_WEIGHT",
    "Bound",
    "Objective",
    "TuneResult",
    "parse_bound",
    "tune",
]

#: Default objective (see the module docstring).
DEFAULT_OBJECTIVE = "rms_error + w*rms_u"
#: Default price w of RMS control in the default objective [rad/(N·m)].
DEFAULT_WEIGHT = 1.0
#: Score of a candidate with a diverged run.
DIVERGED_PENALTY = 1e6

_OBJ_METRICS = tuple(m for m in METRICS if m not in ("samples", "diverged"))


@dataclass(frozen=True)
class Bound:
    """A key searched (or sampled) between ``low`` and ``high``."""

    key: str
    low: float
    high: float
    integer: bool = False

    @property
    def log(self) -> bool:
        """Searched on a log scale: both bounds > 0 and a decade or more apart."""
        return not self.integer and self.low > 0 and self.high / self.low >= 10.0

    def to_unit(self, value: float) -> float:
        """Map a value to the search coordinate.

        Parameters
        ----------
        value : float
            The key's value, in its own unit.

        Returns
        -------
        float
            log10 of it on a log-scale key, else itself.
        """
        return math.log10(value) if self.log else value

    def from_unit(self, coord: float) -> float | int:
        """Map a search coordinate back to a key value.

        Parameters
        ----------
        coord : float
            The search coordinate (:meth:`to_unit`).

        Returns
        -------
        float or int
            The key's value within [low, high] (rounded on a whole-number key).
        """
        if self.integer:
            return int(round(coord))
        value = 10.0**coord if self.log else float(coord)
        return min(max(value, self.low), self.high)

    @property
    def search_bounds(self) -> tuple[float, float]:
        """Bounds in the search coordinate."""
        return self.to_unit(self.low), self.to_unit(self.high)


def parse_bound(item: str, base: Scenario, option: str = "vary") -> Bound:
    """Parse ``KEY=LOW:HIGH`` and check both ends on ``base``.

    Parameters
    ----------
    item : str
        ``KEY=LOW:HIGH``, in the key's own unit.
    base : Scenario
        The scenario the key belongs to (both ends are validated on it).
    option : str
        The option's name, for the error (``vary``, ``robust``).

    Returns
    -------
    Bound
        The key, its range, and whether it is searched on a log scale or as integers.

    Raises
    ------
    ScenarioError
        One line naming the key and what is allowed.
    """
    if "=" not in item:
        raise ScenarioError(f"{option} '{item}': expected KEY=LOW:HIGH, e.g. observer.eps=0.03:0.3")
    key, spec = (s.strip() for s in item.split("=", 1))
    parts = spec.split(":")
    if len(parts) != 2:
        raise ScenarioError(f"{option} {key}: '{spec}' must be LOW:HIGH, e.g. 0.03:0.3")
    try:
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise ScenarioError(f"{option} {key}: '{spec}': LOW and HIGH must be numbers") from None
    if not (math.isfinite(low) and math.isfinite(high)) or not low < high:
        raise ScenarioError(f"{option} {key}: '{spec}': need finite LOW < HIGH")
    current = _lookup(base.to_dict(), key)
    integer = isinstance(current, int) and not isinstance(current, bool)
    if current is not None and not isinstance(current, int | float):
        raise ScenarioError(f"{option} {key}: not a numeric key (it is {current!r})")
    bound = Bound(key, low, high, integer)
    for value in (low, high):
        v: float | int = int(round(value)) if integer else value
        try:
            base.with_overrides({key: v})
        except ScenarioError as exc:
            msg = str(exc)
            for prefix in ("override: ", f"scenario '{base.name}': "):
                msg = msg.removeprefix(prefix)
            raise ScenarioError(f"{option} {key}={value:g}: {msg}") from None
    return bound


class Objective:
    """A safe arithmetic expression over metric names (see the module docstring)."""

    _BINOPS: dict[type, Callable[[Any, Any], Any]] = {
        ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv, ast.Pow: operator.pow,
    }
    _FUNCS: dict[str, Callable[..., Any]] = {
        "abs": np.abs, "sqrt": np.sqrt, "log": np.log, "exp": np.exp,
        "min": np.minimum, "max": np.maximum,
    }
    _ARITY = {"abs": 1, "sqrt": 1, "log": 1, "exp": 1, "min": 2, "max": 2}
    #: the expression is tried on this many sets of metric values when it is made, each
    #: metric drawn log-uniformly in _PROBE_RANGE (seeded), and must be finite at one
    _PROBES = 64
    _PROBE_RANGE = (1e-6, 1e3)

    def __init__(self, text: str, weight: float = DEFAULT_WEIGHT) -> None:
        if not (math.isfinite(weight) and weight >= 0):
            raise ScenarioError(f"weight {weight!r}: must be a finite number >= 0 [rad/(N·m)] "
                                "(the price of control effort; a negative one rewards it)")
        self.text = text
        self.weight = weight
        try:
            self._tree = ast.parse(text, mode="eval").body
        except SyntaxError:
            raise ScenarioError(f"objective '{text}': not a valid expression") from None
        self._check(self._tree)
        used = {n.id for n in ast.walk(self._tree) if isinstance(n, ast.Name)}
        #: the metrics the expression uses, in :data:`METRICS` order
        self.metrics = tuple(m for m in _OBJ_METRICS if m in used)
        rng = np.random.default_rng(0)
        lo, hi = np.log10(self._PROBE_RANGE)
        probe = self({m: 10.0 ** rng.uniform(lo, hi, self._PROBES) for m in _OBJ_METRICS})
        if not np.isfinite(probe).any():
            raise ScenarioError(
                f"objective '{text}': not a finite number (gives {np.ravel(probe)[0]:g}) for "
                f"any of {self._PROBES} sampled sets of metric values (each from "
                f"{self._PROBE_RANGE[0]:g} to {self._PROBE_RANGE[1]:g}) with w = {weight:g}; "
                "it must give a finite number to minimize")

    def _check(self, node: ast.AST) -> None:
        allowed = ", ".join(_OBJ_METRICS)
        if isinstance(node, ast.BinOp) and type(node.op) in self._BINOPS:
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
            self._check(node.operand)
        elif isinstance(node, ast.Constant) and isinstance(node.value, int | float) \
                and not isinstance(node.value, bool):
            if not math.isfinite(_as_float(node.value)):
                raise ScenarioError(f"objective '{self.text}': {node.value!r:.20} is not a "
                                    "finite number")
        elif isinstance(node, ast.Name):
            if node.id not in (*_OBJ_METRICS, "w"):
                raise ScenarioError(
                    f"objective '{self.text}': unknown name '{node.id}' "
                    f"(allowed: {allowed}, w)"
                )
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in self._FUNCS and not node.keywords:
            name, want = node.func.id, self._ARITY[node.func.id]
            if len(node.args) != want:
                raise ScenarioError(
                    f"objective '{self.text}': {name}() takes {want} argument"
                    f"{'s' if want > 1 else ''}, got {len(node.args)}")
            for arg in node.args:
                self._check(arg)
        else:
            raise ScenarioError(
                f"objective '{self.text}': only numbers, + - * / **, parentheses, "
                f"{', '.join(self._FUNCS)} and the names {allowed}, w are allowed"
            )

    def __call__(self, metrics: dict[str, np.ndarray]) -> np.ndarray:
        """Evaluate on arrays of (mean) metrics; returns an array."""
        env = {**metrics, "w": self.weight}

        def ev(node: ast.AST) -> Any:
            if isinstance(node, ast.BinOp):
                return self._BINOPS[type(node.op)](ev(node.left), ev(node.right))
            if isinstance(node, ast.UnaryOp):
                v = ev(node.operand)
                return -v if isinstance(node.op, ast.USub) else v
            if isinstance(node, ast.Constant):  # a float: 9**9**9 overflows to inf, not a bignum
                return np.float64(_as_float(node.value))
            if isinstance(node, ast.Name):
                return env[node.id]
            assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            return self._FUNCS[node.func.id](*(ev(a) for a in node.args))

        with np.errstate(all="ignore"):
            return np.asarray(ev(self._tree), dtype=float)


def _as_float(value: Any) -> float:
    """A number of the expression as a float (inf for an integer too large for one)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


@dataclass
class TuneResult:
    """Outcome of :func:`tune`.

    Attributes
    ----------
    best : dict
        Best values found, key -> value.
    best_metrics : dict
        Mean metrics and ``objective`` at ``best``.
    baseline : dict
        The base scenario's own values of the tuned keys, and its metrics
        (same seeds and robust samples), for comparison.
    evaluations : list of dict
        Every candidate scored: key values, mean metrics, ``objective``.
    robust_samples : list of dict
        The rig variants each candidate was scored on (empty without --robust).
    """

    keys: tuple[str, ...]
    best: dict[str, Any]
    best_metrics: dict[str, float]
    baseline: dict[str, Any]
    evaluations: list[dict[str, Any]] = field(default_factory=list)
    robust_samples: list[dict[str, Any]] = field(default_factory=list)
    generations: int = 0
    runs: int = 0
    seconds: float = 0.0
    message: str = ""
    #: candidates whose runs did not diverge but whose objective was inf or nan
    #: (scored :data:`DIVERGED_PENALTY`), and the first of them (its evaluation row)
    nonfinite: int = 0
    nonfinite_example: dict[str, Any] | None = None


def _robust_samples(robust: Sequence[Bound], samples: int, seed: int) -> list[dict[str, Any]]:
    if not robust:
        return [{}]
    from scipy.stats import qmc

    unit = qmc.LatinHypercube(d=len(robust), seed=seed).random(samples)
    out = []
    for row in unit:
        sample: dict[str, Any] = {}
        for b, x in zip(robust, row, strict=True):
            v = b.low + x * (b.high - b.low)
            sample[b.key] = int(round(v)) if b.integer else float(v)
        out.append(sample)
    return out


def tune(
    base: Scenario,
    bounds: Sequence[Bound],
    *,
    objective: Objective | None = None,
    seeds: int = 1,
    robust: Sequence[Bound] = (),
    samples: int = 8,
    seed: int = 0,
    maxiter: int = 30,
    popsize: int = 10,
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
    engine: str = "exact",
) -> TuneResult:
    """Minimize the objective over ``bounds`` with differential evolution.

    Parameters
    ----------
    base : Scenario
        Scenario with ``--set`` overrides applied.
    bounds : sequence of Bound
        Keys to tune and their ranges.
    objective : Objective, optional
        Default ``rms_error + w*rms_u`` with w = :data:`DEFAULT_WEIGHT`.
    seeds : int
        Noise seeds 0 … K−1 each candidate is run with.
    robust : sequence of Bound
        Uncertain rig keys to sample (see the module docstring).
    samples : int
        Robust samples M (ignored without ``robust``).
    seed : int
        Seed of the optimizer and of the robust sampling.
    maxiter, popsize : int
        Differential-evolution generations and population size per key.
    workers : int, optional
        Threads (cores); default all.
    progress : callable, optional
        Called with 1 after each generation.
    engine : {"exact", "fast"}
        The engine that scores candidates (:data:`esoarm.studies.sweeps.sweep.ENGINES`).

    Returns
    -------
    TuneResult
        The best values found and their metrics, the scenario's own for comparison, and
        every candidate scored.

    Raises
    ------
    ScenarioError
        Bad input (:func:`_check_request`), or an objective that is not a finite number at
        any candidate whose runs did not diverge.

    Notes
    -----
    The steps: the request checked (:func:`_check_request`), the rig variants drawn
    (:func:`_robust_samples`), the scenario's own values as the start
    (:func:`_own_start`), the search (:func:`_search`, every candidate scored by a
    :class:`_Scorer`), then the best found held against the scenario as given
    (:func:`_best_or_own`).
    """
    run_metrics = metrics_runner(engine)
    keys = _check_request(bounds, robust, seeds, samples)
    objective = objective or Objective(DEFAULT_OBJECTIVE)
    variants = _robust_samples(robust, samples, seed)
    scorer = _Scorer(base, bounds, objective, variants, list(range(seeds)), run_metrics,
                     workers)
    own, x0 = _own_start(base, bounds)
    start = time.perf_counter()
    res, gens = _search(scorer, bounds, seed, maxiter, popsize, x0, progress)
    best = {b.key: b.from_unit(float(c)) for b, c in zip(bounds, np.atleast_1d(res.x),
                                                          strict=True)}
    scorer.refuse_nonfinite(keys)
    best, best_row, base_row = _best_or_own(scorer, best, own, inside=x0 is not None)
    nonfinite = scorer.nonfinite
    return TuneResult(
        keys=keys,
        best=best,
        best_metrics={k: v for k, v in best_row.items() if k not in keys},
        baseline=base_row,
        evaluations=scorer.evaluations,
        robust_samples=[v for v in variants if v],
        generations=gens,
        runs=scorer.runs,
        seconds=time.perf_counter() - start,
        message=str(res.message),
        nonfinite=len(nonfinite),
        nonfinite_example=nonfinite[0] if nonfinite else None,
    )


def _check_request(bounds: Sequence[Bound], robust: Sequence[Bound], seeds: int,
                   samples: int) -> tuple[str, ...]:
    """The keys tuned, once each and none also sampled; ScenarioError (bad input) if not."""
    if not bounds:
        raise ScenarioError("vary: give at least one KEY=LOW:HIGH to tune")
    keys = tuple(b.key for b in bounds)
    for key in keys:
        if keys.count(key) > 1:
            raise ScenarioError(f"vary {key}: given more than once")
    for b in robust:
        if b.key in keys:
            raise ScenarioError(f"robust {b.key}: also among the keys tuned (vary)")
    if seeds < 1:
        raise ScenarioError(f"seeds {seeds}: must be >= 1")
    if samples < 1:
        raise ScenarioError(f"samples {samples}: must be >= 1")
    return keys


class _Scorer:
    """The objective of the search: candidates run on the batch engine and scored.

    Each candidate runs on every rig variant with every seed (common random numbers); its
    metrics are averaged and the objective evaluated on the means.  A candidate with a
    diverged run, or whose objective is not finite, scores :data:`DIVERGED_PENALTY`.
    Every row scored by the search is kept (``evaluations``; ``nonfinite``: those whose
    objective was inf or nan), and ``runs`` counts the runs.
    """

    def __init__(self, base: Scenario, bounds: Sequence[Bound], objective: Objective,
                 variants: list[dict[str, Any]], seed_list: list[int],
                 run_metrics: Callable[..., Any], workers: int | None) -> None:
        self.base, self.bounds, self.objective = base, bounds, objective
        self.variants, self.seed_list = variants, seed_list
        self.run_metrics, self.workers = run_metrics, workers
        self.evaluations: list[dict[str, Any]] = []
        self.nonfinite: list[dict[str, Any]] = []  # rows of the search whose objective was inf/nan
        self.runs = 0

    def score(self, candidates: list[dict[str, Any]],
              ) -> tuple[np.ndarray, list[dict[str, float]], np.ndarray]:
        """Objective, evaluation rows and the not-finite mask of ``candidates`` (key -> value)."""
        variants, seed_list = self.variants, self.seed_list
        points = [_apply(self.base, {**cand, **var}, ", ".join([*cand, *var]))
                  for cand in candidates for var in variants]
        table = self.run_metrics(points, seed_list, workers=self.workers)
        self.runs += len(table)
        vals = table.values.reshape(len(candidates), len(variants) * len(seed_list), len(METRICS))
        with np.errstate(all="ignore"):
            means = {m: vals[:, :, i].mean(axis=1) for i, m in enumerate(METRICS)}
        diverged = vals[:, :, METRICS.index("diverged")].max(axis=1) > 0
        raw = np.broadcast_to(self.objective(means), diverged.shape)
        bad = ~diverged & ~np.isfinite(raw)
        obj = np.where(diverged | bad, DIVERGED_PENALTY, raw)
        rows = []
        for j, cand in enumerate(candidates):
            row = {**cand, **{m: float(means[m][j]) for m in _OBJ_METRICS},
                   "diverged_runs": int(vals[j, :, METRICS.index("diverged")].sum()),
                   "objective": float(obj[j])}
            rows.append(row)
        return obj, rows, bad

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The search's objective: x (D,) or (D, S) in search coordinates, kept as rows."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:  # one candidate, shape (D,)
            x = x[:, None]
        cands = [{b.key: b.from_unit(float(c)) for b, c in zip(self.bounds, col, strict=True)}
                 for col in x.T]
        obj, rows, bad = self.score(cands)
        self.evaluations.extend(rows)
        self.nonfinite.extend(row for row, b in zip(rows, bad, strict=True) if b)
        return obj

    def refuse_nonfinite(self, keys: tuple[str, ...]) -> None:
        """ScenarioError: the objective was finite at no candidate whose runs did not diverge."""
        nonfinite = self.nonfinite
        finite_scored = sum(r["diverged_runs"] == 0 for r in self.evaluations) - len(nonfinite)
        if nonfinite and finite_scored == 0:
            objective = self.objective
            raise ScenarioError(
                f"objective '{objective.text}': not a finite number at any of the "
                f"{len(nonfinite)} candidates whose runs did not diverge (e.g. at "
                f"{_describe(nonfinite[0], keys, objective.metrics)}); nothing to minimize")


def _own_start(base: Scenario, bounds: Sequence[Bound],
               ) -> tuple[dict[str, Any], list[float] | None]:
    """The scenario's own values of the keys, and the search's start from them (None: outside).

    The scenario's own values start the search when they lie within the bounds: differential
    evolution replaces a member only by a better one, so the best found is never worse than
    the scenario as given.
    """
    own = {b.key: _lookup(base.to_dict(), b.key) for b in bounds}
    inside = all(isinstance(own[b.key], int | float) and b.low <= own[b.key] <= b.high
                 for b in bounds)
    x0 = [b.to_unit(float(own[b.key])) for b in bounds] if inside else None
    return own, x0


def _search(scorer: _Scorer, bounds: Sequence[Bound], seed: int, maxiter: int, popsize: int,
            x0: list[float] | None, progress: Callable[[int], None] | None) -> tuple[Any, int]:
    """:func:`scipy.optimize.differential_evolution`, seeded and vectorized; result, generations."""
    from scipy.optimize import differential_evolution

    gens = 0

    def callback(*_args: Any, **_kw: Any) -> None:
        nonlocal gens
        gens += 1
        if progress is not None:
            progress(1)

    res = differential_evolution(
        scorer,
        [b.search_bounds for b in bounds],
        seed=seed,
        maxiter=maxiter,
        popsize=popsize,
        tol=1e-4,
        polish=False,
        vectorized=True,
        updating="deferred",
        init="latinhypercube",
        integrality=[b.integer for b in bounds],
        callback=callback,
        x0=x0,
    )
    return res, gens


def _best_or_own(scorer: _Scorer, best: dict[str, Any], own: dict[str, Any], inside: bool,
                 ) -> tuple[dict[str, Any], dict[str, float], dict[str, float]]:
    """The best values and their row, and the scenario's own row, scored again (not kept).

    When the search started from the scenario's values and found nothing better, the best
    point, mapped back from the search coordinate (10**log10 x), may differ from them in the
    last bit and score a round-off worse: the scenario's values are reported as they are.
    """
    _, (best_row,), _ = scorer.score([best])
    _, (base_row,), _ = scorer.score([own])
    if inside and not best_row["objective"] < base_row["objective"]:
        best, best_row = dict(own), base_row
    return best, best_row, base_row


def _describe(row: dict[str, Any], keys: Sequence[str], metrics: Sequence[str]) -> str:
    """``observer.eps = 0.05: rms_u = 0.03`` for a candidate's evaluation row."""
    values = ", ".join(f"{k} = {row[k]:.4g}" for k in keys)
    if not metrics:
        return values
    return values + ": " + ", ".join(f"{m} = {row[m]:.4g}" for m in metrics)


def describe_baseline(res: TuneResult) -> str | None:
    """One warning line when the scenario as given scores better than the best found, or None.

    It can only happen when the scenario's own values lie outside the bounds searched (within
    them they start the search, see :func:`tune`).

    Parameters
    ----------
    res : TuneResult
        A finished search.

    Returns
    -------
    str or None
    """
    gap = res.best_metrics["objective"] - res.baseline["objective"]
    if not gap > 1e-9 * max(abs(res.baseline["objective"]), 1e-300):  # round-off is no news
        return None
    own = ", ".join(f"{k} = {res.baseline[k]:.4g}" for k in res.keys)
    return (f"the scenario as given ({own}, outside the bounds searched) scores better than the "
            f"best found (objective {res.baseline['objective']:.5g} < "
            f"{res.best_metrics['objective']:.5g}): widen the bounds to include it")


def describe_nonfinite(res: TuneResult, objective: Objective) -> str | None:
    """One warning line for the candidates whose objective was inf or nan, or None.

    Parameters
    ----------
    res : TuneResult
        A finished search.
    objective : Objective
        Its objective.

    Returns
    -------
    str or None
    """
    if not res.nonfinite or res.nonfinite_example is None:
        return None
    return (f"objective '{objective.text}' was not a finite number at {res.nonfinite} of "
            f"{len(res.evaluations)} candidates (first at "
            f"{_describe(res.nonfinite_example, res.keys, objective.metrics)}); scored "
            f"{DIVERGED_PENALTY:,.0f}, as candidates with a diverged run are")
