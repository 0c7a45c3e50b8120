"""Arrival prediction (docs/design.md §8, step 2): run curves per interstation and each train's front trajectory.

Takes a Line, a train and a run-curve source; gives a :class:`Trajectory`,
the predicted front position over the whole run (:func:`build_trajectory`).
The front runs each interstation (stop to stop; passes run through) along a
run curve (chainage, time from departure) taken at the train's scheduled
running time, so braking for stop targets and restrictions is in it. The
first time the front reaches a chainage is the node's predicted arrival.

Run curves come from :class:`SimulatorCurves` (the run-curve simulator at the
target-speed ratio that meets the schedule, simulated once per interstation,
in parallel through :func:`planner.io.parallel.map_tasks`) or, as a first
approximation, the ratio-1.0 curve stretched in time (:func:`stretched_curve`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from planner.errors import InputError, PlannerError, StallError
from planner.io.parallel import map_tasks
from planner.line.model import Line, Train, sign

RunCurve = tuple[np.ndarray, np.ndarray]
"""(chainage_m, time_s): the front's chainage and the time since departure along one interstation run."""

RunCurveSource = Callable[[str, str, str, float], RunCurve]
"""``source(train_type, origin, destination, scheduled_s) -> (chainage_m, time_s)``.

The run curve of the front from the origin's stop marker to the destination's,
at the driving the vehicle uses for the scheduled running time ``scheduled_s``
(time from departure; the last time is the running time)."""


STAND_TOL_M = 1e-6
"""Chainages this close [m] are the same point for :meth:`Trajectory.front_leaves` (round-off only)."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Predicted front position over the whole run of one train.

    ``u_m`` is the running coordinate sign(direction) × chainage [m]
    (non-decreasing; repeated at stops), ``t_s`` the absolute time [s after
    midnight] (non-decreasing; arrival then departure at each stop).
    """

    train_id: str
    direction: str
    u_m: np.ndarray
    t_s: np.ndarray
    calls_s: tuple[tuple[float, float], ...] = ()
    """(arrival, departure) at each stop call [s], as predicted (the origin's arrival is its departure, the
    destination's departure its arrival): the events of the day's delay network (:mod:`planner.delay`)."""
    run_min_s: tuple[float, ...] = ()
    """Each leg's minimum running time [s]: the run curve at the highest ratio the source has."""

    @property
    def end_s(self) -> float:
        """Arrival at the destination [s]."""
        return float(self.t_s[-1])

    def front_time(self, chainage_m) -> np.ndarray:
        """First time the front reaches each chainage [s]; +inf beyond the destination.

        Linear in time between curve samples; a chainage exactly at a stop gives
        the arrival there. Chainages before the origin give the departure.
        """
        q = sign(self.direction) * np.asarray(chainage_m, dtype=float)
        u, t = self.u_m, self.t_s
        i = np.searchsorted(u, q, side="left")
        out = np.full(q.shape, np.inf)
        inside = i < len(u)
        ii = np.clip(i, 1, len(u) - 1)
        u0, u1, t0, t1 = u[ii - 1], u[ii], t[ii - 1], t[ii]
        du = np.where(u1 > u0, u1 - u0, 1.0)
        lin = t0 + (t1 - t0) * np.clip((q - u0) / du, 0.0, 1.0)
        exact = inside & (u[np.minimum(i, len(u) - 1)] == q)
        out = np.where(inside, lin, out)
        out = np.where(exact, t[np.minimum(i, len(u) - 1)], out)
        return np.where(q <= u[0], t[0], out)

    def front_leaves(self, chainage_m) -> np.ndarray:
        """Time the front moves on past each chainage [s]; +inf beyond the destination.

        The last time the front is at the chainage: where the train stands with
        its front there (a stop), the departure, as at the origin; elsewhere the
        same as :meth:`front_time`. A resource is entered when the front moves
        past its entry, so this is the entry time of blocking-time windows.
        Chainages within ``STAND_TOL_M`` of a sample count as that sample (the
        run curves of two interstations meet at the stop marker up to round-off).
        """
        q = sign(self.direction) * np.asarray(chainage_m, dtype=float)
        u, t = self.u_m, self.t_s
        j = np.searchsorted(u, q + STAND_TOL_M, side="right")  # first sample past q
        jj = np.clip(j, 1, len(u) - 1)
        u0, u1, t0, t1 = u[jj - 1], u[jj], t[jj - 1], t[jj]
        du = np.where(u1 > u0, u1 - u0, 1.0)
        lin = t0 + (t1 - t0) * np.clip((q - u0) / du, 0.0, 1.0)
        at = np.abs(u[np.maximum(j - 1, 0)] - q) <= STAND_TOL_M  # the front stands or passes at sample j − 1
        out = np.where(at, t[np.maximum(j - 1, 0)], lin)
        out = np.where(j >= len(u), np.where(at, t[-1], np.inf), out)
        return np.where(j == 0, t[0], out)


def build_trajectory(line: Line, train: Train, curves: RunCurveSource) -> Trajectory:
    """Chain the run curves of a train's interstations into one predicted front trajectory.

    Each interstation runs from a stopping call's departure to the next stopping
    call (passes in between are run through); its run curve is asked for the
    scheduled running time (next arrival − departure). A curve slower than the
    schedule makes the train late; lateness is absorbed by the next dwell
    (departure = max(scheduled departure, predicted arrival)) and not otherwise
    propagated.

    Parameters
    ----------
    curves : RunCurveSource
        Gives (chainage_m, time_s) per interstation; one with a ``for_train`` method (:class:`TrainCurves`)
        gives the source of this train (its runs with the temporary restrictions that apply to it).
    """
    if hasattr(curves, "for_train"):
        curves = curves.for_train(train)
    sgn = sign(train.direction)
    calls = train.stop_calls()
    us: list[np.ndarray] = []
    ts: list[np.ndarray] = []
    dep = calls[0].departure_s
    if math.isnan(dep):
        raise InputError(f"timetable.parquet train {train.train_id}: no departure time at the origin")
    at: list[tuple[float, float]] = [(dep, dep)]
    mins: list[float] = []
    for a, b in zip(calls[:-1], calls[1:]):
        sched = b.arrival_s - a.departure_s
        if math.isnan(sched) or sched <= 0:
            raise InputError(
                f"timetable.parquet train {train.train_id}: calls {a.seq}→{b.seq} need departure then a later arrival"
            )
        x, t = curves(train.train_type, a.station_id, b.station_id, sched)
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        us.append(sgn * x)
        ts.append(dep + t)
        arr = dep + float(t[-1])
        nxt = b.departure_s
        dep = arr if math.isnan(nxt) else max(nxt, arr)
        at.append((arr, dep))
        mins.append(float(curves(train.train_type, a.station_id, b.station_id, 0.0)[1][-1]))
    u = np.concatenate(us)
    t = np.concatenate(ts)
    # Guard against round-off in the curves: the front never moves back, time never runs back.
    u = np.maximum.accumulate(u)
    t = np.maximum.accumulate(t)
    return Trajectory(train.train_id, train.direction, u, t, tuple(at), tuple(mins))


def stretched_curve(x_m: np.ndarray, t_s: np.ndarray, scheduled_s: float) -> RunCurve:
    """First approximation of the run at a scheduled time: stretch time uniformly.

    t'(x) = t(x) · T_sched / T_min when the schedule is slower than the curve
    (T_sched ≥ T_min), else the curve unchanged (the train cannot be faster).
    Uniform stretching slows acceleration and braking as much as cruising,
    whereas the vehicle cruises slower at a lower target-speed ratio; the
    position-time error is therefore largest mid-run, at most a few seconds
    for typical supplements of 5–10 %.
    """
    t_min = float(t_s[-1])
    f = scheduled_s / t_min if scheduled_s > t_min > 0 else 1.0
    return np.asarray(x_m, dtype=float), np.asarray(t_s, dtype=float) * f


DEFAULT_RATIOS = (1.0, 0.975, 0.95, 0.925, 0.9, 0.875, 0.85, 0.8, 0.75, 0.7, 0.65, 0.6, 0.5, 0.4, 0.3)
"""Target-speed ratios simulated per interstation; schedules between two are interpolated."""


FINE_DS_M = 1.0
"""The running-time tables' integration step [m], for a run that stalls at the conflict check's coarser one."""


def simulate_interstation(line: Line, train_type: str, origin: str, destination: str,
                          ratios: Sequence[float], ds_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Run curves of one interstation at several target-speed ratios, in one lock-step batch.

    Where a run stalls (crawling up a climb) the batch is run again at the running-time tables' step,
    :data:`FINE_DS_M` (the coarse step of the conflict check can stall where a finer one gets over), and the
    ratios at which it still stalls (a climb it gets over only at speed) are left out, as the tables leave
    them out; where it stalls at every ratio the StallError is raised.

    Returns
    -------
    chainage_m : ndarray (m,)
        Chainage of each grid node, departure marker to arrival marker [m].
    time_s : ndarray (n, m)
        Time from departure at each node, one row per ratio that runs [s].
    """
    from planner.physics.track import SimSettings, make_track
    from planner.physics.run_curve import simulate

    track = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=ds_m))
    train, r = line.train_type(train_type), np.asarray(ratios, dtype=float)
    try:
        res = simulate(track, train, r, record=True)
    except StallError:  # crawling up a climb: at the tables' finer step (a coarse one can stall where it does
        from planner.tables.build import runnable_ratios  # not), and at the ratios it gets over at, as the

        if ds_m > FINE_DS_M:  # tables leave the others out; where none gets over, the stall is raised
            track = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=FINE_DS_M))
        try:
            res = simulate(track, train, r, record=True)
        except StallError:
            r, _ = runnable_ratios(track, train, r, 0.0, 1.0)
            res = simulate(track, train, r, record=True)
    # a copy of the times: a view would hold the batch's whole record (five quantities per run and node)
    return np.asarray(track.position_m(res.s_m), dtype=float), np.array(res.t_s, dtype=float)


class NoCurveError(PlannerError):
    """No run curve exists for an interstation (the train stalls there at every ratio): its trains are
    flagged and left out of the conflict check, as a train the network cannot carry."""

    key = "network.no_curve"


def _interstation_or_stall(line: Line, train_type: str, origin: str, destination: str, ratios, ds_m: float):
    """:func:`simulate_interstation`, or the stall's message where the train stalls at every ratio (a worker's
    exception would end the whole check: one interstation is never the night)."""
    try:
        return simulate_interstation(line, train_type, origin, destination, ratios, ds_m)
    except StallError as e:
        return f"no run curve {origin}->{destination} for {train_type}: {e}"


class SimulatorCurves:
    """Run curves from the run-curve simulator at the ratio that meets the schedule, cached per interstation.

    For each (train type, origin, destination) the simulator runs a batch of
    target-speed ratios once (one lock-step batch costs about as much as one
    run). A scheduled running time between the times of two neighbouring
    ratios r₁ > r₂ gets the convex combination of their curves,
    t(x) = (1 − w) t₁(x) + w t₂(x) with w = (T − T₁)/(T₂ − T₁), which is
    monotone, ends exactly at T, and is what running at an intermediate ratio
    looks like to within the difference of the two neighbours. Slower than
    the lowest ratio: that curve stretched uniformly; faster than ratio 1.0:
    the ratio-1.0 curve (the train runs late).

    Parameters
    ----------
    line : Line
    mode : {"match", "stretch"}
        ``match`` as above; ``stretch``: the ratio-1.0 curve stretched
        uniformly in time (:func:`stretched_curve`), a first approximation.
    ratios : sequence of float
        Ratio grid, descending from 1.0.
    ds_m : float
        Integration step [m]. The conflict check needs times to about a second
        (blocking times are tens of seconds); on the sample line 10 m and 5 m
        steps find the same 62 conflicts with total delays of 804.8 s and
        804.5 s, and 10 m costs a tenth of the 1 m tables.
    n_jobs : int
        Worker processes for :meth:`prepare` (:func:`planner.io.parallel.map_tasks`;
        1 runs in this process).
    """

    def __init__(self, line: Line, *, mode: str = "match", ratios: Sequence[float] = DEFAULT_RATIOS,
                 ds_m: float = 10.0, n_jobs: int = 1):
        if mode not in ("match", "stretch"):
            raise InputError(f"run-curve mode must be 'match' or 'stretch', found {mode!r}")
        r = tuple(sorted({float(x) for x in ratios}, reverse=True))
        if not r or r[0] != 1.0 or r[-1] <= 0:
            raise InputError(f"run-curve ratios must start at 1.0 and stay > 0, found {ratios!r}")
        self.line, self.mode, self.ratios, self.ds_m, self.n_jobs = line, mode, r, ds_m, n_jobs
        self._tables: dict[tuple[str, str, str], tuple[np.ndarray, np.ndarray]] = {}
        self._stalled: dict[tuple[str, str, str], str] = {}

    @property
    def simulated(self) -> int:
        """Interstations simulated so far."""
        return len(self._tables)

    def prepare(self, keys: Iterable[tuple[str, str, str]],
                progress: Callable[[int, int], None] | None = None) -> None:
        """Simulate every (train_type, origin, destination) not cached yet, in parallel."""
        todo = sorted(set(keys) - set(self._tables))
        if not todo:
            return
        ratios = self.ratios if self.mode == "match" else (1.0,)
        # each task carries its interstation's window of the line (what its run sees, as the tables' units do), not
        # the line: on a line a hundred times the sample, pickling the whole line into each of its 7,400 tasks kept
        # the workers waiting on this process for minutes
        tabs = map_tasks(_interstation_or_stall, [(self.line.window(o, d, tt), tt, o, d, ratios, self.ds_m)
                                                  for tt, o, d in todo], self.n_jobs, progress)
        for key, tab in zip(todo, tabs):
            if isinstance(tab, str):  # the train stalls there at every ratio: no curve (its trains are flagged)
                self._stalled[key] = tab
            else:
                self._store(key, tab)

    def _store(self, key, tab) -> None:
        x, T = tab
        # Rows in order of running time, so neighbours bracket a schedule even where a
        # sawtooth vehicle's time is not quite monotone in the ratio.
        self._tables[key] = (x, T[np.argsort(T[:, -1], kind="stable")])

    def table(self, train_type: str, origin: str, destination: str) -> tuple[np.ndarray, np.ndarray]:
        key = (train_type, origin, destination)
        if key not in self._tables and key not in self._stalled:
            self.prepare([key])
        if key in self._stalled:
            raise NoCurveError(self._stalled[key])
        return self._tables[key]

    def __call__(self, train_type: str, origin: str, destination: str, scheduled_s: float) -> RunCurve:
        x, T = self.table(train_type, origin, destination)
        ends = T[:, -1]
        if self.mode == "stretch" or scheduled_s <= ends[0]:
            return stretched_curve(x, T[0], scheduled_s)
        if scheduled_s >= ends[-1]:
            return stretched_curve(x, T[-1], scheduled_s)
        k = int(np.searchsorted(ends, scheduled_s))  # ends rise as the ratio falls
        k = min(max(k, 1), len(ends) - 1)
        w = (scheduled_s - ends[k - 1]) / (ends[k] - ends[k - 1])
        return x, (1.0 - w) * T[k - 1] + w * T[k]


class TrainCurves:
    """Run curves per train: those of the day's line, except on the legs where some of its temporary
    restrictions are lifted while the train runs them (``lifted``, by ``(train_id, leg_seq)`` as
    :func:`planner.job.day.lifted_restrictions` gives it): there the curves of the line without them
    (:func:`planner.line.daily.without_temporary`), one :class:`SimulatorCurves` per set lifted, with the
    same mode, ratios and step, simulated on first use.

    Used as a :data:`RunCurveSource` it is the day's line's (``base``); :func:`build_trajectory` asks
    :meth:`for_train` for each train's own.
    """

    def __init__(self, base: SimulatorCurves, lifted: Mapping[tuple[str, int], tuple[str, ...]]):
        self.base = base
        self._by_train: dict[str, dict[int, tuple[str, ...]]] = {}
        for (tid, seq), ids in lifted.items():
            self._by_train.setdefault(tid, {})[seq] = tuple(ids)
        self._sub: dict[tuple[str, ...], SimulatorCurves] = {}

    def prepare(self, keys, progress=None) -> None:
        self.base.prepare(keys, progress=progress)

    def __call__(self, train_type: str, origin: str, destination: str, scheduled_s: float) -> RunCurve:
        return self.base(train_type, origin, destination, scheduled_s)

    def without(self, ids: tuple[str, ...]) -> SimulatorCurves:
        """The curves of the line without the temporary restrictions ``ids``."""
        from planner.line.operating_day import without_temporary

        if ids not in self._sub:
            b = self.base
            self._sub[ids] = SimulatorCurves(without_temporary(b.line, ids), mode=b.mode, ratios=b.ratios,
                                             ds_m=b.ds_m, n_jobs=1)
        return self._sub[ids]

    def for_train(self, train: Train) -> RunCurveSource:
        """The source of one train: by its legs (stop to stop, in order, as :func:`interstation_keys`)."""
        seqs = self._by_train.get(train.train_id)
        if not seqs:
            return self.base
        calls = train.stop_calls()
        off = {(a.station_id, b.station_id): seqs[i] for i, (a, b) in enumerate(zip(calls[:-1], calls[1:]))
               if i in seqs}

        def source(train_type: str, origin: str, destination: str, scheduled_s: float) -> RunCurve:
            ids = off.get((origin, destination))
            return (self.without(ids) if ids else self.base)(train_type, origin, destination, scheduled_s)

        return source


def train_curves(line: Line, lifted: Mapping[tuple[str, int], tuple[str, ...]] | None = None, **kw):
    """The run-curve source of a day's conflict check and train graph: :class:`SimulatorCurves` of the line
    (``kw``), wrapped in :class:`TrainCurves` when some trains run a leg while a restriction is lifted."""
    base = SimulatorCurves(line, **kw)
    return TrainCurves(base, lifted) if lifted else base


def interstation_keys(trains: Iterable[Train]) -> list[tuple[str, str, str]]:
    """(train_type, origin, destination) of every interstation run (stop to stop) in the timetable."""
    out = []
    for t in trains:
        calls = t.stop_calls()
        out += [(t.train_type, a.station_id, b.station_id) for a, b in zip(calls[:-1], calls[1:])]
    return out
