"""Shared pieces of the command line: errors, verbosity, --set, scenario loading, outputs.

Every command gets these without doing anything: ``--quiet``/``--verbose``
(added to each command by the group, see :func:`add_verbosity_options`), the
mapping of library errors to exit codes (in :func:`esoarm.cli.main`), and the
one-line warnings.  A command that writes files checks its output paths with
:func:`output_path` / :func:`output_dir` before any work and writes them
through :func:`esoarm._io.atomic_path`.
"""

from __future__ import annotations

import contextlib
import functools
import math
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from esoarm._io import OutputError, check_writable

if TYPE_CHECKING:  # imported where used: `esoarm --help` must not load pydantic
    from esoarm.scenario import Scenario

F = TypeVar("F", bound=Callable[..., Any])

PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def one_line(text: str) -> str:
    """``text`` with control characters escaped, so that a message is one line whatever it quotes.

    (A key given as ``'0\\r0'`` must not break the one-line error in two.)

    Parameters
    ----------
    text : str
        A message, or a piece of one quoting user input.

    Returns
    -------
    str
        ``text`` itself when it is printable, else with each control character as its escape.
    """
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class BadInput(click.ClickException):
    """Bad input from the user: one line on stderr, exit status 2."""

    exit_code = 2

    def show(self, file: Any = None) -> None:
        """Print the one-line error on stderr.

        Parameters
        ----------
        file : optional
            Unused (click's signature): the line always goes to stderr.
        """
        click.echo(f"esoarm: error: {one_line(self.format_message())}", err=True)


class RunFailure(click.ClickException):
    """A failure at run time (diverged run, lost link): one line, exit status 1."""

    exit_code = 1

    def show(self, file: Any = None) -> None:
        """Print the one-line failure on stderr.

        Parameters
        ----------
        file : optional
            Unused (click's signature): the line always goes to stderr.
        """
        click.echo(f"esoarm: failed: {one_line(self.format_message())}", err=True)


class Interrupted(click.ClickException):
    """Ctrl-C (or SIGTERM): one line on stderr saying what was kept, exit status 130."""

    exit_code = 130

    def show(self, file: Any = None) -> None:
        """Print the one-line interruption, with what was kept, on stderr.

        Parameters
        ----------
        file : optional
            Unused (click's signature): the line always goes to stderr.
        """
        click.echo(f"esoarm: interrupted: {one_line(self.format_message())}", err=True)


# ---------------------------------------------------------------------------
# verbosity: 0 quiet, 1 normal, 2 verbose (reset for every invocation)

QUIET, NORMAL, VERBOSE = 0, 1, 2
_state = {"level": NORMAL, "quiet": False, "verbose": False}


def reset_verbosity() -> None:
    """Back to normal output (called at the start of every invocation)."""
    _state.update(level=NORMAL, quiet=False, verbose=False)


def verbosity() -> int:
    """The current level.

    Returns
    -------
    int
        :data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`.
    """
    return int(_state["level"])


def _set_level(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if not value:
        return
    assert param.name is not None
    _state[param.name] = True
    if _state["quiet"] and _state["verbose"]:
        raise BadInput("--quiet and --verbose exclude each other; give one")
    _state["level"] = QUIET if param.name == "quiet" else VERBOSE


QUIET_HELP = "Print only the results and errors: no progress, warnings or notes on stderr."
VERBOSE_HELP = ("Also print what is done, step by step, on stderr (progress lines even when "
                "stderr is not a terminal, files written, timings).")


def verbosity_params() -> list[click.Option]:
    """Fresh ``-q/--quiet`` and ``-v/--verbose`` options (they only set the level).

    Returns
    -------
    list of click.Option
        The two options, eager, exposing no value to the command.
    """
    return [
        click.Option(["-q", "--quiet"], is_flag=True, expose_value=False, is_eager=True,
                     callback=_set_level, help=QUIET_HELP),
        click.Option(["-v", "--verbose"], is_flag=True, expose_value=False, is_eager=True,
                     callback=_set_level, help=VERBOSE_HELP),
    ]


def add_verbosity_options(cmd: click.Command) -> click.Command:
    """Give ``cmd`` the ``--quiet``/``--verbose`` options (once).

    Parameters
    ----------
    cmd : click.Command
        A command of the group.

    Returns
    -------
    click.Command
        ``cmd`` itself, its options extended where it had none of the two.
    """
    if not any(p.name in ("quiet", "verbose") for p in cmd.params):
        cmd.params.extend(verbosity_params())
    return cmd


def note(message: str) -> None:
    """An informational line on stderr (not shown with --quiet).

    Parameters
    ----------
    message : str
        The text, without the ``esoarm:`` prefix.
    """
    if verbosity() >= NORMAL:
        click.echo(f"esoarm: {message}", err=True)


def detail(message: str) -> None:
    """A line shown only with --verbose, on stderr.

    Parameters
    ----------
    message : str
        The text, without the ``esoarm:`` prefix.
    """
    if verbosity() >= VERBOSE:
        click.echo(f"esoarm: {message}", err=True)


def warn_line(message: str) -> None:
    """A one-line warning on stderr (not shown with --quiet).

    Parameters
    ----------
    message : str
        The warning, without the ``esoarm: warning:`` prefix.
    """
    if verbosity() >= NORMAL:
        click.echo(f"esoarm: warning: {one_line(message)}", err=True)


def show_warning(message, category, filename, lineno, file=None, line=None):  # type: ignore[no-untyped-def]
    """Print warnings as one line on stderr (ScenarioWarning without a location).

    Installed as :func:`warnings.showwarning`; nothing is shown with --quiet.

    Parameters
    ----------
    message : Warning or str
        The warning.
    category : type
        Its class (a :class:`~esoarm.scenario.ScenarioWarning` is printed without its name).
    filename : str
        Unused: no location is printed.
    lineno : int
        Unused.
    file : optional
        Unused: the line always goes to stderr.
    line : str, optional
        Unused.
    """
    from esoarm.scenario import ScenarioWarning

    if verbosity() < NORMAL:
        return
    if issubclass(category, ScenarioWarning):
        click.echo(f"esoarm: warning: {one_line(str(message))}", err=True)
    else:
        click.echo(f"esoarm: warning: {category.__name__}: {one_line(str(message))}", err=True)


def bad_input_guard(func: F) -> F:
    """Turn :class:`ScenarioError` raised inside a command into exit status 2.

    Parameters
    ----------
    func : callable
        A command's function.

    Returns
    -------
    callable
        ``func`` wrapped: a ScenarioError becomes :class:`BadInput`, worded for the command
        line (:func:`cli_wording`).
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from esoarm.scenario import ScenarioError

        try:
            return func(*args, **kwargs)
        except ScenarioError as exc:
            raise BadInput(cli_wording(str(exc))) from None

    return wrapper  # type: ignore[return-value]


def set_option(func: F) -> F:
    """The repeatable ``--set KEY=VALUE`` option.

    Parameters
    ----------
    func : callable
        A command's function.

    Returns
    -------
    callable
        ``func`` with the option (its values reach the parameter ``overrides``).
    """
    return click.option(
        "--set",
        "overrides",
        multiple=True,
        metavar="KEY=VALUE",
        help="Override a dotted scenario key, value parsed as TOML (strings need no quotes), "
        "e.g. --set observer.eps=0.05 --set observer.discretization=zoh. Repeatable.",
    )(func)


def scenario_argument(func: F) -> F:
    """The positional SCENARIO argument (built-in name or TOML path).

    Parameters
    ----------
    func : callable
        A command's function.

    Returns
    -------
    callable
        ``func`` with the argument (its value reaches the parameter ``scenario``).
    """
    return click.argument("scenario", metavar="SCENARIO")(func)


#: Library wording of an argument -> the command-line option that carries it, where the
#: option is not simply ``--`` + the argument's name (those are found on the command).
CLI_FLAGS = {"override": "--set", "overrides": "--set", "fault": "--fault"}
_LEAD = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)(?=[ :'])")


def cli_wording(message: str) -> str:
    """A library message, worded for the command line.

    The library names its arguments (``override 'observer.epsilon': unknown
    key``, ``max_runs 0: …``); the command line names the option that carries
    them (``--set …``, ``--max-runs 0: …``): :data:`CLI_FLAGS`, else an option
    of the running command whose parameter has that name.

    Parameters
    ----------
    message : str
        A library's one-line message.

    Returns
    -------
    str
        The message with its leading argument name replaced by the option, where one is found.
    """
    match = _LEAD.match(message)
    if match is None:
        return message
    word = match.group(1)
    flag = CLI_FLAGS.get(word)
    ctx = click.get_current_context(silent=True)
    if flag is None and ctx is not None:
        for param in ctx.command.params:
            if isinstance(param, click.Option) and param.name == word:
                flag = max(param.opts, key=len)
                break
    return flag + message[len(word):] if flag else message


def resolve_scenario(name: str, overrides: tuple[str, ...] | list[str]) -> Scenario:
    """Load a scenario with overrides and print its warnings (one line each).

    Parameters
    ----------
    name : str
        A built-in scenario's name or a TOML file.
    overrides : sequence of str
        ``KEY=VALUE`` items of ``--set``.

    Returns
    -------
    Scenario
        The validated scenario.

    Raises
    ------
    ScenarioError
        Bad input: an unknown scenario, key or value.
    """
    from esoarm.kinds import observer_summary
    from esoarm.scenario import ScenarioWarning, load_scenario, scenario_warnings

    scn = load_scenario(name, list(overrides))
    detail(f"scenario '{scn.name}': {scn.n_samples} samples at {scn.sensor.rate_hz:g} Hz, "
           f"{scn.substeps} RK4 steps per sample, {observer_summary(scn)}")

    for msg in scenario_warnings(scn):
        warnings.warn(msg, ScenarioWarning, stacklevel=2)
    added = _motor_added(name, overrides, scn)
    if added:
        warnings.warn(added, ScenarioWarning, stacklevel=2)
    return scn


def _motor_added(name: str, overrides: tuple[str, ...] | list[str], scn: Scenario) -> str | None:
    """A --set motor.KEY on a scenario without a [motor] table adds a whole motor: say so."""
    keys = [item.partition("=")[0].strip() for item in overrides]
    motor_keys = [k for k in keys if k.startswith("motor.")]
    if not motor_keys or scn.motor is None:
        return None
    from esoarm.scenario import load_scenario

    if load_scenario(name, []).motor is not None:
        return None
    rest = {k: v for k, v in scn.motor.model_dump().items() if f"motor.{k}" not in keys}
    shown = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}"
                      for k, v in list(rest.items())[:5])
    return (f"--set {motor_keys[0]}: '{scn.name}' has no [motor] table, so this adds a whole DC "
            f"motor model (back-EMF, driver deadband, PWM), every other motor key at its "
            f"default ({shown}, ...; 'esoarm show' lists them); the arm is no longer driven by "
            "an ideal torque source")


def output_path(value: str | None, option: str, suffixes: tuple[str, ...]) -> Path | None:
    """Check an output file before any work: allowed suffix, a place that can be written.

    Parameters
    ----------
    value : str, optional
        The path given; None: the option was not given.
    option : str
        The option's name, for the error (``--out``).
    suffixes : tuple of str
        The allowed suffixes, lower case with the dot.

    Returns
    -------
    Path or None
        The path; None when ``value`` is None.

    Raises
    ------
    BadInput
        Exit status 2, naming the option and the path.
    """
    if value is None:
        return None
    path = Path(value)
    if not path.suffix and path.name.lower() in suffixes:  # ".csv": a hidden name, no suffix
        raise BadInput(f"{option} '{value}': give a file name before the suffix, e.g. "
                       f"run{path.name.lower()}")
    if path.suffix.lower() not in suffixes:
        raise BadInput(f"{option} '{value}': the file name must end in {' or '.join(suffixes)}")
    _check(path, option, directory=False)  # a directory, a parent that is a file, /proc, ...
    return path


def output_dir(value: str, option: str) -> Path:
    """Check an output directory before any work (it may not exist yet; not the empty path).

    Parameters
    ----------
    value : str
        The directory given.
    option : str
        The option's name, for the error (``--out``).

    Returns
    -------
    Path
        The directory.

    Raises
    ------
    BadInput
        Exit status 2, naming the option and the path.
    """
    if not value:
        raise BadInput(f"{option} '': give a directory name (. for the current directory)")
    path = Path(value)
    _check(path, option, directory=True)
    return path


def _check(path: Path, option: str, directory: bool) -> None:
    try:
        check_writable(path, directory=directory)
    except OutputError as exc:
        raise BadInput(f"{option} '{path}': {exc.reason}") from None


def stderr_is_tty() -> bool:
    """Whether live progress displays should be drawn.

    Returns
    -------
    bool
        stderr is a terminal and the level is not --quiet.
    """
    return sys.stderr.isatty() and verbosity() >= NORMAL


def lever_only(scn: Scenario, command: str) -> None:
    """The rig protocol, its emulator and identification drive one lever arm: refuse others.

    Parameters
    ----------
    scn : Scenario
        The scenario loaded.
    command : str
        The command's name, for the error.

    Raises
    ------
    BadInput
        ``scn`` is not a lever arm (exit status 2).
    """
    from esoarm.kinds import can

    if not can(scn, "RIG"):  # what the plant kind declares
        raise BadInput(f"scenario '{scn.name}': '{command}' works on the lever-arm rig (one "
                       f"joint); plant.kind '{scn.plant.kind}' runs in simulate, sweep, tune, "
                       "replay and arm-study")


#: Without a terminal, a progress line at most this often [s] (logs, pipes, CI) ...
PROGRESS_LINE_S = 10.0
#: ... and with --verbose this often [s].
PROGRESS_LINE_VERBOSE_S = 1.0


#: A time-left estimate is shown once this share of the work is done ...
SETTLE_FRACTION = 0.05
#: ... and this long [s] has passed since the first progress (a rate over less is noise),
#: and it is within a factor 2 of the previous line's estimate, or this share is done.
SETTLE_SECONDS = 3.0
SETTLED_SHARE = 0.25


def settled(fraction: float, seconds: float) -> bool:
    """Whether a time-left estimate made after ``fraction`` of the work, ``seconds`` [s]
    after it started, is worth showing (:data:`SETTLE_FRACTION`, :data:`SETTLE_SECONDS`).

    Parameters
    ----------
    fraction : float
        The share of the work done, 0 … 1.
    seconds : float
        Time since the work started [s].

    Returns
    -------
    bool
    """
    return fraction >= SETTLE_FRACTION and seconds >= SETTLE_SECONDS


@contextlib.contextmanager
def progress(total: float, label: str, unit: str, fmt: Callable[[float], str] = "{:,.0f}".format,
             ) -> Iterator[Callable[[float], None]]:
    """Progress of a long piece of work on stderr; yields ``advance(n)``.

    On a terminal: a live bar with the count, the rate and the time left.
    Elsewhere (a log, a pipe): one line ``esoarm: LABEL: DONE of TOTAL UNIT (… s left)``
    every :data:`PROGRESS_LINE_S` seconds (every :data:`PROGRESS_LINE_VERBOSE_S` with
    --verbose), none for work that ends sooner, and a last line once any was printed.
    Nothing with --quiet.

    Parameters
    ----------
    total : float
        The amount of work, in ``unit``.
    label : str
        What is done (``sweep``), the line's first word.
    unit : str
        The unit of the count (``runs``).
    fmt : callable
        Formats a count for the line (default: a whole number with thousands separators).

    Yields
    ------
    callable
        ``advance(n)``: ``n`` more units done.
    """
    if verbosity() < NORMAL:
        yield lambda n: None
        return
    if stderr_is_tty():
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        class SettledRemaining(TimeRemainingColumn):
            """Rich's time left, shown only once the estimate has settled (:func:`settled`)."""

            def render(self, task):  # type: ignore[no-untyped-def]
                from rich.text import Text

                done = task.completed / task.total if task.total else 0.0
                if not settled(done, task.elapsed or 0.0):
                    return Text("(estimating)", style="progress.remaining")
                return super().render(task)

        with Progress(TextColumn(label), BarColumn(),
                      TextColumn(f"{{task.completed:,.0f}} of {{task.total:,.0f}} {unit}"),
                      TimeElapsedColumn(), TextColumn("left"), SettledRemaining(),
                      console=Console(stderr=True), transient=True) as bar:
            task = bar.add_task(label, total=total)
            yield lambda n: bar.advance(task, n)
        return
    import time

    every = PROGRESS_LINE_VERBOSE_S if verbosity() >= VERBOSE else PROGRESS_LINE_S
    start = time.monotonic()
    state: dict[str, Any] = {"done": 0.0, "last": start, "shown": False, "shown_done": -1.0,
                             "first": None, "estimate": None}

    def line(now: float) -> None:
        done = state["done"]
        left = ""
        if 0 < done < total and state["first"] is not None:
            # the rate since the first progress reported (what came before it -- loading,
            # compiling -- is not work to be repeated), shown once the estimate has settled:
            # enough done, and close to the estimate of the previous line
            t0, d0 = state["first"]
            rate = (done - d0) / max(now - t0, 1e-9)
            estimate = (total - done) / rate if rate > 0 else math.inf
            previous, state["estimate"] = state["estimate"], estimate
            agrees = (previous is not None and 0.5 * previous <= estimate <= 2.0 * previous
                      or done >= SETTLED_SHARE * total)  # a quarter done: a rate measured
            if settled(done / total, now - t0) and math.isfinite(estimate) and agrees:
                left = f", about {estimate:,.0f} s left"
            else:
                left = ", estimating the time left"
        click.echo(f"esoarm: {label}: {fmt(done)} of {fmt(total)} {unit} ({now - start:,.0f} s"
                   f"{left})", err=True)
        state["last"], state["shown"], state["shown_done"] = now, True, done

    def advance(n: float) -> None:
        now = time.monotonic()
        if state["first"] is None:
            state["first"] = (now, state["done"] + n)
        state["done"] += n
        if now - state["last"] >= every:
            line(now)

    try:
        yield advance
    finally:
        if state["shown"] and state["shown_done"] != state["done"]:
            line(time.monotonic())


#: Optional extras: the module a command needs -> (PyPI package, extra).
EXTRAS = {"serial": ("pyserial", "rig"), "pinocchio": ("pin", "arms"),
          "control": ("control", "analyze"), "gymnasium": ("gymnasium", "gym"),
          "distributed": ("dask[distributed]", "cluster")}


def require_extra(module: str, what: str) -> None:
    """Refuse, before any work, a command whose optional dependency is not installed.

    A set-up problem, not a run-time failure: exit status 2, one line naming the extra
    (``esoarm: error: esoarm run needs pyserial: pip install 'esoarm[rig]'``).

    Parameters
    ----------
    module : str
        The module to look for (``serial``), a key of :data:`EXTRAS`.
    what : str
        The command, the line's start (``esoarm run``).
    """
    import importlib.util

    if importlib.util.find_spec(module) is None:
        package, extra = EXTRAS[module]
        raise BadInput(f"{what} needs {package}, which is not installed: "
                       f"pip install 'esoarm[{extra}]'")


class status_lines:  # noqa: N801 - used like a function
    """A status callback for logs and pipes: the latest message as a line every 10 s.

    The counterpart of a terminal's transient status line: ``esoarm: LABEL: MESSAGE`` at
    most every :data:`PROGRESS_LINE_S` seconds (every message with --verbose), nothing
    for work that ends sooner, nothing with --quiet.
    """

    def __init__(self, label: str) -> None:
        import time

        self._label, self._last = label, time.monotonic()

    def __call__(self, message: str) -> None:
        import time

        now = time.monotonic()
        if verbosity() >= VERBOSE or (verbosity() >= NORMAL
                                      and now - self._last >= PROGRESS_LINE_S):
            self._last = now
            click.echo(f"esoarm: {self._label}: {one_line(message)}", err=True)

    def close(self) -> None:
        """Nothing to undo (the terminal's status line has to be cleared)."""
