"""``planner runtime LINE ...``: running time of one train type between two stations."""
from __future__ import annotations

import json
from pathlib import Path

import typer

from ..errors import InputError
from . import app


def plot_run_curve(result, path: Path) -> None:
    """Draw a railway run-curve chart of ``result`` (a RunResult) to a PNG, atomically.

    Speed, on-board maximum and target (km/h) against chainage (km), running
    left to right in the running direction; elapsed time on a second axis; the
    two stations marked.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = result.curve
    km = c["position_m"].to_numpy() / 1000.0
    fig, ax = plt.subplots(figsize=(10, 5.2), dpi=110)
    ax.step(km, c["vmax_kmh"], where="mid", color="0.55", lw=1.2, label="on-board maximum")
    ax.step(km, c["target_kmh"], where="mid", color="tab:orange", lw=1.0, ls="--", label="target (ratio × max)")
    ax.plot(km, c["speed_kmh"], color="tab:blue", lw=1.8, label="speed")
    ax.set_xlabel("chainage [km]")
    ax.set_ylabel("speed [km/h]")
    ax.set_ylim(0, max(float(c["vmax_kmh"].max()), float(c["speed_kmh"].max())) * 1.15)
    if result.direction == "up":
        ax.invert_xaxis()  # run left to right
    ax.grid(True, alpha=0.3)
    top = ax.get_ylim()[1]
    for x, name in ((km[0], result.origin), (km[-1], result.destination)):
        ax.axvline(x, color="k", lw=1.0)
        ax.text(x, top * 0.97, f" {name} ", ha="center", va="top", fontsize=9,
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="k", lw=0.6))
    ax2 = ax.twinx()
    ax2.plot(km, c["time_s"], color="tab:green", lw=1.0, ls=":", label="time")
    ax2.set_ylabel("time since departure [s]", color="tab:green")
    ax2.set_ylim(0, result.time_s * 1.15)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    # below the axes, never over the curves
    ax.legend(h1 + h2, l1 + l2, loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize=8, ncol=4,
              frameon=False)
    ax.set_title(
        f"{result.line_id} {result.direction}: {result.origin} → {result.destination}, type {result.train_type}, "
        f"ratio {result.ratio:.0%}, load {result.load:.0%}, traction ×{result.traction_factor:g}\n"
        f"running time {result.time_s:.1f} s, traction energy {result.energy_kwh:.1f} kWh", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.91, top=0.88, bottom=0.22)
    from planner.io.atomic import save_png

    save_png(fig, path)


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
) -> None:
    """Running time (and traction energy) between two stations at a target-speed ratio."""
    from planner.line.loader import load_line
    from planner.physics.track import SimSettings
    from planner.api import running_time
    from .checks import check_fraction, check_out_file, station_code, train_type_code

    if not 0.0 < ratio <= 1.0:
        raise InputError(f"--ratio must lie in (0, 1], got {ratio}")
    check_fraction(load, "--load", "0 empty … 1 full")
    if not traction > 0.0:
        raise InputError(f"--traction must be > 0, got {traction}")
    check_out_file(plot, "--plot", ".png", "run-curve chart")
    line = load_line(line_dir)
    train_type = train_type_code(line, train_type)
    origin, destination = station_code(line, origin, "--from"), station_code(line, destination, "--to")
    res = running_time(line, train_type, origin, destination, ratio=ratio, load=load,
                       traction_factor=traction, settings=SimSettings(ds))
    if plot is not None:
        plot_run_curve(res, plot)
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
