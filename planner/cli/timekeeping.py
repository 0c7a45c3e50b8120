"""``planner timekeeping``: one interstation in time-keeping support mode (docs/design.md §4).

The same behaviour is what ``planner simulate ... --mode timekeeping`` runs:
that command dispatches to :func:`simulate_timekeeping_cli`.
"""
from __future__ import annotations

import json as _json
import math
from pathlib import Path
from typing import Optional, Sequence

import typer

from ..errors import InfeasibleError, InputError, PlannerError
from . import app
from .checks import DAY_HELP, JOB_HELP


def parse_change(text: str) -> tuple[float, float]:
    """Parse one ``--change T:ARRIVAL`` option into (seconds after departure, new arrival [s]).

    Raises
    ------
    InputError
        Naming the option and the expected form.
    """
    if isinstance(text, (tuple, list)):
        at, arr = text
        return float(at), float(arr)
    parts = str(text).split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        at, arr = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"--change {text!r}: expected T:ARRIVAL, two numbers of seconds after departure "
                         "(e.g. --change 40:130)") from None
    if not (math.isfinite(at) and math.isfinite(arr)):
        raise InputError(f"--change {text!r}: times must be finite numbers of seconds")
    return at, arr


def advice_segments(curve) -> list[dict]:
    """Consecutive runs of the same driver advice: ``[{"from_m", "to_m", "advice"}]`` (running distance)."""
    adv = curve["advice"].astype(str).to_numpy()
    dist = curve["distance_m"].to_numpy()
    out: list[dict] = []
    start = 0
    for i in range(1, len(adv) + 1):
        if i == len(adv) or adv[i] != adv[start]:
            out.append({"from_m": round(float(dist[max(start - 1, 0)]), 3),
                        "to_m": round(float(dist[i - 1]), 3), "advice": str(adv[start])})
            start = i
    return out


def summary(result, *, line_id: str, train_type: str, origin: str, destination: str) -> dict:
    """A JSON-ready, deterministic summary of a :class:`planner.api.TimekeepingResult`."""
    def r(x, nd=3):
        return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)

    return {
        "line": line_id,
        "train_type": train_type,
        "origin": origin,
        "destination": destination,
        "mode": "timekeeping",
        "scheduled_arrival_s": r(result.scheduled_s),
        "arrival_s": r(result.time_s),
        "arrival_error_s": r(result.arrival_error_s),
        "stop_error_m": r(result.stop_error_m),
        "shortfall_s": r(result.shortfall_s),
        "feasible": bool(result.feasible),
        "changes": [
            {"at_s": r(c.at_s), "applied_s": r(c.applied_s), "arrival_s": r(c.arrival_s),
             "earliest_s": r(c.earliest_s), "shortfall_s": r(c.shortfall_s)}
            for c in result.drive.changes
        ],
        "advice": advice_segments(result.curve),
    }


def simulate_timekeeping_cli(line, train_type: str, origin: str, destination: str, arrival_s: float,
                             changes: Sequence = (), load: float = 0.0, traction: float = 1.0,
                             json: bool = False, plot: Optional[Path] = None):
    """What ``planner simulate --mode timekeeping`` and ``planner timekeeping`` do.

    Runs :func:`planner.api.timekeeping_run` and prints a short summary
    (or, with ``json``, the :func:`summary` as JSON on stdout). A scheduled
    arrival that cannot be met raises :class:`planner.errors.InfeasibleError` (after the output) with the
    shortfall. Domain errors propagate as :class:`planner.errors.PlannerError`
    (the console entry point prints them as one line).

    Parameters
    ----------
    line : str or Path or Line
        Line database folder (or a loaded line).
    train_type, origin, destination : str
    arrival_s : float
        Scheduled arrival [s after departure].
    changes : sequence of "T:ARRIVAL" strings or (T, ARRIVAL) pairs
    load, traction : float
        Load factor and traction factor of the real train.
    json : bool
        Print JSON instead of text.
    plot : Path, optional
        Also write a PNG of speed, target and advice.

    Returns
    -------
    planner.api.TimekeepingResult
    """
    from planner.line.model import Line
    from planner.api import timekeeping_run

    parsed = [parse_change(c) for c in (changes or ())]
    if isinstance(line, Line):
        ln = line
    else:
        from .. import load_line

        ln = load_line(line)
    res = timekeeping_run(ln, train_type, origin, destination, arrival_s=arrival_s, changes=parsed,
                          load=load, traction_factor=traction)
    info = summary(res, line_id=ln.line_id, train_type=train_type, origin=origin, destination=destination)
    if plot is not None:
        from planner.report.plots import timekeeping_chart

        timekeeping_chart(res, advice_segments(res.curve), Path(plot), f"{ln.line_id} {train_type} {origin}->{destination} (time-keeping)")

    def verdict():
        # the run is printed either way (what the train did at the limit); an arrival that cannot be
        # kept is still a failure of the request, so it ends the command non-zero
        if not res.feasible:
            raise InfeasibleError(
                f"scheduled arrival {res.scheduled_s:.1f} s cannot be met: earliest possible "
                f"{res.scheduled_s + res.shortfall_s:.1f} s, shortfall {res.shortfall_s:.2f} s (ran at the limit)")
        return res

    if json:
        typer.echo(_json.dumps(info, indent=2))
        return verdict()
    typer.echo(f"{ln.line_id} {train_type} {origin}->{destination}: time-keeping, scheduled arrival "
               f"{res.scheduled_s:.1f} s after departure")
    for c in info["changes"][1:]:
        typer.echo(f"  change at {c['at_s']:.1f} s (applied {c['applied_s']:.2f} s): arrival -> "
                   f"{c['arrival_s']:.1f} s, earliest possible {c['earliest_s']:.1f} s")
    typer.echo(f"  arrived {res.time_s:.2f} s: arrival error {res.arrival_error_s:+.2f} s, "
               f"stop error {res.stop_error_m:+.3f} m, shortfall {res.shortfall_s:.2f} s")
    segs = info["advice"]
    shown = ", ".join(f"{s['advice']} {s['from_m']:.0f}-{s['to_m']:.0f} m" for s in segs[:8])
    more = f", ... ({len(segs)} segments)" if len(segs) > 8 else ""
    typer.echo(f"  advice: {shown}{more}")
    if plot is not None:
        typer.echo(f"  wrote {plot}")
    return verdict()


@app.command()
def timekeeping(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    train_type: str = typer.Option(..., "--train-type", help="Train type."),
    origin: str = typer.Option(..., "--from", help="Departure station id."),
    destination: str = typer.Option(..., "--to", help="Arrival station id (the next stop)."),
    arrival: float = typer.Option(..., "--arrival", help="Scheduled arrival [s after departure]."),
    change: Optional[list[str]] = typer.Option(
        None, "--change", help="T:ARRIVAL — at T s after departure the scheduled arrival becomes ARRIVAL s "
        "after departure (repeatable)."),
    load: float = typer.Option(0.0, "--load", help="Load factor (0 empty ... 1 full)."),
    traction: float = typer.Option(1.0, "--traction", help="Traction factor (1.0 nominal, 0.9 weak)."),
    json: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Write speed/target/advice to this PNG."),
    job: Optional[Path] = typer.Option(None, "--job", help=JOB_HELP),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Drive one interstation by the time-keeping target speed; report arrival and stop errors and advice.

    Exits 1 (after printing the run) when the scheduled arrival cannot be met.
    """
    from planner.line.loader import load_line
    from .checks import check_fraction, check_out_file, day_line, station_code, train_type_code

    try:
        check_fraction(load, "--load", "0 empty … 1 full")
        check_out_file(plot, "--plot", ".png", "plot")
        ln = day_line(load_line(line_dir), job, day)
        simulate_timekeeping_cli(ln, train_type_code(ln, train_type), station_code(ln, origin, "--from"),
                                 station_code(ln, destination, "--to"), arrival, change or (), load,
                                 traction, json, plot)
    except PlannerError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(e.exit_code) from None
