"""``planner runtime LINE ...``: running time of one train type between two stations."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from ..errors import InputError
from . import app
from .checks import DAY_HELP, JOB_HELP


@app.command()
def runtime(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    train_type: str = typer.Option(..., "--train-type", help="Train type (rolling_stock.parquet)."),
    origin: str = typer.Option(..., "--from", help="Departure station_id."),
    destination: str = typer.Option(..., "--to", help="Arrival station_id (next stop)."),
    ratio: float = typer.Option(1.0, "--ratio", help="Target-speed ratio, 0 < R ≤ 1."),
    load: float = typer.Option(0.0, "--load", help="Load factor (0 empty … 1 full)."),
    traction: float = typer.Option(1.0, "--traction", help="Traction factor (1.0 nominal, 0.9 weak)."),
    as_json: bool = typer.Option(False, "--json", help="Print the result as one JSON object."),
    plot: Path = typer.Option(None, "--plot", help="Write a run-curve chart to this PNG file."),
    ds: float = typer.Option(1.0, "--ds", help="Integration distance step in metres."),
    job: Optional[Path] = typer.Option(None, "--job", help=JOB_HELP),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Running time (and traction energy) between two stations at a target-speed ratio."""
    from planner.line.loader import load_line
    from planner.physics.track import SimSettings
    from planner.api import running_time
    from .checks import check_fraction, check_out_file, day_line, station_code, train_type_code

    if not 0.0 < ratio <= 1.0:
        raise InputError(f"--ratio must lie in (0, 1], got {ratio}")
    check_fraction(load, "--load", "0 empty … 1 full")
    if not traction > 0.0:
        raise InputError(f"--traction must be > 0, got {traction}")
    check_out_file(plot, "--plot", ".png", "run-curve chart")
    line = day_line(load_line(line_dir), job, day)
    train_type = train_type_code(line, train_type)
    origin, destination = station_code(line, origin, "--from"), station_code(line, destination, "--to")
    res = running_time(line, train_type, origin, destination, ratio=ratio, load=load,
                       traction_factor=traction, settings=SimSettings(ds))
    if plot is not None:
        from planner.report.plots import run_curve_chart

        run_curve_chart(res, plot)
    if as_json:
        typer.echo(json.dumps({
            "line": res.line_id, "train_type": res.train_type, "origin": res.origin,
            "destination": res.destination, "direction": res.direction,
            "distance_m": round(res.length_m, 3), "ratio": res.ratio, "load": res.load,
            "traction_factor": res.traction_factor, "running_time_s": round(res.time_s, 3),
            "energy_kwh": round(res.energy_kwh, 3),
            "max_speed_kmh": round(float(res.curve["speed_kmh"].max()), 3),
        }))
        return
    typer.echo(f"{res.line_id} {res.direction} {res.origin} -> {res.destination}, type {res.train_type}, "
               f"ratio {res.ratio:g}, load {res.load:g}, traction x{res.traction_factor:g}: "
               f"{res.length_m:.0f} m")
    mins, secs = divmod(round(res.time_s, 1), 60.0)
    typer.echo(f"  running time {res.time_s:.1f} s ({mins:.0f} min {secs:04.1f} s), "
               f"traction energy {res.energy_kwh:.2f} kWh, top speed {res.curve['speed_kmh'].max():.1f} km/h")
    if plot is not None:
        typer.echo(f"  run curve: {plot}")
