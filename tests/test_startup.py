"""Quick start: each command imports only what it needs.

No timing here (the benchmarks measure it); these tests pin down *what* is
imported, which is what start-up time depends on.
"""

from __future__ import annotations

import subprocess
import sys

import click
import numpy as np
import pytest

from esoarm.cli import COMMANDS, SUMMARIES, cli
from esoarm.engines.simulation import reference_metrics
from esoarm.scenario import load_scenario

HEAVY = ("numba", "pydantic", "numpy", "rich", "matplotlib", "dask", "distributed", "scipy")


def _modules_after(code: str) -> set[str]:
    probe = (f"import sys\n{code}\n"
             f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout.split("\n")[-2]
    return set(out.split())


def test_help_imports_nothing_heavy() -> None:
    code = ("from esoarm.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass")
    assert _modules_after(code) == set()


def test_import_esoarm_is_light_until_used() -> None:
    assert _modules_after("import esoarm") == set()
    assert "numba" not in _modules_after("import esoarm.engines.simulation")
    assert "pydantic" in _modules_after("import esoarm; esoarm.load_scenario")


def test_small_sweep_loads_no_compiled_engine() -> None:
    code = ("from esoarm.cli import main\n"
            "try:\n    main(['sweep', 'test-1', '--set', 'duration=0.2', "
            "'--vary', 'observer.eps=0.09'])\nexcept SystemExit:\n    pass")
    loaded = _modules_after(code)
    assert "numba" not in loaded and "matplotlib" not in loaded and "dask" not in loaded
    assert "scipy" not in loaded


def test_grid_warnings_need_no_scipy() -> None:
    # ε = 0.03 s < 2·Ts warns (zoh); the observer check must not pull in the linearization
    code = ("from esoarm.scenario import load_scenario\n"
            "from esoarm.studies.sweeps.grid import build_grid\n"
            "g = build_grid(load_scenario('test-1', {'observer.discretization': 'zoh'}), "
            "['observer.eps=0.03,0.09'])\n"
            "assert g.warnings(), g.warnings()")
    assert "scipy" not in _modules_after(code)


def test_fast_engine_loads_no_numba() -> None:
    from esoarm.engines import fast

    if not fast.available():  # it falls back to the exact engine (numba), with a warning
        pytest.skip("no C compiler here for the fast engine")
    code = ("from esoarm.cli import main\n"
            "try:\n    main(['sweep', 'test-1', '--set', 'duration=0.2', '--engine', 'fast', "
            "'--vary', 'observer.eps=0.09'])\nexcept SystemExit:\n    pass")
    loaded = _modules_after(code)
    assert "numba" not in loaded and "scipy" not in loaded


def test_analysis_still_offers_the_linearization() -> None:
    """The one-import API offers the linearization (the observer's stability module, which
    every scenario check imports, no longer re-exports it: that was an import cycle)."""
    from esoarm import analysis
    from esoarm.studies.frequency import linearization

    assert analysis.to_control is linearization.to_control
    assert analysis.ControlLoop is linearization.ControlLoop


def test_command_summaries_match_the_commands() -> None:
    ctx = click.Context(cli)
    missing = sorted(set(COMMANDS) - set(SUMMARIES))
    assert not missing, f"add the one-line summary of {missing} to esoarm.cli.SUMMARIES"
    assert set(SUMMARIES) <= set(COMMANDS)
    for name, summary in SUMMARIES.items():
        cmd = cli.get_command(ctx, name)
        assert cmd is not None
        assert cmd.get_short_help_str(limit=200) == summary, name


def test_reference_metrics_equal_the_compiled_engine() -> None:
    from esoarm.engines import batch

    pts = [load_scenario("test-1", {"duration": 3.0, "observer.eps": e,
                                    "actuator.delay_samples": d})
           for e in (0.008, 0.05, 0.2) for d in (0, 2)]  # ε = 0.008 s diverges
    ref = reference_metrics(pts, seeds=[0, 3]).values
    np.testing.assert_array_equal(ref, batch.run_metrics(pts, seeds=[0, 3]).values)
    assert ref[:4, -1].all() and not ref[4:, -1].any()


@pytest.mark.slow  # loads (or, on a cold cache, compiles) the metrics kernel
def test_compiled_sweep_loads_no_scipy_linalg() -> None:
    """numba's BLAS probe (an import of all of scipy.linalg, ~0.3 s) is kept off a sweep's
    start-up, and numba's linear algebra still works in the same process afterwards."""
    code = ("from esoarm.cli import main\n"
            "try:\n    main(['sweep', 'test-1', '--set', 'duration=0.2', "
            "'--vary', 'observer.eps=0.05,0.09', '--seeds', '4'])\nexcept SystemExit:\n    pass\n"
            "assert 'scipy.linalg' not in sys.modules\n"
            "import numpy as np, numba\n"
            "from numba.np import arraymath, linalg\n"
            "assert arraymath._HAVE_BLAS and linalg.ensure_blas.__module__ == 'numba.np.linalg'\n"
            "solve = numba.njit(lambda a, b: np.linalg.solve(a, b))\n"
            "assert solve(2.0 * np.eye(2), np.ones(2)).tolist() == [0.5, 0.5]")
    loaded = _modules_after(code)
    assert "numba" in loaded and "scipy" in loaded  # scipy's package (7 ms), not its linalg
