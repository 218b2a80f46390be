"""A newcomer's trial of every command, with good and bad input, classified clean or not.

    python benchmarks/newcomer_trial.py            # runs every case, prints the table
    python benchmarks/newcomer_trial.py --only 12  # one case (its number), with its output

Each case is one invocation a new user might type (none of them is in
``tests/test_newcomer*.py``).  It is *clean* when

* it was meant to work and exits 0 with no traceback and no NumPy warning, or
* it was bad input and exits 2 with one error line (``esoarm: error: …``), no
  traceback and no NumPy warning (the line itself is printed for a human to judge
  whether it names the key or file and what is allowed), or
* it was bad input accepted with a warning that says what was done instead;

anything else (a traceback, a NumPy warning, exit 1 on bad input, bad input
accepted in silence, a hang past the timeout) is *not clean*.  The cases run in a
temporary folder with a few files made first (a twin's excitation log, a short
simulation, broken files).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

GOOD, BAD = "good", "bad"


@dataclass(frozen=True)
class Case:
    """One invocation: ``esoarm ARGS`` (or ``python -c CODE``) and what it should do."""

    args: tuple[str, ...]
    expect: str  # GOOD or BAD
    python: str = ""  # run ``python -c`` with this instead of esoarm


def E(expect: str, *args: str) -> Case:  # noqa: N802 - short on purpose: one line a case
    return Case(tuple(args), expect)


def P(expect: str, code: str) -> Case:  # noqa: N802
    return Case((), expect, code)


GYM = ("import numpy as np; from esoarm.envs import LeverArmEnv as E; e = E(); "
       "e.reset(seed=1); ")

CASES: list[Case] = [
    # simulate
    E(GOOD, "simulate", "test-2", "--set", "duration=1.5", "--json"),
    E(GOOD, "simulate", "uno-rig", "--set", "duration=0.7", "--out", "u.csv"),
    E(GOOD, "simulate", "test-1", "--set", "observer.kind=cascade", "--set", "duration=2"),
    E(BAD, "simulate", "test-1", "--set", "sensor.rate_hz=-50"),
    E(BAD, "simulate", "test-1", "--set", "duration=nan"),
    E(BAD, "simulate", "test-1", "--set", "duration=inf"),
    E(BAD, "simulate", "test-1", "--set", "observer.eps=0"),
    E(BAD, "simulate", "test-1", "--set", "observer.eps=\"fast\""),
    E(BAD, "simulate", "test-1", "--set", "rig.inertia"),
    E(BAD, "simulate", "test-1", "--set", "=3"),
    E(BAD, "simulate", "test-1", "--set", "sensor.seed=1.5"),
    E(BAD, "simulate", "test-1", "--set", "actuator.torque_limit=0"),
    E(BAD, "simulate", "test-1", "--out", "nodir/x.csv", "--set", "duration=1"),
    E(BAD, "simulate", "test-1", "--plot", "fig.bmpx", "--set", "duration=1"),
    E(BAD, "simulate", "no-such-scenario"),
    E(BAD, "simulate", "broken.toml"),
    E(BAD, "simulate", "empty.toml"),
    E(BAD, "simulate", "test-1", "--set", "controller.kind=lqr"),
    E(BAD, "simulate", "test-1", "--set", "reference.kind=sine", "--set", "duration=1"),
    E(BAD, "simulate", "test-1", "--set", "rig.step=0.0007", "--set", "duration=1"),
    # sweep
    E(GOOD, "sweep", "test-1", "--vary", "observer.eps=lin:0.05:0.1:3", "--set", "duration=2",
      "--json"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.05:0.1:3", "--set", "duration=2"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.1:0.05:0"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=a:b:3"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps"),
    E(BAD, "sweep", "test-1", "--seeds", "0"),
    E(BAD, "sweep", "test-1", "--seeds", "-3"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.05:0.1:3", "--workers", "0"),
    E(BAD, "sweep", "test-1", "--vary", "rig.nonsense=1:2:2"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.05:0.1:3", "--chunk", "0"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.01:0.1:1000", "--seeds", "100",
      "--max-runs", "10"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.05:0.1:3", "--out", "s.txtx"),
    E(BAD, "sweep", "test-1", "--vary", "observer.eps=0.05:0.1:3", "--vary",
      "observer.eps=0.06:0.2:2"),
    # tune
    E(GOOD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--set", "duration=1.5",
      "--maxiter", "2", "--popsize", "3", "--json"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.12:0.04"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--objective", "rms_error +"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--objective",
      "__import__('os')"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--weight", "-1"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--popsize", "0"),
    E(BAD, "tune", "test-1", "--vary", "observer.eps=0.04:0.12", "--samples", "5"),
    E(BAD, "tune", "test-1"),
    E(BAD, "tune", "test-1", "--vary", "observer.kind=0:1"),
    # analyze
    E(GOOD, "analyze", "test-2", "--json"),
    E(GOOD, "analyze", "test-1", "--theta0", "0.3"),
    E(BAD, "analyze", "test-1", "--theta0", "nan"),
    E(BAD, "analyze", "test-1", "--bandwidth", "-4"),
    E(BAD, "analyze", "test-1", "--tracking"),
    E(BAD, "analyze", "test-1", "--vary", "observer.eps=0.01:0.2:100000"),
    E(BAD, "analyze", "test-1", "--friction", "coulomb"),
    E(BAD, "analyze", "test-1", "--plot", "bode.gif"),
    E(BAD, "analyze", "two-link", "--bandwidth", "15"),
    # reproduce / help pages
    E(GOOD, "reproduce", "--help"),
    E(GOOD, "pil", "--help"),
    E(GOOD, "commission", "--help"),
    E(GOOD, "flash", "--help"),
    E(GOOD, "run", "--help"),
    E(BAD, "reproduce", "--figure", "99"),
    E(BAD, "run", "test-1"),
    E(BAD, "run", "test-1", "--port", "/dev/nonexistent-esoarm"),
    E(BAD, "flash", "test-1", "--port", "/dev/nonexistent-esoarm"),
    E(BAD, "commission", "test-1"),
    E(BAD, "pil", "test-1", "--target", "z80"),
    E(BAD, "pil", "test-1", "--steps", "0"),
    # replay
    E(GOOD, "replay", "twin.csv", "--scenario", "test-1", "--out", "r.csv"),
    E(BAD, "replay", "missing.csv"),
    E(BAD, "replay", "empty.csv"),
    E(BAD, "replay", "header_only.csv"),
    E(BAD, "replay", "nan_rows.csv"),
    E(BAD, "replay", "unsorted.csv"),
    E(BAD, "replay", "binary.csv"),
    E(BAD, "replay", "twin.csv", "--set", "observer.eps=-1"),
    E(BAD, "replay", "twin.csv", "--out", "r.png"),
    E(BAD, "replay", "twin.csv", "--scenario", "nowhere.toml"),
    # identify
    E(BAD, "identify", "missing.csv"),
    E(BAD, "identify", "header_only.csv"),
    E(BAD, "identify", "twin.csv", "--validate-fraction", "1.5"),
    E(BAD, "identify", "twin.csv", "--max-delay", "-2"),
    E(BAD, "identify", "twin.csv", "--fix", "rig.colour"),
    E(BAD, "identify", "twin.csv", "--cutoff", "0"),
    E(BAD, "identify", "twin.csv", "--input-unit", "furlong"),
    E(BAD, "identify", "twin.csv", "--out", "fit.csv"),
    # excite --plan
    E(GOOD, "excite", "test-1", "--plan", "--duration", "20"),
    E(BAD, "excite", "test-1", "--plan", "--f-min", "5", "--f-max", "1"),
    E(BAD, "excite", "test-1", "--plan", "--amplitude", "-0.2"),
    E(BAD, "excite", "test-1", "--plan", "--duration", "0"),
    E(BAD, "excite", "test-1", "--plan", "--tones", "0"),
    E(BAD, "excite", "test-1"),
    # log import
    E(GOOD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u", "--out", "imp.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=a,y=b,u=c", "--out", "x.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u", "--scale", "y=abc", "--out",
      "x.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u", "--sign", "y=2", "--out",
      "x.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u", "--resample", "0", "--out",
      "x.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u"),
    E(BAD, "log", "import", "missing.mat", "--map", "t=t,y=y,u=u", "--out", "x.csv"),
    E(BAD, "log", "import", "plain.csv", "--map", "t=t,y=y,u=u", "--offset", "q=1", "--out",
      "x.csv"),
    # codegen
    E(GOOD, "codegen", "test-2", "--target", "host", "--out", "gen", "--no-check"),
    E(BAD, "codegen", "test-1", "--target", "pic16"),
    E(BAD, "codegen", "test-1", "--target", "host", "--prefix", "9bad name", "--out", "gen2",
      "--no-check"),
    E(BAD, "codegen", "test-1", "--project", "stm32"),
    E(BAD, "codegen", "test-1", "--target", "host", "--out", "plain.csv", "--no-check"),
    E(BAD, "codegen", "test-1", "--arduino-library", "lib", "--target", "cortex-m4"),
    # compare
    E(GOOD, "compare", "test-1", "--kinds", "eso+flc", "--set", "duration=2", "--json"),
    E(BAD, "compare", "test-1", "--kinds", "eso+magic"),
    E(BAD, "compare", "test-1", "--kinds", ""),
    E(BAD, "compare", "test-1", "--seeds", "0"),
    E(BAD, "compare", "test-1", "--delays", "x"),
    # learn-map
    E(BAD, "learn-map", "twin.csv", "test-1", "--bins", "1"),
    E(BAD, "learn-map", "missing.csv", "test-1", "--out", "m.toml"),
    E(BAD, "learn-map", "twin.csv", "test-1", "--skip", "-1"),
    E(BAD, "learn-map", "twin.csv", "test-1", "--skip", "1e9", "--out", "m.toml"),
    # show / scenarios
    E(GOOD, "show", "emps"),
    E(GOOD, "scenarios"),
    E(BAD, "show", "test-1", "--set", "plant.kind=spaceship"),
    # the Gymnasium environment
    P(GOOD, GYM + "o, r, *_ = e.step(np.array([0.1])); print(o.shape, float(r))"),
    P(BAD, GYM + "e.step(np.array([np.nan]))"),
    P(BAD, GYM + "e.step('up')"),
    P(BAD, GYM + "e.step(np.array([[0.1]]))"),
    P(BAD, "from esoarm.envs import LeverArmEnv as E; E(scenario='no-such')"),
]


def setup(folder: Path) -> None:
    """The files the cases read: a twin's log, a CSV, broken files."""
    env = dict(os.environ)
    subprocess.run([sys.executable, "-m", "esoarm", "-q", "excite", "test-1", "--twin",
                    "--duration", "12", "--log", "twin.csv"], cwd=folder, env=env,
                   check=True, capture_output=True)
    (folder / "empty.csv").write_text("")
    (folder / "header_only.csv").write_text("t,y,u\n")
    (folder / "nan_rows.csv").write_text("t,y,u\n" + "".join(
        f"{k * 0.02},nan,0.1\n" for k in range(300)))
    (folder / "unsorted.csv").write_text("t,y,u\n" + "".join(
        f"{(299 - k) * 0.02},0.0,0.1\n" for k in range(300)))
    (folder / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (folder / "plain.csv").write_text("t,y,u\n" + "".join(
        f"{k * 0.02},{0.001 * k},0.1\n" for k in range(400)))
    (folder / "broken.toml").write_text("[observer\neps = 0.1\n")
    (folder / "empty.toml").write_text("")


def run(case: Case, folder: Path, timeout: float) -> tuple[int | None, str, str, float]:
    argv = ([sys.executable, "-c", case.python] if case.python
            else [sys.executable, "-m", "esoarm", *case.args])
    t0 = time.perf_counter()
    try:
        res = subprocess.run(argv, cwd=folder, capture_output=True, text=True,
                             timeout=timeout, stdin=subprocess.DEVNULL)
        return res.returncode, res.stdout, res.stderr, time.perf_counter() - t0
    except subprocess.TimeoutExpired:
        return None, "", "", time.perf_counter() - t0


def classify(case: Case, rc: int | None, out: str, err: str) -> tuple[bool, str]:
    """(clean, why)."""
    text = out + err
    if rc is None:
        return False, "timeout"
    if "Traceback" in text and not (case.python and case.expect == BAD):
        return False, "traceback"
    if "RuntimeWarning" in text or "encountered in" in text:
        return False, "NumPy warning"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error" in ln.lower() and ln.startswith(("esoarm", "E"))]
    if case.expect == GOOD:
        return (rc == 0, "ok" if rc == 0 else f"exit {rc}: {lines[-1] if lines else ''}")
    if case.python:  # the environment raises: one exception line, a ValueError/TypeError
        last = lines[-1] if lines else ""
        ok = rc == 1 and last.startswith(("ValueError", "TypeError", "KeyError",
                                          "esoarm.scenario.ScenarioError"))
        return ok, last
    if rc == 2 and len(errors) == 1:
        return True, errors[0]
    if rc == 0 and any("warning" in ln.lower() for ln in lines):
        return True, "accepted with a warning: " + next(
            ln for ln in lines if "warning" in ln.lower())
    return False, f"exit {rc}: {' | '.join(lines[-3:])}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", type=int, help="run only this case (its number)")
    ap.add_argument("--timeout", type=float, default=300.0)
    opts = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        setup(folder)
        chosen = [opts.only] if opts.only is not None else range(len(CASES))
        clean = 0
        for i in chosen:
            case = CASES[i]
            rc, out, err, secs = run(case, folder, opts.timeout)
            ok, why = classify(case, rc, out, err)
            clean += ok
            shown = case.python or " ".join(case.args)
            print(f"{i:3d} {'clean' if ok else 'NOT  '} {case.expect:4s} rc={rc} {secs:5.1f}s "
                  f"| {shown[:90]} | {why[:220]}", flush=True)
            if opts.only is not None:
                print(out[-3000:], err[-3000:], sep="\n")
        print(f"{clean} of {len(chosen)} clean")
    return 0


if __name__ == "__main__":
    sys.exit(main())
