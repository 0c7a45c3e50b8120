"""``planner stops``: stopping patterns for every station approach over an adhesion sweep."""
from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Optional

import typer

from ..errors import InputError
from . import app
from .checks import DAY_HELP, JOB_HELP


@app.command()
def stops(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Output folder; datasets stop_summary/ and stop_samples/ go here."),
    adhesion: str = typer.Option("2.5:3.5:0.1", "--adhesion",
                                 help="Adhesion levels [km/h/s]: START:STOP:STEP (inclusive) or a list a,b,c."),
    train_type: Optional[list[str]] = typer.Option(
        None, "--train-type", help="Train type (repeatable); default every type of the line."),
    direction: Optional[str] = typer.Option(None, "--direction", help="down or up; default both."),
    approach_m: str = typer.Option("auto", "--approach", help="Approach length where there is no TASC beacon [m], "
                                   "or auto: the line's approach_m, else where the train must start braking + 10 %."),
    plot: Optional[str] = typer.Option(
        None, "--plot", help="Station id: also write a PNG of its approach (speed, acceleration, jerk per "
        "adhesion level) for the first train type and --direction (default down)."),
    jobs: int = typer.Option(-1, "--jobs", help="Worker processes (-1 = all cores)."),
    job: Optional[Path] = typer.Option(None, "--job", help=JOB_HELP),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Solve minimum-time jerk-limited stopping patterns for every station approach and adhesion level."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
    from .progress import bar as progress_bar

    from planner.line.loader import load_line
    from planner.stopping.sweep import InfeasibleStopWarning, adhesion_levels, stop_sweep
    from planner.datasets.stops import write_stops
    from planner.line.units import KMH_S

    from .checks import check_jobs, check_out_dir, day_line, station_code, train_type_codes

    check_out_dir(out, "--out", "stopping-pattern datasets")
    check_jobs(jobs)
    levels = adhesion_levels(adhesion)
    if approach_m != "auto":
        try:
            approach_m = float(approach_m)
        except ValueError:
            raise InputError(f"--approach {approach_m!r}: give metres (e.g. 550) or auto") from None
    if direction is not None and direction not in ("down", "up"):
        raise InputError(f"--direction {direction!r}: use down or up")
    line = day_line(load_line(line_dir), job, day)
    train_type = train_type_codes(line, train_type)
    plot_dir = direction or "down"
    if plot is not None:
        plot = station_code(line, plot, "--plot")
        st = line.station(plot)
        arrivals = [b.station_id for _, b in line.interstations(plot_dir)]
        if st.station_id not in arrivals:
            raise InputError(f"--plot {plot}: no train arrives at {plot} running {plot_dir}; "
                             f"choose the other --direction")
    with progress_bar(TextColumn("stops"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn()) as bar:
        task = bar.add_task("stops", total=None)
        with warnings.catch_warnings():
            # reported below, one line per approach, instead of one warning per level
            warnings.simplefilter("ignore", InfeasibleStopWarning)
            results = stop_sweep(line, train_types=train_type or None, adhesion_kmh_s=levels,
                                 approach_m=approach_m, directions=[direction] if direction else None,
                                 n_jobs=jobs,
                                 progress=lambda done, total: bar.update(task, completed=done, total=total))
    files = write_stops(results, out)
    png = None
    if plot is not None:
        types = train_type or [line.train_types[0].train_type]
        pick = next(r for r in results
                    if r.station_id == plot and r.direction == plot_dir and r.train_type == types[0])
        from planner.report.plots import approach_chart

        png = approach_chart(pick, Path(out) / "plots" / f"stop_{pick.station_id}_{pick.direction}_"
                            f"{pick.train_type}.png")

    n_pat = sum(len(r.patterns) for r in results)
    n_inf = n_pat - sum(r.n_feasible for r in results)
    lost = [t for r in results for t in r.time_lost_s if not math.isnan(t)]
    typer.echo(f"{line.line_id}: {len(results)} station approaches x up to {len(levels)} adhesion levels "
               f"({levels[0]:g} … {levels[-1]:g} km/h/s) = {n_pat} patterns")
    capped = {r.train_type: max(r.adhesion_ms2) / KMH_S for r in results if max(r.adhesion_ms2) < levels[-1] * KMH_S}
    for tt, top in capped.items():  # a level above what the train's stops ask of its brake is not one of its levels
        typer.echo(f"  {tt}: levels above {top:g} km/h/s (its braking comfort or stopping brake) are that level")
    typer.echo(f"  feasible {n_pat - n_inf}, infeasible {n_inf}"
               + (f" (in {sum(1 for r in results if r.n_feasible < len(r.patterns))} approaches)" if n_inf else ""))
    if lost:
        typer.echo(f"  time lost against the best adhesion: {min(lost):.2f} … {max(lost):.2f} s")
    partial = [r for r in results if r.n_feasible < len(r.patterns)]
    for r in partial[:12]:  # the warnings, one line per approach
        bad = [(a / KMH_S, p) for a, p in zip(r.adhesion_ms2, r.patterns) if not p.feasible]
        span = f"{bad[0][0]:g}" if len(bad) == 1 else f"{bad[0][0]:g} … {bad[-1][0]:g}"
        typer.echo(f"  warning: no pattern at {r.station_id} ({r.direction}, {r.train_type}, from {r.origin}) "
                   f"at adhesion {span} km/h/s; at {bad[0][0]:g}: {bad[0][1].reason}")
    if len(partial) > 12:
        typer.echo(f"  … and {len(partial) - 12} more approaches without a pattern at some level")
    typer.echo(f"  wrote {len(files)} files under {out}")
    if png is not None:
        typer.echo(f"  plot: {png}")
