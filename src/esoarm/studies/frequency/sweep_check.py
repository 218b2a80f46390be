"""``analyze --bandwidth W`` against a sweep optimum: how close the recommendation comes.

The recommendation (:func:`esoarm.studies.frequency.noise.recommend_eps`) is made in
the frequency domain: for each observer kind, the ε whose perturbation estimate
f → ẑ3 has the −3 dB bandwidth W, ranked by the predicted noise-driven RMS Δu.  A
sweep measures the same loop in the time domain.  The sweep optimum uses this
criterion, stated once here and in ``docs/frequency.md``:

    among the grid points (observer kind × ε, seed means), the least measured RMS Δu
    whose measured RMS tracking error is at most that of the linear ESO at the ε
    whose f → ẑ3 bandwidth is W

(the tracking the target bandwidth buys with the paper's observer, at the least
control chatter).  :func:`check_recommendation` runs the grid and the recommended
points on the compiled engine (the numbers ``esoarm sweep`` prints for the same
grid) and reports both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from esoarm.scenario import Scenario
from esoarm.studies.frequency.noise import Recommendation, recommend_eps

__all__ = ["DOC_GRID", "Measured", "SweepCheck", "check_recommendation", "sweep_optimum"]


@dataclass(frozen=True)
class Measured:
    """Seed means of one (kind, ε) point of the sweep.

    Attributes
    ----------
    kind : str
        Observer kind.
    eps : float
        ε [s].
    rms_error : float
        RMS tracking error [rad].
    rms_u, rms_du : float
        RMS control and RMS of u_k − u_{k−1} [N·m].
    """

    kind: str
    eps: float
    rms_error: float
    rms_u: float
    rms_du: float


@dataclass(frozen=True)
class SweepCheck:
    """The recommendation for a bandwidth, its measurement, and the sweep optimum.

    Attributes
    ----------
    bandwidth : float
        Target f → ẑ3 bandwidth W [rad/s].
    recommended : Recommendation
        ``analyze --bandwidth W``'s first choice.
    at_recommended : Measured
        The same (kind, ε) measured.
    linear_eps : float
        ε [s] of the linear ESO at bandwidth W.
    error_limit : float
        Measured RMS error of the linear ESO at ``linear_eps`` [rad]: the criterion's bound.
    optimum : Measured or None
        The sweep optimum (None: no grid point meets the bound).
    """

    bandwidth: float
    recommended: Recommendation
    at_recommended: Measured
    linear_eps: float
    error_limit: float
    optimum: Measured | None

    @property
    def same_kind(self) -> bool:
        """The recommendation and the sweep optimum use the same observer kind."""
        return self.optimum is not None and self.optimum.kind == self.recommended.kind

    @property
    def eps_ratio(self) -> float:
        """Recommended ε / the sweep optimum's ε (nan: no optimum)."""
        return self.recommended.eps / self.optimum.eps if self.optimum else float("nan")


def sweep_optimum(points: Sequence[Measured], error_limit: float) -> Measured | None:
    """The point of least ``rms_du`` with ``rms_error <= error_limit`` [rad] (None: none)."""
    ok = [p for p in points if p.rms_error <= error_limit]
    return min(ok, key=lambda p: p.rms_du) if ok else None


def _measure(scn: Scenario, cells: Sequence[tuple[str, float]],
             seeds: Sequence[int]) -> list[Measured]:
    from esoarm.engines.batch import run_metrics

    points = [scn.with_overrides({"observer.kind": kind, "observer.eps": eps})
              for kind, eps in cells]
    table = run_metrics(points, seeds=list(seeds))
    ns = len(seeds)
    cols = {c: np.asarray(table.column(c), dtype=float).reshape(-1, ns).mean(axis=1)
            for c in ("rms_error", "rms_u", "rms_du")}
    return [Measured(kind, eps, float(cols["rms_error"][i]), float(cols["rms_u"][i]),
                     float(cols["rms_du"][i])) for i, (kind, eps) in enumerate(cells)]


def check_recommendation(scn: Scenario, bandwidth: float, eps_grid: Sequence[float],
                         seeds: Sequence[int] = (0, 1, 2, 3),
                         kinds: tuple[str, ...] = ("linear", "cascade")) -> SweepCheck:
    """Measure ``analyze --bandwidth`` against the sweep optimum on ``scn``.

    Parameters
    ----------
    scn : Scenario
        The scenario (its noise model is the one the recommendation and the sweep see).
    bandwidth : float
        Target f → ẑ3 bandwidth W [rad/s].
    eps_grid : sequence of float
        ε values [s] of the sweep, run for every kind of ``kinds``.
    seeds : sequence of int
        Noise seeds each point is averaged over.
    kinds : tuple of str
        Observer kinds of the recommendation and of the sweep.

    Returns
    -------
    SweepCheck

    Raises
    ------
    ValueError
        No kind reaches the bandwidth (the recommendation is empty), or the linear ESO
        does not (the criterion has no bound).
    """
    recs = recommend_eps(scn, bandwidth, kinds)
    linear = [r for r in recs if r.kind == "linear"]
    if not recs or not linear:
        raise ValueError(f"bandwidth {bandwidth:g} rad/s: not reached by "
                         f"{'the linear ESO' if recs else 'any observer kind'}")
    best = recs[0]
    cells = [(k, float(e)) for k in kinds for e in eps_grid]
    extra = [(best.kind, best.eps), ("linear", linear[0].eps)]
    measured = _measure(scn, [*cells, *extra], seeds)
    grid, at_rec, at_lin = measured[:len(cells)], measured[-2], measured[-1]
    return SweepCheck(bandwidth, best, at_rec, linear[0].eps, at_lin.rms_error,
                      sweep_optimum(grid, at_lin.rms_error))


#: The ε grid [s] of the documented check: ``--vary observer.eps=geom:0.02:0.3:25``.
DOC_GRID = tuple(float(e) for e in np.geomspace(0.02, 0.3, 25))


def main(argv: Sequence[str] | None = None) -> None:  # pragma: no cover - thin wrapper
    """``python -m esoarm.studies.frequency.sweep_check SCENARIO W [KEY=VALUE ...]``.

    Prints the recommendation for bandwidth W [rad/s], its measurement, and the sweep
    optimum over :data:`DOC_GRID` × (linear, cascade), seeds 0-3.
    """
    import sys

    from esoarm.scenario import load_scenario

    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) < 2:
        sys.exit("usage: python -m esoarm.studies.frequency.sweep_check SCENARIO W "
                 "[KEY=VALUE ...]")
    check = check_recommendation(load_scenario(args[0], args[2:]), float(args[1]), DOC_GRID)
    rec, at, opt = check.recommended, check.at_recommended, check.optimum
    print(f"recommended: {rec.kind} eps={rec.eps:.4g} s (budget RMS du {rec.budget.rms_du:.4g}"
          f" N·m); measured RMS du {at.rms_du:.4g} N·m, RMS error {at.rms_error:.4g} rad")
    print(f"criterion: least RMS du with RMS error <= {check.error_limit:.4g} rad (the linear "
          f"ESO at eps={check.linear_eps:.4g} s, bandwidth {check.bandwidth:g} rad/s)")
    if opt is None:
        print("sweep optimum: none (no grid point meets the bound)")
    else:
        print(f"sweep optimum: {opt.kind} eps={opt.eps:.4g} s, RMS du {opt.rms_du:.4g} N·m, "
              f"RMS error {opt.rms_error:.4g} rad; recommended/optimum eps "
              f"{check.eps_ratio:.3g}")


if __name__ == "__main__":  # pragma: no cover
    main()
