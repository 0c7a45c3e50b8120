"""``planner conflicts LINE --out DIR``: check the day's timetable for route conflicts on the track network."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Optional

import typer

from . import app
from .checks import DAY_HELP


@app.command()
def conflicts(
    line_dir: Path = typer.Argument(..., help="Line database folder with nodes.parquet and edges.parquet."),
    out: Path = typer.Option(..., "--out", help="Output folder; writes conflicts/, headways/, occupation/ and unrouted/ datasets."),
    job: Optional[Path] = typer.Option(None, "--job", help="Job file: its [conflicts] parameters, and the line as "
                                       "the nightly job plans it on its operating day (the day's temporary "
                                       "restrictions, per train, and trains), so the answer is the night's."),
    setting_s: Optional[float] = typer.Option(None, "--setting-s", help="Route setting time in s (default 10)."),
    approach_s: Optional[float] = typer.Option(None, "--approach-s", help="Sight/reaction + approach time in s (default 20)."),
    release_s: Optional[float] = typer.Option(None, "--release-s", help="Route release time in s (default 5)."),
    terminal_s: Optional[float] = typer.Option(None, "--terminal-s", help="Time a train stays at its destination, in s (default 0)."),
    curve_mode: str = typer.Option("match", "--curve-mode", help="`match`: ratio meeting the schedule; `stretch`: ratio 1.0 stretched."),
    jobs: int = typer.Option(1, "--jobs", help="Worker processes for the run-curve simulations (-1 = all cores)."),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Route every train, predict its occupation windows and report conflicts (station, track, km) with priority
    decisions, and the minimum headway on every section and switch."""
    from .progress import bar as progress_bar

    from .. import load_line
    from ..errors import InputError
    from planner.datasets.conflicts import check_conflicts, write_conflicts
    from planner.network.windows import BlockingParams
    from planner.network.arrivals import train_curves

    from .checks import check_jobs, check_out_dir, day_line

    check_out_dir(out, "--out", "conflict datasets")
    check_jobs(jobs)
    table: dict = {}
    if job is not None:
        from planner.job.config import load_job

        j = load_job(job)
        if not j.conflicts.enabled:
            typer.echo(f"{job}: [conflicts] enabled = false; nothing to do")
            return
        table = {k: v for k, v in dataclasses.asdict(j.conflicts).items() if k != "enabled"}  # as the night's
    for key, value in (("setting_s", setting_s), ("approach_s", approach_s), ("release_s", release_s),
                       ("terminal_s", terminal_s)):
        if value is not None:
            if not value >= 0:
                raise InputError(f"--{key.replace('_', '-')} must be ≥ 0 s, found {value}")
            table[key] = value
    params = BlockingParams.from_dict(table, where="--")
    lifted: dict = {}
    line = day_line(load_line(line_dir), job, day, lifted)
    if line.network is None:
        raise InputError(f"{line_dir}: no track network; add nodes.parquet and edges.parquet to check conflicts")
    curves = train_curves(line, lifted, mode=curve_mode, n_jobs=jobs)  # per train, as the night's
    with progress_bar() as bar:
        sim = bar.add_task("run curves", total=None)
        pred = bar.add_task("trains", total=len(line.trains))
        report = check_conflicts(
            line, params, curves=curves,
            curve_progress=lambda d, n: bar.update(sim, completed=d, total=n),
            progress=lambda d, n: bar.update(pred, completed=d, total=n),
        )
    files = write_conflicts(report, out)
    for msg in report.summary_lines():
        typer.echo(msg)
    typer.echo(f"  wrote {len(files)} files under {out} (conflicts/, headways/, occupation/, unrouted/)")
