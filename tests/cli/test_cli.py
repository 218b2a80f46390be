"""The command line: simulate, show, scenarios, and every bad input.

Bad input must give exit status 2, one line on stderr naming the offending
key or file, no traceback, and no output file (docs/semantics.md, "Errors and exit codes").
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import pytest

from esoarm.result import CSV_COLUMNS
from esoarm.scenario import builtin_names, load_scenario

# (id, scenario, --set overrides, text the one-line message must contain)
SET_CASES = [
    ("unknown-key", "test-1", ["observer.esp=0.05"],
     ["observer.esp", "did you mean 'observer.eps'"]),
    ("unknown-section", "test-1", ["observr.eps=0.05"], ["observr.eps", "'observer.eps'"]),
    ("table-as-key", "test-1", ["rig=3"], ["'rig'"]),
    ("no-equals", "test-1", ["observer.eps"], ["observer.eps", "KEY=VALUE"]),
    ("empty-key", "test-1", ["=3"], ["empty key"]),
    ("type-str-for-float", "test-1", ["observer.eps=fast"], ["observer.eps", "number"]),
    ("type-float-for-int", "test-1", ["sensor.seed=1.5"], ["sensor.seed", "integer"]),
    ("type-bool-for-int", "test-1", ["actuator.delay_samples=true"], ["actuator.delay_samples"]),
    ("type-int-for-str", "test-1", ["name=5"], ["'name'", "string"]),
    ("type-scalar-for-list", "test-1", ["reference.moves=3"], ["reference.moves", "list"]),
    ("nan", "test-1", ["observer.eps=nan"], ["observer.eps", "finite"]),
    ("inf", "test-1", ["plant.inertia=inf"], ["plant.inertia", "finite"]),
    ("overflow-inf", "test-1", ["sensor.rate_hz=1e400"], ["sensor.rate_hz", "finite"]),
    ("eps-zero", "test-1", ["observer.eps=0"], ["observer.eps", "greater than 0"]),
    ("eps-negative", "test-1", ["observer.eps=-0.1"], ["observer.eps", "greater than 0"]),
    ("rate-zero", "test-1", ["sensor.rate_hz=0"], ["sensor.rate_hz", "greater than 0"]),
    ("rate-negative", "test-1", ["sensor.rate_hz=-50"], ["sensor.rate_hz", "greater than 0"]),
    ("step-zero", "test-1", ["rig.step=0"], ["rig.step", "greater than 0"]),
    ("step-negative", "test-1", ["rig.step=-0.001"], ["rig.step", "greater than 0"]),
    ("duration-zero", "test-1", ["duration=0"], ["duration", "greater than 0"]),
    ("duration-negative", "test-1", ["duration=-20"], ["duration", "greater than 0"]),
    ("duration-below-Ts", "test-1", ["duration=0.001"], ["duration", "sample period"]),
    ("duration-too-long", "test-1", ["duration=1e9"], ["duration", "at most"]),
    ("samples-overflow", "test-1", ["rig.step=1e-10", "sensor.rate_hz=1e10", "duration=1e308"],
     ["duration", "inf samples"]),
    ("step-not-dividing", "test-1", ["rig.step=0.003"], ["rig.step", "divide the sample period"]),
    ("step-above-Ts", "test-1", ["rig.step=0.03"], ["rig.step", "divide the sample period"]),
    ("rate-not-divisible", "test-1", ["sensor.rate_hz=3"], ["rig.step", "divide"]),
    ("resolution-negative", "test-1", ["sensor.resolution_deg=-0.05"],
     ["sensor.resolution_deg", "greater than or equal to 0"]),
    ("noise-negative", "test-1", ["sensor.noise_deg=-0.2"],
     ["sensor.noise_deg", "greater than or equal to 0"]),
    ("k1-zero", "test-1", ["controller.k1=0"], ["controller.k1", "greater than 0"]),
    ("k1-negative", "test-1", ["controller.k1=-10"], ["controller.k1", "greater than 0"]),
    ("k2-zero", "test-1", ["controller.k2=0"], ["controller.k2", "greater than 0"]),
    ("k2-negative", "test-1", ["controller.k2=-25"], ["controller.k2", "greater than 0"]),
    ("torque-limit-zero", "test-1", ["actuator.torque_limit=0"], ["actuator.torque_limit"]),
    ("lag-negative", "test-1", ["actuator.lag=-0.01"], ["actuator.lag"]),
    ("delay-negative", "test-1", ["actuator.delay_samples=-1"], ["actuator.delay_samples"]),
    ("inertia-scale-zero", "test-1", ["rig.inertia_scale=0"], ["rig.inertia_scale"]),
    ("friction-velocity-zero", "test-1", ["rig.friction_velocity=0"], ["rig.friction_velocity"]),
    ("bad-discretization", "test-1", ["observer.discretization=rk4"],
     ["observer.discretization", "'euler'", "'zoh'", "'current'"]),
    ("bad-compensation", "test-1", ["controller.compensation=none"],
     ["controller.compensation", "'eso'", "'model'"]),
    ("bad-reference-kind", "test-1", ["reference.kind=ramp"],
     ["reference.kind", "quintic-steps", "multisine"]),
    ("bad-disturbance-kind", "test-1", ["rig.disturbance.kind=square"],
     ["rig.disturbance.kind", "'sine'"]),
    ("moves-out-of-order", "test-1", ["reference.moves=[[10.0, 2.0, 1.0], [1.0, 2.0, 0.0]]"],
     ["reference.moves[1]", "time order"]),
    ("moves-overlap", "test-1", ["reference.moves=[[1.0, 2.0, 1.0], [2.5, 2.0, 0.0]]"],
     ["reference.moves[1]", "time order"]),
    ("move-zero-duration", "test-1", ["reference.moves=[[1.0, 0.0, 1.0]]"],
     ["reference.moves[0]", "> 0"]),
    ("move-negative-start", "test-1", ["reference.moves=[[-1.0, 2.0, 1.0]]"],
     ["reference.moves[0]", ">= 0"]),
    ("move-two-numbers", "test-1", ["reference.moves=[[1.0, 2.0]]"], ["reference.moves[0]"]),
    ("move-not-number", "test-1", ['reference.moves=[["a", 2.0, 1.0]]'], ["reference.moves[0]"]),
    ("phases-length", "test-2", ["reference.phases=[1.0, 2.0]"], ["reference.phases"]),
    ("frequencies-length", "test-2", ["reference.frequencies=[]"], ["reference.frequencies"]),
    ("key-of-other-reference-kind", "test-1", ["reference.phases=[1.0]"],
     ["reference.phases", "quintic-steps"]),
]

# (id, file body, text the message must contain besides the file name)
FILE_CASES = [
    ("syntax-error", 'name = "x"\n[observer]\neps = = 0.05\n', ["TOML syntax error", "line 3"]),
    ("duplicate-table", "[sensor]\nrate_hz = 50.0\n[sensor]\nseed = 1\n",
     ["TOML syntax error", "line 3"]),
    ("unknown-key", "[observer]\nesp = 0.05\n", ["observer.esp", "did you mean 'observer.eps'"]),
    ("unknown-top-key", "durattion = 5.0\n", ["durattion", "did you mean 'duration'"]),
    ("wrong-type", '[controller]\nk1 = "10"\n', ["controller.k1", "number"]),
    ("table-expected", "observer = 3\n", ["observer"]),
    ("nan", "[observer]\neps = nan\n", ["observer.eps", "finite"]),
    ("inf", "[sensor]\nrate_hz = inf\n", ["sensor.rate_hz", "finite"]),
    ("eps-zero", "[observer]\neps = 0.0\n", ["observer.eps", "greater than 0"]),
    ("step-not-dividing", "[rig]\nstep = 0.0015\n", ["rig.step", "divide"]),
    ("moves-out-of-order", "[reference]\nmoves = [[5.0, 1.0, 1.0], [4.0, 1.0, 0.0]]\n",
     ["reference.moves[1]", "time order"]),
    ("not-utf8", b"\xff\xfe\x00", ["not a text TOML file"]),
]


def _assert_bad_input(res, fragments):
    assert res.exit_code == 2, (res.exit_code, res.stdout, res.stderr, res.exception)
    assert res.exception is None, repr(res.exception)
    assert "Traceback" not in res.stderr + res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    line = lines[0]
    assert line.startswith("esoarm: error: "), line
    for frag in fragments:
        assert frag in line, (frag, line)
    assert res.stdout == ""


@pytest.mark.parametrize(("scenario", "overrides", "fragments"),
                         [c[1:] for c in SET_CASES], ids=[c[0] for c in SET_CASES])
def test_bad_set_value_simulate(run_cli, tmp_path, scenario, overrides, fragments):
    out = tmp_path / "run.csv"
    plot = tmp_path / "run.png"
    args = ["simulate", scenario, "--out", str(out), "--plot", str(plot)]
    for item in overrides:
        args += ["--set", item]
    res = run_cli(*args)
    _assert_bad_input(res, fragments)
    assert list(tmp_path.iterdir()) == []  # nothing written, not even a temporary file


@pytest.mark.parametrize(("scenario", "overrides", "fragments"),
                         [c[1:] for c in SET_CASES[:12]], ids=[c[0] for c in SET_CASES[:12]])
def test_bad_set_value_show(run_cli, scenario, overrides, fragments):
    args = ["show", scenario]
    for item in overrides:
        args += ["--set", item]
    _assert_bad_input(run_cli(*args), fragments)


@pytest.mark.parametrize(("body", "fragments"), [c[1:] for c in FILE_CASES],
                         ids=[c[0] for c in FILE_CASES])
@pytest.mark.parametrize("command", ["simulate", "show"])
def test_bad_scenario_file(run_cli, tmp_path, command, body, fragments):
    src = tmp_path / "bad.toml"
    if isinstance(body, bytes):
        src.write_bytes(body)
    else:
        src.write_text(body, encoding="utf-8")
    outdir = tmp_path / "out"
    outdir.mkdir()
    args = [command, str(src)]
    if command == "simulate":
        args += ["--out", str(outdir / "run.csv")]
    _assert_bad_input(run_cli(*args), [f"'{src}'", *fragments])
    assert list(outdir.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["simulate", "missing.toml"], ["'missing.toml'", "no such file"]),
        (["simulate", "sub/missing-dir/x.toml"], ["'sub/missing-dir/x.toml'", "no such file"]),
        (["show", "test-3"], ["unknown scenario 'test-3'", "did you mean", "test-1"]),
        (["simulate", "nonsense"],
         ["unknown scenario 'nonsense'", "test-1, test-1-urdf, test-2, two-link, uno-rig"]),
        (["simulate", "test-1", "--out", "run.txt"], ["--out", "run.txt", ".csv"]),
        (["simulate", "test-1", "--plot", "fig.jpg"], ["--plot", "fig.jpg", ".png"]),
        (["simulat", "test-1"], ["unknown command 'simulat'", "did you mean 'simulate'"]),
    ],
    ids=["missing-file", "missing-dir", "unknown-builtin", "unknown-name", "out-suffix",
         "plot-suffix", "unknown-command"],
)
def test_bad_names_and_paths(run_cli, tmp_path, monkeypatch, args, fragments):
    monkeypatch.chdir(tmp_path)
    _assert_bad_input(run_cli(*args), fragments)
    assert list(tmp_path.iterdir()) == []


def test_directory_given_as_scenario(run_cli, tmp_path):
    d = tmp_path / "dir.toml"
    d.mkdir()
    _assert_bad_input(run_cli("show", str(d)), [f"'{d}'"])


def test_out_parent_is_a_file(run_cli, tmp_path):
    (tmp_path / "afile").write_text("x", encoding="utf-8")
    _assert_bad_input(run_cli("simulate", "test-1", "--out", str(tmp_path / "afile" / "r.csv")),
                      ["--out", "not a directory"])


def test_directory_given_as_out(run_cli, tmp_path):
    d = tmp_path / "res.csv"
    d.mkdir()
    _assert_bad_input(run_cli("simulate", "test-1", "--out", str(d)), ["--out", "directory"])


# ---------------------------------------------------------------------------
# the real entry point, in a subprocess: exit codes and stderr as a user sees them


def test_entry_point_bad_input_subprocess(run_esoarm, tmp_path):
    src = tmp_path / "broken.toml"
    src.write_text("[observer]\neps = 0.05\ndiscretization = \n", encoding="utf-8")
    out = tmp_path / "run.csv"
    res = run_esoarm("simulate", str(src), "--out", str(out))
    assert res.exit_code == 2
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "broken.toml" in lines[0] and "line 3" in lines[0], res.stderr
    assert not out.exists()
    res = run_esoarm("simulate", "test-1", "--set", "controller.k2=0")
    assert res.exit_code == 2 and res.stderr.count("\n") == 1 and "controller.k2" in res.stderr


def test_entry_point_warning_and_runtime_failure_subprocess(run_esoarm, tmp_path):
    """Euler with Ts/ε = 4: a warning first, then the run diverges -> exit 1, rows kept."""
    out = tmp_path / "run.csv"
    res = run_esoarm("simulate", "test-1", "--set", "observer.eps=0.005", "--out", str(out))
    assert res.exit_code == 1, res.stderr
    assert "Traceback" not in res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 2, res.stderr
    assert lines[0].startswith("esoarm: warning: ") and "unstable" in lines[0]
    assert lines[1].startswith("esoarm: failed: ") and "diverged" in lines[1]
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert 1 < len(rows) - 1 < 1000  # the rows logged before divergence, not a full run
    assert str(len(rows) - 1) in lines[1]


# ---------------------------------------------------------------------------
# warnings for legal but risky settings


@pytest.mark.parametrize(
    ("overrides", "fragment"),
    [
        (["observer.eps=0.01"], "unstable"),  # Euler, Ts/ε = 2: pole at −1
        (["observer.eps=0.015"], "negative real axis"),  # Euler, 1 < Ts/ε < 2
        (["observer.eps=0.03", "observer.discretization=zoh"], "faster than the sample rate"),
        (["observer.eps=0.03", "observer.discretization=current"], "faster than the sample"),
    ],
    ids=["euler-unstable", "euler-ringing", "zoh-too-fast", "current-too-fast"],
)
def test_risky_settings_warn(run_cli, overrides, fragment):
    args = ["show", "test-1"]
    for item in overrides:
        args += ["--set", item]
    res = run_cli(*args)
    assert res.exit_code == 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("esoarm: warning: "), res.stderr
    assert "observer.eps" in lines[0] and fragment in lines[0]
    assert load_scenario("test-1", overrides).observer.eps == float(overrides[0].split("=")[1])


@pytest.mark.parametrize("name", builtin_names())
def test_builtins_do_not_warn(run_cli, name):
    res = run_cli("show", name)
    assert res.exit_code == 0 and res.stderr == ""


# ---------------------------------------------------------------------------
# successful commands


def test_scenarios_lists_builtins(run_cli):
    res = run_cli("scenarios")
    assert res.exit_code == 0
    lines = res.stdout.strip().splitlines()
    names = [line.split()[0] for line in lines]
    assert names == builtin_names() == ["dc-motor-eso", "emps", "test-1", "test-1-urdf",
                                        "test-2", "two-link", "uno-rig"]
    # one column of descriptions after the longest name, each a complete sentence
    column = max(map(len, names)) + 2
    for line in lines:
        name, text = line[:column].rstrip(), line[column:]
        assert name in names and text[:1] not in ("", " "), line
        assert text.endswith("."), line


@pytest.mark.parametrize("name", builtin_names())
def test_show_round_trip(run_cli, tmp_path, name):
    """`esoarm show X` loaded back gives the same scenario (all keys printed)."""
    res = run_cli("show", name)
    assert res.exit_code == 0
    path = tmp_path / "shown.toml"
    path.write_text(res.stdout, encoding="utf-8")
    assert load_scenario(path) == load_scenario(name)
    again = run_cli("show", str(path))
    assert again.stdout == res.stdout


def test_show_round_trip_with_overrides(run_cli, tmp_path):
    sets = ["observer.eps=0.05", "observer.discretization=current", "reference.phases=[0.3]",
            "reference.offset=0.1", "rig.disturbance.amplitude=0", "actuator.lag=0.02",
            "sensor.seed=7", "name=my run"]
    args = ["show", "test-2"]
    for item in sets:
        args += ["--set", item]
    res = run_cli(*args)
    assert res.exit_code == 0, res.stderr
    path = tmp_path / "shown.toml"
    path.write_text(res.stdout, encoding="utf-8")
    back = load_scenario(path)
    assert back == load_scenario("test-2", sets)
    assert back.name == "my run" and back.observer.discretization == "current"
    assert back.reference.phases == [0.3]


def test_simulate_json_matches_api(run_cli):
    from esoarm.engines.simulation import simulate

    res = run_cli("simulate", "test-1", "--set", "duration=4", "--json")
    assert res.exit_code == 0, res.stderr
    data = json.loads(res.stdout)
    ref = simulate("test-1", {"duration": 4.0})
    for key in ("rms_error", "rms_u", "max_abs_error"):
        assert data[key] == ref.metrics[key]
    assert data["samples"] == 200


def test_simulate_writes_csv(run_cli, tmp_path):
    from esoarm.engines.simulation import simulate

    out = tmp_path / "deep" / "run.csv"
    res = run_cli("simulate", "test-2", "--set", "duration=2", "--set",
                  "observer.discretization=zoh", "--out", str(out))
    assert res.exit_code == 0, res.stderr
    assert str(out) in res.stdout
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == CSV_COLUMNS
    table = [[float(v) for v in row] for row in rows[1:]]
    ref = simulate("test-2", {"duration": 2.0, "observer.discretization": "zoh"}).table()
    assert len(table) == len(ref) == 100
    # %.17g round-trips doubles exactly
    assert all(a == b for row, rrow in zip(table, ref, strict=True)
               for a, b in zip(row, rrow, strict=True))
    assert [p.name for p in out.parent.iterdir()] == ["run.csv"]


def test_simulate_prints_metrics_table(run_cli):
    res = run_cli("simulate", "test-1", "--set", "duration=2")
    assert res.exit_code == 0
    assert "RMS tracking error" in res.stdout and "rad" in res.stdout


@pytest.mark.parametrize("command", ["simulate", "show", "scenarios", "reproduce"])
def test_help_has_units(run_cli, command):
    res = run_cli(command, "--help")
    assert res.exit_code == 0
    if command == "simulate":
        for unit in ("[rad]", "[N·m]", "[s]"):
            assert unit in res.stdout


def test_top_level_help_lists_commands(run_cli):
    res = run_cli("--help")
    assert res.exit_code == 0
    for name in ("simulate", "show", "scenarios", "reproduce"):
        assert name in res.stdout


def test_json_values_are_finite(run_cli):
    res = run_cli("simulate", "test-2", "--set", "duration=1", "--json")
    data = json.loads(res.stdout)
    assert all(math.isfinite(data[k]) for k in ("rms_error", "rms_u", "max_abs_error"))


def test_same_command_same_bytes(run_cli, tmp_path):
    """Determinism end to end: two runs write byte-identical CSV files."""
    paths = [tmp_path / "a.csv", tmp_path / "b.csv"]
    for path in paths:
        res = run_cli("simulate", "test-2", "--set", "duration=3", "--set", "sensor.seed=4",
                      "--set", "observer.discretization=current", "--out", str(path))
        assert res.exit_code == 0
    assert paths[0].read_bytes() == paths[1].read_bytes()


@pytest.mark.parametrize(
    ("args", "fragment"),
    [(["simulate"], "Missing argument 'SCENARIO'"),
     (["simulate", "test-1", "--sett", "x=1"], "'--set'"),
     (["simulate", "test-1", "--out"], "requires an argument")],
    ids=["missing-argument", "unknown-option", "option-without-value"],
)
def test_command_line_syntax_errors(run_cli, args, fragment):
    """click's usage errors: exit 2, no traceback, the error line names the problem.

    (click prints its usage line and a help hint above the one error line.)
    """
    res = run_cli(*args)
    assert res.exit_code == 2 and res.exception is None
    assert "Traceback" not in res.stderr
    errors = [ln for ln in res.stderr.splitlines() if "rror" in ln]
    assert len(errors) == 1 and fragment in errors[0], res.stderr


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS semantics")
def test_out_of_memory_is_one_line_exit_1(tmp_path):
    """A run too large for the machine fails in one line, not with a traceback.

    ``simulate`` streams a run this long in constant memory (tests/engines/test_streaming.py),
    so the in-memory engine's out-of-memory path is reached here with streaming turned off
    (``esoarm._limits.STREAM_SAMPLES`` raised before the engines are imported)."""
    import resource

    def limit():  # 1.2 GB of address space: the 1e8-sample arrays cannot fit
        resource.setrlimit(resource.RLIMIT_AS, (1_200_000_000, 1_200_000_000))

    out = tmp_path / "big.csv"
    code = ("import sys; import esoarm._limits as L; L.STREAM_SAMPLES = 10**12; "
            "from esoarm.cli import main; main(sys.argv[1:])")
    proc = subprocess.run(
        [sys.executable, "-c", code,
         "simulate", "test-1", "--set", "duration=1e6", "--set", "sensor.rate_hz=100",
         "--out", str(out)],
        capture_output=True, text=True, timeout=120, preexec_fn=limit,
    )
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines()
             if not ln.startswith("esoarm: warning: ")]  # the run-of-hours warning comes first
    assert len(lines) == 1 and lines[0].startswith("esoarm: failed: out of memory"), proc.stderr
    assert not out.exists()
