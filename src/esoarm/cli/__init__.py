"""The ``esoarm`` command line.

Subcommands live in their own modules and are imported only when invoked, so
``esoarm --help`` stays fast and optional dependencies stay optional.  Exit
codes (docs/semantics.md, "Errors and exit codes"): 0 success, 1 failure at
run time, 2 bad input, 130 interrupted.  Every failure is one line on stderr;
``--verbose`` adds the traceback of an unexpected error.
"""

from __future__ import annotations

import gc
import importlib
import os
import signal
import sys
import textwrap
import warnings

import click

from esoarm import __version__
from esoarm._io import OutputError
from esoarm.cli._common import (
    VERBOSE,
    BadInput,
    RunFailure,
    add_verbosity_options,
    one_line,
    reset_verbosity,
    show_warning,
    verbosity,
    verbosity_params,
)

__all__ = ["main"]

# name -> "module:attribute"; add a line here to register a subcommand.
COMMANDS: dict[str, str] = {
    "reproduce": "esoarm.cli.reproduce:reproduce",
    "simulate": "esoarm.cli.simulate:simulate",
    "scenarios": "esoarm.cli.simulate:scenarios",
    "show": "esoarm.cli.simulate:show",
    "sweep": "esoarm.cli.studies.sweep:sweep", "tune": "esoarm.cli.studies.sweep:tune",
    "emulate": "esoarm.cli.rig:emulate",
    "run": "esoarm.cli.rig:run",
    "replay": "esoarm.cli.rig:replay",
    "arm-study": "esoarm.cli.studies.arms:arm_study",
    "analyze": "esoarm.cli.studies.analyze:analyze",
    "hil": "esoarm.cli.board.hil:hil",
    "excite": "esoarm.cli.identify:excite",
    "identify": "esoarm.cli.identify:identify",
    "log": "esoarm.cli.log:log",
    "codegen": "esoarm.cli.board.codegen:codegen",
    "pil": "esoarm.cli.board.pil:pil",
    "compare": "esoarm.cli.studies.compare:compare",
    "learn-map": "esoarm.cli.studies.learn_map:learn_map",
    "flash": "esoarm.cli.board.flash:flash",
    "commission": "esoarm.cli.board.commission:commission",
}


# name -> the command's one-line summary, shown by `esoarm --help` without
# importing the command (tests/test_cli_startup.py checks they match the
# commands' own help). A command missing here is imported to ask it.
SUMMARIES: dict[str, str] = {
    "compare": "Run the ADRC forms on SCENARIO: RMS error and RMS Δu, means over the seeds.",
    "commission": "Commission a rig: excite, identify, design, generate, flash and run on "
                  "board.",
    "codegen": "Generate self-contained C99 for SCENARIO's observer and controller on a target.",
    "arm-study": "Compare controllers and sweep ε on the arm SCENARIO (plant.kind = \"urdf\").",
    "analyze": "Frequency-domain analysis of SCENARIO's loop, linearized and sampled at Ts.",
    "emulate": "Serve the digital twin of SCENARIO as a device behind a new pseudo-terminal.",
    "excite": "Record an identification experiment on the rig at PORT or on the twin of "
              "SCENARIO.",
    "flash": "Build SCENARIO's on-board firmware and write it to the Uno on PORT.",
    "hil": "Run the Uno firmware in simavr (ATmega328P, 16 MHz) with SCENARIO's twin on its "
           "pins.",
    "identify": "Fit the rig model to logs of 'esoarm excite' or 'esoarm run' (grey-box, output "
                "error).",
    "learn-map": "Learn a position-periodic perturbation from LOG.csv into SCENARIO's "
                 "feedforward table.",
    "log": "Bring logs recorded elsewhere into esoarm's CSV format.",
    "pil": "Run SCENARIO's generated controller on an emulated chip in lockstep with the twin.",
    "replay": "Run the ESO offline over LOG.csv to recover velocity and perturbation estimates.",
    "reproduce": "Run the paper's experiments on the digital twin and compare with its tables.",
    "run": "Drive the rig on PORT through SCENARIO at its rate for its duration.",
    "scenarios": "List the built-in scenarios.",
    "show": "Print the fully resolved SCENARIO as TOML (every key, defaults filled in).",
    "simulate": "Simulate SCENARIO (a built-in name or a TOML file) on the digital twin.",
    "sweep": "Sweep SCENARIO over a grid of parameters × noise seeds (compiled engine).",
    "tune": "Tune keys of SCENARIO to minimize an objective (SciPy differential evolution).",
}


class LazyGroup(click.Group):
    """A click group that imports each subcommand's module on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        """The subcommands' names, sorted (none is imported).

        Parameters
        ----------
        ctx : click.Context
            The group's context.

        Returns
        -------
        list of str
            The names of :data:`COMMANDS`.
        """
        return sorted(COMMANDS)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list of ``--help`` from :data:`SUMMARIES` (no subcommand imported).

        Parameters
        ----------
        ctx : click.Context
            The group's context.
        formatter : click.HelpFormatter
            Where the help text is written.
        """
        names = self.list_commands(ctx)
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            summary = SUMMARIES.get(name)
            if summary is None:
                cmd = self.get_command(ctx, name)
                if cmd is None or cmd.hidden:
                    continue
                rows.append((name, cmd.get_short_help_str(limit)))
            else:
                rows.append((name, textwrap.shorten(summary, limit, placeholder="...")))
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """The subcommand ``cmd_name``, its module imported now, with ``--quiet``/``--verbose``.

        Parameters
        ----------
        ctx : click.Context
            The group's context.
        cmd_name : str
            A name of :data:`COMMANDS`.

        Returns
        -------
        click.Command or None
            The command; None for an unknown name.
        """
        target = COMMANDS.get(cmd_name)
        if target is None:
            return None
        module, attr = target.split(":")
        # every command gets --quiet/--verbose, whoever wrote it
        return add_verbosity_options(getattr(importlib.import_module(module), attr))

    def make_context(self, info_name, args, parent=None, **extra):  # type: ignore[no-untyped-def]
        """A context for one invocation, at the normal verbosity.

        Parameters
        ----------
        info_name : str
            The program's name as invoked.
        args : list of str
            The command-line arguments.
        parent : click.Context, optional
            The parent context.
        **extra
            Passed on to :meth:`click.Group.make_context`.

        Returns
        -------
        click.Context
        """
        reset_verbosity()  # each invocation starts at the normal level
        return super().make_context(info_name, args, parent=parent, **extra)

    def resolve_command(self, ctx, args):  # type: ignore[no-untyped-def]
        """The subcommand the arguments name; an unknown one is bad input, with a close match.

        Parameters
        ----------
        ctx : click.Context
            The group's context.
        args : list of str
            The arguments after the program's options.

        Returns
        -------
        tuple
            (name, command, remaining arguments), as :meth:`click.Group.resolve_command`.

        Raises
        ------
        BadInput
            An unknown command (exit status 2), naming the nearest one.
        """
        name = args[0] if args else ""
        if name and not name.startswith("-") and name not in COMMANDS:
            import difflib

            close = difflib.get_close_matches(name, list(COMMANDS), n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise BadInput(f"unknown command '{name}' (one of {', '.join(sorted(COMMANDS))}){hint}")
        return super().resolve_command(ctx, args)


@click.group(
    cls=LazyGroup,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(__version__, prog_name="esoarm")
def cli() -> None:
    """esoarm: ESO-based feedback-linearization control of a robotic lever arm.

    Runs the paper's experiments on a built-in digital twin of the rig
    (12 V DC motor, encoder at 50 Hz) and drives real rigs. Angles in rad,
    torques in N·m, times in s unless a name says otherwise; a prismatic axis
    (plant.kind = "axis", e.g. the scenario emps) in m and N. Exit status: 0
    success, 1 failure at run time, 2 bad input, 130 interrupted; every
    failure is one line on stderr. The sampled-data loop, the scenario format,
    the output columns and the error rules: docs/semantics.md.
    """


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point.

    Click runs in non-standalone mode so that esoarm decides the exit codes:
    a usage or input error is 2, a run-time failure 1, Ctrl-C 130 (click's own
    standalone mode would turn Ctrl-C into "Aborted!" with status 1).

    Run as the command (``argv`` None), the process ends after this: every live
    object is then moved to the garbage collector's permanent generation
    (:func:`gc.freeze`), which spares the interpreter's last full collection at
    exit -- about 40 ms once NumPy, pydantic and the kinds are loaded, a tenth of a
    short command.  Nothing is lost: atexit handlers still run, every file esoarm
    writes is closed by the code that writes it, and the memory goes back to the
    system with the process.  Called with ``argv`` (in a longer-lived process),
    the collector is left alone.

    Run as the command, it also tells pydantic not to look for plugins (unless
    ``PYDANTIC_DISABLE_PLUGINS`` is set already): esoarm uses none, and finding them
    reads the entry points of every installed package when the first scenario
    model is built, about 15 ms of every command.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program's name; None: the process's own (``sys.argv``).
    """
    if argv is None:
        os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    try:
        _main(argv)
    finally:
        if argv is None:
            gc.freeze()


def _main(argv: list[str] | None) -> None:
    warnings.showwarning = show_warning
    if hasattr(signal, "SIGXFSZ"):  # a file-size limit: an error on write, not a kill
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        rv = cli.main(args=argv, prog_name="esoarm", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("esoarm: interrupted", err=True)
        sys.exit(130)
    except KeyboardInterrupt:
        click.echo("esoarm: interrupted", err=True)
        sys.exit(130)
    except click.exceptions.NoArgsIsHelpError as exc:
        # `esoarm` (or `esoarm log`) alone: the help, as with --help, not an error line
        click.echo(exc.ctx.get_help() if exc.ctx is not None else cli.get_help(
            click.Context(cli, info_name="esoarm")))
        sys.exit(0)
    except click.MissingParameter as exc:
        where = exc.ctx.command_path if exc.ctx is not None else "esoarm"
        click.echo(f"esoarm: error: {_missing(exc)} (see '{where} --help')", err=True)
        sys.exit(2)
    except click.UsageError as exc:
        # one line, like every other input error, with where to look for help
        where = exc.ctx.command_path if exc.ctx is not None else "esoarm"
        message = one_line(" ".join(exc.format_message().split())).rstrip(".")
        click.echo(f"esoarm: error: {message} (see '{where} --help')", err=True)
        sys.exit(2)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except MemoryError:
        click.echo("esoarm: failed: out of memory; shorten the run (duration, rate_hz) or "
                   "split the work", err=True)
        sys.exit(1)
    except OutputError as exc:  # full disk, file-size limit, lost permission, ...
        click.echo(f"esoarm: failed: {one_line(str(exc))} (no partial file left behind)", err=True)
        sys.exit(1)
    except BrokenPipeError:  # e.g. `esoarm show test-1 | head`
        sys.stderr.close()
        sys.exit(0)
    except Exception as exc:  # a bug: still one line, the traceback with --verbose
        if verbosity() >= VERBOSE:
            import traceback

            traceback.print_exc()
        where = f" ({exc.__class__.__module__}.{exc.__class__.__name__})"
        text = str(exc).strip().splitlines()
        click.echo(f"esoarm: internal error{where}: {text[0] if text else 'no message'} "
                   "(rerun with --verbose for the traceback, and please report it)", err=True)
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


def _missing(exc: click.MissingParameter) -> str:
    """The one-line message for a missing argument, saying what to give."""
    param = exc.param
    if param is not None and param.name == "scenario":
        return ("missing SCENARIO: a built-in name (list them with 'esoarm scenarios') or a "
                "scenario TOML file")
    # click's "Choose from:\n\tavr,\n\t..." as one line: "Choose from: avr, cortex-m4"
    return one_line(" ".join(exc.format_message().split())).replace(". Choose", "; choose") \
        .rstrip(".")


cli.params.extend(verbosity_params())  # also accepted before the command: esoarm -q …

__all__ += ["BadInput", "RunFailure", "cli"]
