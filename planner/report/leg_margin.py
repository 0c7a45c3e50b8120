"""One leg of the margin report: minimum, bad-day minimum and its shares, stopping patterns, closed loop.

Takes a :class:`planner.line.model.Line`, a leg (train type, stop, next stop),
its scheduled running times and the :class:`planner.report.margin_rule.MarginRule`;
gives a :class:`LegResult` (:func:`leg_result`) with the plain numbers of one
row of the ``margins`` dataset (their meaning: :mod:`planner.report.margins`).
The run-curve simulator, the tables, the stopping-pattern solver and the
closed-loop driver do the work; nothing here reads or writes files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from planner.errors import InputError, StallError
from planner.line.model import Line, per_line, sign
from planner.line.units import KMH, KMH_S, kmh
from planner.report.margin_rule import MarginRule
from planner.stopping.approach import DEFAULT_APPROACH_M, approach_start, brake_cap_ms2, train_adhesion_ms2
from planner.stopping.sweep import DEFAULT_ADHESION_KMH_S, adhesion_levels
from planner.tables.flags import NO_STOP, LegFlag

BAD_DAY = "bad_day"
"""Scenario name of the margin report's bad day in a :class:`~planner.tables.flags.LegFlag`."""
PATTERN_BACKOFF_M = 25.0
"""Step [m] by which the pattern start moves back when the lowest adhesion cannot stop in time."""
def approach_limits(line: Line, train, track, s_start_m: float):
    """Speed limits [m/s] and safe-side gradient steps [‰] over the approach from ``s_start_m``.

    The approach as :func:`planner.stopping.sweep.approach_patterns` (and the vehicle)
    builds it, from :mod:`planner.stopping.approach`: speed limit = the on-board maximum
    of each grid interval; gradient = averaged over the train, each linear
    piece at its least favourable value.
    """
    from planner.stopping import approach

    speed = approach.speed_limits(track, s_start_m)
    grads = approach.gradient_steps(line, train.length_m, track.direction, float(track.position_m(s_start_m)),
                                    float(track.length_m - s_start_m))
    return speed, grads


def stop_pattern(line: Line, train, track, s_start_m: float, v_start_ms: float, adhesion_ms2: float, speed, grads):
    """Solve the stopping pattern of the approach from ``s_start_m`` at one adhesion level (a StopPattern)."""
    from planner.stopping import approach
    from planner.stopping.pattern import StopPattern, solve_stop

    x_stop = float(track.length_m - s_start_m)
    v0 = min(float(v_start_ms), speed[0][1])  # the simulator's speed at a node may exceed its interval by round-off
    try:
        dl = approach.decel_limits(line, train, track.direction, float(track.position_m(s_start_m)), x_stop,
                                   adhesion_ms2, grads)
    except InputError as e:  # a fall so steep that no deceleration is left: no pattern
        return StopPattern(False, str(e), v_start_ms=v0, x_stop_m=x_stop, jerk_max_ms3=train.jerk_limit_ms3)
    return solve_stop(v0, x_stop, jerk_max=train.jerk_limit_ms3, decel_limits=dl, speed_limits=speed)


def bad_day_run(line: Line, train_type: str, origin: str, destination: str, row: dict, bad_load: float,
                bad_traction: float, adhesion: bool, ds_m: float):
    """The run whose time is a leg's bad-day minimum, for drawing: ``(position_m, speed_kmh, time_s)`` or None.

    As :func:`_bad_day` makes it, from the margins ``row``: the run at ratio 1.0 with the bad day's load and
    traction to the row's pattern start (``pattern_start_m``), then the stopping pattern from there at the row's
    bad-day adhesion (``adhesion_min_kmh_s``); with the adhesion effect off, the degraded run to the marker. The
    same functions on a grid with the pattern start as a node; its end differs from the row's
    ``degraded_min_running_time_s`` by the grids' difference only (the margins' grid has the evaluation
    points as nodes too). None for a leg without a bad-day minimum (unassessed, no stopping pattern)."""
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings, make_track

    start, a = row.get("pattern_start_m"), row.get("adhesion_min_kmh_s")
    deg = row.get("degraded_min_running_time_s")
    if start is None or deg is None or not (math.isfinite(float(start)) and math.isfinite(float(deg))):
        return None
    train = line.train_type(train_type)
    plain = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=ds_m))
    c = abs(float(start) - float(plain.position_m(0.0)))
    track = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=ds_m), nodes_m=[c]) \
        if adhesion else plain
    res = simulate(track, train, np.array([1.0]), load=np.array([bad_load]), traction_factor=np.array([bad_traction]),
                   snapshots_m=[c] if adhesion else (), record=True)
    if not adhesion:
        return (np.asarray(track.chainage_m, float), kmh(np.asarray(res.v_ms[0], float)),
                np.asarray(res.t_s[0], float))
    if a is None or not math.isfinite(float(a)):
        return None
    kc = track.node_index(c)
    sn = res.snapshots[c]
    pat = stop_pattern(line, train, track, c, float(sn.v_ms[0]), float(a) * KMH_S, *approach_limits(line, train, track, c))
    if not pat.feasible:
        return None
    smp = pat.sample(0.2)
    return (np.concatenate([np.asarray(track.chainage_m[:kc + 1], float), np.asarray(track.position_m(c + smp.x_m), float)]),
            np.concatenate([kmh(np.asarray(res.v_ms[0][:kc + 1], float)), kmh(np.asarray(smp.v_ms, float))]),
            np.concatenate([np.asarray(res.t_s[0][:kc + 1], float), float(sn.t_s[0]) + np.asarray(smp.t_s, float)]))


@dataclass
class LegResult:
    """Everything computed for one leg (module doc for the meaning of each quantity)."""

    direction: str
    train_type: str
    origin: str
    destination: str
    passes: tuple
    length_m: float
    min_time_s: float
    slowest_time_s: float
    energy_full_kwh: float
    degraded_min_s: float
    degraded_loss_running_s: float
    degraded_loss_stop_s: float
    degraded_loss_load_s: float
    degraded_loss_traction_s: float
    degraded_loss_stop_model_s: float
    pattern_start_s_m: float
    pattern_start_m: float
    pattern_source: str
    v_pattern_degraded_ms: float
    stop_time_degraded_s: float
    stop_time_nominal_s: float
    adhesion_min_kmh_s: float
    adhesion_loss_s: float
    sweep_adhesion_kmh_s: np.ndarray
    sweep_duration_s: np.ndarray
    note: str
    tables_source: str
    schedules: list = field(default_factory=list)  # dicts per scheduled time
    curves: dict | None = None  # with record=True: run curves for the report
    tables: object = None  # the RunningTimeTables used (read or computed)
    energy_a_kwh: np.ndarray | None = None
    flags: tuple = ()  # physical verdicts (planner.tables.flags.LegFlag): why the leg is unassessed
    lifted: tuple = ()  # ids of the day's temporary restrictions lifted for this group's trains (margin_legs)
    restrictions: tuple = ()  # ids of the temporary restrictions the leg was computed with


def _closed_loop(track, train, tables, designated: np.ndarray, rule: MarginRule, record: bool = False):
    """Nominal and bad-day closed-loop runs of the on-board nearest rule, per designated time.

    Returns the running times, shape (2n,): the n designated times at the tables' conditions,
    then the same under the rule's bad-day load and traction, NaN where a run stalls; and, with
    ``record``, the simulator's BatchResult of those 2n runs (None where one stalls).
    Driven by :func:`planner.tables.closed_loop.drive_tables` (the closed-loop proof's own driver).
    """
    from planner.tables.closed_loop import SCENARIOS, Scenario, drive_runs, drive_tables

    scs, modes = [SCENARIOS["nominal"], Scenario("bad_day", rule.bad_load, rule.bad_traction)], ["nearest"] * 2
    if record:
        try:
            _, _, res = drive_tables(track, train, tables, designated, scs, modes, record=True)
            return np.asarray(res.time_s, float), res
        except StallError:
            pass
    return drive_runs(track, train, tables, designated, scs, modes)[0], None


def _first_pattern(line, train, track, res, run: int, cands, adhesion_ms2: float):
    """First pattern start (moving back from the nominal one) from which ``run`` can stop at this adhesion.

    Returns ``(start_m, t_s, v_ms, pattern, speed_limits, gradients)``; ``pattern`` is
    None when no candidate works (then the nominal start's values).
    """
    first = None
    for c in cands:
        sn = res.snapshots[c]
        v, t = float(sn.v_ms[run]), float(sn.t_s[run])
        speed, grads = approach_limits(line, train, track, c)
        pat = stop_pattern(line, train, track, c, v, adhesion_ms2, speed, grads)
        if first is None:
            first = (c, t, v, None, speed, grads)
        if pat.feasible:
            return c, t, v, pat, speed, grads
    return first


def train_adhesion_kmh_s(train, adhesion_kmh_s) -> np.ndarray:
    """The sweep's levels for ``train`` [km/h/s], ascending (:func:`planner.stopping.approach.train_adhesion_ms2`)."""
    levels = train_adhesion_ms2(train, [a * KMH_S for a in adhesion_levels(adhesion_kmh_s)])
    return np.asarray([round(a / KMH_S, 9) for a in levels], dtype=float)


@per_line
def passed_stations(line: Line, origin: str, destination: str) -> tuple[str, ...]:
    """Stations strictly between two stops, in running order (made once per line object and pair of stops,
    :func:`~planner.line.model.per_line`: the margin report asks for each of its rows, 0.6 s of the job process on
    a line of 1,100 stations)."""
    d = line.direction_between(origin, destination)
    a, b = line.station(origin).position_m, line.station(destination).position_m
    lo, hi = min(a, b), max(a, b)
    st = [s for s in line.stations if lo < s.position_m < hi]
    st.sort(key=lambda s: sign(d) * s.position_m)
    return tuple(s.station_id for s in st)


def leg_result(line: Line, train_type: str, origin: str, destination: str, scheduled: Sequence[float], *,
               tables=None, energy_a_kwh=None, ratios=None, rule: MarginRule = MarginRule(),
               adhesion_kmh_s=DEFAULT_ADHESION_KMH_S, approach_m: float | str = DEFAULT_APPROACH_M,
               after_departure_m: float | None = 200.0, eval_interval_m: float | None = None, settings=None,
               eval_auto_s: float | None = None, closed_loop_errors: dict | None = None, record: bool = False,
               min_target_speed_ms: float = 20.0 * KMH) -> LegResult:
    """Compute one leg: minimum, slowest, degraded minimum, pattern sweep, closed loop per scheduled time.

    Parameters
    ----------
    line : Line
    train_type, origin, destination : str
        The leg (stop to next stop; stations between are passed).
    scheduled : sequence of float
        Distinct scheduled running times of the leg in the timetable [s] (may be empty).
    tables : planner.tables.onboard.RunningTimeTables, optional
        The leg's tables as read from a ``--tables`` folder; computed with
        :func:`planner.tables.build.interstation_tables` when None.
    energy_a_kwh : ndarray, optional
        Table (a) energy [kWh] that goes with ``tables``.
    ratios : ratio grid spec or list, optional
        For computed tables (default grid; its floor is the leg's, :func:`planner.tables.ratios.leg_ratio_grid`).
    rule : MarginRule
    adhesion_kmh_s : spec or list
        Adhesion sweep [km/h/s] (:func:`adhesion_levels`), the rail's; the train's levels
        (:func:`train_adhesion_kmh_s`), the lowest is the degraded level.
    approach_m : float or "auto"
        Pattern start before the marker where there is no TASC beacon [m]; ``"auto"``: the line's, else
        from the physics (:func:`planner.stopping.approach.approach_start`, the lowest level of the train).
    after_departure_m : float or None
        Evaluation point after departure for computed tables [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points for computed tables [m]; None: beacons only.
    settings : SimSettings, optional
    eval_auto_s : float or None
        Fill interval of computed tables on a leg without beacon points [s of running at its maximum].
    closed_loop_errors : dict, optional
        ``{("nominal" | "degraded", designated_s rounded to 1e-6): error_s}`` already
        computed (``--closed-loop``); missing ones are simulated.
    min_target_speed_ms : float
        The floor of computed tables' grid: ratio × the leg's maximum = this [m/s].
    record : bool
        Also return the run curves (minimum, as scheduled for the first
        scheduled time, degraded with its stopping pattern) in ``.curves``.

    Returns
    -------
    LegResult
    """
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings

    settings = settings or SimSettings()
    train = line.train_type(train_type)
    ext = line.run_between(origin, destination)
    tables, energy_a, tsource = _leg_tables(line, train_type, origin, destination, tables, energy_a_kwh, ratios,
                                            after_departure_m, eval_interval_m, settings, min_target_speed_ms,
                                            eval_auto_s)
    adh = train_adhesion_kmh_s(train, adhesion_kmh_s)
    track, cands, src = _track_and_starts(line, train_type, origin, destination, ext.length_m, tables,
                                          approach_m, settings, float(adh[0]) * KMH_S)
    # ratio 1.0 at the tables' conditions (run 0), the bad day's load and traction (run 1) and its load
    # alone (run 2, to split the bad day's cost by effect), states at the pattern starts
    try:
        res = simulate(track, train, np.array([1.0, 1.0, 1.0]), load=np.array([0.0, rule.bad_load, rule.bad_load]),
                       traction_factor=np.array([1.0, rule.bad_traction, 1.0]), snapshots_m=cands, record=record)
    except StallError as e:  # a physical verdict: the leg is unassessed, the flag says where and why
        return _stalled_leg(line, train, track, cands, src, tables, energy_a, tsource, ext, e, rule,
                            adh, scheduled, closed_loop_errors)
    t_end = np.asarray(res.time_s, float)
    if abs(float(tables.ratios[0]) - 1.0) <= 1e-9:
        min_time, e_full = float(tables.time_a_s[0]), float(energy_a[0])
    else:  # a grid without 1.0: the simulated nominal run is the minimum
        min_time, e_full = float(t_end[0]), float(np.asarray(res.energy_kwh)[0])

    bad = _bad_day(line, train, track, res, cands, ext.length_m, adh, rule, src)
    sweep, loss = _adhesion_sweep(line, train, track, res, cands, adh, bad.adhesion_kmh_s)
    out = LegResult(
        direction=ext.direction, train_type=train_type, origin=origin, destination=destination,
        passes=passed_stations(line, origin, destination), length_m=float(ext.length_m), min_time_s=min_time,
        slowest_time_s=float(tables.time_a_s[-1]), energy_full_kwh=e_full, degraded_min_s=bad.degraded_s,
        degraded_loss_running_s=bad.t_deg_s - bad.t_nom_s, degraded_loss_stop_s=bad.stop_deg_s - bad.stop_nom_s,
        degraded_loss_load_s=bad.t_load_s - bad.t_nom_s, degraded_loss_traction_s=bad.t_deg_s - bad.t_load_s,
        # the nominal run with the bad day's stop model against the table minimum (constant stopping brake):
        # not a bad-day effect, but part of degraded - minimum, so the four shares add up to it
        degraded_loss_stop_model_s=bad.t_nom_s + bad.stop_nom_s - min_time,
        pattern_start_s_m=float(bad.start_s_m), pattern_start_m=float(ext.start_m + ext.sign * bad.start_s_m),
        pattern_source=bad.source, v_pattern_degraded_ms=bad.v_deg_ms, stop_time_degraded_s=bad.stop_deg_s,
        stop_time_nominal_s=bad.stop_nom_s, adhesion_min_kmh_s=bad.adhesion_kmh_s, adhesion_loss_s=loss,
        sweep_adhesion_kmh_s=adh, sweep_duration_s=sweep, note=bad.note, tables_source=tsource, tables=tables,
        energy_a_kwh=energy_a)
    if bad.pattern is None and not bad.adhesion_off:  # no pattern stops it at the marker: where it must stop
        out.flags = (LegFlag(NO_STOP, BAD_DAY, float(ext.end_m), bad.note),)
    sched = np.asarray(sorted({float(x) for x in scheduled}), float)
    cl = _scheduled_runs(out, track, train, tables, energy_a, sched, rule, closed_loop_errors, record)
    if record:
        out.curves = _curves(track, res, bad.start_s_m, bad.pattern, cl, float(sched[0]) if sched.size else math.nan,
                             whole=bad.adhesion_off)
    return out


def _stalled_leg(line: Line, train, track, cands, src: str, tables, energy_a, tsource: str, ext, err: StallError,
                 rule: MarginRule, adhesion_kmh_s, scheduled, closed_loop_errors) -> LegResult:
    """A leg whose bad-day run stalls: unassessed (degraded minimum unknown), flagged with where and why.

    What does not need the bad day is still computed from the nominal run alone: the minimum, the
    adhesion sweep at the nominal approach speed, the on-time ratio, the closed loop (its bad-day runs
    NaN where they stall) and the energy. It has no run curves (``record`` draws the bad day's).
    """
    from planner.physics.run_curve import simulate

    scenario = "nominal" if (err.load, err.traction_factor) == (0.0, 1.0) else BAD_DAY
    flag = LegFlag.stall(err, scenario)
    adh = np.asarray(adhesion_kmh_s, dtype=float)  # the train's levels (train_adhesion_kmh_s)
    a_bad, a_min = _bad_adhesion(train, adh, rule)
    nan = math.nan
    sweep, loss = np.full(adh.size, nan), nan
    min_time, e_full = nan, nan
    if scenario != "nominal":
        res = simulate(track, train, np.array([1.0]), snapshots_m=cands)
        sweep, loss = _adhesion_sweep(line, train, track, res, cands, adh, a_min)
        min_time, e_full = ((float(tables.time_a_s[0]), float(energy_a[0]))
                            if abs(float(tables.ratios[0]) - 1.0) <= 1e-9
                            else (float(res.time_s[0]), float(res.energy_kwh[0])))
    out = LegResult(
        direction=ext.direction, train_type=train.train_type, origin=tables.origin, destination=tables.destination,
        passes=passed_stations(line, tables.origin, tables.destination), length_m=float(ext.length_m),
        min_time_s=min_time, slowest_time_s=float(tables.time_a_s[-1]), energy_full_kwh=e_full, degraded_min_s=nan,
        degraded_loss_running_s=nan, degraded_loss_stop_s=nan, degraded_loss_load_s=nan,
        degraded_loss_traction_s=nan, degraded_loss_stop_model_s=nan, pattern_start_s_m=float(cands[0]),
        pattern_start_m=float(ext.start_m + ext.sign * cands[0]), pattern_source=src, v_pattern_degraded_ms=nan,
        stop_time_degraded_s=nan, stop_time_nominal_s=nan, adhesion_min_kmh_s=a_min, adhesion_loss_s=loss,
        sweep_adhesion_kmh_s=adh, sweep_duration_s=sweep,
        note=f"{flag.reason}: {'minimum' if scenario == 'nominal' else 'degraded minimum'} unknown",
        tables_source=tsource, tables=tables, energy_a_kwh=energy_a, flags=(flag,))
    sched = np.asarray(sorted({float(x) for x in scheduled}), float)
    _scheduled_runs(out, track, train, tables, energy_a, sched, rule, closed_loop_errors, False)
    return out


def _leg_tables(line: Line, train_type: str, origin: str, destination: str, tables, energy_a_kwh, ratios,
                after_departure_m, eval_interval_m, settings, min_target_speed_ms, eval_auto_s=None):
    """The leg's tables and table (a) energy: as given (``dataset``) or computed (``computed``)."""
    from planner.tables.build import interstation_tables
    from planner.tables.ratios import leg_ratio_grid

    if tables is None:
        grid = leg_ratio_grid(ratios, line, train_type, origin, destination, min_target_speed_ms)
        it = interstation_tables(line, train_type, origin, destination, grid,
                                 after_departure_m=after_departure_m, eval_interval_m=eval_interval_m,
                                 eval_auto_s=eval_auto_s,
                                 settings=settings)
        return it.onboard(), np.asarray(it.energy_a_kwh, float), "computed"
    if energy_a_kwh is None:
        energy_a_kwh = np.full(len(tables.ratios), np.nan)
    return tables, np.asarray(energy_a_kwh, float), "dataset"


def _track_and_starts(line: Line, train_type: str, origin: str, destination: str, length: float, tables,
                      approach_m, settings, adhesion_ms2: float):
    """The leg's track with nodes at the evaluation points and the candidate pattern starts.

    Returns ``(track, candidates, source)``: the candidates [m running distance] move back
    from the nominal pattern start in :data:`PATTERN_BACKOFF_M` steps, for when the lowest adhesion needs
    longer.
    """
    from planner.physics.track import make_track

    pts_s = [float(x) for x in tables.eval_distance_m]
    start = approach_start(line, origin, destination, approach_m, train_type=train_type, adhesion_ms2=adhesion_ms2,
                           settings=settings)
    # at or before the departure marker (approach not shorter than the leg): from the marker, where
    # the train stands and no pattern exists; the note then says the degraded minimum is unknown
    s_p, src = max(start.s_m, 0.0), start.source
    n_c = int(max(s_p - 0.25 * length, 0.0) // PATTERN_BACKOFF_M) + 1
    cands = [c for c in (s_p - PATTERN_BACKOFF_M * j for j in range(n_c)) if c > 0.0] or [s_p]
    track = make_track(line, train_type, origin, destination, settings=settings, nodes_m=pts_s + cands)
    cands = [float(track.s_m[track.node_index(c)]) for c in cands]
    return track, cands, src


@dataclass
class BadDay:
    """The bad day's run of one leg: to the pattern start, then its stop (see :func:`_bad_day`)."""

    start_s_m: float
    source: str
    t_deg_s: float
    v_deg_ms: float
    t_nom_s: float
    t_load_s: float
    stop_deg_s: float
    stop_nom_s: float
    adhesion_kmh_s: float
    adhesion_off: bool
    pattern: object
    note: str

    @property
    def degraded_s(self) -> float:
        """The bad-day minimum: the degraded run to the pattern start + its stop [s]."""
        return self.t_deg_s + self.stop_deg_s


def _bad_adhesion(train, adh: np.ndarray, rule: MarginRule) -> tuple[float | None, float]:
    """The bad day's adhesion [km/h/s] (None: the effect is off) and the level its stop uses.

    A configured level above the train's braking cap is the cap for this train; with the effect
    off, or no level configured, the lowest of the train's levels ``adh``."""
    a_bad = rule.bad_adhesion_kmh_s(adh)
    if a_bad is not None:
        a_bad = min(a_bad, round(brake_cap_ms2(train) / KMH_S, 9))
    return a_bad, float(adh[0]) if a_bad is None else a_bad


def _bad_day(line: Line, train, track, res, cands, length: float, adh: np.ndarray, rule: MarginRule,
             src: str) -> BadDay:
    """Degraded minimum: the degraded run to the pattern start + the pattern at the bad day's adhesion.

    Also the nominal run's time at that start and its stop with the same stop model, and the run
    with the bad day's load alone, for the shares of the bad day's cost.
    """
    t_end = np.asarray(res.time_s, float)
    a_bad, a_min = _bad_adhesion(train, adh, rule)
    c, t_deg, v_deg, pat, speed, grads = _first_pattern(line, train, track, res, 1, cands, a_min * KMH_S)
    note = ""
    if a_bad is None:  # adhesion effect off: the degraded run stops with the tables' stopping brake
        c, pat = cands[0], None
        sn = res.snapshots[c]
        t_deg, v_deg = float(sn.t_s[1]), float(sn.v_ms[1])
    elif pat is None:
        note = (f"no stopping pattern at adhesion {a_min:g} km/h/s from any start up to "
                f"{length - cands[-1]:.0f} m before the marker: degraded minimum unknown")
    elif c != cands[0]:
        note = (f"at adhesion {a_min:g} km/h/s the stopping pattern must start {length - c:.0f} m "
                f"before the marker, not {length - cands[0]:.0f} m")
        src += "+moved"
    t_nom_c = float(res.snapshots[c].t_s[0])
    t_load_c = float(res.snapshots[c].t_s[2])
    if a_bad is None:  # no adhesion effect: both stops with the tables' stopping brake (one stop model)
        stop_deg = float(t_end[1]) - t_deg
        stop_nom = float(t_end[0]) - t_nom_c
    else:
        stop_deg = pat.duration_s if pat is not None else math.nan
        # the nominal stop over the same approach with the same stop model (the pattern), at the best
        # adhesion of the sweep: the stop part of the bad-day loss is then the adhesion effect alone
        p_nom = stop_pattern(line, train, track, c, float(res.snapshots[c].v_ms[0]), float(adh[-1]) * KMH_S,
                             speed, grads)
        stop_nom = p_nom.duration_s if p_nom.feasible else math.nan
        if not p_nom.feasible and pat is not None:
            note = (note + "; " if note else "") + (
                f"no nominal stopping pattern at adhesion {float(adh[-1]):g} km/h/s from {length - c:.0f} m "
                "before the marker: the stop part of the loss is unknown")
    return BadDay(start_s_m=c, source=src, t_deg_s=t_deg, v_deg_ms=v_deg, t_nom_s=t_nom_c, t_load_s=t_load_c,
                  stop_deg_s=stop_deg, stop_nom_s=stop_nom, adhesion_kmh_s=a_min, adhesion_off=a_bad is None,
                  pattern=pat, note=note)


def _adhesion_sweep(line: Line, train, track, res, cands, adh: np.ndarray, a_min: float):
    """The adhesion effect at the nominal approach speed, every level of the sweep from one start.

    Returns the pattern durations per level [s] (NaN where none) and the growth from the highest to
    the lowest level [s].
    """
    cn, _, v_nom, pn, sp_n, gr_n = _first_pattern(line, train, track, res, 0, cands, a_min * KMH_S)
    sweep = np.full(adh.size, math.nan)
    if pn is not None:
        for i, a in enumerate(adh):
            p = stop_pattern(line, train, track, cn, v_nom, a * KMH_S, sp_n, gr_n)
            sweep[i] = p.duration_s if p.feasible else math.nan
    return sweep, float(sweep[0] - sweep[-1])


def _scheduled_runs(out: LegResult, track, train, tables, energy_a: np.ndarray, sched: np.ndarray,
                    rule: MarginRule, closed_loop_errors: dict | None, record: bool):
    """Per scheduled time: the on-time ratio, the closed-loop arrival errors and the energy (into ``out``).

    Returns the simulator's closed-loop result when runs were simulated (for the run curves), else None.
    """
    if not sched.size:
        return None
    from planner.tables.onboard import NearestRule

    cl = None
    known = closed_loop_errors or {}
    err_nom = np.array([known.get(("nominal", round(t, 6)), math.nan) for t in sched])
    err_deg = np.array([known.get(("degraded", round(t, 6)), math.nan) for t in sched])
    todo = ~(np.isfinite(err_nom) & np.isfinite(err_deg))
    if record:
        todo[:] = True  # the recorded run is wanted whatever the dataset holds
    if todo.any():
        times, cl = _closed_loop(track, train, tables, sched[todo], rule, record=record)
        t_n, t_d = np.split(times, 2)
        err_nom[todo] = np.where(np.isfinite(err_nom[todo]), err_nom[todo], t_n - sched[todo])
        err_deg[todo] = np.where(np.isfinite(err_deg[todo]), err_deg[todo], t_d - sched[todo])
    r0 = NearestRule().depart(tables, sched)
    idx = {float(x): i for i, x in enumerate(tables.ratios)}
    for i, t in enumerate(sched):
        out.schedules.append({
            "scheduled_s": float(t), "ratio_on_time": float(r0[i]), "arrival_error_s": float(err_nom[i]),
            "arrival_error_degraded_s": float(err_deg[i]),
            "energy_at_ratio_kwh": float(energy_a[idx[float(r0[i])]]),
        })
    return cl


def _curves(track, res, c: float, pat, cl, scheduled_s: float, whole: bool = False) -> dict:
    """Run curves of one leg for the report: plain arrays (km/h, s, chainage m).

    ``whole``: the degraded run to the marker (adhesion effect off), not only to the pattern start.
    """
    kc = len(track.chainage_m) - 1 if whole else track.node_index(c)
    out = {
        "position_m": np.asarray(track.chainage_m, float),
        "vmax_kmh": kmh(np.asarray(track.vmax_ms, float)),
        "min_speed_kmh": kmh(res.v_ms[0]),
        "min_time_s": res.t_s[0],
        "degraded_position_m": np.asarray(track.chainage_m[: kc + 1], float),
        "degraded_speed_kmh": kmh(res.v_ms[1][: kc + 1]),
        "degraded_time_s": res.t_s[1][: kc + 1],
        "pattern_start_m": float(track.position_m(c)),
        "scheduled_s": scheduled_s,
    }
    if pat is not None:
        smp = pat.sample(0.2)
        out["pattern_position_m"] = np.asarray(track.position_m(c + smp.x_m), float)
        out["pattern_speed_kmh"] = kmh(smp.v_ms)
        out["pattern_time_s"] = res.t_s[1][kc] + smp.t_s
    if cl is not None:
        out["sched_speed_kmh"] = kmh(cl.v_ms[0])
        out["sched_time_s"] = cl.t_s[0]
        out["sched_ratio"] = cl.ratio[0]
    return out
