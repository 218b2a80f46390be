"""Every script in examples/ runs to completion, as a user would run it, and writes its outputs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # end to end (the fast tier is -m 'not slow')

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))

#: Files each example must write into its output directory.
OUTPUTS = {
    "single_run.py": ("single_run.csv", "single_run.png"),
    "compare_compensation.py": ("heavy-disturbance.toml", "compare_compensation.png"),
    "observer_design.py": (),
    "two_link_arm.py": ("two_link.csv", "two_link.png"),
    "arm_ur5.py": (),  # needs example-robot-data (optional): it says so and stops without it
    "gym_loop.py": ("gym_frame.png",),
    "identify_twin.py": ("excite.csv", "fitted.toml", "identify.png"),
}


def test_every_example_is_known():
    assert {p.name for p in EXAMPLES} == set(OUTPUTS)


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(script, tmp_path):
    out = tmp_path / "out"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, str(script), str(out)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120, check=False)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.strip()
    assert "Traceback" not in res.stderr
    for name in OUTPUTS[script.name]:
        path = out / name
        assert path.is_file() and path.stat().st_size > 0, name
