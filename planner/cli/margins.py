"""``planner margins LINE --out DIR``: the margin-time report (datasets and one HTML page)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import InputError, PlannerError
from . import app


def _curves_leg(text: str | None) -> tuple[str, str, str] | None:
    """``TYPE:ORIGIN-DESTINATION`` → (type, origin, destination)."""
    if not text:
        return None
    try:
        tt, leg = text.split(":", 1)
        o, d = leg.split("-", 1)
    except ValueError:
        raise InputError(f"--curves {text!r}: give TYPE:ORIGIN-DESTINATION, e.g. E10:TKD-OHS") from None
    return tt.strip(), o.strip(), d.strip()


@app.command()
def margins(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Output folder: margins/, margin_totals/ and margins.html go here."),
    tables_dir: Optional[Path] = typer.Option(
        None, "--tables", help="Folder written by `planner tables` (reused; legs it lacks are computed)."),
    stops_dir: Optional[Path] = typer.Option(
        None, "--stops", help="Folder written by `planner stops`: its adhesion levels are the sweep."),
    closed_loop_dir: Optional[Path] = typer.Option(
        None, "--closed-loop", help="Folder written by `planner simulate` (nominal and perturbed, mode nearest)."),
    job: Optional[Path] = typer.Option(
        None, "--job", help="Job file: the configuration the nightly job uses ([margins], [stops], [tables], [conflicts])."),
    train_type: Optional[list[str]] = typer.Option(None, "--train-type", help="Train type (repeatable); default all."),
    adhesion: Optional[str] = typer.Option(None, "--adhesion", help="Adhesion sweep START:STOP:STEP in km/h/s "
                                           "(default 2.5:3.5:0.1); the lowest level is the bad day's."),
    curves: Optional[str] = typer.Option(None, "--curves", help="Leg whose run curves the page draws, "
                                         "TYPE:ORIGIN-DESTINATION; default the least bad-day margin."),
    no_conflicts: bool = typer.Option(False, "--no-conflicts", help="Skip the route-conflict section."),
    jobs: int = typer.Option(-1, "--jobs", help="Worker processes (-1 = all cores)."),
) -> None:
    """Margin-time report: minimum, scheduled and bad-day running time of every leg, flags, totals, HTML page."""
    from planner.line.loader import load_line
    from planner.line.units import hms
    from planner.report.leg_flags import FLAG, FLAGS
    from planner.pages.margin_report import write_html
    from planner.report.margin_datasets import write_margins
    from planner.report.margins import compute_margins, margin_options
    from .tables import _progress

    from .checks import check_jobs, check_out_dir, station_code, train_type_code, train_type_codes

    try:
        check_jobs(jobs)
        check_out_dir(out, "--out", "margin report")
        j = None
        if job is not None:
            from planner.job.config import load_job

            j = load_job(job)
        for name, p in (("--tables", tables_dir), ("--stops", stops_dir), ("--closed-loop", closed_loop_dir)):
            if p is not None and not p.is_dir():
                raise InputError(f"{name} {p}: no such folder")
        line = load_line(line_dir)
        # with --job, the configuration the nightly job uses (the same library call); else the defaults
        options = margin_options(j, line) if j is not None else {}
        if j is None:  # the job's default fill interval too, for legs without beacon points (as `planner tables`)
            from planner.tables.eval_points import DEFAULT_AUTO_S

            options["eval_auto_s"] = DEFAULT_AUTO_S
        if adhesion is not None:
            options["adhesion_kmh_s"] = adhesion
        if no_conflicts:
            options["conflicts"] = False
        train_type = train_type_codes(line, train_type)
        chosen = _curves_leg(curves)
        if chosen is not None:
            chosen = (train_type_code(line, chosen[0], "--curves"), station_code(line, chosen[1], "--curves"),
                      station_code(line, chosen[2], "--curves"))
        with _progress("margins") as update:
            report = compute_margins(
                line, **options, train_types=train_type or None, tables_dir=tables_dir, stops_dir=stops_dir,
                closed_loop_dir=closed_loop_dir, chosen=chosen, n_jobs=jobs, progress=update)
        files = write_margins(report, out)
        page = write_html(report, line, out / "margins.html")
    except PlannerError:
        raise  # the root command prints it as one line (cli.main)
    rows = report.rows
    s = rows[rows.scheduled_running_time_s.notna()]
    typer.echo(f"{line.line_id}: {len(rows)} legs x train type ({len(s)} timetabled, "
               f"{int((s.passes.map(len) > 0).sum())} passing stations); tables "
               f"{report.sources['tables_dataset']} read, {report.sources['tables_computed']} computed")
    typer.echo("  flags: " + ", ".join(f"{int(s[f].sum())} {FLAG[f].badge}" for f in FLAGS)
               + f"; {int((~s.supplement_met).sum())} below the supplement rule")
    if s.unassessed.any():
        u = s[s.unassessed].iloc[0]
        typer.echo(f"  UNASSESSED: {int(s.unassessed.sum())} leg(s) have no bad-day minimum, e.g. {u.train_type} "
                   f"{u.direction} {u.origin}->{u.destination}: {u.unassessed_reason}")
    a = s[~s.unassessed]
    if len(a):
        w = a.sort_values("remaining_margin_s", kind="stable").iloc[0]
        typer.echo(f"  least bad-day margin: {w.train_type} {w.direction} {w.origin}->{w.destination} "
                   f"{w.remaining_margin_s:+.1f} s (scheduled {w.scheduled_running_time_s:.0f} s, minimum "
                   f"{w.min_running_time_s:.1f} s, bad day {w.degraded_min_running_time_s:.1f} s)")
    for r in report.totals[report.totals.level == "line"].itertuples(index=False):
        typer.echo(f"  {r.direction}: {r.n_trains} trains, margin {hms(r.margin_s)} ({r.margin_percent:.1f} %), "
                   f"bad-day margin {hms(r.remaining_margin_s, sign=True)} (h:mm:ss)"
                   + (f" (unknown: {r.n_unassessed} legs unassessed)" if r.n_unassessed else ""))
    if report.conflicts is not None:
        n = report.conflicts["conflict_id"].nunique() if len(report.conflicts) else 0
        typer.echo(f"  route conflicts: {n}")
    typer.echo(f"  wrote {len(files)} dataset files and {page}")
