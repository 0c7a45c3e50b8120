"""`planner import csv|railjson|railml` and `planner export csv`: bring a line in, or take it out as CSV."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app
from .checks import check_out_dir

import_app = typer.Typer(
    name="import", no_args_is_help=True, add_completion=False, rich_markup_mode=None,
    help="Write a line database from CSV, OSRD railjson or railML 2.x; every default used is listed.",
)
export_app = typer.Typer(name="export", no_args_is_help=True, add_completion=False, rich_markup_mode=None,
                         help="Write a line database in another format.")
app.add_typer(import_app, name="import")
app.add_typer(export_app, name="export")

_OUT = typer.Option(None, "--out", help="Line folder to create (any name; the line id comes from the data).")
_FORCE = typer.Option(False, "--force", help="Replace --out if it exists (atomically, after validation).")
_EXTRA = typer.Option(None, "--extra", help="TOML with what the source cannot give (stop markers, beacons, "
                                            "timetable, comfort limits); see docs/line-database.md.")
_CATEGORY = typer.Option([], "--category", help="TYPE=CATEGORY: train type TYPE takes the source's speed limits "
                                                "for CATEGORY (railML trainCategory, railjson speed tag); repeat "
                                                "per train type. See docs/importing.md.")


def _need_out(out: Path | None) -> Path:
    if out is None:
        from ..errors import InputError

        raise InputError("--out is required: name the line folder to create, e.g. --out lines/myline")
    check_out_dir(out, "--out", "line database")
    return out


def _report(run) -> None:
    """Run an import and print its summary; every problem of a source on its own line, then the error."""
    from ..errors import SourceProblems

    try:
        summary = run()
    except SourceProblems as e:
        for p in e.problems:
            typer.echo(f"  - {p}", err=True)
        raise
    for line in summary.lines():
        typer.echo(line)


@import_app.command("csv")
def import_csv_cmd(
    src: Path = typer.Argument(None, help="Folder with one <table>.csv per table."),
    out: Path = _OUT,
    force: bool = _FORCE,
    template: Path = typer.Option(None, "--template", help="Instead of importing, write empty commented "
                                                           "templates (one CSV per table) into this folder."),
) -> None:
    """Import a line from CSV files with the same columns as the Parquet tables (units in the header)."""
    from planner.line.importers.csv import import_csv, write_templates

    if template is not None:
        check_out_dir(template, "--template", "CSV templates")
        for p in write_templates(template):
            typer.echo(f"wrote {p}")
        return
    if src is None:
        from ..errors import InputError

        raise InputError("give the CSV folder (SRC_DIR), or --template DIR to write empty templates")
    _report(lambda: import_csv(src, _need_out(out), force=force))


@import_app.command("railjson")
def import_railjson_cmd(
    infra: Path = typer.Argument(..., help="OSRD railjson infrastructure file (.json)."),
    path: str = typer.Option(..., "--path", help="Operational point ids along the line, in running order "
                                                 "(down direction), comma-separated: OP1,OP2,...; a track "
                                                 "section id stands for its whole section (for infras "
                                                 "without operational points)."),
    rolling_stock: list[Path] = typer.Option([], "--rolling-stock", help="OSRD rolling-stock JSON; repeat "
                                                                         "for several train types."),
    line_id: str = typer.Option(None, "--line-id", help="Line id (default: [line] line_id of --extra, else "
                                                        "the infra file's stem and the first and last point "
                                                        "of --path)."),
    category: list[str] = _CATEGORY,
    extra: Path = _EXTRA,
    out: Path = _OUT,
    force: bool = _FORCE,
) -> None:
    """Import the line along the named operational points of an OSRD railjson infrastructure."""
    from planner.line.importers.railjson import import_railjson

    ops = [p.strip() for p in path.split(",") if p.strip()]
    _report(lambda: import_railjson(infra, ops, rolling_stock, _need_out(out), extra=extra, line_id=line_id,
                                    force=force, categories=category))


@import_app.command("railml")
def import_railml_cmd(
    file: Path = typer.Argument(..., help="railML 2.x file (.xml / .railml)."),
    line: str = typer.Option(..., "--line", help="id of the <line> in <trackGroups> whose tracks, in "
                                                 "sequence, make the line."),
    rolling_stock: list[Path] = typer.Option([], "--rolling-stock", help="OSRD rolling-stock JSON; repeat "
                                                                         "for several train types."),
    line_id: str = typer.Option(None, "--line-id", help="Line id (default: [line] line_id of --extra, else "
                                                        "the railML line id)."),
    category: list[str] = _CATEGORY,
    extra: Path = _EXTRA,
    out: Path = _OUT,
    force: bool = _FORCE,
) -> None:
    """Import a railML 2.x line: tracks, gradient and speed changes, signals, balises, OCPs."""
    from planner.line.importers.railml import import_railml

    _report(lambda: import_railml(file, line, rolling_stock, _need_out(out), extra=extra, force=force,
                                  new_line_id=line_id, categories=category))


@export_app.command("csv")
def export_csv_cmd(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Folder to write <table>.csv into."),
) -> None:
    """Write every table of a line database as CSV (what `planner import csv` reads back identically)."""
    from planner.line.importers.csv import export_csv

    check_out_dir(out, "--out", "CSV files")
    for p in export_csv(line_dir, out):
        typer.echo(f"wrote {p}")
