"""Shared fixtures: undo global state, run the CLI the way ``esoarm.cli.main`` does."""

from __future__ import annotations

import subprocess
import sys
import warnings
from dataclasses import dataclass

import pytest
from hypothesis import HealthCheck, settings

# Bounded, deterministic property tests in CI (2 cores, shared budget).
settings.register_profile(
    "esoarm", max_examples=60, deadline=None, derandomize=True, database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("esoarm")


@pytest.fixture(autouse=True)
def _restore_global_state():
    """Undo what a test may change globally: warning filters/printer, figures."""
    saved_show = warnings.showwarning
    with warnings.catch_warnings():
        yield
    warnings.showwarning = saved_show
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")


@dataclass
class CliResult:
    """Exit status and the two output streams of one CLI invocation."""

    exit_code: int
    stdout: str
    stderr: str
    exception: BaseException | None = None


@pytest.fixture
def run_cli():
    """Invoke the ``esoarm`` group in-process, with the handling of ``main``.

    Like :func:`esoarm.cli.main`: warnings are printed by ``show_warning`` (one
    line on stderr), and click's standalone mode maps BadInput to exit 2 and
    RunFailure to exit 1.  Every warning is shown (no once-per-location).
    """
    from click.testing import CliRunner

    from esoarm.cli import cli
    from esoarm.cli._common import show_warning

    def invoke(*args: str) -> CliResult:
        runner = CliRunner()
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = show_warning
            res = runner.invoke(cli, list(args), prog_name="esoarm")
        exc = res.exception if not isinstance(res.exception, SystemExit) else None
        return CliResult(res.exit_code, res.stdout, res.stderr, exc)

    return invoke


@pytest.fixture
def run_esoarm():
    """Run the real console entry point ``esoarm.cli.main`` in a subprocess."""

    def invoke(*args: str, cwd=None) -> CliResult:
        proc = subprocess.run(
            [sys.executable, "-c", "import sys; from esoarm.cli import main; main(sys.argv[1:])",
             *args],
            capture_output=True, text=True, cwd=cwd, timeout=120,
        )
        return CliResult(proc.returncode, proc.stdout, proc.stderr)

    return invoke
