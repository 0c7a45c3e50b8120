"""`planner restrictions import`: temporary speed restrictions from CSV or OSRD JSON into a daily feed."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app

restrictions_app = typer.Typer(
    name="restrictions", no_args_is_help=True, add_completion=False, rich_markup_mode=None,
    help="Temporary speed restrictions of a line's daily feed (docs/operating-day.md).",
)
app.add_typer(restrictions_app, name="restrictions")


@restrictions_app.command("import")
def import_cmd(
    src: Path = typer.Argument(..., help="CSV (the columns of restrictions.parquet) or OSRD temporary speed "
                                         "limit JSON (.json)."),
    line: Path = typer.Option(..., "--line", help="The line folder the restrictions lie on (validated against it)."),
    feed: Path = typer.Option(..., "--feed", help="Daily feed folder to write restrictions.parquet into."),
    time_zone: str = typer.Option(..., "--time-zone", help="The line's IANA time zone (the job's [day] time_zone), "
                                                           "e.g. Asia/Tokyo."),
    replace: bool = typer.Option(False, "--replace/--append",
                                 help="Replace the feed's restrictions, or append to them (default; an id already "
                                      "in the feed is refused)."),
    infra: Path = typer.Option(None, "--infra", help="OSRD JSON only: the railjson infrastructure of the line."),
    path: str = typer.Option("", "--path", help="OSRD JSON only: the operational points the line was imported "
                                                "along, comma-separated, in running order."),
) -> None:
    """Validate restrictions against the line and write them into the feed atomically (nothing on any error)."""
    from planner.line.importers.restrictions import import_restrictions
    from planner.line.loader import load_line

    s = import_restrictions(src, load_line(line), feed, tz=time_zone, replace=replace, infra=infra,
                            path_ops=[p.strip() for p in path.split(",") if p.strip()])
    for out in s.lines():
        typer.echo(out)
