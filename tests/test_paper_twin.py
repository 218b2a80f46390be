"""The twin calibrated to the paper: the shipped values reproduce the recorded loss, the
report shows both twins."""

from __future__ import annotations

import math

import pytest

from esoarm.scenario import ScenarioError, load_scenario
from esoarm.studies.paper_twin import (
    SEARCH,
    SEEDS,
    TWIN_NAMES,
    load_twin,
    paper_residuals,
    twin_overrides,
)
from esoarm.studies.reproduce import run_reproduction
from esoarm.studies.twins_report import GAINS_FREE, compared_twins, twin_rows, twins_section


def test_twins_are_valid_overlays():
    assert load_twin("nominal") == ({}, {})
    values, record = load_twin("paper")
    assert set(values) <= set(SEARCH) | {"actuator.delay_samples"}
    for test in ("test-1", "test-2"):
        scn = load_scenario(test, twin_overrides("paper"))
        for key, value in values.items():
            section, name = key.split(".")
            assert getattr(getattr(scn, section), name) == value
    assert record["seeds"] == list(SEEDS)
    with pytest.raises(ScenarioError, match="one of nominal, paper"):
        load_twin("hardware")
    assert TWIN_NAMES == ("nominal", "paper")


def test_recorded_loss_is_the_loss_of_the_shipped_values():
    """The calibration record is recomputed from the shipped values, not trusted."""
    values, record = load_twin("paper")
    resid, _ = paper_residuals(values, tuple(record["seeds"]))
    loss = float(resid @ resid)
    assert loss == pytest.approx(record["loss"], rel=1e-9)
    nominal, _ = paper_residuals({}, tuple(record["seeds"]))
    assert loss < 0.5 * float(nominal @ nominal)


def test_recorded_gain_evidence_is_recomputed():
    """The evidence that the gains stand in the way: the recorded loss with the gains free."""
    _values, record = load_twin("paper")
    free = record.get("with_gains_free")
    if free is None:
        pytest.skip("no gain evidence recorded")
    resid, _ = paper_residuals(free["values"], tuple(record["seeds"]))
    assert float(resid @ resid) == pytest.approx(free["loss"], rel=1e-9)
    assert free["loss"] < record["loss"]


def test_twins_section_shows_both_twins():
    nominal = run_reproduction(compare=False)
    reps = compared_twins({"nominal": nominal})
    assert reps["nominal"] is nominal and set(TWIN_NAMES) <= set(reps)
    rows = twin_rows(reps)
    assert len(rows) == 12
    for row in rows:
        for name in reps:
            assert math.isclose(row[f"{name}_ratio"], row[name] / row["published"])
    row = next(r for r in rows if (r["test"], r["eps"], r["metric"]) == ("test-1", 0.09, "rms_u"))
    assert row["published"] == 0.4141  # Table II, quoted
    assert row["paper"] == reps["paper"].metric("test-1", 0.09, "rms_u")
    text = twins_section(reps)
    for word in ("nominal twin", "paper twin", "Table II", "Table III", "claims",
                 "range", "rig.coulomb_friction", "What stands in the way"):
        assert word in text
    if GAINS_FREE in reps:
        assert "stand in the way" in text


def test_cli_reproduce_on_the_paper_twin(run_cli, tmp_path):
    import json

    out = tmp_path / "res"
    res = run_cli("reproduce", "--twin", "paper", "--out", str(out))
    assert res.exit_code == 0, res.stderr
    assert "esoarm: the paper digital" in res.stdout
    data = json.loads((out / "tables.json").read_text())
    rep = run_reproduction(twin_overrides("paper"), compare=False)
    row = next(r for r in data["tables"] if r["test"] == "test-1" and r["eps"] == 0.09
               and r["compensation"] == "eso")
    assert row["rms_u"] == rep.metric("test-1", 0.09, "rms_u")
    html = (out / "report.html").read_text()
    assert 'id="twins"' in html and "nominal twin" in html
