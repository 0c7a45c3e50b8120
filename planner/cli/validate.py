"""``planner validate LINE_DIR``: check a line database and summarise it."""
from __future__ import annotations

from pathlib import Path

import typer

from ..errors import LineValidationError, PlannerError
from planner.line.model import Line
from planner.line.units import kmh
from planner.line.validate import format_violations, format_warnings
from . import app


def summary(line: Line) -> list[str]:
    """Short human summary of a valid line, one fact per line."""
    n_st = len(line.stations)
    no_beacon = sum(1 for s in line.speed_limits if not s.has_beacon)
    eval_pts = sum(1 for b in line.beacons if b.evaluation_point)
    n_calls = sum(len(t.calls) for t in line.trains)
    out = [
        f"line {line.line_id} ({line.name}): valid, schema v{line.schema_version}",
        f"  length:             {(line.end_m - line.start_m) / 1000:.3f} km "
        f"(chainage {line.start_m:.1f} … {line.end_m:.1f} m), "
        + (f"max {kmh(line.max_speed_ms):.0f} km/h" if line.max_speed_ms < float("inf")
           else "no line maximum (each train's own where no restriction applies)"),
        f"  stations:           {n_st} ({max(n_st - 1, 0)} interstations per direction)",
        f"  speed restrictions: {len(line.speed_limits)} ({no_beacon} without ATS-P beacon)",
        f"  beacons:            {len(line.beacons)} ({eval_pts} evaluation points)",
        f"  signals:            {len(line.signals)}",
        f"  train types:        {len(line.train_types)} "
        f"({', '.join(t.train_type for t in line.train_types)})",
        f"  trains:             {len(line.trains)} with {n_calls} calls",
    ]
    if line.network is not None:
        out.append(f"  network:            {len(line.network.nodes)} nodes, {len(line.network.edges)} edges")
    out.append(f"  source digest:      sha256:{line.source_digest}")
    return out


@app.command()
def validate(
    line_dir: Path = typer.Argument(..., help="Line database folder (holds line.parquet, stations.parquet, ...)."),
) -> None:
    """Check a line database against docs/line-database.md (`planner schema`); print a summary (exit 0) or every problem (exit 1)."""
    from planner.line.loader import load_line

    warnings: list = []
    try:
        line = load_line(line_dir, warnings)
    except LineValidationError as e:
        for msg in format_violations(e.violations):
            typer.echo(msg, err=True)
        typer.echo(f"{line_dir}: {e.total} problem(s); the line database is invalid "
                   f"(the rules: docs/line-database.md, or `planner schema`)", err=True)
        raise typer.Exit(1)
    except PlannerError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(e.exit_code)
    for msg in summary(line):
        typer.echo(msg)
    for note in line.upgrade_notes:  # an earlier schema version, read as the current one
        typer.echo(f"note: {note}; `planner line upgrade {line_dir}` rewrites the folder", err=True)
    for msg in format_warnings(warnings):  # grouped by rule: a count and the first few rows
        typer.echo(f"warning: {msg}" if not msg.startswith("  ") else msg, err=True)
