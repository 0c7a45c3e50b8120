"""The whole-timetable conflict check (docs/design.md §8): routes → arrivals → blocking windows → conflicts.

Takes a :class:`~planner.line.model.Line` with a track network and a
timetable, the blocking-time parameters and a run-curve source; gives a
:class:`ConflictCheck` (routes, windows and conflict records as arrays and
plain values). Its datasets (``conflicts``, ``occupation``) and the printed
summary are built from it in :mod:`planner.datasets.conflicts`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from planner.line.model import Line, Train
from planner.network.arrivals import (NoCurveError, RunCurveSource, SimulatorCurves, build_trajectory,
                                      interstation_keys)
from planner.network.headways import resource_headways
from planner.network.priority import detect_conflicts
from planner.network.routes import Route, TrackGraph, plan_routes
from planner.network.windows import BlockingParams, Windows, occupation_windows


@dataclass(frozen=True, eq=False)
class ConflictCheck:
    """What the conflict check found for one line.

    Attributes
    ----------
    graph : TrackGraph
        The line's track graph (names the resources of ``windows``).
    trains : tuple of Train
        The timetable, in order; ``windows.train`` indexes it.
    routes : dict
        ``train_id`` → :class:`Route`, in timetable order.
    windows : Windows
        Blocking-time windows of every train.
    conflicts : list of dict
        One record per (conflict, resource), from :func:`detect_conflicts`.
    headways : list of dict
        The tightest pair of following trains per resource, from :func:`resource_headways`.
    unrouted : dict
        ``train_id`` → why it has no route (one line), in timetable order: trains the track network
        cannot carry, left out of ``trains`` and of everything above, which is what the check finds
        on a timetable without them.
    """

    line_id: str
    params: BlockingParams
    graph: TrackGraph
    trains: tuple[Train, ...]
    routes: dict[str, Route]
    windows: Windows
    conflicts: list[dict[str, Any]]
    headways: list[dict[str, Any]]
    unrouted: dict[str, str] = field(default_factory=dict)
    plans: tuple = ()
    """Per train of ``trains``: (its (arrival, departure) per stop call as predicted, its legs' minimum
    running times) from its trajectory (:class:`~planner.network.arrivals.Trajectory`), for the day's delay
    network (:mod:`planner.delay`)."""


def check_timetable(line: Line, params: BlockingParams | Mapping[str, Any] | None = None, *,
                    curves: RunCurveSource | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    curve_progress: Callable[[int, int], None] | None = None) -> ConflictCheck:
    """Check a line's whole timetable for route conflicts on its track network.

    Parameters
    ----------
    line : Line
        Line with ``network`` and a timetable.
    params : BlockingParams or mapping, optional
        Blocking-time parameters (a job file's ``[conflicts]`` table works).
    curves : RunCurveSource, optional
        Run curves per interstation; default :class:`SimulatorCurves` (ratio
        matched to the schedule).
    progress : callable(done, total), optional
        Called after each train is predicted.
    curve_progress : callable(done, total), optional
        Called as run curves are simulated (before the trains are predicted).

    Returns
    -------
    ConflictCheck
    """
    p = params if isinstance(params, BlockingParams) else BlockingParams.from_dict(params)
    g = TrackGraph(line)
    unrouted: dict[str, str] = {}
    routes_d = plan_routes(line, g, unrouted=unrouted)  # a train the network cannot carry is a flag, not the night
    trains = [t for t in line.trains if t.train_id in routes_d]
    routes = [routes_d[t.train_id] for t in trains]
    src = curves or SimulatorCurves(line)
    if hasattr(src, "prepare"):
        src.prepare(sorted(set(interstation_keys(trains))), progress=curve_progress)
    parts, plans, kept = [], [], []
    for k, (t, r) in enumerate(zip(trains, routes)):
        try:
            traj = build_trajectory(line, t, src)
        except NoCurveError as e:  # it stalls on one of its legs: a flag on the train, like an unroutable one
            unrouted[t.train_id] = f"train {t.train_id} ({t.direction}): {e}"
            routes_d.pop(t.train_id)
            continue
        plans.append((traj.calls_s, traj.run_min_s))
        parts.append(occupation_windows(g, r, traj, line.train_type(t.train_type).length_m, p, len(kept)))
        kept.append((t, r))
        if progress:
            progress(k + 1, len(trains))
    trains, routes = [t for t, _ in kept], [r for _, r in kept]
    w = Windows.concat(parts)
    records = detect_conflicts(g, trains, routes, w)
    return ConflictCheck(line.line_id, p, g, tuple(trains), routes_d, w, records, resource_headways(g, trains, w),
                         unrouted, tuple(plans))
