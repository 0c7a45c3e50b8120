"""``planner tables`` and ``planner simulate``: running-time tables and their closed-loop proof."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Optional
from typing import Iterator, Optional

import typer

from ..errors import PlannerError
from . import app
from .checks import DAY_HELP, JOB_HELP


BUILTIN_MODES = ("nearest", "interpolate", "adaptive", "timekeeping")
"""The on-board modes `planner simulate --mode` knows without registration (its help lists them)."""


def all_modes() -> list[str]:
    """Every mode `planner simulate --mode` accepts: the built-in ones, then registered ones."""
    from planner.tables.closed_loop import modes

    return list(BUILTIN_MODES) + [m for m in modes() if m not in BUILTIN_MODES]


@contextmanager
def _progress(label: str) -> Iterator:
    """A rich progress bar; yields a ``(done, total)`` callback for the library functions."""
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
    from .progress import bar as progress_bar

    with progress_bar(TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn()) as bar:
        task = bar.add_task(label, total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


@app.command()
def tables(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Output folder; datasets eval_points/, table_a/, table_b/, table_c/ "
                             "and table_d/ go here."),
    train_type: Optional[list[str]] = typer.Option(
        None, "--train-type", help="Train type (repeatable); default every type of the line."),
    ratios: Optional[str] = typer.Option(
        None, "--ratios", help="Ratio grid: 'start:stop:step' pieces and/or values, e.g. "
        "'1.0:0.7:0.1,0.7:floor:0.05' (the default) or '1,0.9,0.8'."),
    after_departure_m: float = typer.Option(
        200.0, "--after-departure", help="Distance of the evaluation point after departure [m]; 0 = none."),
    eval_interval_m: float = typer.Option(
        0.0, "--eval-interval", help="Odometer evaluation points at this regular interval after the point "
        "after departure [m], in addition to the beacons; 0 = beacons only (the default)."),
    # 30.0 = planner.tables.eval_points.DEFAULT_AUTO_S (not imported: the CLI starts without numpy)
    eval_auto_s: float = typer.Option(
        30.0, "--eval-auto", help="On a leg with no beacon evaluation point (and no --eval-interval): "
        "odometer points every this many seconds of running at the leg's maximum speed; 0 = none."),
    jobs: int = typer.Option(-1, "--jobs", help="Worker processes (-1 = all cores)."),
    job: Optional[Path] = typer.Option(None, "--job", help=JOB_HELP),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Compute running-time tables (a), (b), (c) and (d) for every interstation, direction and train type.

    (a) running time from departure per ratio; (b) remaining time from every evaluation point;
    (c) the same for the degraded reference train (adaptive mode); (d) remaining time by the
    train's own state at the last evaluation point (sawtooth vehicles only).

    Evaluation points: the departure, the point after departure (--after-departure), the flagged
    beacons and, with --eval-interval, odometer points at that regular interval; a leg without
    beacon points gets odometer points every --eval-auto seconds of running at its maximum.
    """
    from planner.line.loader import load_line
    from planner.tables.build import build_tables
    from planner.datasets.tables import write_tables
    from .checks import check_jobs, check_out_dir, day_line, train_type_codes

    check_out_dir(out, "--out", "tables")
    check_jobs(jobs)
    line = day_line(load_line(line_dir), job, day)
    train_type = train_type_codes(line, train_type)
    with _progress("tables") as update:
        results = build_tables(line, train_types=train_type or None, ratios=ratios,
                               after_departure_m=after_departure_m or None,
                               eval_interval_m=eval_interval_m or None, eval_auto_s=eval_auto_s or None,
                               n_jobs=jobs, progress=update)
    files = write_tables(results, out)
    n_b = sum(r.remaining_s.size for r in results)
    grid = results[0].ratios if results else []
    typer.echo(f"{line.line_id}: tables for {len(results)} interstation x direction x train type, "
               f"{len(grid)} ratios ({', '.join(f'{r:g}' for r in grid)})")
    n_odo = sum(p.kind == "interval" for r in results for p in r.points)
    typer.echo(f"  evaluation points: {sum(len(r.points) for r in results)} ({n_odo} at the regular interval), "
               f"table (b) rows: {n_b}")
    shown = 3
    for r in results[:shown]:
        typer.echo(f"  {r.train_type} {r.direction} {r.origin}->{r.destination}: minimum "
                   f"{r.time_a_s[0]:.1f} s, slowest {r.time_a_s[-1]:.1f} s")
    if len(results) > shown:
        typer.echo(f"  … {len(results) - shown} more (every one in {out / 'table_a'})")
    for r in results:  # physical verdicts: flags on their legs, not errors
        for f in r.flags:
            typer.echo(f"  flag {r.train_type} {r.direction} {r.origin}->{r.destination}: {f.reason}")
    typer.echo(f"  wrote {len(files)} files under {out}")


@app.command()
def simulate(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    tables_dir: Optional[Path] = typer.Option(None, "--tables", help="Folder written by `planner tables` "
                                              "(table modes)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder for closed_loop/ and "
                                       "closed_loop_summary/ (table modes)."),
    scenario: str = typer.Option("nominal", "--scenario", help="nominal (as the tables) or perturbed "
                                 "(load 1.0, traction x 0.9)."),
    mode: str = typer.Option("nearest", "--mode", help="On-board mode, one of " + ", ".join(BUILTIN_MODES)
                             + ": nearest (published rule), interpolate (fractional ratios), adaptive "
                             "(interpolate + learns the train's deviation from the tables), timekeeping "
                             "(cruise speed from the remaining time and distance, docs/design.md §4; one interstation "
                             "with arrival changes: `planner timekeeping`); modes registered with "
                             "planner.tables.closed_loop.register_mode are accepted too."),
    train_type: Optional[list[str]] = typer.Option(None, "--train-type", help="Train type (repeatable)."),
    extra_s: float = typer.Option(60.0, "--extra", help="Sweep designated times up to minimum + this [s]."),
    jobs: int = typer.Option(-1, "--jobs", help="Worker processes (-1 = all cores)."),
) -> None:
    """Closed loop: the on-board logic (its nominal model) drives the real train (the scenario)
    against designated running times from the minimum to the minimum + --extra; reports arrival
    errors (the simulated train stops on the marker by construction: no stop error)."""
    from planner.tables.closed_loop import overall
    from planner.datasets.closed_loop import run_closed_loop, write_closed_loop
    from planner.line.loader import load_line
    from .checks import check_jobs, check_out_dir, train_type_codes

    known = all_modes()
    if mode not in known:
        raise PlannerError(f"--mode {mode!r} is unknown; use one of {', '.join(known)}")
    check_jobs(jobs)
    check_out_dir(out, "--out", "closed-loop datasets")
    if tables_dir is None or out is None:
        raise PlannerError(f"--mode {mode} needs --tables DIR (from `planner tables`: the sweep starts "
                           "at their minimum) and --out DIR")
    line = load_line(line_dir)
    train_type = train_type_codes(line, train_type)
    with _progress(f"simulate {scenario}/{mode}") as update:
        results = run_closed_loop(line, tables_dir, train_types=train_type or None, scenario=scenario,
                                  mode=mode, extra_s=extra_s, n_jobs=jobs, progress=update)
    files = write_closed_loop(results, out)
    o = overall(results)
    typer.echo(f"{line.line_id}: closed loop {scenario}/{mode}, {o['n_runs']} runs over "
               f"{len(results)} interstation x direction x train type")
    typer.echo(f"  |arrival error| over {o['n_feasible']} feasible runs: median {o['median_abs_error_s']:.2f} s, "
               f"p95 {o['p95_abs_error_s']:.2f} s, max {o['max_abs_error_s']:.2f} s")
    n_inf = o["n_runs"] - o["n_feasible"] - sum(int(r.stalled.sum()) for r in results)  # stalled: below
    if n_inf:
        typer.echo(f"  {n_inf} runs infeasible by physics (designated below the {scenario} minimum); "
                   f"worst arrival after that minimum {o['infeasible_excess_max_s']:.2f} s")
    for r in results:  # physical verdicts: flags on their legs, not errors
        for f in r.flags:
            typer.echo(f"  flag {r.train_type} {r.direction} {r.origin}->{r.destination}: {int(r.stalled.sum())} "
                       f"runs did not arrive: {f.reason}")
    typer.echo(f"  wrote {len(files)} files under {out}")
