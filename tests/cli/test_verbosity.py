"""--quiet, --verbose and --json on every command: results on stdout, the rest on stderr."""

from __future__ import annotations

import json

import click
import pytest

from esoarm.cli import cli

COMMANDS = cli.list_commands(click.Context(cli))
RISKY = ["--set", "observer.eps=0.012", "--set", "duration=0.5"]  # warns (Euler, Ts/ε > 1)


@pytest.mark.parametrize("name", COMMANDS)
def test_every_command_has_quiet_and_verbose(run_cli, name):
    res = run_cli(name, "--help")
    assert res.exit_code == 0
    assert "--quiet" in res.stdout and "--verbose" in res.stdout


def test_quiet_and_verbose_exclude_each_other(run_cli):
    res = run_cli("show", "test-1", "--quiet", "--verbose")
    assert res.exit_code == 2
    assert res.stderr.strip() == "esoarm: error: --quiet and --verbose exclude each other; give one"


def test_quiet_silences_warnings_not_results_or_errors(run_cli):
    loud = run_cli("simulate", "test-1", *RISKY, "--json")
    assert loud.exit_code == 0 and "esoarm: warning:" in loud.stderr
    quiet = run_cli("simulate", "test-1", *RISKY, "--json", "--quiet")
    assert quiet.exit_code == 0 and quiet.stderr == ""
    assert json.loads(quiet.stdout) == json.loads(loud.stdout)
    err = run_cli("simulate", "test-1", "--set", "observer.eps=0", "--quiet")
    assert err.exit_code == 2 and err.stderr.startswith("esoarm: error: ")


def test_quiet_before_the_command_works_too(run_cli):
    res = run_cli("--quiet", "simulate", "test-1", *RISKY, "--json")
    assert res.exit_code == 0 and res.stderr == ""


def test_verbose_says_what_is_done(run_cli):
    res = run_cli("simulate", "test-1", *RISKY, "--json", "--verbose")
    assert res.exit_code == 0
    assert "esoarm: scenario 'test-1': 25 samples at 50 Hz" in res.stderr
    json.loads(res.stdout)


@pytest.mark.parametrize("args", [
    ["simulate", "test-1", *RISKY],
    ["sweep", "test-1", "--vary", "observer.eps=0.012,0.05", "--set", "duration=0.5"],
    ["tune", "test-1", "--vary", "observer.eps=0.03:0.1", "--set", "duration=0.5",
     "--maxiter", "1", "--popsize", "2", "--seeds", "1", "--no-plot"],
], ids=["simulate", "sweep", "tune"])
@pytest.mark.parametrize("level", [[], ["--verbose"]], ids=["normal", "verbose"])
def test_json_stdout_is_exactly_one_object(run_cli, args, level):
    res = run_cli(*args, "--json", *level)
    assert res.exit_code == 0, res.stderr
    assert isinstance(json.loads(res.stdout), dict)  # nothing else on stdout
    assert res.stdout.count("\n") == 1
