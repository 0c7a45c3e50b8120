"""The train graph (time-distance diagram, ダイヤグラム) of a line and a day: data, charts, interactive page.

Stations stand on the vertical axis at their chainage (the line's origin at the
top, so down trains fall to the right, as planners draw them), time runs along
the horizontal axis. Each train is drawn from its **predicted trajectory**: the
front's chainage over time that the conflict check of :mod:`planner.network`
predicts from the run-curve simulator (:func:`planner.network.arrivals.build_trajectory`
with :class:`planner.network.arrivals.SimulatorCurves`), not straight lines between
timetable points, so acceleration and braking bend the line and a stop is a
flat step (front at the stop marker from arrival to departure). Nothing here
simulates: the trajectories, blocking-time windows and conflicts are the
network module's, read through its public functions or from the ``occupation``
and ``conflicts`` datasets of a run.

What the graph shows:

* **locals and rapids** told apart: a *rapid* passes at least one
  intermediate station of its run, a *local* stops at every one; rapids are
  drawn in a warm colour and thicker, locals in a cool colour, each direction
  in its own shade;
* **stops** as flat steps, **loop stops** (where the route search puts a
  stopping train on the loop to be overtaken, :attr:`planner.network.routes.Route.loop_calls`)
  with a ring, so an overtake reads as a rapid crossing a standing local there;
* **conflicts**: the overlap of two trains' blocking windows on one resource,
  a magenta box from overlap start to end over the resource's chainage, at
  least :data:`CONFLICT_MIN_PX` on each side; clicked, both trains' stairways
  with their overlap;
* the **predicted day** (the ``delay_events`` dataset, every delay carried forward), on the page: each late
  train's run dashed beside its line where it is late, a dot at each late event
  (:mod:`planner.report.graph_predicted`);
* the **blocking-time stairway** of a selected train: its occupation windows,
  one box per section/switch from window opening (entry − setting − approach)
  to closing (tail clear + release).

Outputs: :func:`train_graph_chart` (SVG or PNG by the file suffix, one direction or
both), :func:`planner.pages.train_graph.render_page` (one self-contained HTML page, no network, inline
SVG built by a small script from compact data: zoom to an hour, hover a train
for number, type, times and margin, click it for its stairway).

Size of the page: per train the trajectory is thinned with the
Ramer–Douglas–Peucker algorithm to :data:`TOL_T_S` / :data:`TOL_X_M` (below a
pixel at the one-hour zoom) and stored delta-coded in whole decisecond and
metre steps; the blocking windows likewise. The page grows linearly with the
number of trains (about 2.7 kB per train on the sample line: 0.97 MB for its 356
trains, 5.4 MB for 2,000; see ``benchmarks/bench_graph_page.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import Line, Train, sign

__all__ = [
    "TOL_T_S", "TOL_X_M", "WINDOW_COLUMNS", "TrainPath", "GraphData", "service_of", "simplify", "train_paths",
    "graph_data", "graph_notes", "line_stations", "parse_hhmm", "hhmm", "time_window", "day_window", "start_window",
    "peak_window", "match_train", "clip_path", "train_graph_chart",
]

TOL_T_S = 1.0
"""Largest time error of the thinned trajectory [s] (a pixel at the one-hour zoom is ~3 s)."""
TOL_X_M = 5.0
"""Largest chainage error of the thinned trajectory [m] (a pixel of the 28 km sample line is ~40 m)."""

COLOURS = {
    ("down", "local"): "#1f5fa8", ("down", "rapid"): "#d2461e",
    ("up", "local"): "#3a9a5b", ("up", "rapid"): "#a0327f",
}
"""Line colour by direction and service (colour-blind-safe pairs: blue/orange, green/purple)."""
CONFLICT_COLOUR = "#ff00ff"
"""Conflict boxes: magenta with a black edge, a hue no train line has (the nearest, the up rapids' plum,
is ΔE*ab ≈ 66 away; the old red was ≈ 19 from the down rapids' orange-red)."""
STAIR_COLOUR = "#f2b705"
"""Blocking-time stairway of the selected train, or of the first train of a clicked conflict."""
STAIR_B_COLOUR = "#56b4e9"
"""Blocking-time stairway of the waiting train of a clicked conflict."""
CONFLICT_MIN_PX = 12
"""Smallest side of a conflict box on the page [px]: a 4 s overlap is visible in the whole-day view."""


# ---------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------
def service_of(train: Train) -> str:
    """``rapid`` when the train passes an intermediate station of its run, else ``local``."""
    inner = train.calls[1:-1]
    return "rapid" if any(not c.stops for c in inner) else "local"


def simplify(t_s: np.ndarray, x_m: np.ndarray, tol_t_s: float = TOL_T_S, tol_x_m: float = TOL_X_M) -> np.ndarray:
    """Indices of the points of a polyline kept by Ramer–Douglas–Peucker.

    Distances are measured in the scaled plane (t / tol_t_s, x / tol_x_m), so
    every dropped point lies within one unit of the kept chord: within
    ``tol_t_s`` in time *or* ``tol_x_m`` in chainage of the drawn line
    (Douglas & Peucker, *Cartographica* 10(2), 1973). First and last points and
    the two ends of every flat step (a stop) are always kept.

    Returns
    -------
    ndarray of int
        Sorted indices into the inputs.
    """
    t = np.asarray(t_s, dtype=float) / tol_t_s
    x = np.asarray(x_m, dtype=float) / tol_x_m
    n = len(t)
    if n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    # the two ends of each stand (same chainage, time running) are corners the chart must show
    flat = np.flatnonzero((np.diff(x) == 0) & (np.diff(t) > 0))
    keep[flat] = keep[flat + 1] = True
    fixed = np.flatnonzero(keep)
    # Every chord is split on its own, so the kept set does not depend on the order the chords are
    # taken in: all chords of one depth are split at once (numpy over their points, one pass per
    # depth, not a Python pass per chord), with the per-chord arithmetic of the textbook recursion.
    a, b = fixed[:-1], fixed[1:]
    while True:
        open_ = b - a >= 2
        a, b = a[open_], b[open_]
        if a.size == 0:
            break
        dt, dx = t[b] - t[a], x[b] - x[a]
        # math.hypot per chord, as the recursion had it (np.hypot may differ in the last bit)
        seg = np.array([math.hypot(p, q) for p, q in zip(dt.tolist(), dx.tolist())])
        n_in = b - a - 1
        starts = np.cumsum(n_in) - n_in  # where each chord's points begin in the flat arrays
        chord = np.repeat(np.arange(a.size), n_in)
        i = np.arange(chord.size) - starts[chord] + a[chord] + 1  # the points strictly inside
        tt, xx = t[i] - t[a][chord], x[i] - x[a][chord]
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.abs(tt * dx[chord] - xx * dt[chord]) / seg[chord]
        closed = (seg == 0.0)[chord]  # both ends at one place: the distance to that place
        if closed.any():
            d[closed] = np.hypot(tt[closed], xx[closed])
        worst = np.maximum.reduceat(d, starts)
        split = worst > 1.0
        if not split.any():
            break
        # the farthest point of each chord split (the first of equals, as argmax takes it)
        first = np.flatnonzero(d == worst[chord])
        hit = first[split[chord[first]]]
        hit = hit[np.r_[True, chord[hit][1:] != chord[hit][:-1]]]
        m = i[hit]
        keep[m] = True
        a, b = np.concatenate([a[split], m]), np.concatenate([m, b[split]])
    return np.flatnonzero(keep)


@dataclass(frozen=True, eq=False)
class TrainPath:
    """One train as the graph draws it.

    Attributes
    ----------
    t_s, x_m : ndarray
        Thinned front trajectory: time [s after midnight], chainage [m].
    calls : tuple
        ``(station_id, arrival_s, departure_s, stops)`` per call (NaN where none).
    loop_stations : tuple of str
        Stations where the train stands on the loop to be overtaken.
    """

    train_id: str
    train_type: str
    direction: str
    service: str
    t_s: np.ndarray
    x_m: np.ndarray
    calls: tuple
    loop_stations: tuple[str, ...] = ()

    @property
    def start_s(self) -> float:
        return float(self.t_s[0])

    @property
    def end_s(self) -> float:
        return float(self.t_s[-1])


def train_paths(line: Line, curves=None, *, tol_t_s: float = TOL_T_S, tol_x_m: float = TOL_X_M,
                loops: Mapping[str, Iterable[str]] | None = None) -> list[TrainPath]:
    """Predicted trajectory of every timetabled train, thinned for drawing; a train that stalls on a leg at
    every ratio has none (the conflict check flags it, in the ``unrouted`` dataset).

    Parameters
    ----------
    line : Line
    curves : RunCurveSource, optional
        Run curves per interstation (default
        :class:`planner.network.arrivals.SimulatorCurves` of the line, the same the
        conflict check uses; pass the one the check used to share its cache).
    loops : mapping, optional
        ``train_id`` → stations where it stands on a loop (from the routes).
    """
    from planner.network.arrivals import NoCurveError, SimulatorCurves, build_trajectory, interstation_keys

    src = curves if curves is not None else SimulatorCurves(line)
    if hasattr(src, "prepare"):
        src.prepare(sorted(set(interstation_keys(line.trains))))
    out = []
    for t in line.trains:
        try:
            traj = build_trajectory(line, t, src)
        except NoCurveError:  # it stalls on a leg at every ratio: not drawn (flagged by the conflict check)
            continue
        x = sign(t.direction) * traj.u_m
        keep = simplify(traj.t_s, x, tol_t_s, tol_x_m)
        calls = tuple((c.station_id, float(c.arrival_s), float(c.departure_s), bool(c.stops)) for c in t.calls)
        out.append(TrainPath(t.train_id, t.train_type, t.direction, service_of(t),
                             np.round(traj.t_s[keep], 1), np.round(x[keep], 1), calls,
                             tuple(sorted((loops or {}).get(t.train_id, ())))))
    return out


def loop_stations(line: Line, routes: Mapping[str, Any]) -> dict[str, tuple[str, ...]]:
    """``train_id`` → stations where its route stands on a loop, from :func:`planner.network.routes.plan_routes`."""
    out = {}
    for t in line.trains:
        r = routes.get(t.train_id)
        if r is not None and r.loop_calls:
            seqs = set(r.loop_calls)
            out[t.train_id] = tuple(c.station_id for c in t.calls if c.seq in seqs)
    return out


WINDOW_COLUMNS = ("train_id", "resource_id", "from_m", "to_m", "start_s", "end_s")
"""What a graph draws of the occupation windows (its page's stairways, its chart's): what a reader of the
``occupation`` dataset reads for it (a fourth of its columns; the whole dataset, read for the 10x line's page,
was most of the largest process of that night)."""


@dataclass(eq=False)
class GraphData:
    """Everything one graph needs: stations, train paths, windows, conflicts, margins.

    ``windows`` and ``conflicts`` are pandas DataFrames with the columns of the
    ``occupation`` (at least :data:`WINDOW_COLUMNS`) and ``conflicts`` datasets (empty without a track network);
    ``margins`` maps ``train_id`` → per-train totals of the ``margin_totals``
    dataset (empty when not known).
    """

    line_id: str
    line_name: str
    start_m: float
    end_m: float
    stations: list[tuple[str, str, float]]
    trains: list[TrainPath]
    windows: Any = None
    conflicts: Any = None
    margins: dict[str, dict[str, float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    restrictions: list[tuple] = field(default_factory=list)
    """The day's temporary restrictions as time–location blocks, ``(restriction_id, start_m, end_m, from_s,
    until_s, limit_kmh, direction)``, times on the timetable's clock (s after midnight of the operating day),
    clipped to the day (:func:`planner.job.day.restriction_blocks`); empty without a day."""
    predicted: dict | None = None
    """``train_id`` → :class:`planner.report.graph_predicted.PredictedPath` of each train late on the predicted day
    (every delay carried forward, the ``delay_events`` dataset), in the order of ``trains``; None when not known."""

    def train(self, train_id: str) -> TrainPath:
        """The train of that id, matched as :func:`match_train` does (case-insensitive when unambiguous)."""
        found = match_train([t.train_id for t in self.trains], train_id)
        for t in self.trains:
            if t.train_id == found:
                return t
        raise InputError(f"--train {train_id}: no such train on line {self.line_id} "
                         f"(e.g. {', '.join(t.train_id for t in self.trains[:3])})")

    @property
    def day_s(self) -> tuple[float, float]:
        """First departure and last arrival of the day [s after midnight]."""
        if not self.trains:
            return 0.0, 86400.0
        return min(t.start_s for t in self.trains), max(t.end_s for t in self.trains)


MARGIN_COLUMNS = ("margin_s", "remaining_margin_s", "min_remaining_margin_s", "n_legs", "n_impossible",
                  "n_short_bad_day", "n_tight", "n_unreachable")


def margins_by_train(margin_totals) -> dict[str, dict[str, float]]:
    """Per-train margin totals (rows with ``level == 'train'`` of the ``margin_totals`` dataset)."""
    if margin_totals is None or len(margin_totals) == 0:
        return {}
    rows = margin_totals[margin_totals["level"] == "train"]
    out = {}
    for r in rows.itertuples(index=False):
        out[str(r.train_id)] = {c: float(getattr(r, c)) for c in MARGIN_COLUMNS if hasattr(r, c)}
    return out


def line_stations(line: Line) -> list[tuple[str, str, float]]:
    """The stations as a graph lists them: ``(station_id, name, position_m)`` along the line."""
    return [(s.station_id, s.name, float(s.position_m)) for s in sorted(line.stations, key=lambda s: s.position_m)]


def graph_notes(network: bool, drawn: bool, margins: Mapping) -> list[str]:
    """What a graph says it lacks: the blocking windows and conflicts, when the line has no track network or they
    are not ``drawn`` (not checked), and the per-train margins when there are none."""
    notes = []
    if not network:
        notes.append("the line database has no track network: no blocking windows or conflicts to draw")
    elif not drawn:
        notes.append("route conflicts not checked ([conflicts] enabled = false): no blocking windows or conflicts")
    if not margins:
        notes.append("per-train margins not given (they come from a run's margin_totals dataset)")
    return notes


def graph_data(line: Line, *, paths: Sequence[TrainPath] | None = None, windows=None, conflicts=None,
               margin_totals=None, params=None, curves=None, check: bool = True, delay_events=None) -> GraphData:
    """Collect the graph of a line: trajectories, and (with a track network) windows and conflicts.

    Given ``windows``/``conflicts`` (the ``occupation``/``conflicts`` datasets
    of a run) they are used as they are; otherwise, when the line has a track
    network, :func:`planner.datasets.conflicts.check_conflicts` computes them with the
    same run-curve source as the trajectories (simulated once).

    Parameters
    ----------
    paths : sequence of TrainPath, optional
        Trajectories computed before (:func:`train_paths`).
    margin_totals : DataFrame, optional
        The ``margin_totals`` dataset; per-train margins for the page.
    params : BlockingParams or mapping, optional
        Blocking-time parameters for the conflict check.
    check : bool
        Run the conflict check when windows/conflicts are not given (False:
        draw without them, as when the job has ``[conflicts] enabled = false``).
    delay_events : DataFrame, optional
        The ``delay_events`` dataset of the line (at least
        :data:`planner.report.graph_predicted.PREDICTED_COLUMNS`): the late trains' predicted runs.
    """
    from planner.datasets.conflicts import check_conflicts
    from planner.network.arrivals import SimulatorCurves
    from planner.network.routes import plan_routes

    src = curves if curves is not None else SimulatorCurves(line)
    loops: dict[str, tuple[str, ...]] = {}
    drawn = line.network is not None and (check or (windows is not None and conflicts is not None))
    if drawn:
        if windows is None or conflicts is None:
            report = check_conflicts(line, params, curves=src)
            windows, conflicts = report.occupation, report.conflicts
            routes = report.routes
        else:
            routes = plan_routes(line, unrouted={})  # a train the network cannot carry is drawn without a loop
        loops = loop_stations(line, routes)
    else:
        windows = conflicts = None  # not checked: the page says so, never "0 conflicts"
    if paths is None:
        paths = train_paths(line, src, loops=loops)
    elif loops:
        paths = [p if p.loop_stations or p.train_id not in loops
                 else TrainPath(p.train_id, p.train_type, p.direction, p.service, p.t_s, p.x_m, p.calls,
                                loops[p.train_id]) for p in paths]
    margins = margins_by_train(margin_totals)
    notes = graph_notes(line.network is not None, drawn, margins)
    predicted = None
    if delay_events is not None:
        from planner.report.graph_predicted import predicted_paths

        predicted = predicted_paths(line, delay_events, paths)
    return GraphData(line.line_id, line.name, float(line.start_m), float(line.end_m), line_stations(line), list(paths),
                     windows, conflicts, margins, notes, predicted=predicted)


# ---------------------------------------------------------------------------
# Times
# ---------------------------------------------------------------------------
def parse_hhmm(text: str, option: str) -> float:
    """``HH:MM`` (or ``HH:MM:SS``; hours may exceed 23 for after midnight) → s after midnight."""
    parts = str(text).strip().split(":")
    try:
        if len(parts) not in (2, 3) or not all(p.isdigit() for p in parts):
            raise ValueError
        h, m = int(parts[0]), int(parts[1])
        s = int(parts[2]) if len(parts) == 3 else 0
        if m >= 60 or s >= 60 or h > 47:
            raise ValueError
    except ValueError:
        raise InputError(f"{option} {text!r}: expected a time HH:MM (e.g. 07:30; 24:15 is after midnight)") from None
    return float(h * 3600 + m * 60 + s)


def hhmm(t: float, seconds: bool = False) -> str:
    """s after midnight → ``HH:MM`` (``HH:MM:SS``); hours run past 24 after midnight."""
    if t is None or not math.isfinite(t):
        return "–"
    t = int(round(t))
    if seconds:
        return f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"
    return f"{t // 3600:02d}:{t // 60 % 60:02d}"


def time_window(data: GraphData, t0: float | None, t1: float | None) -> tuple[float, float]:
    """The window [s] from ``t0`` to ``t1``, each defaulting to the day's whole hour around it (:func:`day_window`)."""
    return day_window(data.day_s, t0, t1)


def day_window(day_s: tuple[float, float], t0: float | None, t1: float | None) -> tuple[float, float]:
    """:func:`time_window` of a day from ``day_s[0]`` to ``day_s[1]``."""
    a, b = day_s
    lo = math.floor(a / 3600) * 3600 if t0 is None else t0
    hi = math.ceil(b / 3600) * 3600 if t1 is None else t1
    if not hi > lo:
        raise InputError(f"--from {hhmm(lo)} --to {hhmm(hi)}: the end must be after the start")
    return float(lo), float(hi)


START_HOURS = 2.0
"""Length of the window the page opens on [h]: the sample's 07:00-09:00 draws 63 trains, a train of each
direction about every 4 minutes, 40 px apart on a 1400 px window (the whole day, 356 trains in 20 h,
puts them 7 px apart)."""


def start_window(data: GraphData, hours: float = START_HOURS) -> tuple[float, float]:
    """The readable window a page opens on: ``hours`` long, starting on a whole hour inside the day's whole
    hours, the one that holds the most trains among those starting before noon (the morning peak; all of them
    when the day starts after noon; the earliest on a tie). A day no longer than that is shown whole.

    A train counts in a window when its run overlaps it (it is drawn there)."""
    return peak_window(data.day_s, np.array([t.start_s for t in data.trains]),
                       np.array([t.end_s for t in data.trains]), hours)


def peak_window(day_s: tuple[float, float], start_s: np.ndarray, end_s: np.ndarray,
                hours: float = START_HOURS) -> tuple[float, float]:
    """:func:`start_window` of trains that run from ``start_s`` to ``end_s`` on a day ``day_s``."""
    lo, hi = day_window(day_s, None, None)
    span = hours * 3600.0
    if hi - lo <= span or not len(start_s):
        return lo, hi
    starts = np.arange(lo, hi - span + 1.0, 3600.0)
    if (starts < 12 * 3600.0).any():
        starts = starts[starts < 12 * 3600.0]
    a, b = np.asarray(start_s, float), np.asarray(end_s, float)
    n = [int(np.count_nonzero((a < s + span) & (b > s))) for s in starts]
    best = float(starts[int(np.argmax(n))])
    return best, best + span


def match_train(ids: Iterable[str], text: str) -> str | None:
    """The id of ``ids`` that ``text`` names: the same, else the only one equal ignoring case; None otherwise
    (the page's search box and ``#train=`` match the same way)."""
    ids = list(ids)
    text = str(text).strip()
    if text in ids:
        return text
    folded = [i for i in ids if i.lower() == text.lower()]  # as the page's toLowerCase
    return folded[0] if len(folded) == 1 else None


def clip_path(t: np.ndarray, x: np.ndarray, lo: float, hi: float):
    """The part of a polyline inside [lo, hi] in time, one point beyond each end kept (for clipping)."""
    i0 = max(int(np.searchsorted(t, lo, side="left")) - 1, 0)
    i1 = min(int(np.searchsorted(t, hi, side="right")) + 1, len(t))
    return t[i0:i1], x[i0:i1]


# ---------------------------------------------------------------------------
# Chart
# ---------------------------------------------------------------------------
def train_graph_chart(data, path: str | Path, *, direction: str = "both", t0: float | None = None,
               t1: float | None = None, train: str | None = None, run_label: str = "") -> Path:
    """The train graph as an SVG or PNG file (by the suffix), written atomically; the legend right of the plot.

    Parameters
    ----------
    direction : {"both", "down", "up"}
    t0, t1 : float, optional
        Time window [s after midnight] (default: the whole day, whole hours).
    train : str, optional
        A train to highlight, with its blocking-time stairway.
    run_label : str
        The run and its operating day (:func:`planner.pages.run_head.run_words`), a second title line.
    """
    import io

    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Rectangle

    from planner.io.atomic import write_bytes_atomic
    from planner.line.model import line_title
    from planner.report.plots import _agg

    plt = _agg()

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in ("svg", "png"):
        raise InputError(f"{path}: the chart is written as .svg or .png, not {path.suffix or 'no suffix'}")
    if direction not in ("both", "down", "up"):
        raise InputError(f"direction must be both, down or up, not {direction!r}")
    lo, hi = time_window(data, t0, t1)
    sel = data.train(train) if train else None
    hours = (hi - lo) / 3600.0
    width = float(min(max(8.0, 2.2 * hours + 2.0), 48.0))
    plt.rcParams.update({"svg.hashsalt": "planner-graph", "svg.fonttype": "none", "font.size": 8})
    fig, ax = plt.subplots(figsize=(width, 7.5), dpi=100)
    ax.set_xlim(lo, hi)
    ax.set_ylim(data.end_m, data.start_m)  # origin at the top
    for sid, name, x in data.stations:
        ax.axhline(x, color="#c8ccd1", lw=0.6, zorder=0)
    ax.set_yticks([x for _, _, x in data.stations])
    ax.set_yticklabels([f"{name} ({sid})" for sid, name, _ in data.stations])
    step = 3600 if hours > 3 else 600 if hours > 1 else 300
    ticks = np.arange(math.ceil(lo / step) * step, hi + 1, step)
    ax.set_xticks(ticks)
    ax.set_xticklabels([hhmm(t) for t in ticks])
    if step < 3600:
        ax.set_xticks(np.arange(math.ceil(lo / 3600) * 3600, hi + 1, 3600), minor=True)
    ax.grid(axis="x", color="#e3e6ea", lw=0.5)
    ax.grid(axis="x", which="minor", color="#b9bec4", lw=0.8)
    groups: dict[tuple[str, str], list] = {}
    for tp in data.trains:
        if direction != "both" and tp.direction != direction:
            continue
        if tp.end_s < lo or tp.start_s > hi:
            continue
        t, x = clip_path(tp.t_s, tp.x_m, lo, hi)
        groups.setdefault((tp.direction, tp.service), []).append(np.column_stack([t, x]))
    for (d, svc), segs in sorted(groups.items()):
        ax.add_collection(LineCollection(segs, colors=COLOURS[(d, svc)], linewidths=1.2 if svc == "rapid" else 0.8,
                                         label=f"{d} {svc} ({len(segs)})", zorder=2))
    # loop stops: a ring where a train stands on the loop
    pos = {sid: x for sid, _, x in data.stations}
    for tp in data.trains:
        if not tp.loop_stations or (direction != "both" and tp.direction != direction):
            continue
        for sid, arr, dep, _ in tp.calls:
            if sid in tp.loop_stations and lo <= arr <= hi:
                ax.plot([(arr + dep) / 2], [pos[sid]], marker="o", ms=5, mfc="none", mec="#333", mew=0.8, zorder=3)
    con = data.conflicts
    if con is not None and len(con):
        c = con if direction == "both" else con[(con.direction_a == direction) | (con.direction_b == direction)]
        c = c[(c.overlap_end_s >= lo) & (c.overlap_start_s <= hi)]
        rects = [Rectangle((r.overlap_start_s, r.from_m), max(r.overlap_end_s - r.overlap_start_s, 1.0),
                           max(r.to_m - r.from_m, 1.0)) for r in c.itertuples()]
        if rects:
            ax.add_collection(PatchCollection(rects, facecolor=CONFLICT_COLOUR, edgecolor="black", lw=0.8,
                                              alpha=0.85, zorder=4))
            # a marker of fixed size at each overlap, so a few seconds over a few hundred metres stay visible
            ax.scatter((c.overlap_start_s + c.overlap_end_s) / 2, (c.from_m + c.to_m) / 2, s=36, marker="s",
                       c=CONFLICT_COLOUR, edgecolors="black", linewidths=0.8, zorder=4,
                       label=f"conflict: windows overlap ({c.conflict_id.nunique()})")
    if sel is not None:
        w = data.windows
        if w is not None and len(w):
            mine = w[w.train_id == sel.train_id]
            rects = [Rectangle((r.start_s, min(r.from_m, r.to_m)), r.end_s - r.start_s,
                               max(abs(r.to_m - r.from_m), 20.0)) for r in mine.itertuples()]
            ax.add_collection(PatchCollection(rects, facecolor=STAIR_COLOUR, edgecolor="#8a6500", lw=0.4,
                                              alpha=0.45, zorder=1))
            ax.plot([], [], "s", color=STAIR_COLOUR, label=f"{sel.train_id}: blocking-time stairway")
        ax.plot(sel.t_s, sel.x_m, color="black", lw=2.2, zorder=5, label=f"train {sel.train_id}")
    leg = ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0, fontsize=7, framealpha=0.9)
    dirs = "both directions" if direction == "both" else direction
    ax.set_title(f"{line_title(data.line_name, data.line_id)} — train graph, {dirs}, {hhmm(lo)}–{hhmm(hi)}"
                 + (f"\n{run_label}" if run_label else ""))
    ax.set_xlabel("time")
    fig.set_figwidth(width + leg.get_window_extent().width / fig.dpi + 0.1)  # outside: the plot keeps its size
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, metadata={"Date": None, "Creator": "planner"} if fmt == "svg" else {"Software": None})
    plt.close(fig)
    return write_bytes_atomic(path, buf.getvalue()) or path
