"""`planner schema`: the line-database contract (docs/line-database.md), generated from planner/line/schema.py."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app


@app.command("schema")
def schema_cmd(
    write: Path = typer.Option(None, "--write", help="Write the Markdown here (e.g. docs/line-database.md) "
                                                     "instead of printing it."),
) -> None:
    """Print the line-database schema: every table, column, unit and validation rule."""
    from planner.io.atomic import write_bytes_atomic
    from planner.line.schema_doc import line_database_doc
    from .checks import check_out_file

    check_out_file(write, "--write", ".md", "schema document")
    text = line_database_doc()
    if write is None:
        typer.echo(text, nl=False)
    else:
        write_bytes_atomic(write, text.encode())
        typer.echo(f"wrote {write}")
