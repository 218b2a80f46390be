"""The first ``esoarm reproduce`` after a fresh ``pip install``: numba compiles its kernels.

    python benchmarks/bench_first_reproduce.py                  # this checkout
    python benchmarks/bench_first_reproduce.py --src A --src B  # before / after, paired

Each source tree is installed (not editable) into a new virtual environment
with its dependencies (``pip install SRC``; from pip's cache or PyPI), so the
numba cache beside the installed sources is empty, as on a user's machine.
Then, one tree after the other (paired, the machine may be shared),
``esoarm reproduce --out DIR`` is timed twice: first (kernels compiled) and
again (kernels loaded from the cache).  Printed: wall and CPU time (user +
system, of the command and its children) [s], the load average before and
after each command, and the kernels numba cached (``*.nbi`` index files: one
per compiled function, each with its specializations).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def install(src: Path, venv: Path) -> Path:
    """A new virtual environment at ``venv`` with ``src`` installed; its bin directory."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(src)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return venv / "bin"


def timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float, int]:
    """(wall [s], CPU [s] of the command and its children, exit status)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    return wall, usage.ru_utime + usage.ru_stime, os.waitstatus_to_exitcode(status)


def clean_env() -> dict[str, str]:
    """This process's environment without what would point a venv's esoarm at this checkout
    or at a warm numba cache, and with a headless matplotlib."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "PYTHONDONTWRITEBYTECODE")}
    env["MPLBACKEND"] = "Agg"
    return env


def reproduce(bindir: Path, out: Path, env: dict[str, str]) -> tuple[float, float, int]:
    """``esoarm reproduce --out OUT`` of the venv at ``bindir``: (wall [s], CPU [s], status)."""
    run_env = {**env, "PATH": f"{bindir}{os.pathsep}{env.get('PATH', '')}"}
    return timed([str(bindir / "esoarm"), "reproduce", "--out", str(out)], run_env)


def cached_kernels(venv: Path) -> list[str]:
    """Every numba-cached function of the installed package, with its specializations."""
    out = []
    for index in sorted(venv.glob("lib/python*/site-packages/esoarm/**/*.nbi")):
        nbc = len(list(index.parent.glob(index.name[: -len(".nbi")] + ".*.nbc")))
        out.append(f"{index.name} ({nbc} specialization{'s' if nbc != 1 else ''})")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--src", action="append", type=Path,
                        help="source tree to install (repeat for a paired comparison); "
                        "default this checkout")
    parser.add_argument("--warm", action="store_true", help="also time a second, warm run")
    args = parser.parse_args()
    sources = args.src or [ROOT]
    env = clean_env()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory(prefix="esoarm-first-") as tmp:
        bins = []
        for i, src in enumerate(sources):
            t0 = time.perf_counter()
            bins.append(install(src.resolve(), Path(tmp) / f"venv{i}"))
            print(f"installed {src} in {time.perf_counter() - t0:.0f} s")
        print("\n| source | run | wall [s] | CPU [s] | load before | load after |\n"
              "|---|---|---:|---:|---|---|")
        for label in ("first", "warm") if args.warm else ("first",):
            for i, (src, bindir) in enumerate(zip(sources, bins, strict=True)):
                out = Path(tmp) / f"out{i}-{label}"
                before = load()
                wall, cpu, status = reproduce(bindir, out, env)
                note = "" if status == 0 else f" (exit {status})"
                print(f"| {src} | {label}{note} | {wall:.1f} | {cpu:.1f} | {before} | {load()} |",
                      flush=True)
        for i, src in enumerate(sources):
            print(f"\nnumba-cached functions after the runs, {src}:")
            for line in cached_kernels(Path(tmp) / f"venv{i}"):
                print(f"  {line}")


if __name__ == "__main__":
    main()
