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
control chatter).  The kinds compared are the registered observer kinds that declare
``NOISE_BUDGET``, the reference is the one that declares ``BASELINE`` (the linear ESO):
both asked of the registry (:func:`esoarm.kinds.having`), so a kind registered with the
flag is compared too.  :func:`check_recommendation` runs the grid and the recommended
points on the compiled engine (the numbers ``esoarm sweep`` prints for the same
grid) and reports both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from esoarm.kinds import baseline_observer, having
from esoarm.scenario import Scenario
from esoarm.studies.frequency.noise import Recommendation, recommend_eps

__all__ = ["DOC_GRID", "Measured", "SweepCheck", "TrackingMatch", "check_recommendation",
           "match_tracking", "sweep_optimum"]


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
    """The point of least ``rms_du`` with ``rms_error <= error_limit``.

    Parameters
    ----------
    points : sequence of Measured
        Measured points of a sweep.
    error_limit : float
        The largest RMS tracking error allowed [rad].

    Returns
    -------
    Measured or None
        None when no point is within the limit.
    """
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
                         kinds: tuple[str, ...] | None = None) -> SweepCheck:
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
    kinds : tuple of str, optional
        Observer kinds of the recommendation and of the sweep; default the registered
        kinds that declare ``NOISE_BUDGET`` (the package's: linear, cascade).

    Returns
    -------
    SweepCheck

    Raises
    ------
    ValueError
        No kind reaches the bandwidth (the recommendation is empty), or the linear ESO
        does not (the criterion has no bound).
    """
    kinds = having("observer", "NOISE_BUDGET") if kinds is None else kinds
    base = baseline_observer()
    recs = recommend_eps(scn, bandwidth, kinds)
    linear = [r for r in recs if r.kind == base]
    if not recs or not linear:
        raise ValueError(f"bandwidth {bandwidth:g} rad/s: not reached by "
                         f"{f'the {base} ESO' if recs else 'any observer kind'}")
    best = recs[0]
    cells = [(k, float(e)) for k in kinds for e in eps_grid]
    extra = [(best.kind, best.eps), (base, linear[0].eps)]
    measured = _measure(scn, [*cells, *extra], seeds)
    grid, at_rec, at_lin = measured[:len(cells)], measured[-2], measured[-1]
    return SweepCheck(bandwidth, best, at_rec, linear[0].eps, at_lin.rms_error,
                      sweep_optimum(grid, at_lin.rms_error))


@dataclass(frozen=True)
class TrackingMatch:
    """One kind's ε at the tracking error of the linear ESO at bandwidth W (measured).

    Attributes
    ----------
    kind : str
        Observer kind.
    eps : float
        The largest ε [s] whose measured RMS error (seed mean) is at most the bound.
    measured : Measured
        That point, measured.
    budget_du : float
        The noise budget's RMS Δu at that ε [N·m] (the ranking).
    """

    kind: str
    eps: float
    measured: Measured
    budget_du: float


#: Search grid of :func:`match_tracking`: ε_lin(W) × these factors.
MATCH_FACTORS = tuple(float(f) for f in np.geomspace(0.6, 1.6, 11))


def match_tracking(scn: Scenario, bandwidth: float,
                   kinds: tuple[str, ...] | None = None,
                   seeds: Sequence[int] = (0, 1, 2, 3)) -> tuple[float, list[TrackingMatch]]:
    """``analyze --bandwidth W --tracking``: each kind at the linear ESO's tracking, ranked.

    The bound is the measured RMS tracking error (seed mean, compiled engine) of the linear
    ESO at the ε whose f → ẑ3 bandwidth is W, ε_lin.  For every other kind, the ε grid
    ε_lin × :data:`MATCH_FACTORS` is measured; its crossing of the bound is interpolated in
    log ε between the last grid point within the bound and the next, measured again, and
    kept if within the bound (else that grid point).  A kind none of whose points tracks
    as well is left out.  The result is sorted by the noise budget's RMS Δu (the first is
    the recommendation: the least chatter at the tracking bandwidth W buys).

    Parameters
    ----------
    scn : Scenario
        The scenario with its noise model.
    bandwidth : float
        Target f → ẑ3 bandwidth W [rad/s] of the linear ESO.
    kinds : tuple of str, optional
        Observer kinds compared; default the registered kinds that declare
        ``NOISE_BUDGET`` (the package's: linear, cascade).  The reference is the kind that
        declares ``BASELINE`` (:func:`esoarm.kinds.baseline_observer`).
    seeds : sequence of int
        Noise seeds of each measurement.

    Returns
    -------
    (float, list of TrackingMatch)
        The bound [rad] and the kinds that meet it, least budget RMS Δu first.

    Raises
    ------
    ValueError
        The linear ESO does not reach the bandwidth.
    """
    from esoarm.studies.frequency.noise import noise_budget

    kinds = having("observer", "NOISE_BUDGET") if kinds is None else kinds
    base = baseline_observer()
    why: list[str] = []
    linear = [r for r in recommend_eps(scn, bandwidth, (base,), why)]
    if not linear:
        raise ValueError(f"bandwidth {bandwidth:g} rad/s: not reached by the {base} ESO"
                         + (f" ({why[0].partition(': ')[2]})" if why else ""))
    eps_lin = linear[0].eps
    others = [k for k in kinds if k != base]
    cells = [(base, eps_lin)] + [(k, eps_lin * f) for k in others for f in MATCH_FACTORS]
    measured = _measure(scn, cells, seeds)
    at_lin, bound = measured[0], measured[0].rms_error
    out = [TrackingMatch(base, eps_lin, at_lin, linear[0].budget.rms_du)]
    for i, kind in enumerate(others):
        row = measured[1 + i * len(MATCH_FACTORS):1 + (i + 1) * len(MATCH_FACTORS)]
        ok = [j for j, m in enumerate(row) if m.rms_error <= bound]
        if not ok:
            continue
        j = max(ok)
        best = row[j]
        if j + 1 < len(row):  # the crossing, in log ε, measured
            a, b = row[j], row[j + 1]
            t = (bound - a.rms_error) / (b.rms_error - a.rms_error)
            eps = float(np.exp(np.log(a.eps) + t * (np.log(b.eps) - np.log(a.eps))))
            m = _measure(scn, [(kind, eps)], seeds)[0]
            if m.rms_error <= bound:
                best = m
        point = scn.with_overrides({"observer.kind": kind, "observer.eps": best.eps})
        out.append(TrackingMatch(kind, best.eps, best, noise_budget(point).rms_du))
    return bound, sorted(out, key=lambda r: r.budget_du)


#: The ε grid [s] of the documented check: ``--vary observer.eps=geom:0.02:0.3:25``.
DOC_GRID = tuple(float(e) for e in np.geomspace(0.02, 0.3, 25))


def main(argv: Sequence[str] | None = None) -> None:  # pragma: no cover - thin wrapper
    """``python -m esoarm.studies.frequency.sweep_check SCENARIO W [KEY=VALUE ...] [--tracking]``.

    Prints the recommendation for bandwidth W [rad/s] (with ``--tracking``: that of
    :func:`match_tracking`), its measurement, and the sweep optimum over :data:`DOC_GRID` ×
    the kinds that declare ``NOISE_BUDGET`` (linear, cascade), seeds 0-3.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments; default the process's own.
    """
    import sys

    from esoarm.scenario import load_scenario

    args = list(sys.argv[1:] if argv is None else argv)
    tracking = "--tracking" in args
    args = [a for a in args if a != "--tracking"]
    if len(args) < 2:
        sys.exit("usage: python -m esoarm.studies.frequency.sweep_check SCENARIO W "
                 "[KEY=VALUE ...] [--tracking]")
    if tracking:
        scn = load_scenario(args[0], args[2:])
        bound, matches = match_tracking(scn, float(args[1]))
        grid = _measure(scn, [(k, e) for k in having("observer", "NOISE_BUDGET")
                              for e in DOC_GRID],
                        (0, 1, 2, 3))
        best = sweep_optimum(grid, bound)
        for m in matches:
            print(f"tracking match: {m.kind} eps={m.eps:.4g} s, budget RMS du {m.budget_du:.4g} "
                  f"N·m, measured RMS du {m.measured.rms_du:.4g} N·m, RMS error "
                  f"{m.measured.rms_error:.4g} rad (bound {bound:.4g} rad)")
        if best is not None:
            print(f"sweep optimum: {best.kind} eps={best.eps:.4g} s, RMS du {best.rms_du:.4g} "
                  f"N·m, RMS error {best.rms_error:.4g} rad; recommended/optimum eps "
                  f"{matches[0].eps / best.eps:.3g}")
        return
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
