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


@restrictions_app.command("show")
def show_cmd(
    job_file: Path = typer.Argument(..., help="Job file (TOML) naming the lines and their daily feeds ([day])."),
    day: str = typer.Option("", "--day", metavar="YYYY-MM-DD", help="This operating day instead of the job's."),
) -> None:
    """The operating day's window, and per line the restrictions in force, the trains that do not run and what
    changed since the previous operating day."""
    from planner.job.config import load_job
    from planner.job.day import day_and_feed, day_changes, resolve_day, with_day
    from planner.line.loader import load_line
    from planner.line.operating_day import whole_day
    from planner.pages.day_changes import summary

    job = load_job(job_file)
    job = resolve_day(with_day(job, day) if day else job)
    for p in job.job.lines:
        line = load_line(job.resolve(p))
        d, feed = day_and_feed(job, line)
        w = d.window
        typer.echo(f"{p}: operating day {w.day} ({w.day:%A}) {w.start_local} to {w.end_local} "
                   f"({w.length_s / 3600:g} h)")
        some = f" ({', '.join(d.cancelled[:6])}{' …' if len(d.cancelled) > 6 else ''})" if d.cancelled else ""
        typer.echo(f"  trains: {len(d.trains)} run, {len(d.cancelled)} do not{some}")
        typer.echo(f"  restrictions in force: {len(d.restrictions)}")
        for r in d.restrictions:
            rec = r.record()
            typer.echo(f"    {r.restriction_id}: {r.start_m:g}–{r.end_m:g} m {rec['limit_kmh']:g} km/h {r.direction}"
                       f"{' ' + r.train_type if r.train_type else ''}, {r.valid_from} → {r.valid_until}"
                       f" ({'whole day' if whole_day(r, w) else 'part of the day'}; "
                       f"{'temporary beacon' if r.has_beacon else 'DB-fed pattern'}): {r.reason}")
        c = day_changes(job, line, d, feed)
        if c is not None:
            typer.echo(f"  since {c['previous_weekday']} {c['previous_day']}: {summary(c)}"
                       + (f" ({c['note']})" if c["note"] else ""))
        for n in d.notes:
            typer.echo(f"  note: {n}")
