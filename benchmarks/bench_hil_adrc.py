"""The learned table and the bumpless switch on the simulated Uno: the hil numbers of
docs/adrc.md.

    python benchmarks/bench_hil_adrc.py [--only map|switch|stop] [--duration S]

Each row is ``esoarm hil SCENARIO --once`` (the Uno firmware in simavr, the twin on its
pins) driven by ``esoarm run`` on the host, beside ``esoarm simulate`` of the same
scenario (the reference engine) and, for the switch, ``esoarm emulate --lockstep`` (the
emulated device):

map
    uno-rig with a cogging torque (A = 0.08 N·m, 6 periods a revolution): a 40 s simulated
    run learns the table (``esoarm learn-map``, 72 bins), then the rig runs without and
    with it.
switch
    uno-rig switched from the PID to the ESO + FLC at 2 s and back at 11 s (``run
    --switch-at 2 --set controller.switch_back=11``), bumpless and hard: |Δu| of the
    applied command at each switch sample, and the largest |Δu| elsewhere.
stop
    uno-rig with an end stop at 0.8 rad (``rig.end_stops = [-0.5, 0.8]``; the reference's
    1.0 rad is past it), without and with the ESO's gate (``actuator.stop_gate = 0.01``):
    the largest |ẑ3| and |u| while held (4-10 s), the RMS error after the release (t ≥ 10 s)
    and the time the arm leaves the stop.

Needs the hil toolchain (gcc-avr, arduino-mk, libsimavr-dev); a few minutes.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ESOARM = [sys.executable, "-m", "esoarm"]
COG = ["--set", "rig.cogging.amplitude=0.08", "--set", "rig.cogging.periods=6"]


def _esoarm(*args: str) -> subprocess.CompletedProcess[str]:
    res = subprocess.run([*ESOARM, *args], capture_output=True, text=True, timeout=900)
    if res.returncode != 0:
        raise SystemExit(f"esoarm {' '.join(args)}: {res.stderr.strip()}")
    return res


def _on_device(server: list[str], scenario: str, run_args: list[str], log: Path) -> dict:
    """``esoarm run`` against a device served by ``server`` (hil or emulate)."""
    dev = subprocess.Popen([*ESOARM, *server], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        assert dev.stdout is not None
        first = dev.stdout.readline()
        if not first.startswith("device: "):
            raise SystemExit(f"esoarm {' '.join(server)}: {first}{dev.stderr.read()}")  # type: ignore[union-attr]
        port = first.split(": ", 1)[1].strip()
        res = _esoarm("run", scenario, "--port", port, "--json", "--log", str(log),
                      "--watchdog", "2", *run_args)
        return dict(json.loads(res.stdout))
    finally:
        try:
            dev.wait(60)
        except subprocess.TimeoutExpired:
            dev.terminate()
            dev.wait(10)


def _simulate(scenario: str, args: list[str], out: Path | None = None) -> dict:
    extra = ["--out", str(out)] if out else []
    return dict(json.loads(_esoarm("simulate", scenario, *args, "--json", *extra).stdout))


def _u_column(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], u [N·m]) of a run or simulate CSV (comment lines skipped)."""
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    head = lines[0].split(",")
    data = np.genfromtxt(lines[1:], delimiter=",")
    return data[:, head.index("t")], data[:, head.index("u")]


def _jumps(t: np.ndarray, u: np.ndarray, times: list[float]) -> tuple[list[float], float]:
    """|Δu| at the first sample at or after each time, and the largest |Δu| elsewhere."""
    du = np.abs(np.diff(u))
    ks = [int(np.searchsorted(t, s - 1e-9)) for s in times]
    at = [float(du[k - 1]) for k in ks]
    rest = np.delete(du, [k - 1 for k in ks])
    return at, float(np.max(rest))


def bench_map(duration: float, tmp: Path) -> None:
    learn = tmp / "cog.csv"
    _simulate("uno-rig", [*COG, "--set", "duration=40"], learn)
    mapped = tmp / "mapped.toml"
    _esoarm("learn-map", str(learn), "uno-rig", *COG, "--bins", "72", "--out", str(mapped))
    dur = ["--set", f"duration={duration:g}"]
    print(f"uno-rig with cogging (A = 0.08 N·m, n = 6), {duration:g} s, table learned from a "
          "40 s simulated run (72 bins)\n")
    print("| | simulate RMS error [rad] | hil RMS error [rad] | hil max error [rad] |")
    print("|---|---|---|---|")
    for name, keys in (("no table", ["--set", "controller.feedforward_map=[]"]),
                       ("learned table", [])):
        sim = _simulate(str(mapped), [*keys, *dur])
        hil = _on_device(["hil", str(mapped), "--once"], str(mapped), [*keys, *dur],
                         tmp / "run.csv")
        print(f"| {name} | {sim['rms_error']:.5f} | {hil['rms_error']:.5f} | "
              f"{hil['max_abs_error']:.4f} |")


def bench_switch(duration: float, tmp: Path) -> None:
    times = [2.0, 11.0]
    dur = ["--set", f"duration={max(duration, 12.0):g}", "--set", "controller.switch_back=11"]
    print(f"uno-rig, PID → ESO + FLC at 2 s, back at 11 s, {max(duration, 12.0):g} s\n")
    print("| transfer | where | \\|Δu\\| at 2 s [N·m] | \\|Δu\\| at 11 s [N·m] "
          "| largest \\|Δu\\| elsewhere [N·m] | RMS error [rad] |")
    print("|---|---|---|---|---|---|")
    for transfer in ("bumpless", "hard"):
        keys = ["--set", "controller.kind=switch", "--set", "controller.switch_at=2",
                "--set", f"controller.transfer={transfer}", *dur]
        sim_csv = tmp / "sim.csv"
        sim = _simulate("uno-rig", keys, sim_csv)
        rows = [("simulate", sim, sim_csv)]
        run_keys = ["--switch-at", "2", "--set", f"controller.transfer={transfer}", *dur]
        for where, server in (("emulator", ["emulate", "uno-rig", "--lockstep"]),
                              ("hil", ["hil", "uno-rig", "--once"])):
            log = tmp / f"{where}.csv"
            rows.append((where, _on_device(server, "uno-rig", run_keys, log), log))
        for where, summary, path in rows:
            t, u = _u_column(path)
            at, rest = _jumps(t, u, times)
            print(f"| {transfer} | {where} | {at[0]:.2g} | {at[1]:.2g} | {rest:.3f} | "
                  f"{summary['rms_error']:.5f} |")


def _columns(path: Path, names: list[str]) -> list[np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    head = lines[0].split(",")
    data = np.genfromtxt(lines[1:], delimiter=",")
    return [data[:, head.index(n)] for n in names]


def bench_stop(tmp: Path) -> None:
    stops = ["--set", "rig.end_stops=[-0.5, 0.8]"]
    print("uno-rig with an end stop at 0.8 rad, 20 s\n")
    print("| ESO's gate | where | max \\|ẑ3\\| held [rad/s²] | max \\|u\\| held [N·m] "
          "| RMS error after release [rad] | leaves the stop at [s] |")
    print("|---|---|---|---|---|---|")
    for gate in ("0", "0.01"):
        keys = [*stops, "--set", f"actuator.stop_gate={gate}"]
        sim_csv = tmp / "sim.csv"
        _simulate("uno-rig", keys, sim_csv)
        hil_csv = tmp / "hil.csv"
        # --max-error 1.5: ungated, the arm stays on the stop 0.8 rad behind the reference,
        # past run's default following-error guard (0.5 rad), which would end the run there
        _on_device(["hil", "uno-rig", *stops, "--once"], "uno-rig",
                   [*keys, "--max-error", "1.5"], hil_csv)
        for where, path in (("simulate", sim_csv), ("hil", hil_csv)):
            t, theta, err, u, z3 = _columns(path, ["t", "theta", "error", "u", "z3"])
            held, after = (t > 4.0) & (t < 10.0), t >= 10.0
            leaves = t[after][np.argmax(theta[after] < 0.79)]  # a few encoder counts off
            name = "none" if gate == "0" else f"stop_gate = {gate} rad"
            print(f"| {name} | {where} | {np.abs(z3[held]).max():.2f} | "
                  f"{np.abs(u[held]).max():.3f} | {np.sqrt(np.mean(err[after] ** 2)):.4f} | "
                  f"{leaves:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["map", "switch", "stop"])
    ap.add_argument("--duration", type=float, default=20.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if args.only in (None, "map"):
            bench_map(args.duration, tmp)
            print()
        if args.only in (None, "switch"):
            bench_switch(args.duration, tmp)
            print()
        if args.only in (None, "stop"):
            bench_stop(tmp)


if __name__ == "__main__":
    main()
