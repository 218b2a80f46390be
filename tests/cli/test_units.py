"""Units by plant kind: a prismatic axis prints m, m/s, N; every rotary plant rad, N·m.

Every table, JSON ``"units"`` field and plot label reads :func:`esoarm.kinds.units`;
these tests run the commands on the built-in prismatic axis (``emps``) and on the lever
arm (``test-1``) and read what they print.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from esoarm.contract import PRISMATIC_UNITS, ROTARY_UNITS, Units
from esoarm.engines.metrics import METRICS, metric_units
from esoarm.kinds import PLANTS, hook, units
from esoarm.scenario import builtin_names, load_scenario


def test_units_follow_the_plant_kind():
    assert units(load_scenario("emps")) == PRISMATIC_UNITS
    assert units(load_scenario("emps", {"plant.motion": "rotary"})) == ROTARY_UNITS
    assert units(load_scenario("test-1")) == ROTARY_UNITS
    assert units(None) == ROTARY_UNITS
    for name in builtin_names():
        scn = load_scenario(name)
        prismatic = scn.plant.kind == "axis" and scn.plant.motion == "prismatic"
        if scn.plant.kind == "dc-motor":  # a speed loop: rad/s measured, V applied
            from esoarm.plants.dc_motor import SPEED_UNITS

            assert units(scn) == SPEED_UNITS, name
            continue
        assert units(scn) == (PRISMATIC_UNITS if prismatic else ROTARY_UNITS), name


def test_every_plant_kind_names_its_units_or_is_rotary():
    for module in PLANTS:
        fn = hook(module, "units_of")
        if fn is not None:
            assert isinstance(fn(module.Params()), Units), module.KIND


def test_metric_units_cover_every_metric():
    for u in (ROTARY_UNITS, PRISMATIC_UNITS):
        assert set(metric_units(u)) == set(METRICS)
    assert metric_units(PRISMATIC_UNITS)["rms_error"] == "m"
    assert metric_units(PRISMATIC_UNITS)["rms_f_error"] == "m/s²"
    assert metric_units(ROTARY_UNITS)["rms_u"] == "N·m"


def _table_units(stdout: str) -> dict[str, str]:
    """metric label -> unit column of a rich simulate table."""
    out = {}
    for line in stdout.splitlines():
        cells = [c.strip() for c in line.strip("│┃ ").split("│")]
        if len(cells) == 3 and cells[0] in ("RMS tracking error", "RMS control", "max |error|"):
            out[cells[0]] = cells[2]
    return out


def test_simulate_prismatic_axis_says_m_and_n(run_cli):
    res = run_cli("simulate", "emps", "--set", "duration=0.5")
    assert res.exit_code == 0, res.stderr
    assert _table_units(res.stdout) == {"RMS tracking error": "m", "RMS control": "N",
                                        "max |error|": "m"}
    assert "rad" not in res.stdout and "N·m" not in res.stdout
    res = run_cli("simulate", "emps", "--set", "duration=0.5", "--json")
    data = json.loads(res.stdout)
    assert data["units"]["rms_error"] == "m" and data["units"]["rms_u"] == "N"
    assert data["units"]["rms_rate_error"] == "m/s"
    # a micrometre error keeps its digits (a rotary table's 5 decimals would print 0.00003)
    value = next(c.strip() for line in run_cli("simulate", "emps", "--set", "duration=0.5"
                                               ).stdout.splitlines()
                 if "RMS tracking error" in line for c in [line.split("│")[2]])
    assert float(value) == pytest.approx(data["rms_error"], rel=1e-3)


def test_simulate_rotary_table_unchanged(run_cli):
    res = run_cli("simulate", "test-1", "--set", "duration=2")
    assert _table_units(res.stdout) == {"RMS tracking error": "rad", "RMS control": "N·m",
                                        "max |error|": "rad"}
    data = json.loads(run_cli("simulate", "test-1", "--set", "duration=2", "--json").stdout)
    assert data["units"]["rms_error"] == "rad" and data["units"]["rms_u"] == "N·m"
    # five decimals, as the paper's tables
    assert f"{data['rms_error']:.5f}" in res.stdout


def test_run_plot_labels_follow_the_units():
    from esoarm.engines.simulation import simulate
    from esoarm.plotting.run import plot_run

    fig = plot_run(simulate(load_scenario("emps", {"duration": 0.2}), warn=False))
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["position [m]", "tracking error [m]", "control u [N]",
                      "perturbation [m/s²]"]
    assert " m, RMS u " in fig.get_suptitle() and fig.get_suptitle().endswith(" N")
    fig = plot_run(simulate(load_scenario("test-1", {"duration": 0.2}), warn=False))
    assert [ax.get_ylabel() for ax in fig.axes] == [
        "angle [rad]", "tracking error [rad]", "control u [N·m]", "perturbation [rad/s²]"]


def test_replay_prismatic_axis_plot_labels(tmp_path):
    from esoarm.hardware.replay import replay
    from esoarm.plotting.run import figure_replay

    scn = load_scenario("emps")
    t = np.arange(200) * 1e-3
    res = replay(scn, t, 0.01 * np.sin(t), 30.0 * np.ones_like(t), 1e-3)
    labels = [ax.get_ylabel() for ax in figure_replay(res).axes]
    assert labels == ["position [m]", "ẑ2 rate [m/s]", "ẑ3 perturbation [m/s²]", "u [N]"]
    res = replay(load_scenario("test-1"), t, 0.01 * np.sin(t), np.zeros_like(t), 1e-3)
    assert figure_replay(res).axes[0].get_ylabel() == "angle [rad]"


def test_replay_command_on_prismatic_axis(run_cli, tmp_path):
    log = tmp_path / "log.csv"
    t = np.arange(300) * 1e-3
    np.savetxt(log, np.column_stack([t, 0.02 * t, 25.0 + 0 * t]), delimiter=",",
               header="t,y,u", comments="")
    out, fig = tmp_path / "z.csv", tmp_path / "z.png"
    res = run_cli("replay", str(log), "--scenario", "emps", "--out", str(out), "--plot", str(fig))
    assert res.exit_code == 0, res.stderr
    assert fig.read_bytes()[:4] == b"\x89PNG" and out.is_file()


def test_sweep_plot_labels_follow_the_units():
    from esoarm.studies.sweeps.plots import _label, _metric_label

    assert _label("plant.mass", PRISMATIC_UNITS) == "plant.mass [kg]"
    assert _label("plant.viscous_friction", PRISMATIC_UNITS) == "plant.viscous_friction [N·s/m]"
    assert _label("actuator.torque_limit", PRISMATIC_UNITS) == "actuator.torque_limit [N]"
    assert _label("actuator.torque_limit") == "actuator.torque_limit [N·m]"
    assert _label("rig.coulomb_friction") == "rig.coulomb_friction [N·m]"
    assert _label("observer.eps", PRISMATIC_UNITS) == "observer.eps [s]"
    assert _metric_label("RMS control", "force", PRISMATIC_UNITS) == "RMS control [N]"


def test_pareto_labels_follow_the_units():
    from esoarm.studies.sweeps.plots import figure_pareto

    fig = figure_pareto([1.0, 2.0], [0.2, 0.1], units=PRISMATIC_UNITS)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("RMS control [N]", "RMS tracking error [m]")
    ax = figure_pareto([1.0, 2.0], [0.2, 0.1]).axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("RMS control [N·m]",
                                                  "RMS tracking error [rad]")


@pytest.mark.slow  # the axis's batch kernels compile with numba (a minute or more)
def test_sweep_prismatic_axis_table_json_and_plot(run_cli, tmp_path):
    png = tmp_path / "s.png"
    res = run_cli("sweep", "emps", "--set", "duration=0.3", "--vary", "plant.mass=90,100",
                  "--plot", str(png))
    assert res.exit_code == 0, res.stderr
    assert "RMS error [m]" in res.stdout and "RMS u [N]" in res.stdout
    assert "rad" not in res.stdout and "N·m" not in res.stdout
    assert png.read_bytes()[:4] == b"\x89PNG"
    res = run_cli("sweep", "emps", "--set", "duration=0.3", "--vary", "plant.mass=90,100",
                  "--json")
    data = json.loads(res.stdout)
    assert data["units"]["rms_error"] == "m" and data["units"]["max_abs_u"] == "N"


def test_identify_axis_refuses_plot_it_cannot_draw(run_cli, tmp_path):
    log = tmp_path / "log.csv"
    t = np.arange(300) * 1e-3
    np.savetxt(log, np.column_stack([t, 0.02 * t, 25.0 + 0 * t]), delimiter=",",
               header="t,y,u", comments="")
    res = run_cli("identify", str(log), "--scenario", "emps", "--plot", str(tmp_path / "f.png"))
    assert res.exit_code == 2
    assert "--plot" in res.stderr and "axis" in res.stderr
    assert not (tmp_path / "f.png").exists()


def test_divergence_and_saturation_messages_name_the_units(run_cli):
    from esoarm.engines.diagnosis import saturation_warning, what_left

    assert what_left(2e6, 0.0, 0.0, 0.0, 0.0, 1e6) == "the angle θ = 2e+06 rad"
    assert what_left(2e6, 0.0, 0.0, 0.0, 0.0, 1e6, PRISMATIC_UNITS) == "the position θ = 2e+06 m"
    assert saturation_warning(0.9, 0.5).startswith("the command sat at the torque limit ±0.5 N·m")
    assert saturation_warning(0.9, 35.0, PRISMATIC_UNITS).startswith(
        "the command sat at the force limit ±35 N in 90 %")
    res = run_cli("simulate", "emps", "--set", "duration=0.5", "--set",
                  "actuator.torque_limit=1")
    assert "force limit ±1 N in" in res.stderr and "N·m" not in res.stderr
