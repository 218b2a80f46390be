"""Calibration of ``esoarm identify``: seeded twins over wide ranges, fitted as a user would.

Simulation-based calibration (Talts et al. 2018): a rig is drawn from a documented prior
(:func:`draw_rig`), excited with the default plan of ``esoarm excite --twin``, and fitted by
``esoarm identify LOG --json``, each run as a separate command exactly as a user types it.
The result is sorted into one of four classes (:func:`classify`):

* *recovered*: exit 0 and every fitted truth inside its written 95 % interval;
* *refused*: exit 1 or 2, with the one-line reason;
* *flagged*: exit 0, every written interval contains its truth, and every parameter whose
  truth lies outside its interval is named in words (interval withheld, poorly determined,
  or at a bound of the fit);
* *confidently wrong*: exit 0 and a written interval, not flagged, that misses the truth
  far: beyond its 99.9 % extension (:data:`FAR` × its half-width; the delay by any
  sample);
* *missed*: exit 0 and written intervals that miss only near (inside their 99.9 %
  extension): a 95 % interval misses one time in twenty, so with eight of them a third
  of an exact estimator's answers have one; they count against the coverage.

The prior (all of it applied to the twin of ``test-1``; the nominal scenario given to
``identify`` stays ``test-1`` with only the sensor's rate and resolution, which a user
knows, set):

=========================  ==============================================================
inertia scale              log-uniform 0.5 … 2 × plant.inertia
viscous friction           log-uniform 0.1 … 10 × 0.01 N·m·s/rad
Coulomb friction           uniform 0 … 1.5 × the excitation's RMS torque 0.2 N·m
stiction                   half of the rigs: uniform 0 … 0.1 N·m above Coulomb
backlash                   one rig in five: uniform 0 … 0.5°
encoder noise              log-uniform 0.05 … 0.5°; one rig in four coloured, AR(1) φ 0.3 … 0.8
vibration                  one rig in five: 0 … 0.3° at 3 … 0.4·fs Hz
actuator lag               one rig in three: uniform 0 … 30 ms
transport delay            uniform 0 … 3 samples
PWM resolution             one rig in four: 8 … 12 bits
gravity offset             plant.m2 uniform 0.5 … 0.6 kg (test-1: 0.55)
sample rate                50 Hz (6 in 10), 100 (2 in 10), 200 or 1000 Hz; 60 s, at most
                           12000 samples (1 kHz: 12 s)
=========================  ==============================================================

Rigs are rotary (the lever arm); ``esoarm excite`` drives only the lever arm, so prismatic
axes are not part of the draw (see docs/benchmarks-identify-calibration.md).

What the inertia is judged against (:meth:`Rig.judged_truth`). With gear backlash the twin
becomes a two-mass drive train (:mod:`esoarm.plants.backlash`): the arm's inertia I =
rig.inertia_scale · plant.inertia, and a motor side Jm = ``rig.motor_inertia`` (1e-3 kg·m²,
4 % of test-1's inertia) that a rigid gear (backlash 0) does not have at all. In contact the
motor drives I + Jm, and a rigid model, identify's, sees that sum: on the 34 backlash rigs
of the held-out seeds 6,000,000 … the fitted inertia was (I + Jm)/plant.inertia to within
0.45 % on 28 (0.9-1.8 % on the other 6), whatever the play (0.02° to 0.5°). So with backlash
the inertia is judged against (I + Jm) / plant.inertia, the inertia of the rigid twin that
reproduces the rig outside the gap (the fitted scenario identify writes has no backlash, and
its plant.inertia is that sum). Until 2026-12-06 08:00 UTC it was judged against I alone,
which counted 10 of the 16 "confidently wrong" rigs of seeds 6,000,000 … 6,000,199; the page
gives both counts.
"""

from __future__ import annotations

import functools
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["FAR", "HELD_OUT_START", "Rig", "RigOutcome", "classify", "draw_rig", "far_miss",
           "from_json", "run_rig", "sticking_rig", "summary", "verdict_of"]

#: Seeds from this one on are held out of any tuning of the estimator (reported apart).
#: (Seeds 1_000_000 … were held out first; the first of them, 1_000_001, a 200 Hz rig whose
#: 2-sample delay was fitted as 1 sample and a lag, led to a change, so they are no longer.
#: Seeds 2_000_000 … were held out next; their results (35 rigs) were read on 2026-12-06
#: before the estimator was changed again, so they are no longer held out either.  Seeds
#: 5_000_000 … were declared on 2026-12-06 04:50 UTC, before any tuning of that session;
#: their first 28 rigs, run at 05:34-05:57 on commit 1795e02 after main was merged, had 6
#: confidently wrong (the delay and the lag decided before the stiction), which led to a
#: change, so they are no longer held out either.  Seeds 6_000_000 … were declared at
#: 05:58 UTC, before that change was tried; all 200 of them were run on the frozen commit
#: 3c43bde (8.5 % confidently wrong) and then used to change the estimator (backlash, the
#: delay at 200 Hz, the interval floor), so they are tuning data now.  Seeds 7_000_000 …
#: 7_000_199 were declared the held-out range at 07:53 UTC on 2026-12-06, before any result
#: on them was looked at; they are run once, on a frozen commit, for the final table.  Seeds
#: 8_000_000 … 8_000_119 were declared a second held-out range at 08:59 UTC and run once on
#: the same frozen commit 45e3d9f.  Both ranges are seen now: the estimator was changed on
#: their four confidently wrong rigs (branch trust9: the delay's profile walked with the
#: final model, the AR sandwich at 1 kHz, the lag's state at a segment's start, the fit
#: without a poorly determined stiction joined in).  Seeds 9_000_000 … 9_000_199 are
#: declared the held-out range in commit b215a86 (11:16 UTC on 2026-12-06), before any
#: run on them; they are run once, on the commit frozen for it, for the final table.)
HELD_OUT_START = 9_000_000
#: RMS of the default plan's multisine [N·m] (``esoarm excite --amplitude``).
EXCITATION_RMS = 0.2
RATES = (50.0, 50.0, 50.0, 50.0, 50.0, 50.0, 100.0, 100.0, 200.0, 1000.0)
#: At most this many samples per log: above 200 Hz the default plan's 60 s is shortened
#: (1 kHz: 12 s), so that the study finishes in hours, not days.
MAX_SAMPLES = 12_000


@dataclass(frozen=True)
class Rig:
    """One drawn twin: its seed, the ``--set`` overrides of the twin and of ``identify``."""

    seed: int
    truth: dict[str, float]
    twin_sets: tuple[str, ...]
    identify_sets: tuple[str, ...]
    #: Truth keys whose model the fit has (the others are model error it must survive).
    judged: tuple[str, ...]
    #: Further options of ``esoarm excite`` (none for a drawn rig: the default plan).
    excite_args: tuple[str, ...] = ()

    @property
    def rate_hz(self) -> float:
        """Sample rate of the log [Hz]."""
        return self.truth["sensor.rate_hz"]

    def judged_truth(self, key: str) -> float:
        """The value a fitted ``key`` is judged against: the drawn truth, but with gear
        backlash the inertia of the rigid drive train (arm plus the motor side
        ``rig.motor_inertia`` reflected to the arm, over plant.inertia; see the module
        docstring).

        Parameters
        ----------
        key : str
            A fitted scenario key, e.g. ``"rig.inertia_scale"``.

        Returns
        -------
        float
            Its judged true value [the key's unit].
        """
        value = self.truth[key]
        if key == "rig.inertia_scale" and self.truth.get("rig.backlash_deg", 0.0) > 0.0:
            inertia, motor_inertia = _test1_inertias()
            value += motor_inertia / inertia
        return value


@functools.lru_cache(maxsize=1)
def _test1_inertias() -> tuple[float, float]:
    """test-1's plant.inertia and rig.motor_inertia [kg·m²] (the twin of every drawn rig)."""
    from esoarm.scenario import load_scenario

    scn = load_scenario("test-1")
    return float(scn.plant.inertia), float(scn.rig.motor_inertia)


def draw_rig(seed: int) -> Rig:
    """The twin of seed ``seed`` (see the module docstring for the prior).

    Parameters
    ----------
    seed : int
        Seed of the draw (with the stream tag 30); also the twin's ``sensor.seed`` modulo
        100 000. Seeds from :data:`HELD_OUT_START` on are the held-out rigs.

    Returns
    -------
    Rig
        The drawn truth (friction in N·m and N·m·s/rad, noise and backlash in degrees, lag
        in s, delay in samples, rate in Hz), the ``--set`` overrides of the twin and of
        ``identify`` (rate and resolution only), and the keys the fit is judged on.
    """
    rng = np.random.default_rng([seed, 30])

    def loguni(lo: float, hi: float) -> float:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    rate = float(RATES[int(rng.integers(len(RATES)))])
    t: dict[str, float] = {
        "rig.inertia_scale": loguni(0.5, 2.0),
        "rig.viscous_friction": 0.01 * loguni(0.1, 10.0),
        "rig.coulomb_friction": float(rng.uniform(0.0, 1.5 * EXCITATION_RMS)),
        "rig.stiction": float(rng.uniform(0.0, 0.1)) if rng.random() < 0.5 else 0.0,
        "rig.backlash_deg": float(rng.uniform(0.0, 0.5)) if rng.random() < 0.2 else 0.0,
        "sensor.noise_deg": loguni(0.05, 0.5),
        "actuator.lag": float(rng.uniform(0.0, 0.03)) if rng.random() < 1 / 3 else 0.0,
        "actuator.delay_samples": float(rng.integers(0, 4)),
        "actuator.pwm_bits": float(rng.integers(8, 13)) if rng.random() < 0.25 else 0.0,
        "plant.m2": float(rng.uniform(0.5, 0.6)),
        "sensor.rate_hz": rate,
    }
    phi = float(rng.uniform(0.3, 0.8)) if rng.random() < 0.25 else 0.0
    vib = float(rng.uniform(0.0, 0.3)) if rng.random() < 0.2 else 0.0
    vib_hz = float(rng.uniform(3.0, 0.4 * rate))
    resolution = 0.05 if rate <= 100 else 0.01
    sets = [f"{k}={int(v) if k in ('actuator.delay_samples', 'actuator.pwm_bits') else v!r}"
            for k, v in t.items()]
    sets += [f"sensor.noise_ar=[{phi!r}]" if phi else "sensor.noise_ar=[]",
             f"sensor.vibration_deg={vib!r}", f"sensor.vibration_hz={vib_hz!r}",
             f"sensor.resolution_deg={resolution}", f"sensor.seed={seed % 100_000}"]
    judged = ["rig.inertia_scale", "plant.m2", "rig.coulomb_friction", "rig.viscous_friction",
              "rig.stiction", "actuator.lag", "actuator.delay_samples"]
    if not phi and not vib and not t["rig.backlash_deg"]:
        judged.append("sensor.noise_deg")
    return Rig(seed, {**t, "sensor.noise_ar_phi": phi, "sensor.vibration_deg": vib},
               tuple(sets),
               (f"sensor.rate_hz={rate:g}", f"sensor.resolution_deg={resolution}"),
               tuple(judged))


@dataclass
class RigOutcome:
    """What ``identify`` did with one rig."""

    rig: Rig
    verdict: str  # recovered | refused | flagged | missed | wrong | excite-failed
    exit_code: int
    reason: str = ""
    #: key -> (truth, value, lo, hi, written) for the judged keys.
    params: dict[str, tuple[float, float, float, float, bool]] = field(default_factory=dict)
    missed: list[str] = field(default_factory=list)
    flagged: list[str] = field(default_factory=list)
    seconds: float = 0.0
    stuck_share: float = math.nan


def _esoarm(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "esoarm", *args], capture_output=True,
                          text=True, env=env, check=False)


def run_rig(rig: Rig, workdir: Path | None = None) -> RigOutcome:
    """Excite the twin of ``rig`` and identify it with the ``esoarm`` command (a subprocess).

    Parameters
    ----------
    rig : Rig
        The drawn twin (:func:`draw_rig`): ``esoarm excite test-1 --twin`` runs with its
        overrides for min(60 s, :data:`MAX_SAMPLES` / rate), then ``esoarm identify --json``.
    workdir : pathlib.Path, optional
        Folder for the temporary log (default: the system's temporary folder); removed after.

    Returns
    -------
    RigOutcome
        ``excite-failed`` or ``refused`` with the last stderr line as the reason, or the
        verdict of :func:`classify`; ``seconds`` is identify's wall time [s] and
        ``stuck_share`` the share of samples the true arm did not move [1].
    """
    env = dict(os.environ)
    env.setdefault("MPLBACKEND", "Agg")
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        log = Path(tmp) / f"rig{rig.seed}.csv"
        sets = [a for s in rig.twin_sets for a in ("--set", s)]
        duration = min(60.0, MAX_SAMPLES / rig.rate_hz)
        ex = _esoarm(["excite", "test-1", "--twin", "--seed", str(rig.seed % 1000), "--log",
                      str(log), "--duration", f"{duration:g}", *rig.excite_args, *sets], env)
        if ex.returncode != 0:
            return RigOutcome(rig, "excite-failed", ex.returncode,
                              (ex.stderr.strip().splitlines() or ["?"])[-1])
        stuck = _stuck_share(log)
        isets = [a for s in rig.identify_sets for a in ("--set", s)]
        t0 = time.perf_counter()
        res = _esoarm(["identify", str(log), "--json", *isets], env)
        secs = time.perf_counter() - t0
    if res.returncode != 0:
        reason = (res.stderr.strip().splitlines() or ["?"])[-1]
        return RigOutcome(rig, "refused", res.returncode, reason, seconds=secs,
                          stuck_share=stuck)
    out = classify(rig, json.loads(res.stdout))
    out.seconds, out.stuck_share = secs, stuck
    return out


def sticking_rig(seed: int, coulomb: float = 0.25, stiction: float = 0.05) -> Rig:
    """A twin that sticks most of the default multisine: Coulomb friction above its RMS
    torque, and no breakaway probe (``esoarm excite --probe 0``), so that the multisine
    is not raised to break the arm away.  Everything else is the draw of ``seed``
    (:func:`draw_rig`) at 50 Hz without delay, lag or backlash.

    Parameters
    ----------
    seed : int
        Seed of the draw the other parameters come from.
    coulomb, stiction : float
        Coulomb friction and breakaway friction above it [N·m] (the multisine's RMS is
        0.2 N·m).

    Returns
    -------
    Rig
        The rig, judged on the same keys as a drawn one.
    """
    base = draw_rig(seed)
    t = {**base.truth, "rig.coulomb_friction": coulomb, "rig.stiction": stiction,
         "sensor.rate_hz": 50.0, "actuator.delay_samples": 0.0, "actuator.lag": 0.0,
         "rig.backlash_deg": 0.0}
    keep = ("rig.coulomb_friction", "rig.stiction", "sensor.rate_hz", "actuator.delay_samples",
            "actuator.lag", "rig.backlash_deg", "sensor.resolution_deg")
    sets = [s for s in base.twin_sets if s.split("=")[0] not in keep]
    sets += [f"rig.coulomb_friction={coulomb!r}", f"rig.stiction={stiction!r}",
             "sensor.rate_hz=50.0", "actuator.delay_samples=0", "actuator.lag=0.0",
             "rig.backlash_deg=0.0", "sensor.resolution_deg=0.05"]
    return Rig(seed, t, tuple(sets), ("sensor.rate_hz=50", "sensor.resolution_deg=0.05"),
               base.judged, ("--probe", "0"))


def _stuck_share(log: Path) -> float:
    """Share of samples where the true arm moved less than 1e-4 rad (stuck) [1]."""
    import csv

    with open(log, encoding="utf-8") as fh:
        rows = [r for r in csv.reader(line for line in fh if not line.startswith("#"))]
    head = rows[0]
    col = head.index("theta_true") if "theta_true" in head else head.index("theta")
    th = np.array([float(r[col]) for r in rows[1:]])
    return float(np.mean(np.abs(np.diff(th)) < 1e-4))


def classify(rig: Rig, data: dict) -> RigOutcome:
    """Sort an exit-0 ``identify --json`` answer for ``rig`` (see the module docstring).

    Parameters
    ----------
    rig : Rig
        The twin whose log was identified (its truth and judged keys).
    data : dict
        The parsed ``esoarm identify --json`` output (its ``parameters``: value, ci95,
        fitted, withheld, identifiable, at_bound per key, in the key's own unit).

    Returns
    -------
    RigOutcome
        Verdict ``wrong`` when a written 95 % interval misses its truth, else ``flagged``
        when a missed truth is named in words (withheld, poorly determined, at a bound), else
        ``recovered``; per judged key (truth, value, lo, hi, written), and the keys missed
        and flagged.
    """
    params: dict[str, tuple[float, float, float, float, bool]] = {}
    for key in rig.judged:
        e = data["parameters"].get(key)
        if e is None or not e.get("fitted", True):
            continue
        truth = rig.judged_truth(key)
        lo, hi = e["ci95"] if e.get("ci95") is not None else (math.nan, math.nan)
        written = (e.get("ci95") is not None and not e.get("withheld", False)
                   and e.get("identifiable", True) and not e.get("at_bound", False))
        params[key] = (truth, float(e["value"]), float(lo), float(hi), written)
    verdict, missed, flagged = verdict_of(params)
    return RigOutcome(rig, verdict, 0, "", params, missed, flagged)


#: A written 95 % interval misses *far* when the truth lies beyond the value by more than
#: this many times the interval's half-width on the truth's side: outside the 99.9 %
#: interval (3.29/1.96 standard errors) of the same estimate.
FAR = 3.29 / 1.96


def far_miss(key: str, truth: float, value: float, lo: float, hi: float) -> bool:
    """Whether a written interval [lo, hi] around ``value`` misses ``truth`` far
    (:data:`FAR`); the delay, an integer, misses far whenever it misses.

    Parameters
    ----------
    key : str
        The scenario key judged (e.g. ``"rig.inertia_scale"``).
    truth : float
        The twin's true value.
    value : float
        The written estimate.
    lo, hi : float
        The written 95 % interval.

    Returns
    -------
    bool
        True when the truth lies outside [lo, hi] by more than :data:`FAR` half-widths
        (or the key is the delay and it misses at all).
    """
    if lo - 1e-12 <= truth <= hi + 1e-12:
        return False
    half = value - lo if truth < lo else hi - value
    return key == "actuator.delay_samples" or not half > 0 or abs(truth - value) > FAR * half


def verdict_of(params: dict[str, tuple[float, float, float, float, bool]]
               ) -> tuple[str, list[str], list[str]]:
    """The verdict of an exit-0 answer from its judged parameters (see :func:`classify`).

    Parameters
    ----------
    params : dict
        key -> (truth, value, lo, hi, written).

    Returns
    -------
    (verdict, missed, flagged)
        ``wrong`` when a written interval misses its truth far (:func:`far_miss`),
        ``missed`` when written intervals miss only near (within the 99.9 % interval: with
        eight 95 % intervals, a third of the answers of an exact estimator have one),
        ``flagged`` when a truth outside its interval is named in words, else
        ``recovered``; the keys whose written interval misses, and those flagged.
    """
    missed: list[str] = []
    flagged: list[str] = []
    far = False
    for key, (truth, value, lo, hi, written) in params.items():
        if lo - 1e-12 <= truth <= hi + 1e-12:
            continue
        (missed if written else flagged).append(key)
        far = far or (written and far_miss(key, truth, value, lo, hi))
    verdict = ("wrong" if far else "missed" if missed else "flagged" if flagged
               else "recovered")
    return verdict, missed, flagged


def summary(outcomes: list[RigOutcome]) -> dict[str, float]:
    """Counts of each class, shares [%] of the rigs that reached identify (not those whose
    excitation stopped), and the coverage of the written intervals [%].

    Parameters
    ----------
    outcomes : list of RigOutcome
        One per rig run (:func:`run_rig`, or :func:`from_json`).

    Returns
    -------
    dict of str to float
        ``rigs``, ``identified`` (rigs whose excitation finished), the count of each verdict
        (``recovered``, ``refused``, ``flagged``, ``wrong``, ``excite-failed``), each of the
        first four as ``<verdict>_percent`` of the identified rigs [%],
        ``intervals_written`` and ``coverage_percent``: the share of written 95 % intervals
        that contain their truth [%].
    """
    n = len(outcomes)
    count = {v: sum(o.verdict == v for o in outcomes)
             for v in ("recovered", "refused", "flagged", "missed", "wrong", "excite-failed")}
    written = [p for o in outcomes for p in o.params.values() if p[4]]
    covered = sum(lo - 1e-12 <= truth <= hi + 1e-12 for truth, _v, lo, hi, _w in written)
    identified = n - count["excite-failed"]  # the shares are of the rigs identify saw
    out: dict[str, float] = {"rigs": n, "identified": identified, **count}
    for v in ("recovered", "refused", "flagged", "missed", "wrong"):
        out[f"{v}_percent"] = 100.0 * count[v] / max(identified, 1)
    out["intervals_written"] = len(written)
    out["coverage_percent"] = 100.0 * covered / max(len(written), 1)
    return out


def from_json(items: list[dict]) -> list[RigOutcome]:
    """Outcomes back from the ``--json`` dump of the benchmark (the rigs redrawn by seed).

    Parameters
    ----------
    items : list of dict
        The dump's outcomes: ``seed``, ``verdict``, ``exit``, ``reason``, ``params`` (key ->
        [truth, value, lo, hi, written]), ``missed``, ``flagged``, ``seconds`` [s] and
        ``stuck`` [1].

    Returns
    -------
    list of RigOutcome
        One per item, in order, its :class:`Rig` redrawn from the seed by :func:`draw_rig`.
    """
    out = []
    for o in items:
        rig = draw_rig(int(o["seed"]))
        # the truth judged by today's rule (Rig.judged_truth), not the dump's
        params = {k: (rig.judged_truth(k), *v[1:]) for k, v in o["params"].items()}
        verdict, missed, flagged = o["verdict"], list(o["missed"]), list(o["flagged"])
        if verdict in ("recovered", "flagged", "missed", "wrong"):  # by today's rule
            verdict, missed, flagged = verdict_of(params)  # type: ignore[arg-type]
        out.append(RigOutcome(rig, verdict, int(o["exit"]), o["reason"],
                              params, missed, flagged,  # type: ignore[arg-type]
                              float(o["seconds"]), float(o["stuck"])))
    return out
