"""The ``planner`` command: one typer app, a sub-command per job step.

Each sub-command lives in its own module here and registers itself on ``app``;
this module only wires them together and turns domain errors into one line.
"""
from __future__ import annotations

import sys

import typer

from ..errors import PlannerError

app = typer.Typer(
    name="planner",
    help="Plan train running for a whole line: tables, stopping patterns, margins, bundles.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # help texts name job-file sections like [margins]; rich markup would swallow them
    rich_markup_mode=None,
)


@app.callback()
def _root() -> None:
    """Plan train running for a whole line: tables, stopping patterns, margins, bundles."""
    # A callback keeps `planner validate ...` a sub-command even while it is the only one
    # (typer otherwise collapses a one-command app into that command).

# Sub-command modules; each does `from . import app` and decorates its commands.
from . import validate  # noqa: E402,F401
from . import bundle  # noqa: E402,F401
from . import conflicts  # noqa: E402,F401
from . import runtime  # noqa: E402,F401
from . import tables  # noqa: E402,F401
from . import stops  # noqa: E402,F401
from . import margins  # noqa: E402,F401
from . import run  # noqa: E402,F401
from . import datasets  # noqa: E402,F401
from . import timekeeping  # noqa: E402,F401
from . import graph  # noqa: E402,F401
from . import diff  # noqa: E402,F401


def main() -> None:
    """Console entry point: domain errors become one line on stderr, never a traceback."""
    try:
        app()
    except PlannerError as e:
        typer.echo(f"error: {e}", err=True)
        sys.exit(e.exit_code)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)
