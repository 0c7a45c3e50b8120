"""``planner line upgrade DIR``: rewrite a line database of an earlier schema version in the current one."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app

line_app = typer.Typer(name="line", no_args_is_help=True, add_completion=False, rich_markup_mode=None,
                       help="Line-database housekeeping.")
app.add_typer(line_app, name="line")


@line_app.command("upgrade")
def upgrade_cmd(line_dir: Path = typer.Argument(..., help="Line database folder (holds line.parquet).")) -> None:
    """Rewrite a line database of an earlier schema version (old column names, version) in the current one,
    table by table atomically; one line per change. A folder of the current version is left as it is."""
    from planner.line.schema import SCHEMA_VERSION
    from planner.line.upgrade import upgrade_folder

    changes = upgrade_folder(line_dir)
    if not changes:
        typer.echo(f"{line_dir}: schema version {SCHEMA_VERSION} already; nothing to upgrade")
        return
    for c in changes:
        typer.echo(f"{line_dir}: {c}")
    typer.echo(f"{line_dir}: upgraded to schema version {SCHEMA_VERSION}")
