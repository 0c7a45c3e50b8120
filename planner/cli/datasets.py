"""`planner datasets`: the documented schema of every published dataset (outputs/README.md)."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app


@app.command("datasets")
def datasets_cmd(
    write: Path = typer.Option(None, "--write", help="Write the Markdown here (e.g. outputs/README.md) "
                                                     "instead of printing it."),
) -> None:
    """Print the catalogue of published datasets with their columns, units and partitioning."""
    from planner.report.catalog import readme
    from planner.io.atomic import write_bytes_atomic

    from .checks import check_out_file

    check_out_file(write, "--write", ".md", "catalogue")
    text = readme()
    if write is None:
        typer.echo(text, nl=False)
    else:
        write_bytes_atomic(write, text.encode())
        typer.echo(f"wrote {write}")
