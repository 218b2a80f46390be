"""Shared pieces of the command line: errors, --set, scenario loading, outputs."""

from __future__ import annotations

import functools
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

if TYPE_CHECKING:  # imported where used: `esoarm --help` must not load pydantic
    from esoarm.scenario import Scenario

F = TypeVar("F", bound=Callable[..., Any])

PLOT_SUFFIXES = (".png", ".pdf", ".svg")


class BadInput(click.ClickException):
    """Bad input from the user: one line on stderr, exit status 2."""

    exit_code = 2

    def show(self, file: Any = None) -> None:
        click.echo(f"esoarm: error: {self.format_message()}", err=True)


class RunFailure(click.ClickException):
    """A failure at run time (diverged run, lost link): one line, exit status 1."""

    exit_code = 1

    def show(self, file: Any = None) -> None:
        click.echo(f"esoarm: failed: {self.format_message()}", err=True)


def show_warning(message, category, filename, lineno, file=None, line=None):  # type: ignore[no-untyped-def]
    """Print warnings as one line on stderr (ScenarioWarning without a location)."""
    from esoarm.scenario import ScenarioWarning

    if issubclass(category, ScenarioWarning):
        click.echo(f"esoarm: warning: {message}", err=True)
    else:
        click.echo(f"esoarm: warning: {category.__name__}: {message}", err=True)


def bad_input_guard(func: F) -> F:
    """Turn :class:`ScenarioError` raised inside a command into exit status 2."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from esoarm.scenario import ScenarioError

        try:
            return func(*args, **kwargs)
        except ScenarioError as exc:
            raise BadInput(str(exc)) from None

    return wrapper  # type: ignore[return-value]


def set_option(func: F) -> F:
    """The repeatable ``--set KEY=VALUE`` option."""
    return click.option(
        "--set",
        "overrides",
        multiple=True,
        metavar="KEY=VALUE",
        help="Override a dotted scenario key, value parsed as TOML (strings need no quotes), "
        "e.g. --set observer.eps=0.05 --set observer.discretization=zoh. Repeatable.",
    )(func)


def scenario_argument(func: F) -> F:
    """The positional SCENARIO argument (built-in name or TOML path)."""
    return click.argument("scenario", metavar="SCENARIO")(func)


def resolve_scenario(name: str, overrides: tuple[str, ...] | list[str]) -> Scenario:
    """Load a scenario with overrides and print its warnings (one line each)."""
    from esoarm.scenario import ScenarioWarning, load_scenario, scenario_warnings

    scn = load_scenario(name, list(overrides))

    for msg in scenario_warnings(scn):
        warnings.warn(msg, ScenarioWarning, stacklevel=2)
    return scn


def output_path(value: str | None, option: str, suffixes: tuple[str, ...]) -> Path | None:
    """Check an output path before any work: allowed suffix, not a directory."""
    if value is None:
        return None
    path = Path(value)
    if path.suffix.lower() not in suffixes:
        raise BadInput(f"{option} '{value}': the file name must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise BadInput(f"{option} '{value}': is a directory, expected a file name")
    if path.parent.exists() and not path.parent.is_dir():
        raise BadInput(f"{option} '{value}': '{path.parent}' is not a directory")
    return path


def stderr_is_tty() -> bool:
    """Whether progress displays should be drawn."""
    return sys.stderr.isatty()
