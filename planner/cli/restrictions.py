"""`planner restrictions import`: temporary speed restrictions from CSV or OSRD JSON into a daily feed."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from . import app

restrictions_app = typer.Typer(
    name="restrictions", no_args_is_help=True, add_completion=False, rich_markup_mode=None,
    help="Temporary speed restrictions of a line's daily feed (docs/operating-day.md).",
)
app.add_typer(restrictions_app, name="restrictions")


def _of_job(job_file: Path, line_opt: Optional[str]):
    """(line, feed folder, time zone) of one line of a job file: its only line, or the one ``--line`` names (a
    folder as [job] lines writes it, or its line_id)."""
    from planner.errors import InputError
    from planner.job.config import load_job
    from planner.job.day import time_zone
    from planner.line.loader import load_line

    job = load_job(job_file)
    if not job.day.feeds:
        raise InputError(f"{job_file}: the job names no daily feeds ([day] feeds); add the line's feed folder there")
    pairs = list(zip(job.job.lines, job.day.feeds))
    if line_opt is None and len(pairs) > 1:
        raise InputError(f"{job_file} plans {len(pairs)} lines: say which with --line ({', '.join(job.job.lines)})")
    for p, f in pairs:
        if line_opt is None or line_opt in (p, Path(p).name):
            return load_line(job.resolve(p)), job.resolve(f), time_zone(job)
    for p, f in pairs:  # by line_id
        ln = load_line(job.resolve(p))
        if ln.line_id == line_opt:
            return ln, job.resolve(f), time_zone(job)
    raise InputError(f"--line {line_opt}: not a line of {job_file} ({', '.join(job.job.lines)})")


JOB_ARG = typer.Argument(..., help="Job file (TOML): it names the line, its daily feed and its time zone.")
LINE_OPT = typer.Option(None, "--line", help="The line, when the job plans several (its folder or line_id).")


@restrictions_app.command("import")
def import_cmd(
    src: Path = typer.Argument(..., help="CSV (the columns of restrictions.parquet) or OSRD temporary speed "
                                         "limit JSON (.json)."),
    job_file: Optional[Path] = typer.Option(None, "--job", help="Job file naming the line, its feed and time zone "
                                                                "(instead of --line, --feed, --time-zone)."),
    line: Optional[Path] = typer.Option(None, "--line", help="The line folder the restrictions lie on (validated "
                                                             "against it); with --job, the line when it has several."),
    feed: Optional[Path] = typer.Option(None, "--feed", help="Daily feed folder to write restrictions.parquet into."),
    time_zone: Optional[str] = typer.Option(None, "--time-zone", help="The line's IANA time zone (the job's [day] "
                                                                      "time_zone), e.g. Asia/Tokyo."),
    replace: bool = typer.Option(False, "--replace/--append",
                                 help="Replace the feed's restrictions, or append to them (default; an id already "
                                      "in the feed is refused)."),
    infra: Path = typer.Option(None, "--infra", help="OSRD JSON only: the railjson infrastructure of the line."),
    path: str = typer.Option("", "--path", help="OSRD JSON only: the operational points the line was imported "
                                                "along, comma-separated, in running order."),
) -> None:
    """Validate restrictions against the line and write them into the feed atomically (nothing on any error)."""
    from planner.errors import InputError
    from planner.line.importers.restrictions import import_restrictions
    from planner.line.loader import load_line

    if job_file is not None:
        if feed is not None or time_zone is not None:
            raise InputError("--job names the feed and the time zone: leave --feed and --time-zone out")
        ln, feed, time_zone = _of_job(job_file, None if line is None else str(line))
    elif line is None or feed is None or time_zone is None:
        raise InputError("give --job JOB.toml, or all of --line, --feed and --time-zone")
    else:
        ln = load_line(line)
    s = import_restrictions(src, ln, feed, tz=time_zone, replace=replace, infra=infra,
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


@restrictions_app.command("list")
def list_cmd(job_file: Path = JOB_ARG, line: Optional[str] = LINE_OPT) -> None:
    """Every restriction of the line's daily feed, whatever its validity: id, stretch, limit, direction, track,
    train type, validity, beacon and reason."""
    from planner.line.importers.restrictions import feed_rows

    ln, feed, tz = _of_job(job_file, line)
    rows = feed_rows(ln, feed, tz)
    typer.echo(f"{feed}: {len(rows)} restriction(s) of line {ln.line_id} (local times, {tz})")
    for r in rows:
        typer.echo(f"  {r['restriction_id']}: {r['start_m']:g}–{r['end_m']:g} m {r['limit_kmh']:g} km/h "
                   f"{r['direction']}" + (f" track {r['track']}" if r.get("track") else "")
                   + (f" {r['train_type']} only" if r.get("train_type") else "")
                   + f", {r['valid_from']} → {r['valid_until']} "
                   f"({'temporary beacon' if r['has_beacon'] else 'DB-fed pattern'}): {r['reason']}")


@restrictions_app.command("lift")
def lift_cmd(job_file: Path = JOB_ARG,
             restriction_id: str = typer.Argument(..., help="The restriction to end early."),
             at: str = typer.Option(..., "--at", help="When it ends: local time of the line (YYYY-MM-DDTHH:MM, no "
                                                      "offset), inside its validity."),
             line: Optional[str] = LINE_OPT) -> None:
    """End a restriction early: its valid_until becomes --at (validated like an import, written atomically)."""
    from planner.line.importers.restrictions import lift

    ln, feed, tz = _of_job(job_file, line)
    before, after = lift(ln, feed, tz, restriction_id, at)
    typer.echo(f"lifted {restriction_id}: in force {before['valid_from']} → {after['valid_until']} (was until "
               f"{before['valid_until']}); {feed / 'restrictions.parquet'}")


@restrictions_app.command("remove")
def remove_cmd(job_file: Path = JOB_ARG,
               restriction_id: str = typer.Argument(..., help="The restriction to delete from the feed."),
               line: Optional[str] = LINE_OPT) -> None:
    """Delete a restriction from the line's daily feed (written atomically)."""
    from planner.line.importers.restrictions import remove

    ln, feed, tz = _of_job(job_file, line)
    row = remove(ln, feed, tz, restriction_id)
    typer.echo(f"removed {restriction_id} ({row['start_m']:g}–{row['end_m']:g} m, {row['valid_from']} → "
               f"{row['valid_until']}); {feed / 'restrictions.parquet'}")


@restrictions_app.command("export")
def export_cmd(job_file: Path = JOB_ARG,
               out: Path = typer.Option(..., "--out", help="CSV file to write (what `restrictions import` reads)."),
               line: Optional[str] = LINE_OPT) -> None:
    """The line's restrictions as a CSV file that `planner restrictions import --replace` reads back."""
    from planner.line.importers.restrictions import export_csv
    from .checks import check_out_file

    check_out_file(out, "--out", ".csv", "restrictions CSV")
    ln, feed, tz = _of_job(job_file, line)
    typer.echo(f"wrote {export_csv(ln, feed, tz, out)}")

