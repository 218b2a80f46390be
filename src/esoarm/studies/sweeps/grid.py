"""The grid of a sweep: ``--vary KEY=SPEC`` parsed into values, points built per chunk.

SPEC is a comma list (each item a TOML value, else a string; commas inside ``[...]`` do not
split, so an item may be an arm's per-joint list), ``lin:START:STOP:NUM``
(:func:`numpy.linspace`) or ``geom:START:STOP:NUM`` (:func:`numpy.geomspace`).  The grid is
the cross product in the order given (first key slowest), each point with ``sensor.seed`` =
0 … K−1 (seed fastest).  Its size is checked against a limit before anything is allocated.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from esoarm._limits import MAX_RUNS
from esoarm.scenario import Scenario, ScenarioError, parse_override, scenario_warnings

__all__ = ["SweepGrid", "VarySpec", "build_grid", "parse_vary"]


def _too_many(n: float, max_runs: int, what: str) -> ScenarioError:
    return ScenarioError(
        f"{what} {n:,.0f} runs (grid points × seeds), more than the limit of {max_runs:,}: "
        f"that is about {n * 80 / 1e6:,.0f} MB for the results alone; "
        f"shrink the grid or raise the limit (--max-runs N, or max_runs=N in Python)")


@dataclass(frozen=True)
class VarySpec:
    """One varied key and its values, in order."""

    key: str
    values: tuple[Any, ...]
    spacing: str = "list"  # "list" | "lin" | "geom"

    @property
    def numeric(self) -> bool:
        """All values are numbers (not strings or booleans)."""
        return all(isinstance(v, int | float) and not isinstance(v, bool) for v in self.values)


def _lookup(data: dict[str, Any], key: str) -> Any:
    node: Any = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def parse_vary(item: str, base: Scenario | None = None, max_values: int = MAX_RUNS) -> VarySpec:
    """Parse one ``KEY=SPEC`` (see the module docstring).

    With ``base``, values of integer keys given as ``lin``/``geom`` are made
    integers when they are whole numbers.  A ``lin``/``geom`` NUM above
    ``max_values`` is rejected before anything is allocated.

    Parameters
    ----------
    item : str
        ``KEY=SPEC``: a dotted scenario key and its values (a list, ``lin:`` or ``geom:``),
        each in the key's own unit.
    base : Scenario, optional
        The scenario the key belongs to (integer keys stay integers).
    max_values : int
        The most values a ``lin``/``geom`` SPEC may ask for.

    Returns
    -------
    VarySpec
        The key and its values, in the order given.

    Raises
    ------
    ScenarioError
        One line naming the key and what is allowed.
    """
    if "=" not in item:
        raise ScenarioError(
            f"vary '{item}': expected KEY=SPEC, e.g. observer.eps=geom:0.03:0.3:10"
        )
    key, spec = (s.strip() for s in item.split("=", 1))
    if not key:
        raise ScenarioError(f"vary '{item}': empty key")
    if not spec:
        raise ScenarioError(f"vary {key}: empty value list")
    head = spec.split(":", 1)[0]
    if head in ("lin", "geom") and ":" in spec:
        parts = spec.split(":")
        if len(parts) != 4:
            raise ScenarioError(f"vary {key}: '{spec}' must be {head}:START:STOP:NUM")
        try:
            start, stop = float(parts[1]), float(parts[2])
            num = int(parts[3])
        except ValueError:
            raise ScenarioError(
                f"vary {key}: '{spec}': START and STOP must be numbers and NUM a whole number"
            ) from None
        if not (math.isfinite(start) and math.isfinite(stop)):
            raise ScenarioError(f"vary {key}: '{spec}': START and STOP must be finite")
        if num < 1:
            raise ScenarioError(f"vary {key}: '{spec}': NUM must be >= 1")
        if num > max_values:
            raise _too_many(num, max_values, f"vary {key}: '{spec}' alone is")
        if head == "geom":
            if start == 0 or stop == 0 or (start < 0) != (stop < 0):
                raise ScenarioError(
                    f"vary {key}: '{spec}': geom needs START and STOP non-zero and of one sign"
                )
            arr = np.geomspace(start, stop, num)
        else:
            arr = np.linspace(start, stop, num)
        values: list[Any] = [float(v) for v in arr]
        if base is not None and isinstance(_lookup(base.to_dict(), key), int) and not isinstance(
            _lookup(base.to_dict(), key), bool
        ):
            if all(v == round(v) for v in values):
                values = [int(round(v)) for v in values]
        return VarySpec(key, tuple(values), head)
    if ":" in spec and not any(c in spec for c in "\"'[{"):
        raise ScenarioError(
            f"vary {key}: '{spec}' is not a SPEC: a range names its spacing first, "
            f"lin:START:STOP:NUM or geom:START:STOP:NUM (e.g. {key}=lin:{spec.split(':')[0]}"
            f":…), else give the values as a comma list"
        )
    items = [s.strip() for s in _split_top_level(spec)]
    if any(not s for s in items):
        raise ScenarioError(f"vary {key}: '{spec}' has an empty item")
    values = [parse_override(f"{key}={s}")[1] for s in items]
    return VarySpec(key, tuple(values), "list")


def _split_top_level(spec: str) -> list[str]:
    """Split a comma list, not at commas inside [...] or quotes (per-joint lists, strings).

    ``[0.02,0.02],[0.03,0.04]`` is two values, each a list of one ε per joint.
    """
    items, depth, quote, start = [], 0, "", 0
    for i, c in enumerate(spec):
        if quote:
            quote = "" if c == quote else quote
        elif c in "\"'":
            quote = c
        elif c in "[{":
            depth += 1
        elif c in "]}":
            depth = max(depth - 1, 0)
        elif c == "," and depth == 0:
            items.append(spec[start:i])
            start = i + 1
    items.append(spec[start:])
    return items


class GridPoints(Sequence[Scenario]):
    """The scenarios of a grid, built on demand (index or slice), never all kept.

    A grid of many points would otherwise hold thousands of validated
    scenario objects (several kB each); a chunk builds only its own.
    """

    def __init__(self, base: Scenario, vary: tuple[VarySpec, ...]) -> None:
        self._base = base
        self._keys = [v.key for v in vary]
        self._values = [v.values for v in vary]
        self._sizes = [len(v) for v in self._values]
        self._n = int(np.prod(self._sizes)) if self._sizes else 0

    def __len__(self) -> int:
        return self._n

    def combo(self, index: int) -> tuple[Any, ...]:
        """Values of the varied keys at grid point ``index`` (first key slowest).

        Parameters
        ----------
        index : int
            A grid point, 0 … len − 1.

        Returns
        -------
        tuple
            One value per varied key, in the order of ``--vary``.
        """
        out = []
        for size, values in zip(reversed(self._sizes), reversed(self._values), strict=True):
            index, j = divmod(index, size)
            out.append(values[j])
        return tuple(reversed(out))

    def __getitem__(self, index):  # type: ignore[no-untyped-def, override]
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._n))]
        if index < 0:
            index += self._n
        if not 0 <= index < self._n:
            raise IndexError(index)
        over = dict(zip(self._keys, self.combo(index), strict=True))
        return _apply(self._base, over, ", ".join(self._keys))


@dataclass(frozen=True)
class SweepGrid:
    """A validated sweep: base scenario, varied keys, seeds.

    Attributes
    ----------
    base : Scenario
        The scenario with ``--set`` overrides applied.
    vary : tuple of VarySpec
        Varied keys, first slowest.
    seeds : tuple of int
        Noise seeds run at every grid point (fastest); empty when
        ``sensor.seed`` is itself a varied key (each point keeps its own).
    points : GridPoints
        The scenario of each grid point, in grid order (built on demand).
    risky : tuple of str
        Distinct risky-setting warnings over the grid (one per message).
    """

    base: Scenario
    vary: tuple[VarySpec, ...]
    seeds: tuple[int, ...]
    points: GridPoints = field(repr=False)
    risky: tuple[str, ...] = ()

    @property
    def keys(self) -> tuple[str, ...]:
        """The varied keys, as given."""
        return tuple(v.key for v in self.vary)

    @property
    def n_runs(self) -> int:
        """Grid points × seeds (× 1 when ``sensor.seed`` itself is varied)."""
        return len(self.points) * max(len(self.seeds), 1)

    def point_values(self) -> Iterator[tuple[Any, ...]]:
        """Values of the varied keys at each grid point, in grid order.

        Returns
        -------
        iterator of tuple
            One tuple per grid point, a value per varied key.
        """
        return itertools.product(*(v.values for v in self.vary))

    def point_seeds(self) -> Iterator[tuple[int, ...]]:
        """The seeds each grid point runs with, in grid order.

        Returns
        -------
        iterator of tuple of int
            Per grid point, its noise seeds (``sensor.seed``): 0 … K−1, or the varied seed.
        """
        if self.seeds:
            return itertools.repeat(self.seeds, len(self.points))
        i = self.keys.index("sensor.seed")
        return ((int(values[i]),) for values in self.point_values())

    def warnings(self) -> list[str]:
        """Distinct risky-setting warnings over the grid (one per message).

        Returns
        -------
        list of str
            One line each, in the order first met.
        """
        return list(self.risky)


def build_grid(base: Scenario, vary: Sequence[str], seeds: int = 1, *,
               max_runs: int = MAX_RUNS,
               progress: Callable[[int], None] | None = None) -> SweepGrid:
    """Parse ``--vary`` items and validate every grid point before any run.

    Parameters
    ----------
    base : Scenario
        Scenario with ``--set`` overrides already applied.
    vary : sequence of str
        ``KEY=SPEC`` items; at least one.
    seeds : int
        K ≥ 1: every point runs with ``sensor.seed`` = 0 … K−1.
    max_runs : int
        Refuse grids of more runs (grid points × seeds) than this, before
        building anything (default :data:`MAX_RUNS`).
    progress : callable, optional
        Called with the number of grid points checked since the last call.

    Returns
    -------
    SweepGrid
        The varied keys and values, the seeds, and every grid point's validated scenario.

    Raises
    ------
    ScenarioError
        Bad SPEC, unknown key, a value out of range (the message names the key),
        or more runs than ``max_runs``.
    """
    if isinstance(max_runs, bool) or not isinstance(max_runs, int) or max_runs < 1:
        raise ScenarioError(f"max_runs {max_runs!r}: must be a whole number >= 1")
    if not vary:
        raise ScenarioError("vary: give at least one KEY=SPEC")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ScenarioError(f"seeds {seeds!r}: must be a whole number >= 1")
    specs = [parse_vary(item, base, max_values=max_runs) for item in vary]
    n_runs = math.prod(len(s.values) for s in specs) * seeds
    if n_runs > max_runs:
        raise _too_many(n_runs, max_runs, "this sweep is")
    keys = [s.key for s in specs]
    for key in keys:
        if keys.count(key) > 1:
            raise ScenarioError(f"vary {key}: given more than once")
        if key == "sensor.seed" and seeds > 1:
            raise ScenarioError(
                "vary sensor.seed: give the number of noise seeds instead (seeds K, or 1)")
    # each value alone first: the message then names the key and value
    # (with one key the grid points are exactly these)
    if len(specs) > 1:
        for spec in specs:
            for value in spec.values:
                _apply(base, {spec.key: value}, spec.key)
    points = GridPoints(base, tuple(specs))
    risky: dict[str, None] = {}
    checked = 0
    for scn in points:  # every point validated (and its warnings noted), none kept
        for msg in scenario_warnings(scn):
            risky.setdefault(msg, None)
        checked += 1
        if progress is not None and checked == 100:
            progress(checked)
            checked = 0
    if progress is not None and checked:
        progress(checked)
    # with sensor.seed as a grid key each point keeps its own seed (seeds = ())
    seed_list = () if "sensor.seed" in keys else tuple(range(seeds))
    return SweepGrid(base, tuple(specs), seed_list, points, tuple(risky))


def _apply(base: Scenario, over: dict[str, Any], keys: str) -> Scenario:
    try:
        return base.with_overrides(over)
    except ScenarioError as exc:
        msg = str(exc)
        for prefix in ("override: ", f"scenario '{base.name}': "):
            if msg.startswith(prefix):
                msg = msg[len(prefix):]
        shown = ", ".join(f"{k}={v!r}" for k, v in over.items())
        raise ScenarioError(f"vary {shown}: {msg}") from None
