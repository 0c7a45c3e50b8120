"""The ``planner`` command: one typer app, a sub-command per job step.

Each sub-command lives in its own module here and registers itself on ``app``;
this module only wires them together and turns domain errors into one line.
"""
from __future__ import annotations

import sys

import typer
import typer.core

from ..errors import PlannerError

class _Group(typer.core.TyperGroup):
    """The root group: a domain error from any sub-command becomes one line on stderr and its exit code,
    also when the app is invoked as an object (tests, embedding), not only through :func:`main`."""

    def invoke(self, ctx):
        from .checks import DAY_NOTES

        DAY_NOTES.clear()
        try:
            out = super().invoke(ctx)
            for note in DAY_NOTES:  # after the command's own output, and only when it succeeded
                typer.echo(note, err=True)
            return out
        except PlannerError as e:
            typer.echo(f"error: {e}", err=True)
            raise typer.Exit(e.exit_code) from None
        except OSError as e:  # an environment fault no up-front check could see (disk full, a folder gone meanwhile)
            where = f" ({e.filename})" if e.filename else ""
            typer.echo(f"error: {e.strerror or e}{where}: a fault of the machine, not of the input; free space, "
                       "fix the permissions or choose another path, and run again", err=True)
            raise typer.Exit(1) from None


app = typer.Typer(
    name="planner",
    cls=_Group,
    help="Plan train running for a whole line: tables, stopping patterns, margins, bundles.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
    # help texts name job-file sections like [margins]; rich markup would swallow them
    rich_markup_mode=None,
)


def _print_version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"planner {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the planner version and exit."),
) -> None:
    """Plan train running for a whole line: tables, stopping patterns, margins, bundles."""
    # A callback keeps `planner validate ...` a sub-command even while it is the only one
    # (typer otherwise collapses a one-command app into that command).

# Sub-command modules; each does `from . import app` and decorates its commands.
from . import validate  # noqa: E402,F401
from . import bundle  # noqa: E402,F401
from . import conflicts  # noqa: E402,F401
from . import robustness  # noqa: E402,F401
from . import runtime  # noqa: E402,F401
from . import tables  # noqa: E402,F401
from . import stops  # noqa: E402,F401
from . import margins  # noqa: E402,F401
from . import run  # noqa: E402,F401
from . import datasets  # noqa: E402,F401
from . import timekeeping  # noqa: E402,F401
from . import cache  # noqa: E402,F401
from . import schema  # noqa: E402,F401
from . import importer  # noqa: E402,F401
from . import graph  # noqa: E402,F401
from . import diff  # noqa: E402,F401
from . import kernels  # noqa: E402,F401
from . import restrictions  # noqa: E402,F401
from . import line  # noqa: E402,F401


def main() -> None:
    """Console entry point: domain errors become one line on stderr, never a traceback; so does a bug
    (exit 70), its traceback saved to a temporary file that the line names."""
    try:
        app()
    except PlannerError as e:
        typer.echo(f"error: {e}", err=True)
        sys.exit(e.exit_code)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)
    except Exception as e:  # noqa: BLE001 - a bug, not bad input: one line, the traceback kept in a file
        typer.echo(f"error: internal error in planner ({_one_line(e)}). This is a bug: "
                   f"please report it with the traceback saved in {_save_traceback()}", err=True)
        sys.exit(70)  # EX_SOFTWARE


def console() -> None:
    """The ``planner`` command's process entry point (``python -m planner.cli`` too): :func:`main`, then the
    process ends at once (:func:`_exit_now`). Callers in a process of their own making call :func:`main`,
    which ends in ``SystemExit`` as a command does."""
    try:
        main()
    except SystemExit as e:  # every command's end, normal or not (click ends in SystemExit)
        _exit_now(e)


def _exit_now(e: SystemExit) -> None:
    """End the process with ``e``'s code without the interpreter's teardown, once every other thread has ended.

    The teardown frees every object one at a time: after a nightly run that held a whole line's results
    it was ~0.2 s of the command's wall time, for memory the system takes back at once. What a normal exit
    does that matters still happens: the ``atexit`` handlers run (joblib's and loky's clean-up of their
    temporary folders and processes among them) and standard output and error are flushed. While a thread
    other than this one is alive (a daemon aside), its work is not cut short: the normal exit, which waits
    for it; so is an exit with a message instead of a code.
    """
    import atexit
    import os
    import threading

    others = [t for t in threading.enumerate() if t is not threading.current_thread() and not t.daemon]
    if others or not isinstance(e.code, (int, type(None))):
        raise e
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can reach it
            pass
    os._exit(e.code or 0)


def _one_line(e: BaseException) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())[:300]


def _save_traceback() -> str:
    """Write the current exception's traceback to a fresh temporary file; its path (or why it could not)."""
    import tempfile
    import traceback

    try:
        fd, path = tempfile.mkstemp(prefix="planner-traceback-", suffix=".txt")
        with open(fd, "w", encoding="utf-8") as f:
            traceback.print_exc(file=f)
        return path
    except OSError as err:
        return f"(no file: {err.strerror or err})"
