"""Running-time tables (a) and (b) for every interstation, direction and train type (docs/design.md §3).

Table (a): for every grid ratio r, the running time departure → arrival at
constant r (and the traction energy). Table (b): for every evaluation point X
and pair (r_before, r_after), the running time from X to arrival when the train
ran at r_before up to X and at r_after from X on.

The evaluation points are those of :func:`planner.tables.eval_points.evaluation_points`:
the departure, the point after departure, the odometer points at the regular
interval (``eval_interval_m``, none by default) and the flagged beacons; a leg with no
beacon point gets odometer points every ``eval_auto_s`` seconds of running at its maximum
(:func:`planner.tables.eval_points.train_evaluation_points`; the nightly job's default 30 s). Each
point after departure costs n_r² runs and n_r² rows of table (b).

How it is computed (per interstation, direction and train type)
---------------------------------------------------------------
1. One batch of n_r runs at constant ratio from departure to arrival, with a
   snapshot of the state at every evaluation point: the totals are table (a),
   the snapshots are the states at X after running at each r_before (speed,
   time, and whether powering, holding or braking).
2. One batch of n_r² runs for each evaluation point X after departure, all in
   one simulation from departure: the run (X, r_before, r_after) holds
   r_before up to X and r_after from X on (a ratio change at X, as the
   vehicle makes it). Up to X it is the constant-ratio run at r_before, to
   the bit, so its arrival time minus that run's time at X is table (b) at X.
   At the departure itself the state does not depend on r_before (standing
   at s = 0), so every row of table (b) there is table (a).

Work: the batch is lock-stepped on one distance grid (evaluation points are
grid nodes), and runs in the same state are stepped once
(:mod:`planner.physics.reuse`): before X a switched run is its constant-ratio
run, and after X the runs with the same r_after meet within a few hundred
metres (on its target, or on the braking curve), those switched at different
points too. So the batch steps about n_r runs over the leg plus each switch's
transient, not n_x · n_r² runs over the rest of the leg. Interstations × directions
× train types are spread over processes with joblib; each task gets the (small,
picklable) window of the Line it can see and names, and the
results are assembled in the fixed task order, so the output does not depend
on ``n_jobs`` or scheduling.

3. Table (c), for the ``adaptive`` on-board mode: the same n_r constant-ratio
   runs for a reference train (full load, traction × 0.9: the degraded train of
   the margin report), in the same batch, giving at every point the remaining
   time at constant ratio of both trains and the table train's speed there.
4. Table (d), also for ``adaptive``, for sawtooth vehicles at the last evaluation point only: the
   remaining time from a grid of states there (speed every 2 km/h, out of or in
   the coasting band) at every ratio of a 1 % grid, for the table and the reference train
   (:func:`approach_table`, one batch of short runs). Tables (b) and (c) index
   the state at a point by the ratio run before it; at the last point, where no
   later decision can correct anything, the vehicle looks its own state up
   instead (a sawtooth train's place in its coasting band is not a function of
   that ratio, and cost up to 1.5 s there). A constant-speed vehicle's state at
   the point is (r_b × maximum speed, or a braking curve), which the rows of
   table (b) already index, so it gets no table (d).

Stalls (a physical verdict, :mod:`planner.tables.flags`): where the reference train stalls there is
no table (c) (nor (d)) on the leg, ``ref_stall_m`` says where at each ratio and the leg carries a
flag; where the table train itself stalls at the slow ratios of the grid (a momentum grade), those
ratios are left out of the leg's tables, with a flag; where it stalls at every ratio the
:class:`~planner.errors.StallError` surfaces (no tables can exist).

Datasets (hive-partitioned line / direction / train_type, see schemas below):
``eval_points``, ``table_a``, ``table_b``, ``table_c``, ``table_d``. The vehicle
reads them back with :func:`planner.datasets.tables.load_tables`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from planner.errors import InfeasibleError, StallError
from planner.tables.eval_points import (
    DEFAULT_AFTER_DEPARTURE_M,
    DEFAULT_INTERVAL_M,
    EvalPoint,
    check_auto,
    check_interval,
    interstation_length_m,
    train_evaluation_points,
)
from planner.line.model import DIRECTIONS, Line
from planner.tables.flags import NOMINAL, LegFlag
from planner.tables.onboard import ApproachTable, RunningTimeTables
from planner.io.parallel import map_tasks
from planner.tables.ratios import leg_ratio_grid
from planner.line.units import ms


REF_LOAD = 1.0
"""Load factor of the reference train of tables (c) and (d): the full-load train."""
REF_TRACTION = 0.9
"""Traction factor of the reference train of tables (c) and (d) (0.9 = weak catenary). With
``REF_LOAD`` it is the degraded train the margin report plans for (``MarginRule.degraded_*``):
the adaptive mode places the real train between the table train and this one."""
APPROACH_SPEED_STEP_MS = ms(2.0)
"""Speed step of table (d) [m/s] (2 km/h)."""
APPROACH_RATIO_STEP = 0.01
"""Ratio step of table (d)'s ratios after the last point (the grid ratios are kept as well)."""
APPROACH_SPEED_MARGIN_MS = 3 * APPROACH_SPEED_STEP_MS
"""Table (d) covers speeds up to the fastest table-train speed at the point plus this [m/s]."""


@dataclass(frozen=True, eq=False)
class InterstationTables:
    """Tables (a) and (b) of one interstation, direction and train type.

    Attributes
    ----------
    line_id, direction, train_type, origin, destination : str
    ratios : ndarray, shape (n_r,)
        Grid ratios, descending.
    points : tuple of EvalPoint, length n_x
        Evaluation points (``dep`` first).
    time_a_s, energy_a_kwh : ndarray, shape (n_r,)
        Table (a): running time [s] and traction energy [kWh] per ratio.
    elapsed_s : ndarray, shape (n_r, n_x)
        Time from departure to each point at constant ratio [s].
    speed_ms : ndarray, shape (n_r, n_x)
        Speed at each point at constant ratio [m/s].
    ref_remaining_s : ndarray, shape (n_x, n_r)
        Table (c): remaining time from each point at constant ratio, reference train [s].
    approach : ApproachTable or None
        Table (d) at the last evaluation point (sawtooth vehicles; None for the others and where
        a run of it stalls).
    ref_stall_m : ndarray, shape (n_r,)
        Per ratio, the chainage where the reference train stalls at constant ratio [m]; NaN
        where it does not. Where any does, the leg has no table (c) (nor (d)).
    flags : tuple of LegFlag
        Physical verdicts on the leg (:mod:`planner.tables.flags`): the reference train's stall.
    remaining_s : ndarray, shape (n_x, n_r, n_r)
        Table (b) ``[x, i_before, j_after]`` [s].
    """

    line_id: str
    direction: str
    train_type: str
    origin: str
    destination: str
    ratios: np.ndarray
    points: tuple[EvalPoint, ...]
    time_a_s: np.ndarray
    energy_a_kwh: np.ndarray
    elapsed_s: np.ndarray
    remaining_s: np.ndarray
    ref_remaining_s: np.ndarray | None = None
    ref_load: float = float("nan")
    speed_ms: np.ndarray | None = None
    ref_traction_factor: float = float("nan")
    approach: ApproachTable | None = None
    ref_stall_m: np.ndarray | None = None
    flags: tuple[LegFlag, ...] = ()

    def onboard(self) -> RunningTimeTables:
        """The vehicle's view of these tables (same numbers as the datasets hold)."""
        return RunningTimeTables(
            origin=self.origin,
            destination=self.destination,
            ratios=self.ratios,
            time_a_s=self.time_a_s,
            eval_point_ids=tuple(p.eval_point_id for p in self.points),
            eval_distance_m=np.array([p.s_m for p in self.points]),
            eval_position_m=np.array([p.position_m for p in self.points]),
            remaining_s=self.remaining_s,
            ref_remaining_s=self.ref_remaining_s,
            speed_ms=None if self.speed_ms is None else self.speed_ms.T.copy(),
            approach=self.approach,
            flags=self.flags,
        )


class _Half:
    """The runs ``sl`` of a BatchResult: times, energies and snapshot states."""

    def __init__(self, res, sl: slice):
        from planner.physics.run_curve import RunState

        self.time_s = np.asarray(res.time_s, float)[sl]
        self.energy_kwh = np.asarray(res.energy_kwh, float)[sl]
        self.snapshots = {
            key: RunState(*(None if getattr(st, f.name) is None else np.asarray(getattr(st, f.name))[sl]
                            for f in dataclasses.fields(RunState)))
            for key, st in res.snapshots.items()
        }


def _snapshot(snapshots: dict, s_m: float):
    """The snapshot taken at ``s_m`` (keys may carry grid round-off)."""
    if s_m in snapshots:
        return snapshots[s_m]
    keys = np.array(list(snapshots), dtype=float)
    return snapshots[list(snapshots)[int(np.argmin(np.abs(keys - s_m)))]]


def _table_b(track, train, r: np.ndarray, s_pts: list[float], full: "_Half", kw: dict):
    """Table (b) of one interstation: one batch of the switched runs, with the constant-ratio runs ``full``
    (module doc, step 2).

    Returns
    -------
    elapsed_s, speed_ms : ndarray (n_r, n_x)
        Time and speed at each evaluation point at each ratio run from departure.
    remaining_s : ndarray (n_x, n_r, n_r)
        Remaining time from point k, ratio before i, ratio after j.
    """
    from planner.physics.run_curve import simulate

    n_r, n_x = len(r), len(s_pts)
    elapsed = np.zeros((n_r, n_x))
    speed = np.zeros((n_r, n_x))
    remaining = np.empty((n_x, n_r, n_r))
    remaining[0] = full.time_s[None, :]  # at departure every row is table (a)
    for k in range(1, n_x):
        snap = _snapshot(full.snapshots, s_pts[k])
        elapsed[:, k] = snap.t_s
        speed[:, k] = snap.v_ms
    if n_x == 1:
        return elapsed, speed, remaining
    # run (k, i, j), k = 1 … n_x − 1, in that order: ratio r_i from departure, r_j from X_k on (a ratio change
    # there). Up to X_k it is the constant-ratio run i, to the bit, so its arrival time less run i's time at X_k
    # is the remaining time; the runs that meet (the same ratio after, on the same target or braking curve)
    # are stepped once from there, across points too (planner.physics.reuse)
    block = n_r * n_r  # the runs of point k are the k-th block
    before = r[np.tile(np.repeat(np.arange(n_r), n_r), n_x - 1)]
    ratio, changes = before, []
    for k in range(1, n_x):
        ratio = ratio.copy()
        ratio[(k - 1) * block:k * block] = np.tile(r, n_r)
        changes.append((s_pts[k], ratio))
    res = simulate(track, train, before, changes=changes, **kw)
    remaining[1:] = np.asarray(res.time_s, float).reshape(n_x - 1, n_r, n_r) - elapsed.T[1:, :, None]
    return elapsed, speed, remaining


def interstation_tables(
    line: Line,
    train_type: str,
    origin: str,
    destination: str,
    ratios: Sequence[float],
    *,
    after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M,
    eval_interval_m: float | None = DEFAULT_INTERVAL_M,
    settings=None,
    eval_auto_s: float | None = None,
    load: float = 0.0,
    traction_factor: float = 1.0,
    ref_load: float = REF_LOAD,
    ref_traction_factor: float = REF_TRACTION,
) -> InterstationTables:
    """Compute tables (a) and (b) of one interstation (module doc, steps 1–2).

    Parameters
    ----------
    line : Line
    train_type, origin, destination : str
    ratios : sequence of float
        Grid ratios, descending (see :func:`planner.tables.ratios.ratio_grid`).
    after_departure_m : float or None
        Distance of the evaluation point after departure [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points after it [m]; None: beacons only
        (:func:`planner.tables.eval_points.evaluation_points`).
    settings : planner.physics.track.SimSettings, optional
        Integrator settings (distance step).
    eval_auto_s : float or None
        On a leg without beacon evaluation points and without ``eval_interval_m``, odometer points
        every this many seconds of running at the leg's maximum
        (:func:`planner.tables.eval_points.train_evaluation_points`); None: none.
    load, traction_factor : float
        Conditions the tables assume (docs/design.md §3: load 0, traction 1.0).
    ref_load, ref_traction_factor : float
        Load and traction factor of the reference train of tables (c) and (d).

    Returns
    -------
    InterstationTables
    """
    from planner.physics.track import SimSettings, make_track

    settings = settings or SimSettings()
    direction = line.direction_between(origin, destination)
    points = train_evaluation_points(line, train_type, origin, destination, after_departure_m=after_departure_m,
                                     interval_m=eval_interval_m, auto_s=eval_auto_s, settings=settings)
    s_pts = [p.s_m for p in points]
    track = make_track(line, train_type, origin, destination, settings=settings, nodes_m=s_pts)
    train = line.train_type(train_type)
    r = np.asarray(ratios, dtype=float)
    n_x = len(points)
    kw = dict(load=load, traction_factor=traction_factor)
    try:
        full, ref_rem, ref_stall, flags = _constant_runs(track, train, r, s_pts, kw, ref_load, ref_traction_factor)
    except StallError:
        # the table train itself stalls at some ratios (a momentum grade: it only gets over at speed):
        # those ratios are left out of this leg's tables, with a flag; stalling at every ratio it
        # cannot have tables at all, and that error (train data or gradients) surfaces
        r, nominal = runnable_ratios(track, train, r, load, traction_factor)
        full, ref_rem, ref_stall, flags = _constant_runs(track, train, r, s_pts, kw, ref_load, ref_traction_factor)
        flags = (nominal,) + flags
    time_a = full.time_s
    elapsed, speed, remaining = _table_b(track, train, r, s_pts, full, kw)
    approach = None
    # table (d) only where the state at the last point is not a function of the ratio run before
    # it: a constant-speed vehicle there is at r_b x maximum (or on a braking curve), a sawtooth
    # vehicle anywhere in its coasting band, powering or not (module doc, step 4)
    if n_x > 1 and ref_rem is not None and train.cruise == "sawtooth":
        try:
            approach = approach_table(track, train, s_pts[-1], float(speed[:, -1].max()), r, load=load,
                                      traction_factor=traction_factor, ref_load=ref_load,
                                      ref_traction_factor=ref_traction_factor)
        except InfeasibleError:
            approach = None  # a start from (nearly) standstill stalls: the adaptive mode uses table (c)
    return InterstationTables(
        line_id=line.line_id,
        direction=direction,
        train_type=train_type,
        origin=origin,
        destination=destination,
        ratios=r,
        points=points,
        time_a_s=time_a,
        energy_a_kwh=np.asarray(full.energy_kwh, float),
        elapsed_s=elapsed,
        remaining_s=remaining,
        ref_remaining_s=ref_rem,
        ref_load=float(ref_load) if ref_rem is not None else float("nan"),
        speed_ms=speed,
        ref_traction_factor=float(ref_traction_factor) if ref_rem is not None else float("nan"),
        approach=approach,
        ref_stall_m=ref_stall,
        flags=flags,
    )


def _constant_runs(track, train, r: np.ndarray, s_pts: list[float], kw: dict, ref_load: float,
                   ref_traction_factor: float):
    """The constant-ratio runs of the table train and of the reference train (table (c)), in one batch
    (the integrator's cost is per step, nearly independent of the batch size).

    Returns ``(full, ref_remaining_s, ref_stall_m, flags)``: where the reference train stalls there is
    no table (c) (``ref_remaining_s`` None) and a flag says where (:func:`_ref_stalls`).

    Raises
    ------
    StallError
        The table train itself stalls at some ratio.
    """
    from planner.physics.run_curve import simulate

    n_r, n_x = len(r), len(s_pts)
    try:
        both = simulate(track, train, np.concatenate([r, r]), snapshots_m=s_pts[1:],
                        load=np.concatenate([np.full(n_r, kw["load"]), np.full(n_r, ref_load)]),
                        traction_factor=np.concatenate([np.full(n_r, kw["traction_factor"]),
                                                        np.full(n_r, ref_traction_factor)]))
    except StallError:
        # the full-load reference (or the table train) stalls: the table train alone; where it runs,
        # no table (c) here and a flag on the leg that says where (the adaptive mode runs nowhere on it)
        full = _Half(simulate(track, train, r, snapshots_m=s_pts[1:], **kw), slice(None))
        ref_stall, flags = _ref_stalls(track, train, r, ref_load, ref_traction_factor)
        return full, None, ref_stall, flags
    full, ref = _Half(both, slice(0, n_r)), _Half(both, slice(n_r, 2 * n_r))
    ref_rem = np.empty((n_x, n_r))
    ref_rem[0] = ref.time_s
    for k in range(1, n_x):
        ref_rem[k] = ref.time_s - _snapshot(ref.snapshots, s_pts[k]).t_s
    return full, ref_rem, np.full(n_r, np.nan), ()


def runnable_ratios(track, train, r: np.ndarray, load: float, traction_factor: float):
    """The grid ratios at which the table train gets through at constant ratio, and the leg's flag for the
    others (at the fastest that stalls); re-raises the stall when none runs. One run per ratio."""
    from planner.physics.run_curve import simulate

    keep, first = np.ones(len(r), bool), None
    for i, x in enumerate(r):
        try:
            simulate(track, train, np.array([x]), load=load, traction_factor=traction_factor)
        except StallError as e:
            keep[i] = False
            first = first or (x, e)
    x, e = first
    if not keep.any():
        raise e
    f = LegFlag.stall(e, NOMINAL)
    left = ", ".join(f"{y:g}" for y in r[~keep])
    return r[keep], LegFlag(f.kind, f.scenario, f.position_m,
                            f"{f.reason} at ratio {x:g}: ratio(s) {left} left out of this leg's tables")


def _ref_stalls(track, train, r: np.ndarray, ref_load: float, ref_traction_factor: float):
    """Where the reference train stalls at each grid ratio, and the leg's flag for it.

    One run per ratio (a batch stops at its first stall): only on a leg where the batch stalled.

    Returns
    -------
    stall_m : ndarray (n_r,)
        Chainage where the run at each ratio stalls [m]; NaN where it does not.
    flags : tuple of LegFlag
        One flag, at the fastest ratio that stalls (others stall near it; ``stall_m`` has each).
    """
    from planner.physics.run_curve import simulate

    out, flags = np.full(len(r), np.nan), []
    for i, x in enumerate(r):
        try:
            simulate(track, train, np.array([x]), load=ref_load, traction_factor=ref_traction_factor)
        except StallError as e:
            out[i] = e.position_m[1]
            if not flags:
                flags.append(LegFlag.reference_stall(x, e.position_m[1], ref_load, ref_traction_factor))
    return out, tuple(flags)


def approach_ratios(ratios: Sequence[float], step: float = APPROACH_RATIO_STEP) -> np.ndarray:
    """Ratios after the last point in table (d): the grid plus a ``step`` grid down to its lowest, descending.

    Examples
    --------
    >>> approach_ratios([1.0, 0.9], step=0.05).tolist()
    [1.0, 0.95, 0.9]
    """
    r = np.asarray(ratios, float)
    fine = np.arange(r[0], r[-1] - 1e-9, -step)
    return np.unique(np.round(np.concatenate([r, fine]), 6))[::-1]


def approach_table(track, train, s_x: float, top_speed_ms: float, ratios: Sequence[float], *,
                   load: float, traction_factor: float, ref_load: float,
                   ref_traction_factor: float) -> ApproachTable:
    """Table (d) at the evaluation point ``s_x``: remaining time from a grid of states there.

    One batch: every start speed 0, 2, 4 … km/h up to ``top_speed_ms`` plus a margin, in each
    phase the vehicle can be in (powering or not; only a sawtooth vehicle's future depends on
    it), times every ratio of :func:`approach_ratios`, for the table train and the reference
    train. Each run starts at ``s_x`` at t = 0, so its running time is the remaining time.

    Raises
    ------
    InfeasibleError
        If a run stalls (e.g. the reference train from standstill on a steep rise).
    """
    from planner.physics.run_curve import PHASE_COAST, PHASE_POWER, RunState, simulate

    ra = approach_ratios(ratios)
    v = np.arange(0.0, top_speed_ms + APPROACH_SPEED_MARGIN_MS + 1e-9, APPROACH_SPEED_STEP_MS)
    powering = (True, False) if train.cruise == "sawtooth" else (True,)
    n_p, n_v, n_a = len(powering), len(v), len(ra)
    phase = np.repeat([PHASE_POWER if p else PHASE_COAST for p in powering], n_v * n_a).astype(np.int8)
    speed = np.tile(np.repeat(v, n_a), n_p)
    ratio = np.tile(ra, n_p * n_v)
    n = speed.size
    both = lambda x: np.concatenate([x, x])  # noqa: E731  (table train, then reference train)
    start = RunState(s_m=np.full(2 * n, float(s_x)), t_s=np.zeros(2 * n), v_ms=both(speed),
                     phase=both(phase), ratio=both(ratio))
    res = simulate(track, train, both(ratio), start=start,
                   load=np.r_[np.full(n, load), np.full(n, ref_load)],
                   traction_factor=np.r_[np.full(n, traction_factor), np.full(n, ref_traction_factor)])
    t = np.asarray(res.time_s, float).reshape(2, n_p, n_v, n_a)
    k = track.node_index(float(s_x))
    vmax = float(track.vmax_interval_ms[min(k, len(track.vmax_interval_ms) - 1)])
    return ApproachTable(speeds_ms=v, powering=powering, ratios=ra, time_s=t[0], ref_time_s=t[1], vmax_ms=vmax,
                         coast_band_ms=float(train.coast_band_ms) if train.cruise == "sawtooth" else 0.0)


def table_tasks(line: Line, train_types: Sequence[str] | None = None) -> list[tuple[str, str, str, str]]:
    """The fixed task order: (train_type, direction, origin, destination)."""
    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    for t in types:
        line.train_type(t)  # UnknownNameError early, naming the known types
    return [
        (t, d, a.station_id, b.station_id)
        for t in types
        for d in DIRECTIONS
        for a, b in line.interstations(d)
    ]


def _task(line: Line, train_type: str, origin: str, destination: str, ratios, after_departure_m, settings,
          eval_interval_m=None, eval_auto_s=None):
    """joblib worker: one interstation, direction, train type (module-level, picklable inputs)."""
    return interstation_tables(
        line, train_type, origin, destination, ratios,
        after_departure_m=after_departure_m, eval_interval_m=eval_interval_m, settings=settings,
        eval_auto_s=eval_auto_s,
    )


def build_tables(
    line: Line,
    *,
    train_types: Sequence[str] | None = None,
    ratios: str | Sequence[float] | None = None,
    after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M,
    eval_interval_m: float | None = DEFAULT_INTERVAL_M,
    eval_auto_s: float | None = None,
    n_jobs: int = -1,
    settings=None,
    progress: Callable[[int, int], None] | None = None,
) -> list[InterstationTables]:
    """Tables for every interstation × direction × train type of a line, in parallel.

    Parameters
    ----------
    line : Line
    train_types : sequence of str, optional
        Default every train type of the line.
    ratios : str, sequence of float or None
        Ratio grid spec or list (:func:`planner.tables.ratios.ratio_grid`); default grid if None.
    after_departure_m : float or None
        Distance of the evaluation point after departure [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points [m]; None: beacons only.
    eval_auto_s : float or None
        Fill interval of legs without beacon points, in seconds at the leg's maximum; None: none.
    n_jobs : int
        joblib processes; -1 = all cores, 1 = in this process.
    settings : planner.physics.track.SimSettings, optional
    progress : callable ``(done, total)``, optional
        Called after each finished task (in task order).

    Returns
    -------
    list of InterstationTables
        In :func:`table_tasks` order, independent of ``n_jobs``.
    """
    eval_interval_m = check_interval(eval_interval_m)
    eval_auto_s = check_auto(eval_auto_s)
    tasks = table_tasks(line, train_types)
    grids = [leg_ratio_grid(ratios, line, t[0], t[2], t[3]) for t in tasks]  # each leg's floor
    # longest interstations first, so no core idles on one long task at the end; the results
    # are put back in task order, so the output does not depend on this or on n_jobs
    order = sorted(range(len(tasks)), key=lambda i: -interstation_length_m(line, tasks[i][2], tasks[i][3]))
    results = map_tasks(_task, [(line, tasks[i][0], tasks[i][2], tasks[i][3], grids[i], after_departure_m, settings,
                                 eval_interval_m, eval_auto_s) for i in order], n_jobs, progress)
    out: list[InterstationTables | None] = [None] * len(tasks)
    for i, res in zip(order, results):
        out[i] = res
    return out


# --- datasets -------------------------------------------------------------------


