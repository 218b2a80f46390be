"""The generated C as a firmware engineer uses it: the API, warnings, instances, faults, tuning.

- every kind compiles without a warning under ``-std=c99 -Wall -Wextra -Wpedantic
  -Wconversion -Wdouble-promotion -Werror`` for the host, the AVR, a Cortex-M0+ (soft float),
  a Cortex-M4F and a Cortex-M7, and cppcheck reports nothing (a test per target, skipped
  with the reason when the tool is absent);
- two instances in one program do not interfere; two designs (two prefixes) link into one;
- a non-finite y is refused (last command held, fault flag set) and the state is untouched;
- ε, b0, k1, k2 changed at run time give the gains (and the commands) of a design generated
  at those values (an independent reference: the Python design);
- the reference generator holds the last target for ever (no counter runs out), and a run ten
  times the scenario's duration with setpoints sent from the host tracks them.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from esoarm.codegen import CodegenError, c_source, generate
from esoarm.codegen.generate import Generated
from esoarm.kinds import CONTROLLERS, OBSERVERS
from esoarm.scenario import load_scenario

FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wdouble-promotion",
         "-Werror", "-O2"]
#: target -> (compiler, its flags)
COMPILERS = {
    "host": ("gcc", []),
    "avr": ("avr-gcc", ["-mmcu=atmega328p", "-Os"]),
    "cortex-m0plus": ("arm-none-eabi-gcc", ["-mcpu=cortex-m0plus", "-mthumb",
                                            "-mfloat-abi=soft"]),
    "cortex-m4": ("arm-none-eabi-gcc", ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16",
                                        "-mfloat-abi=hard"]),
    "cortex-m7": ("arm-none-eabi-gcc", ["-mcpu=cortex-m7", "-mthumb", "-mfpu=fpv5-d16",
                                        "-mfloat-abi=hard"]),
}
OBS = [(m.KIND, d) for m in OBSERVERS if c_source(m) for d in ("euler", "zoh", "current")]
CTL = [m.KIND for m in CONTROLLERS if c_source(m)]

MAIN = """#include "esoarm_controller.h"
#include "esoarm_reference.h"
int main(void)
{
    esoarm_state s;
    esoarm_reference r;
    esoarm_params p;
    esoarm_real out[3];
    esoarm_init(&s);
    esoarm_reference_init(&r);
    esoarm_default_params(&p);
    p.eps = p.eps * (esoarm_real)1.5;
    (void)esoarm_set_params(&s, &p);
    esoarm_reference_next(&r, out);
    (void)esoarm_step(&s, (esoarm_real)0.1, out[0], out[1], out[2]);
    esoarm_reset(&s);
    return (int)s.fault;
}
"""


def _need(tool: str) -> None:
    if shutil.which(tool) is None:
        pytest.skip(f"not installed: {tool}")


def _write(gen: Generated, folder: Path, main: str | None = MAIN) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in gen.files.items():
        (folder / name).write_text(text)
    if main is not None:
        (folder / "main.c").write_text(main)
    return folder


def _designs(target: str) -> list[tuple[str, Generated, bool]]:
    """Every observer kind × discretization × controller kind on test-1, uno-rig (a motor,
    both observer sums) and test-2 (a multisine reference), in each precision the target
    offers; True where the reference and main.c are compiled too (once per precision and
    reference kind: they do not depend on the kinds)."""
    from esoarm.codegen.generate import TARGETS

    out = []
    for precision in TARGETS[target]:
        for i, (obs, disc) in enumerate(OBS):
            for j, ctl in enumerate(CTL):
                scn = load_scenario("test-1", {"observer.kind": obs,
                                               "observer.discretization": disc,
                                               "controller.kind": ctl})
                out.append((f"{obs}-{disc}-{ctl}-{precision}",
                            generate(scn, target, precision), i == j == 0))
        for name, comp in (("uno-rig", None), ("uno-rig-plain", False), ("test-2", None)):
            scn = load_scenario(name.removesuffix("-plain"))
            out.append((f"{name}-{precision}", generate(scn, target, precision, comp),
                        name != "uno-rig-plain"))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("target", list(COMPILERS))
def test_every_kind_compiles_warning_free(target: str, tmp_path: Path) -> None:
    cc, flags = COMPILERS[target]
    _need(cc)
    failures = []
    for name, gen, full in _designs(target):
        folder = _write(gen, tmp_path / name)
        for src in ("esoarm_controller.c", "esoarm_reference.c", "main.c")[:3 if full else 1]:
            res = subprocess.run([cc, *FLAGS, *flags, "-c", src, "-o", "/dev/null"],
                                 cwd=folder, capture_output=True, text=True)
            if res.returncode != 0 or res.stderr.strip():
                failures.append(f"{name}/{src}: {res.stderr.strip().splitlines()[:3]}")
    assert not failures, "\n".join(failures)


@pytest.mark.slow
@pytest.mark.parametrize("target", ["host", "avr", "cortex-m0plus"])
def test_cppcheck_reports_nothing(target: str, tmp_path: Path) -> None:
    _need("cppcheck")
    for name, gen, _ in _designs(target)[::3]:  # every third design: all kinds are covered
        _write(gen, tmp_path / name)
    res = subprocess.run(["cppcheck", "--enable=all", "--inconclusive", "--std=c99",
                          "--suppress=missingIncludeSystem", "--suppress=unusedFunction",
                          "--suppress=unmatchedSuppression",
                          "--error-exitcode=3", "-q", str(tmp_path)],
                         capture_output=True, text=True)
    assert res.returncode == 0 and not res.stderr.strip(), res.stderr[:2000]


def test_no_heap_no_recursion_no_globals() -> None:
    import re

    gen = generate(load_scenario("uno-rig"), "avr", "float32")
    for text in (gen.source, gen.ref_source):
        assert not re.search(r"\b(malloc|calloc|realloc|free)\s*\(", text)
        # every file-scope object is a static const table
        for line in text.splitlines():
            if re.match(r"^(static\s+)?(volatile\s+)?(esoarm_real|double|float|u?int\d+_t|int)"
                        r"\s+\w+\s*(\[|=|;)", line):
                assert line.startswith("static const"), line
    # the header names the scenario, its hash, the version, the units of the API
    assert "esoarm_step(esoarm_state *s, esoarm_real y, esoarm_real theta_d" in gen.header
    for word in ("[rad]", "[rad/s]", "[rad/s^2]", "[N m]", "ESOARM_SCENARIO_HASH",
                 "ESOARM_ESOARM_VERSION", "[s]"):
        assert word in gen.header, word
    assert "REF_KSTART" not in gen.source and "REF_KSTART" in gen.ref_source


def test_bad_prefix_refused() -> None:
    for bad in ("Esoarm", "1axis", "a-b", "x" * 30, ""):
        with pytest.raises(CodegenError, match="--prefix"):
            generate(load_scenario("test-1"), "host", "float64", prefix=bad)


# ---- behaviour on the host ----------------------------------------------------------

HARNESS = r"""#include <math.h>
#include <stdio.h>
#include "esoarm_controller.h"
#include "esoarm_reference.h"
/* reads lines "y r0 r1 r2" and commands; prints u for each step */
int main(int argc, char **argv)
{
    static esoarm_state a, b;
    esoarm_params p;
    char cmd[16];
    double y, r0, r1, r2;
    (void)argc; (void)argv;
    esoarm_init(&a);
    esoarm_init(&b);
    while (scanf("%15s", cmd) == 1) {
        if (cmd[0] == 's') {            /* s y r0 r1 r2: step a */
            if (scanf("%lf %lf %lf %lf", &y, &r0, &r1, &r2) != 4) return 2;
            double u = (double)esoarm_step(&a, (esoarm_real)y, (esoarm_real)r0,
                                           (esoarm_real)r1, (esoarm_real)r2);
            printf("%.17g %d\n", u, (int)a.fault);
        } else if (cmd[0] == 'b') {     /* b y r0 r1 r2: step b */
            if (scanf("%lf %lf %lf %lf", &y, &r0, &r1, &r2) != 4) return 2;
            (void)esoarm_step(&b, (esoarm_real)y, (esoarm_real)r0, (esoarm_real)r1,
                              (esoarm_real)r2);
        } else if (cmd[0] == 'p') {     /* p eps b0 k1 k2: set a's parameters */
            if (scanf("%lf %lf %lf %lf", &y, &r0, &r1, &r2) != 4) return 2;
            p.eps = (esoarm_real)y; p.b0 = (esoarm_real)r0;
            p.k1 = (esoarm_real)r1; p.k2 = (esoarm_real)r2;
            printf("%d", esoarm_set_params(&a, &p));
            for (int i = 0; i < ESOARM_OBS_NT; ++i) printf(" %.17g", (double)a.obs_t[i]);
            printf(" |");
            for (int i = 0; i < ESOARM_CTL_NT; ++i) printf(" %.17g", (double)a.ctl_t[i]);
            printf("\n");
        }
    }
    return 0;
}
"""


def _host(gen: Generated, tmp: Path) -> Path:
    _need("gcc")
    folder = _write(gen, tmp, HARNESS)
    exe = folder / "h"
    subprocess.run(["gcc", "-O2", "-ffp-contract=off", "-std=c99", "esoarm_controller.c",
                    "esoarm_reference.c", "main.c", "-lm", "-o", str(exe)], cwd=folder,
                   check=True)
    return exe


def _drive(exe: Path, script: str) -> list[str]:
    res = subprocess.run([str(exe)], input=script, capture_output=True, text=True, check=True)
    return res.stdout.splitlines()


def _signal(n: int, seed: int = 3) -> list[float]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    return [float(v) for v in 0.3 * np.sin(2 * t) + 1e-3 * rng.standard_normal(n)]


def test_two_instances_do_not_interfere(tmp_path: Path) -> None:
    exe = _host(generate(load_scenario("test-1"), "host", "float64"), tmp_path)
    y = _signal(300)
    alone = "".join(f"s {v!r} 0.5 0 0\n" for v in y)
    both = "".join(f"b {-3 * v!r} -1 2 3\ns {v!r} 0.5 0 0\n" for v in y)
    assert _drive(exe, alone) == _drive(exe, both)
    assert len(set(_drive(exe, alone))) > 100  # the command moves


def test_nan_measurement_refused_and_state_kept(tmp_path: Path) -> None:
    exe = _host(generate(load_scenario("test-1"), "host", "float64"), tmp_path)
    y = _signal(200)
    clean = _drive(exe, "".join(f"s {v!r} 0.5 0 0\n" for v in y))
    script = ""
    for i, v in enumerate(y):
        if i in (50, 120):
            script += "s nan 0.5 0 0\ns inf 0.5 0 0\n"
        if i == 160:
            script += "s 0.1 nan 0 0\n"
        script += f"s {v!r} 0.5 0 0\n"
    out = _drive(exe, script)
    u = [line.split()[0] for line in out]
    fault = [int(line.split()[1]) for line in out]
    # the refused samples return the last command, set the fault, leave the state alone
    assert u[50] == u[51] == u[49] and fault[49] == 0 and fault[50] == 1
    kept = [line for i, line in enumerate(u) if i not in (50, 51, 122, 123, 164)]
    assert kept == [line.split()[0] for line in clean]
    assert fault[164] == 1 | 2 and fault[-1] == 3


def test_two_designs_link_into_one_program(tmp_path: Path) -> None:
    _need("gcc")
    a = generate(load_scenario("test-1"), "host", "float32", prefix="axis_a")
    b = generate(load_scenario("uno-rig"), "host", "float64", prefix="axis_b")
    _write(a, tmp_path, None)
    _write(b, tmp_path, None)
    (tmp_path / "main.c").write_text(r"""#include <stdio.h>
#include "axis_a_controller.h"
#include "axis_a_reference.h"
#include "axis_b_controller.h"
#include "axis_b_reference.h"
int main(void)
{
    axis_a_state a; axis_b_state b; axis_a_reference ra; axis_b_reference rb;
    axis_a_real oa[3]; axis_b_real ob[3];
    int k;
    axis_a_init(&a); axis_b_init(&b); axis_a_reference_init(&ra); axis_b_reference_init(&rb);
    for (k = 0; k < 500; ++k) {
        axis_a_reference_next(&ra, oa);
        axis_b_reference_next(&rb, ob);
        (void)axis_a_step(&a, 0.0f, oa[0], oa[1], oa[2]);
        (void)axis_b_step(&b, 0.0, ob[0], ob[1], ob[2]);
    }
    printf("%s %s %g %g\n", AXIS_A_SCENARIO, AXIS_B_SCENARIO, (double)a.u, b.u);
    return 0;
}
""")
    srcs = [f"{p}_{m}.c" for p in ("axis_a", "axis_b") for m in ("controller", "reference")]
    res = subprocess.run(["gcc", *FLAGS, *srcs, "main.c", "-lm", "-o", "two"], cwd=tmp_path,
                         capture_output=True, text=True)
    assert res.returncode == 0 and not res.stderr.strip(), res.stderr
    out = subprocess.run([str(tmp_path / "two")], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("test-1 uno-rig ")
    # the same design twice with the default prefix does not link: the reason for --prefix
    (tmp_path / "dup").mkdir()
    for sub in ("x", "y"):
        _write(generate(load_scenario("test-1"), "host", "float64"), tmp_path / "dup" / sub,
               None)
    res = subprocess.run(["gcc", "x/esoarm_controller.c", "y/esoarm_controller.c",
                          "-nostartfiles", "-o", "/dev/null"], cwd=tmp_path / "dup",
                         capture_output=True, text=True)
    assert "multiple definition of `esoarm_init'" in res.stderr


@pytest.mark.parametrize(("obs", "disc"), OBS)
def test_retuned_gains_match_the_python_design(obs: str, disc: str, tmp_path: Path) -> None:
    """set_params(ε', b0', k1', k2') gives the vectors of a design at those values."""
    base = {"observer.kind": obs, "observer.discretization": disc, "observer.eps": 0.09,
            "controller.k1": 10.0, "controller.k2": 25.0, "plant.inertia": 0.5}
    new = {**base, "observer.eps": 0.05, "controller.k1": 14.0, "controller.k2": 40.0,
           "plant.inertia": 0.4}
    exe = _host(generate(load_scenario("test-1", base), "host", "float64"), tmp_path)
    ref = generate(load_scenario("test-1", new), "host", "float64")
    exe_new = _host(ref, tmp_path / "new")
    line = _drive(exe, "p 0.05 2.5 14 40\n")[0]
    line_new = _drive(exe_new, "p 0.05 2.5 14 40\n")[0]  # the same values: nothing to change
    rc, rest = line.split(" ", 1)
    assert rc == "0"
    got = np.array([float(v) for v in rest.replace("|", "").split()])
    want = np.array([float(v) for v in line_new.split(" ", 1)[1].replace("|", "").split()])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-300)
    # and the commands of a retuned run equal those of the design at the new values
    y = _signal(400)
    run = "".join(f"s {v!r} 0.3 0 0\n" for v in y)
    u_retuned = np.array([float(s.split()[0]) for s in _drive(exe, "p 0.05 2.5 14 40\n" + run)[1:]])
    u_design = np.array([float(s.split()[0]) for s in _drive(exe_new, run)])
    np.testing.assert_allclose(u_retuned, u_design, rtol=1e-9, atol=1e-12)


def test_bad_parameters_refused(tmp_path: Path) -> None:
    exe = _host(generate(load_scenario("test-1"), "host", "float64"), tmp_path)
    for bad in ("p 0 2 10 25", "p -0.1 2 10 25", "p nan 2 10 25", "p 0.09 0 10 25",
                "p 0.09 2 inf 25"):
        out = _drive(exe, bad + "\ns 0.1 0 0 0\n")
        assert out[0].startswith("-1 "), bad
        assert int(out[1].split()[1]) & 4, bad  # ESOARM_FAULT_PARAMS
    pid = _host(generate(load_scenario("test-1", {"controller.kind": "pid"}), "host",
                         "float64"), tmp_path / "pid")
    assert _drive(pid, "p 0.09 2 0 0\n")[0].startswith("0 ")  # the PID has no k1, k2
    assert _drive(pid, "p 0.09 2 3 0\n")[0].startswith("-1 ")


def test_reference_holds_for_ever_and_pil_tracks_setpoints_ten_times_the_duration() -> None:
    """The scenario's moves from the reference generator past 2^32 samples' worth of
    calls is not testable directly; its counter stops after the last move (read from the
    C) and a run ten times the duration tracks setpoints the host sends."""
    from esoarm.codegen.host import HostChip
    from esoarm.codegen.lockstep import lockstep

    base = load_scenario("test-1")
    gen = generate(base, "host", "float32")
    assert "if (k < REF_KLAST) r->k = k + 1u;" in gen.ref_source
    long = load_scenario("test-1", {"duration": 10 * base.duration})
    run = lockstep(long, HostChip(generate(long, "host", "float32")))
    assert run.steps == long.n_samples
    assert run.max_rel_du <= 1e-4
    late = slice(len(run.theta) // 2, None)  # the last half: long after the moves
    assert np.max(np.abs(run.theta[late] - run.theta_ref[late])) < 0.05
