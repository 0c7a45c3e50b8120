"""The library's single-run calls, for scripts and notebooks: take a line (or its folder), give frames.

:func:`running_time` (one run at a target-speed ratio) and :func:`timekeeping_run`
(one interstation in time-keeping mode) sit on top of the pure integrator in
:mod:`planner.physics` and the controller in :mod:`planner.tables.timekeeping`;
here the line folder is loaded and the arrays become pandas frames in display
units (km/h). ``planner`` re-exports both.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd

from planner.errors import InputError
from planner.line.model import Line
from planner.line.units import kmh
from planner.physics.run_curve import PHASE_NAMES, _check_ratio, simulate
from planner.physics.track import SimSettings, make_track
from planner.tables.timekeeping import ADVICE_NAMES, RECOMPUTE_M, RECOMPUTE_S, DriveResult, drive


def _as_line(line_or_path) -> Line:
    """A loaded line as it is; a line database folder loaded and validated."""
    if isinstance(line_or_path, Line):
        return line_or_path
    from planner.line.loader import load_line

    return load_line(line_or_path)


@dataclass(frozen=True, eq=False)
class RunResult:
    """One run from a station stop to the next (:func:`running_time`).

    Attributes
    ----------
    time_s : float
        Running time, departure to standing at the arrival marker [s].
    energy_kwh : float
        Mechanical traction work at the wheel [kWh].
    curve : pandas.DataFrame
        One row per grid node: ``position_m`` (chainage), ``distance_m`` (from
        the departure marker), ``time_s``, ``speed_kmh``, ``accel_ms2`` (mean
        over the step arriving at the node), ``phase`` (name), ``vmax_kmh``
        (on-board maximum), ``target_kmh`` (ratio in force × on-board maximum),
        ``ratio``.
    """

    line_id: str
    train_type: str
    origin: str
    destination: str
    direction: str
    length_m: float
    ratio: float
    load: float
    traction_factor: float
    time_s: float
    energy_kwh: float
    curve: "object"


def running_time(line_or_path, train_type: str, origin: str, destination: str, *, ratio: float = 1.0,
                 load: float = 0.0, traction_factor: float = 1.0,
                 ratio_changes: Sequence[tuple[float, float]] = (),
                 settings: SimSettings | None = None) -> RunResult:
    """Running time of one train type between two stations at a target-speed ratio.

    Parameters
    ----------
    line_or_path : Line or path
        A line, or a line database folder (loaded with :func:`planner.load_line`).
    train_type, origin, destination : str
        The direction follows from the two stations.
    ratio : float
        Target-speed ratio from departure, in (0, 1].
    load : float
        Load factor (0 empty … 1 full).
    traction_factor : float
        Multiplies the tractive-effort curve (0.9 = weak catenary).
    ratio_changes : sequence of (position_m, ratio)
        Ratio changes at chainages between the two stop markers.
    settings : SimSettings, optional
        Distance step (default 1 m).

    Returns
    -------
    RunResult

    Examples
    --------
    >>> from planner.line import testing
    >>> res = running_time(testing.line(), "T", "S0", "S1")
    >>> round(res.time_s, 1)
    135.8
    """
    line = _as_line(line_or_path)
    settings = settings or SimSettings()
    train = line.train_type(train_type)
    ext = line.run_between(origin, destination)
    direction, sg, x0, x1 = ext.direction, ext.sign, ext.start_m, ext.end_m
    changes_s = []
    for pos, r in ratio_changes:
        d = sg * (float(pos) - x0)
        if not (0.0 <= d < sg * (x1 - x0)):
            raise InputError(f"ratio change at position_m={pos} lies outside {origin}->{destination} "
                             f"({x0} … {x1} m)")
        changes_s.append((d, float(r)))
    _check_ratio(np.array([ratio] + [r for _, r in changes_s], dtype=float), "ratio")
    track = make_track(line, train_type, origin, destination, settings=settings,
                       nodes_m=[d for d, _ in changes_s])
    res = simulate(track, train, float(ratio), load=float(load), traction_factor=float(traction_factor),
                   changes=[(d, np.array([r])) for d, r in changes_s], record=True)
    rat = res.ratio[0]
    curve = pd.DataFrame({
        "position_m": track.position_m(res.s_m),
        "distance_m": res.s_m,
        "time_s": res.t_s[0],
        "speed_kmh": kmh(res.v_ms[0]),
        "accel_ms2": res.a_ms2[0],
        "phase": pd.Categorical.from_codes(res.phase[0].astype(int), categories=list(PHASE_NAMES)),
        "vmax_kmh": kmh(track.vmax_ms),
        "target_kmh": kmh(rat * track.vmax_ms),
        "ratio": rat,
    })
    return RunResult(
        line_id=line.line_id, train_type=train_type, origin=origin, destination=destination,
        direction=direction, length_m=track.length_m, ratio=float(ratio), load=float(load),
        traction_factor=float(traction_factor), time_s=float(res.time_s[0]),
        energy_kwh=float(res.energy_kwh[0]), curve=curve,
    )


@dataclass(frozen=True)
class TimekeepingResult:
    """Result of :func:`timekeeping_run` (a ``RunResult``-like object).

    Attributes
    ----------
    time_s : float
        Actual arrival [s after departure].
    scheduled_s : float
        Scheduled arrival in force at the end [s after departure].
    arrival_error_s : float
        ``time_s − scheduled_s`` [s] (positive: late).
    stop_error_m : float
        Stop position − stop marker [m] (positive: overrun).
    shortfall_s : float
        > 0 when the scheduled arrival could not be met at all: the predicted
        lateness (earliest possible arrival − scheduled). The run then drives
        flat out and ``arrival_error_s`` ≈ ``shortfall_s``.
    curve : pandas.DataFrame
        One row per grid node: ``position_m`` (chainage), ``distance_m``
        (from the departure marker), ``time_s``, ``speed_kmh``,
        ``target_kmh`` (the speed the driver is shown), ``advice``
        (``power``/``hold``/``coast``/``brake``).
    changes : pandas.DataFrame
        The schedule at departure and every change: ``at_s``, ``applied_s``,
        ``arrival_s``, ``earliest_s``, ``shortfall_s``.
    drive : DriveResult
        The arrays behind it.
    """

    time_s: float
    scheduled_s: float
    arrival_error_s: float
    stop_error_m: float
    shortfall_s: float
    curve: object
    changes: object
    drive: DriveResult

    @property
    def feasible(self) -> bool:
        """True if the final scheduled arrival could be kept."""
        return self.shortfall_s <= 0.0


def timekeeping_run(line_or_path, train_type: str, origin: str, destination: str, *,
                    arrival_s: float, changes=(), load: float = 0.0,
                    traction_factor: float = 1.0, settings=None,
                    recompute_s: float = RECOMPUTE_S, recompute_m: float = RECOMPUTE_M) -> TimekeepingResult:
    """One interstation driven in time-keeping mode (docs/design.md §4); see :func:`drive`.

    Parameters
    ----------
    line_or_path : Line or str or Path
        A loaded line or a line database folder.
    train_type, origin, destination : str
        Train type and the two stations (direction follows from them).
    arrival_s : float
        Scheduled arrival [s after departure].
    changes : sequence of (at_s, arrival_s)
        Scheduled-arrival changes: at ``at_s`` seconds after departure the
        arrival becomes ``arrival_s`` seconds after departure.
    load, traction_factor : float
        Conditions of the real train (load factor, traction multiplier).
    settings : planner.physics.track.SimSettings, optional
        Grid step (default 1 m).

    Returns
    -------
    TimekeepingResult

    Examples
    --------
    >>> from planner.line import testing
    >>> line = testing.line(length_m=1000.0, limits=[(400.0, 600.0, 60.0)])
    >>> r = timekeeping_run(line, "T", "S0", "S1", arrival_s=80.0, changes=[(40.0, 90.0)])
    >>> abs(r.arrival_error_s) < 0.2 and abs(r.stop_error_m) < 0.2
    True
    """
    line = _as_line(line_or_path)
    train = line.train_type(train_type)
    track = make_track(line, train_type, origin, destination,
                       settings=settings if settings is not None else SimSettings())
    d = drive(track, train, arrival_s, changes=changes, load=load, traction_factor=traction_factor,
              recompute_s=recompute_s, recompute_m=recompute_m)
    curve = pd.DataFrame({
        "position_m": np.asarray(track.position_m(d.s_m), dtype=float),
        "distance_m": d.s_m,
        "time_s": d.t_s,
        "speed_kmh": kmh(d.v_ms),
        "target_kmh": kmh(d.target_ms),
        "advice": pd.Categorical.from_codes(d.advice.astype(int), categories=list(ADVICE_NAMES)),
    })
    ch = pd.DataFrame([r.__dict__ for r in d.changes],
                      columns=["at_s", "applied_s", "arrival_s", "earliest_s", "shortfall_s"])
    return TimekeepingResult(
        time_s=d.time_s, scheduled_s=d.scheduled_s, arrival_error_s=d.arrival_error_s,
        stop_error_m=d.stop_error_m, shortfall_s=d.shortfall_s, curve=curve, changes=ch, drive=d)
