"""The model-based predictor for issue 33's 2× delay goal on test-1 (measurements).

    python benchmarks/bench_model_predictor.py [--seeds 14,15,16,17] [--update docs/adrc.md]

The goal (as in ``bench_predictor.py``): test-1 holds twice the transport delay the paper's ESO
holds (RMS error ≤ 2× the paper's ESO without delay) at equal ε, at 50 Hz and 1 kHz, ε = 0.05
and 0.03 s.  Every design is told the delay (``observer.input_delay`` =
``actuator.delay_samples`` = N) and sees the reference N samples ahead.

The design measured here, a Smith predictor built on the nominal model:

- the ESO is *model-assisted*: the exact held-input ("current") ESO of ε with the nominal
  model's acceleration m(θ, θ̇) = −(G(θ) + Fc tanh(θ̇/vs) + Fv θ̇)/I0 added to b0·u_{k−N} as a
  known input, so that ẑ3 estimates only what the model leaves (the sine disturbance, the
  inertia error, the friction the model misses); G is the plant's nominal gravity (what the FLC's
  ``compensation = "model"`` uses), Fc and Fv the friction the user gives (from identification);
- the predictor propagates (θ̂, θ̇̂) over the N samples with the same model, the N commands
  already sent and ẑ3 held, and hands the FLC θ̂, θ̇̂ at t_{k+N} and the perturbation
  ẑ3 + m(θ̂_{k+N}, θ̇̂_{k+N}) there: a velocity reversal inside the horizon is predicted
  with its friction step instead of being learned N samples late.

The model's smoothing velocity vs = 0.05 rad/s (five times the twin's 0.01) was chosen on seeds
0-1 (1 kHz ε = 0.05 and 50 Hz ε = 0.03): with the twin's own 0.01 an over-estimated Fc (1.5×)
drives a limit cycle.  The rows with Fc × 0, 0.5 and 1.5 measure how much the design relies
on knowing the friction.  Seeds 0-1 chose the design, 2-9 were looked at; the table is on
the seeds given (14-17 were declared held out before their first run).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
from doc_block import write_block

import esoarm.observers.linear as lin
from esoarm.engines.simulation import SimulationDiverged, prepare, simulate
from esoarm.plants.model import gravity_coefficient
from esoarm.scenario import Scenario, load_scenario
from esoarm.studies.adrc.compare import _scenario, form_keys

sys.path.insert(0, str(Path(__file__).parent))
from bench_predictor import paper_holds  # noqa: E402

HELD = (14, 15, 16, 17)
CASES = [(50.0, 0.05), (50.0, 0.03), (1000.0, 0.05), (1000.0, 0.03)]
#: the model's tanh smoothing velocity [rad/s] (chosen on seeds 0-1, see the module docstring)
MODEL_VS = 0.05


@numba.njit(cache=True)
def model_acc(theta: float, omega: float, model: tuple[float, ...]) -> float:
    """m(θ, θ̇) = −(gcoef cos θ + Fc tanh(θ̇/vs) + Fv θ̇)/I0 [rad/s²]."""
    gcoef, fc, vs, fv, i0 = model
    return -(gcoef * math.cos(theta) + fc * math.tanh(omega / vs) + fv * omega) / i0


@numba.njit(cache=True)
def horizon(theta: float, omega: float, f: float, us: np.ndarray, b0: float, ts: float,
            model: tuple[float, ...]) -> tuple[float, float, float]:
    """(θ, θ̇, f + m) at t_{k+N}: the held-input steps with a = f + b0 u_i + m(θ_i, θ̇_i)."""
    half = 0.5 * ts * ts
    for i in range(len(us)):
        u = us[i]
        acc = f + b0 * u + model_acc(theta, omega, model)
        theta, omega = theta + ts * omega + half * acc, omega + ts * acc
    return theta, omega, f + model_acc(theta, omega, model)


def wrapped(eps: float, model: tuple[float, ...]) -> tuple[Callable, Callable]:
    """(estimate, advance) of the model-assisted ESO + model predictor for one run."""
    st: dict = {}
    advance_kind = lin.advance

    def estimate(z, y, p, zhat):  # type: ignore[no-untyped-def]
        obs = p[1:]
        nd, ts, b0 = int(obs[lin.DELAY]), obs[lin.TS], obs[lin.B0]
        if "phi" not in st:
            d = lin.design_observer(eps, ts, b0, "current")
            st.update(phi=d.phi, gam=d.gamma, gain=d.gain, q=np.array([y[0], 0.0, 0.0]))
        q = st["q"] + st["gain"] * (y[0] - st["q"][0])  # ẑ = z + Lc (y − z1)
        st["qh"] = q
        zhat[0], zhat[1], zhat[2] = horizon(q[0], q[1], q[2], np.asarray(z[3:3 + nd]), b0, ts,
                                            model)

    def advance(z, zhat, y, u, p):  # type: ignore[no-untyped-def]
        obs = p[1:]
        nd, b0 = int(obs[lin.DELAY]), obs[lin.B0]
        qh = st["qh"]
        ud = z[3] if nd else u[0]
        # z⁺ = Φ ẑ + Γ (u_{k−N} + m(ẑ1, ẑ2)/b0): the model's acceleration a known input
        st["q"] = st["phi"] @ qh + st["gam"] * (ud + model_acc(qh[0], qh[1], model) / b0)
        advance_kind(z, zhat, y, u, p)  # keeps the commands held
    return estimate, advance


def nominal_model(scn: Scenario, fc_scale: float, vs: float = MODEL_VS) -> tuple[float, ...]:
    """(gcoef, Fc, vs, Fv, I0): the plant's nominal gravity and I0, Fc × ``fc_scale``, Fv."""
    p, r = scn.plant, scn.rig
    return (gravity_coefficient(p.m1, p.m2, p.l1, p.l2, p.g), fc_scale * r.coulomb_friction, vs,
            r.viscous_friction, p.inertia)


def rms_error(scn: Scenario, delay: int, seeds: tuple[int, ...], fc_scale: float,
              vs: float = MODEL_VS) -> float:
    """Mean RMS of θ − θd over ``seeds``; inf if a run diverged."""
    theta_ref = np.asarray(prepare(scn).theta_ref).ravel()
    eps = float(np.ravel([scn.observer.eps])[0])
    out = []
    for seed in seeds:
        point = _scenario(scn, {**form_keys("delay-predictor+preview", scn, delay),
                                "observer.discretization": "current", "sensor.seed": seed})
        est, adv = wrapped(eps, nominal_model(scn, fc_scale, vs))
        saved = lin.estimate, lin.advance
        lin.estimate, lin.advance = est, adv  # the reference engine looks them up
        try:
            res = simulate(point, warn=False)
        except SimulationDiverged:
            return math.inf
        finally:
            lin.estimate, lin.advance = saved
        th = np.asarray(res.theta).ravel()
        e = float(np.sqrt(np.mean((th - theta_ref[:len(th)]) ** 2)))
        if not math.isfinite(e):
            return math.inf
        out.append(e)
    return float(np.mean(out))


#: row label -> (Fc scale, model vs [rad/s])
ROWS = {
    "Fc as the twin's (vs 0.05)": (1.0, MODEL_VS),
    "Fc × 0.5": (0.5, MODEL_VS),
    "Fc × 1.5": (1.5, MODEL_VS),
    "Fc × 0 (gravity and viscous only)": (0.0, MODEL_VS),
    "Fc as the twin's, vs as the twin's (0.01)": (1.0, 0.01),
}


def table(cases: list[tuple[float, float]], seeds: tuple[int, ...]) -> str:
    """One row per model, one column per case: the largest delay held and the RMS errors."""
    cols, yards, papers = [], [], []
    cells: dict[str, list[str]] = {r: [] for r in ROWS}
    for rate, eps in cases:
        scn = load_scenario("test-1", {"sensor.rate_hz": rate, "observer.eps": eps})
        fine = rate <= 50.0
        yard, paper = paper_holds(scn, seeds, fine)
        limit, goal = 2.0 * yard, 2 * paper
        cols.append(f"{rate:g} Hz, ε = {eps} s")
        yards.append(f"{yard:.5f} ({limit:.5f})")
        papers.append(f"{paper} (goal {goal})")
        delays = list(range(1, 17)) if fine else [goal // 2, goal, round(1.25 * goal)]
        for name, (fcs, vs) in ROWS.items():
            t = time.perf_counter()
            held, seen = 0, []
            for d in delays:
                e = rms_error(scn, d, seeds, fcs, vs)
                seen.append((d, e))
                if e > limit:
                    break
                held = d
            text = (f"{held}" if held else f"< {delays[0]}") + (" ✓" if held >= goal else " ✗")
            if not fine:
                text += " (" + ", ".join(f"{d}: {e:.4f}" for d, e in seen) + ")"
            else:
                e_goal = dict(seen).get(goal)
                if e_goal is not None:
                    text += f" ({goal}: {e_goal:.4f})"
            cells[name].append(text)
            print(f"<!-- {rate:g} Hz, ε {eps}: {name} {time.perf_counter() - t:.0f} s -->",
                  flush=True)
    lines = ["| friction model | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols),
             "| delay-free RMS of the paper's ESO [rad] (2× limit) | " + " | ".join(yards) + " |",
             "| the paper's ESO holds | " + " | ".join(papers) + " |"]
    lines += [f"| {name} | " + " | ".join(cells[name]) + " |" for name in ROWS]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default=",".join(map(str, HELD)),
                    help="sensor seeds (default: the held-out 14-17)")
    ap.add_argument("--update", default=None, metavar="MD",
                    help="write the table between the markers in this file")
    args = ap.parse_args()
    seeds = tuple(int(s) for s in args.seeds.split(","))
    t0 = time.perf_counter()
    text = (f"The largest delay held by the model-based predictor on seeds "
            f"{', '.join(map(str, seeds))} (the reference previewed N samples; ✓ the goal, 2× "
            "the paper's ESO's delay; 50 Hz searched 1..16, 1 kHz at half the goal, the goal "
            "and 1.25× it, RMS error [rad] in brackets):\n\n" + table(CASES, seeds)
            + f"\n\n<!-- {time.perf_counter() - t0:.0f} s -->\n")
    print(text)
    if args.update:
        write_block(Path(args.update), "bench_model_predictor:table", text)
        print(f"wrote the table into {args.update}")


if __name__ == "__main__":
    main()
