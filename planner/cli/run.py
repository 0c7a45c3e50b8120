"""`planner run JOB.toml`: the nightly job, end to end."""
from __future__ import annotations

from pathlib import Path

import typer

from . import app


@app.command("run")
def run(
    job_file: Path = typer.Argument(..., help="Job file (TOML), e.g. jobs/nightly.toml."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar per step."),
    no_cache: bool = typer.Option(False, "--no-cache",
                                  help="Trust no cache entry: recompute every unit, write every dataset file "
                                       "and encode every bundle (nothing taken from the previous run) and publish "
                                       "a new run even if nothing changed (fresh entries replace the old ones)."),
    day: str = typer.Option("", "--day", metavar="YYYY-MM-DD",
                            help="Plan this operating day instead of the job's [day] day (default: the next one)."),
) -> None:
    """Validate, build tables, stopping patterns, closed loop, margins, bundles and conflicts; publish atomically."""
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    from planner.io.parallel import stop_workers

    job = load_job(job_file)
    if day:
        from planner.job.day import with_day

        job = with_day(job, day)
    try:
        s = run_job(job, show_progress=progress, use_cache=not no_cache)
    finally:
        stop_workers()  # the command ends here: its idle workers need not wind down on their own
    for note in s.notes:
        typer.echo(f"note: {note}", err=True)
    for warning in s.warnings:
        typer.echo(f"warning: {warning}", err=True)
    if s.up_to_date:
        typer.echo(f"up to date: {s.run_dir} (nothing recomputed)")
        return
    typer.echo(f"published run {s.run_id}: {s.run_dir}")
    typer.echo("  step          time [s]  computed  reused")
    for step, secs in s.timings.items():
        typer.echo(f"  {step:<12} {secs:9.1f} {s.computed.get(step, ''):>9} {s.reused.get(step, ''):>7}")
    typer.echo(f"  total        {s.wall_s:9.1f}   (wall: conflicts, graph and bundles run beside other steps)")
    typer.echo("  rows: " + ", ".join(f"{k} {v}" for k, v in sorted(s.rows.items())))
    typer.echo("  flags: " + ", ".join(f"{k} {v}" for k, v in sorted(s.flags.items())))
    typer.echo(f"  bundles: {len(s.bundles)} in {s.run_dir / 'bundles'}")
    for html in sorted((s.run_dir / "report").glob("*.html")):
        typer.echo(f"  report: {html}")
