"""Margin-time report: how much running-time supplement each interstation has, and how much it needs (docs/design.md §6).

A timetable grants each run from one stop to the next a *scheduled running
time* (arrival at the next stop − departure). This module compares it with
what the train can do.

Rows (dataset ``margins``)
--------------------------
One row per **leg** × scheduled running time, where a leg is a run from one
stop to the next stop of a train type in a direction:

* every interstation (consecutive stations) × direction × train type of the
  line, also when no train of that type runs it (then the timetable columns
  are null);
* every stop-to-stop run of the timetable whose calls differ, e.g. a rapid
  that passes stations: its leg runs between its consecutive *stops* (a pass
  is not a stop) and lists the stations passed in ``passes``.

Trains with the same leg and the same scheduled time share one row
(``n_trains``, ``train_ids``); a leg with two different scheduled times in
the timetable gets two rows. On an operating day with a temporary restriction
in force for part of the day, the trains that run a leg while it is lifted
(:func:`planner.line.operating_day.leg_restrictions`: in force at no instant of
their run of the leg) get a row of their own, computed on the day's line without
it, with its own tables and closed loop (:mod:`planner.report.margin_legs`);
``restrictions`` names the temporary restrictions each row is computed with.

What each row holds, and how
----------------------------
* **minimum running time**: ratio 1.0, load 0, traction × 1.0 (the
  conditions of the tables) — table (a) at ratio 1.0; and the same rounded
  *up* to the timetable unit of 10 s (:func:`round_up_s`).
* **margin** = scheduled − minimum [s], and in percent of the minimum.
* **degraded minimum**: the fastest run on a *bad day* — full load
  (``degraded_load``, 1.0), traction × ``degraded_traction`` (0.9) and the
  *lowest adhesion of the stopping-pattern sweep* (or ``degraded_adhesion_kmh_s``)
  at the arrival stop. Each effect can be switched off in the job file
  (``bad_day_load``, ``bad_day_traction``, ``bad_day_adhesion``; an effect that
  is off takes its nominal value, and without adhesion the stop is the tables'
  stopping brake), and its share is a column: ``degraded_loss_load_s`` (the
  load alone), ``degraded_loss_traction_s`` (traction on top of the load),
  ``degraded_loss_stop_s`` (the stop at the bad day's adhesion against the best),
  and ``degraded_loss_stop_model_s``, which is no effect of the bad day but of
  the model: the minimum stops with the tables' constant stopping brake, the
  bad day with a jerk-limited stopping pattern, so this is the nominal run with
  the pattern (at the best adhesion) − the minimum. The four add up to
  degraded − minimum. It is built in two parts:

  1. the degraded run at ratio 1.0 from departure to the **pattern start**,
     where the on-board stopping control takes over: the TASC beacon of the
     arrival stop in that direction; where there is none, ``approach_m`` before the
     stop marker when the job or the line sets it, else where the minimum-time run
     must start braking at the train's lowest adhesion level, plus 10 %
     (:func:`planner.stopping.approach.approach_start`,
     the one definition the stopping-pattern sweep uses too), simulated with
     the run-curve integrator;
  2. plus the duration of the minimum-time jerk-limited stopping pattern
     (:func:`planner.stopping.pattern.solve_stop`) from the degraded speed there, at
     the lowest adhesion: deceleration limit ``min(comfort, adhesion, brake)`` plus
     the gradient's part, the gradient averaged over the train as in the run
     curves and bounded per piece from the safe side
     (:func:`planner.stopping.approach.decel_limits`), speed limit the on-board
     maximum over the approach, jerk limit the vehicle's — the approach as
     :mod:`planner.stopping.sweep` (the line-level sweep, and the vehicle) builds it.

  If the lowest adhesion cannot stop the train from that start within the
  remaining distance, the start moves back (in 25 m steps) until it can; the
  row's ``note`` says so. ``stop_time_nominal_s`` is the nominal run's stop
  over the same approach with the same stop model: the pattern from the
  nominal run's speed there at the *highest* adhesion of the sweep, so
  ``degraded_loss_stop_s`` is the effect of the adhesion and the approach speed
  alone (no change of stop model hides in it); ``adhesion_loss_s`` is the growth of the
  pattern duration from the highest to the lowest adhesion of the sweep at
  the nominal approach speed (docs/design.md §5: "the margin report uses the growth
  in stopping time").
* **remaining margin** = scheduled − degraded minimum [s].
* **supplement required** by the rule (:class:`MarginRule`, configurable in
  the job file's ``[margins]``): ``supplement_percent`` % of the minimum plus
  ``supplement_min_per_100km`` minutes per 100 km (common timetable
  practice, e.g. UIC leaflet 451-1: 3 % + 1 min/100 km by default), and
  whether the margin meets it.
* **ratio at an on-time departure**: the on-board nearest rule
  (:class:`planner.tables.onboard.NearestRule`) on table (a) with the designated
  time = scheduled; the **closed-loop arrival error** (actual − scheduled,
  positive = late) of the on-board logic (nearest rule at every evaluation
  point) with that designated time, nominal (``arrival_error_s``) and under
  the degraded load and traction (``arrival_error_degraded_s``; the
  simulator's stopping brake, as in :mod:`planner.tables.closed_loop`).
* **energy**: table (a) traction energy at that ratio against at ratio 1.0;
  the difference is what the margin saves.
* **flags** (:mod:`planner.report.leg_flags` says each in words):
  ``impossible`` — scheduled below the minimum running time: no driving
  makes it, on any day; ``short_bad_day`` — not impossible, but scheduled
  below the degraded minimum: late on a bad day, by ``-remaining_margin_s``;
  ``infeasible`` — either of the two (the flag before they were told apart,
  kept so that existing queries and older runs compare);
  ``tight`` — not infeasible, but the remaining margin is below
  ``tight_threshold_s``; ``unreachable`` — scheduled above the slowest table
  time (lowest ratio), so the vehicle cannot stretch the run that long;
  ``inaccurate`` — the closed-loop sweep of the leg (``planner simulate``, the
  nightly job's closed loop) misses the designated arrival by more than
  ``arrival_error_threshold_s`` (10 s) in some scenario and mode
  (``closed_loop_max_error_s``): the on-board logic cannot keep the time
  there, e.g. a long leg with too few evaluation points;
  ``unassessed`` — the minimum or the degraded minimum could not be computed
  (e.g. no stopping pattern at the lowest adhesion from any start, or the
  train stalls on a climb on the bad day), with ``unassessed_reason``: then
  ``short_bad_day``, ``infeasible`` and ``tight`` are unknown, written as null in the
  dataset (``impossible`` only needs the minimum; ``infeasible`` is true where it is),
  and the report lists the leg first. Where the cause is physical (a
  :class:`planner.tables.flags.LegFlag`) the leg says what, under which
  conditions and where: ``unassessed_cause`` (``stall``, ``no_stop``),
  ``unassessed_scenario`` (``bad_day``, ``nominal``) and
  ``unassessed_position_m`` (the chainage of the stall, or the stop marker
  the train cannot stop at). Such a leg is a verdict, not a failure: every
  other column that does not need the bad day (minimum, on-time ratio,
  nominal closed loop, energy) is still computed, and so is every other leg.
  ``flag_reason`` says every flag of the row in words (how far below the
  minimum, how short on the bad day and the bad day's shares); ``bad_day_cause``
  names the largest share (``load``, ``traction``, ``adhesion``, ``stop_model``)
  of a leg short on the bad day or tight.

Totals (dataset ``margin_totals``, :func:`margin_totals`): per train (sum
over its legs), per direction × train type, and per direction over all train
types (``train_type = "all"``), each with flag counts.

Layout
------
* :mod:`planner.report.margin_rule`: the rule, rounding, margins and flags,
  totals (pure: plain numbers and arrays in, columns out);
* :mod:`planner.report.leg_flags`: what each flag says, its badge, card and
  colour, and the words of ``flag_reason`` and ``bad_day_cause`` (pure);
* :mod:`planner.report.leg_margin`: one leg with the simulator, the tables
  (read from ``--tables`` or computed), the stopping patterns and the closed loop;
* :mod:`planner.report.margin_legs`: the timetable as legs, and the groups the rows are computed in
  (leg × scheduled time × restrictions lifted for its trains);
* this module: the whole line (:func:`compute_margins`);
* :mod:`planner.report.margin_datasets`: the ``margins`` and ``margin_totals``
  datasets, and the readers of the other steps' folders;
* :mod:`planner.pages.margin_report` and :mod:`planner.pages.margin_charts`: the page and its charts.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from planner.errors import InputError
from planner.io.parallel import map_tasks
from planner.line.model import DIRECTIONS, Line, sign
from planner.line.units import KMH, KMH_S, kmh, kmh_s
from planner.report.leg_flags import flag_reasons
from planner.report.leg_margin import LegResult, leg_result, passed_stations
from planner.report.margin_legs import (
    Lifted,
    TrainLeg,
    applied_restrictions,
    group_window,
    lifted_of,
    looked_up,
    scheduled_times,
    timetable_legs,
)
from planner.report.margin_datasets import (
    MARGINS_SCHEMA,
    ClosedLoopFacts,
    closed_loop_index,
    closed_loop_worst,
    given_leg,
    given_tables,
    stops_facts,
)
from planner.report.margin_rule import TOTALS_COLUMNS, MarginRule, margin_columns, margin_totals
from planner.stopping.approach import DEFAULT_APPROACH_M
from planner.stopping.sweep import DEFAULT_ADHESION_KMH_S, adhesion_levels


# =====================================================================================
# The whole line
# =====================================================================================

@dataclass(eq=False)
class MarginReport:
    """The margin report of one line: rows, totals and what the HTML page needs.

    Attributes
    ----------
    rows : pandas.DataFrame
        One row per leg × scheduled time, columns of :data:`MARGINS_SCHEMA`
        plus the partition columns ``line, direction, train_type``.
    totals : pandas.DataFrame
        :func:`margin_totals` rows plus ``line``.
    sweep : pandas.DataFrame
        Stopping-pattern duration per leg and adhesion level at the nominal
        approach speed: ``direction, train_type, origin, destination,
        adhesion_kmh_s, stop_time_s``.
    curves : dict or None
        Run curves of the chosen leg (``chosen``), see :func:`leg_result`.
    chosen : dict or None
        Key of the leg whose run curves are drawn (``direction, train_type,
        origin, destination, scheduled_running_time_s``).
    conflicts : pandas.DataFrame or None
        :func:`planner.datasets.conflicts.conflicts_table` rows (None: not checked).
    conflicts_note : str
        Why conflicts were not checked, or "".
    legs : dict
        With a ``memo``: the leg groups read back (``hits``), computed (``computed``) and the entries it
        rejected (``rejected``: ``(kind, key, why)``), for the job's accounting of the run that made it.
    """

    line_id: str
    line_name: str
    rule: MarginRule
    adhesion_kmh_s: np.ndarray
    approach_m: float | str
    rows: object
    totals: object
    sweep: object
    curves: dict | None = None
    chosen: dict | None = None
    conflicts: object = None
    conflicts_note: str = ""
    sources: dict = field(default_factory=dict)
    legs: dict = field(default_factory=dict)


def leg_task(line, tt, o, d, sched, tabs, energy, kw):
    """Worker: one leg (module level, picklable inputs). Given tables are not sent back (``tables`` None):
    the caller has them (or their reference), and a copy of every leg's would double them in its memory."""
    given, (tabs, energy) = tabs, given_leg(tabs, energy)
    r = leg_result(line, tt, o, d, sched, tables=tabs, energy_a_kwh=energy, **kw)
    if given is not None and r.tables is tabs:
        r.tables = None
    return r


def margin_options(job, line: Line) -> dict:
    """The margin report's configuration from a job: keyword arguments of :func:`compute_margins`.

    The one place a job file becomes the margins' configuration: the nightly job
    (:mod:`planner.job.pipeline`) and ``planner margins --job`` both call it, so the
    two cannot drift.

    Parameters
    ----------
    job : planner.job.config.Job
        Its ``[margins]`` (the rule), ``[stops]`` (adhesion sweep, approach),
        ``[tables]`` (ratio grid with its floor, evaluation points, integration
        step) and ``[conflicts]`` sections are read.
    line : Line
        The line (each leg's grid takes its own floor: ratio × the train's maximum there = ``min_target_kmh``).

    Returns
    -------
    dict
        ``rule, ratios, min_target_speed_ms, adhesion_kmh_s, approach_m, after_departure_m,
        eval_interval_m, eval_auto_s, settings, conflicts, conflict_params``.
    """
    from planner.physics.track import SimSettings

    tp = job.tables
    c = job.conflicts
    return dict(rule=MarginRule.from_section(job.margins), ratios=tp.ratios, min_target_speed_ms=tp.min_target_kmh * KMH,
                adhesion_kmh_s=job.stops.adhesion_kmh_s, approach_m=job.stops.approach_m,
                after_departure_m=tp.eval_offset_m, eval_interval_m=tp.eval_interval_m or None,
                eval_auto_s=tp.eval_auto_s or None,
                settings=SimSettings(ds_m=tp.ds_m), conflicts=c.enabled,
                conflict_params={"setting_s": c.setting_s, "approach_s": c.approach_s, "release_s": c.release_s})


def compute_margins(
    line: Line,
    *,
    rule: MarginRule = MarginRule(),
    train_types: Sequence[str] | None = None,
    tables_dir: str | Path | None = None,
    stops_dir: str | Path | None = None,
    closed_loop_dir: str | Path | None = None,
    ratios=None,
    min_target_speed_ms: float = 20.0 * KMH,
    adhesion_kmh_s=DEFAULT_ADHESION_KMH_S,
    approach_m: float | str = DEFAULT_APPROACH_M,
    after_departure_m: float | None = 200.0,
    eval_interval_m: float | None = None,
    eval_auto_s: float | None = None,
    chosen: tuple[str, str, str] | None = None,
    conflicts: bool = True,
    conflict_params=None,
    settings=None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
    given: tuple[dict, dict] | None = None,
    lifted: Lifted | None = None,
    closed_loop: dict | None = None,
    memo=None,
) -> MarginReport:
    """The margin report of a whole line (module doc for every column).

    Parameters
    ----------
    line : Line
    rule : MarginRule
        Supplement rule, tight threshold, degraded conditions.
    train_types : sequence of str, optional
        Default every train type of the line.
    tables_dir : path, optional
        ``planner tables --out`` folder; legs it lacks (e.g. rapids' legs
        passing stations) are computed.
    stops_dir : path, optional
        ``planner stops --out`` folder: its adhesion levels replace ``adhesion_kmh_s``.
    closed_loop_dir : path, optional
        ``planner simulate --out`` folder(s): errors of the nearest rule at the
        scheduled times are taken from it where present.
    ratios : ratio grid spec or list, optional
        Grid for computed tables (default grid).
    min_target_speed_ms : float
        Its floor: ratio × the train's maximum on the leg = this [m/s].
    adhesion_kmh_s : spec or list
        Adhesion sweep [km/h/s]; its lowest level is the degraded one.
    approach_m : float or "auto"
        Pattern start before the stop marker where there is no TASC beacon [m]; ``"auto"``: the line's
        ``approach_m``, else where the train must start braking + 10 %.
    after_departure_m : float or None
        Evaluation point after departure for computed tables [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points for computed tables [m]; None: beacons only.
    eval_auto_s : float or None
        Fill interval of computed tables' legs without beacon points [s of running at the maximum].
    chosen : (train_type, origin, destination), optional
        Leg whose run curves the report draws; default the row with the least
        remaining margin.
    conflicts : bool
        Check the timetable for route conflicts when the line has a track network.
    conflict_params : mapping or BlockingParams, optional
    settings : SimSettings, optional
    n_jobs : int
        Worker processes over legs (1 = this process, -1 = all cores).
    progress : callable ``(done, total)``, optional
    given : (tables, energy), optional
        :func:`~planner.report.margin_datasets.given_tables` of the same line, types and ``tables_dir``, read
        beforehand; else read here. A table may be a reference to it instead
        (:func:`~planner.report.margin_datasets.given_leg`: the nightly job gives each leg the tables step's
        stored result, read on the worker that computes the leg), its energy then left out.
    lifted : mapping, optional
        ``(train_id, leg_seq)`` → ids of the line's temporary restrictions lifted while that train runs
        that leg (:func:`planner.job.day.lifted_restrictions`): such trains' legs are rows of their own,
        computed on the line without them (:mod:`planner.report.margin_legs`; the given tables and
        closed loop, made with them, are not used there).
    closed_loop : dict or ClosedLoopFacts, optional
        The ``closed_loop`` and ``closed_loop_summary`` Arrow tables of the line
        (:func:`planner.datasets.closed_loop.datasets`), used instead of reading them from
        ``closed_loop_dir``; or what the margins read of them, made beforehand
        (:class:`~planner.report.margin_datasets.ClosedLoopFacts` at
        :func:`~planner.report.margin_legs.looked_up_by_leg`: the nightly job makes them on the worker that
        writes the closed loop's datasets).
    memo : optional
        Each leg group as a unit of its own (:class:`planner.job.leg_memo.LegMemo`: ``key(line, group,
        times, options)``, ``get(key)``, ``put(key, result)``): a group whose key is stored is not computed
        again, so an edit recomputes the legs it touches. With ``run(keys, tasks)`` it computes or reads the groups
        itself (the nightly job's :class:`planner.job.leg_memo.LegUnits`: units of its runner).

    Returns
    -------
    MarginReport
    """
    import pandas as pd

    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    for t in types:
        line.train_type(t)
    adh, no_pattern, adh_of = stops_facts(Path(stops_dir), line.line_id) if stops_dir is not None \
        else (np.asarray(adhesion_levels(adhesion_kmh_s), dtype=float), {}, {})
    legs = [lg for lg in timetable_legs(line) if lg.train_type in types]
    sched = scheduled_times(line, types, legs, lifted)
    tabs, energy = given if given is not None else given_tables(line, types, tables_dir)
    cl_from = bool(closed_loop_dir) or closed_loop is not None
    cl_dir = Path(closed_loop_dir) if closed_loop_dir else None
    if isinstance(closed_loop, ClosedLoopFacts):  # made where the closed loop's rows are
        cl_index, cl_worst = closed_loop.index, closed_loop.worst
    else:
        times = looked_up(sched)
        cl_index = closed_loop_index(cl_dir, line.line_id, rule, closed_loop, times) if cl_from else {}
        cl_worst = closed_loop_worst(cl_dir, line.line_id, closed_loop) if cl_from else {}
    kw = dict(ratios=ratios, min_target_speed_ms=min_target_speed_ms, rule=rule, adhesion_kmh_s=adh,
              approach_m=approach_m, after_departure_m=after_departure_m, eval_interval_m=eval_interval_m,
              eval_auto_s=eval_auto_s, settings=settings)

    by_leg: dict[tuple, dict] = {}  # the closed-loop errors of each leg, in one pass (not one per leg)
    for k, v in cl_index.items():
        by_leg.setdefault(k[:4], {})[k[4:]] = v

    def known_errors(key) -> dict:
        return dict(by_leg.get(key, {}))

    keys = sorted(sched, key=lambda k: (DIRECTIONS.index(k[0]), k[1],
                                        sign(k[0]) * line.station(k[2]).position_m,
                                        sign(k[0]) * line.station(k[3]).position_m, k[4]))
    # each task ships the slice of the line its leg can see (Line.window), not the whole line and
    # timetable: on a 10x line pickling the whole line per leg made this step quadratic; a group
    # with restrictions lifted computes its own tables and closed loop (the given ones have them)
    windows = {k: group_window(line, k) for k in keys}
    # each train type's own adhesion levels where the stops step gave them: its bad day is its own
    tasks = [(windows[k], k[1], k[2], k[3], sorted(sched[k]), None if k[4] else tabs.get(k[:4]),
              None if k[4] else energy.get(k[:4]), kw | {"closed_loop_errors": {} if k[4] else known_errors(k[:4]),
                                                         "adhesion_kmh_s": adh_of.get(k[1], adh)})
             for k in keys]
    results: list[LegResult] = _memoised(memo, line, keys, tasks, n_jobs, progress)
    for k, r, task in zip(keys, results, tasks):  # the window holds only the leg's two stations: the passed ones
        r.passes = passed_stations(line, r.origin, r.destination)  # from the line
        if r.tables is None:  # the given tables it used (leg_task), or their reference: read if drawn
            r.tables = task[5]
        r.lifted, r.restrictions = k[4], applied_restrictions(windows[k], k[0], k[1])
    results = [no_stop(r, no_pattern) for r in results]

    rows, sweep, row_lifted = _rows(line, results, legs, rule, cl_worst, lifted)
    tl = pd.DataFrame.from_records(
        [{"train_id": lg.train_id, "direction": lg.direction, "train_type": lg.train_type, "origin": lg.origin,
          "destination": lg.destination, "scheduled_running_time_s": lg.scheduled_s,
          "departure_s": lg.departure_s, "leg_seq": lg.leg_seq, "lifted": ",".join(lifted_of(lg, lifted))}
         for lg in legs],
        columns=["train_id", "direction", "train_type", "origin", "destination", "scheduled_running_time_s",
                 "departure_s", "leg_seq", "lifted"])
    # the same float key on both sides (scheduled times come from the same subtraction)
    totals = margin_totals(rows.assign(lifted=row_lifted), tl, key_extra=("lifted",)) if len(tl) \
        else pd.DataFrame(columns=TOTALS_COLUMNS)
    totals.insert(0, "line", line.line_id)
    curves, chosen_key = _chosen_curves(line, rows, results, chosen, kw, adh_of)
    con, note = _conflicts(line, conflicts, conflict_params)
    return MarginReport(
        line_id=line.line_id, line_name=line.name, rule=rule, adhesion_kmh_s=adh, approach_m=approach_m,
        rows=rows.reset_index(drop=True), totals=totals, sweep=pd.DataFrame.from_records(sweep),
        curves=curves, chosen=chosen_key, conflicts=con, conflicts_note=note,
        sources={"tables_dataset": sum(r.tables_source == "dataset" for r in results),
                 "tables_computed": sum(r.tables_source == "computed" for r in results),
                 "closed_loop_dataset": bool(cl_index)},
        legs={} if memo is None else memo.stats(),
    )


def _memoised(memo, line: Line, keys: list, tasks: list, n_jobs: int, progress) -> list[LegResult]:
    """The legs' results: :func:`leg_task` for each task, those ``memo`` holds taken from it (each computed one
    stored in it as :func:`leg_task` gave it); or, with a ``memo`` that runs them (``run(keys, tasks)``), its
    results."""
    if memo is None:
        return map_tasks(leg_task, tasks, n_jobs, progress)
    ids = [memo.key(line, k, t[4], t[7]) for k, t in zip(keys, tasks)]
    if hasattr(memo, "run"):  # the nightly job's: each group a unit of its runner (planner.job.leg_memo.LegUnits)
        return memo.run(ids, tasks)
    results = [memo.get(i) for i in ids]
    todo = [j for j, r in enumerate(results) if r is None]
    for j, r in zip(todo, map_tasks(leg_task, [tasks[j] for j in todo], n_jobs, progress)):
        memo.put(ids[j], r)
        results[j] = r
    return results


def no_stop(r: LegResult, no_pattern: dict) -> LegResult:
    """``r``, or where the stopping patterns (the stops step's, which the bundles hold) do not stop the train at
    the end of its leg at some adhesion level (``no_pattern``: :func:`stops_facts`), the leg flagged ``no_stop``
    and unassessed: no bad-day figure (its bad day must not stop the train where the vehicle's DB cannot, from
    a pattern start moved back that no bundle has)."""
    import dataclasses

    from planner.tables.flags import NO_STOP, LegFlag

    miss = no_pattern.get((r.train_type, r.direction, r.origin, r.destination))
    if miss is None:
        return r
    levels, reason, stop_m = miss
    a = sorted(levels)
    at = f"{a[0]:g}" if len(a) == 1 else f"{a[0]:g}…{a[-1]:g}"
    why = f"no stopping pattern at {r.destination} for adhesion {at} km/h/s ({len(a)} level{'s' * (len(a) > 1)}): {reason}"
    nan = math.nan
    return dataclasses.replace(r, degraded_min_s=nan, degraded_loss_running_s=nan, degraded_loss_stop_s=nan,
                               degraded_loss_load_s=nan, degraded_loss_traction_s=nan, degraded_loss_stop_model_s=nan,
                               stop_time_degraded_s=nan, note=why, flags=(LegFlag(NO_STOP, "stops", stop_m, why),))


def _rows(line: Line, results: Sequence[LegResult], legs: Sequence[TrainLeg], rule: MarginRule,
          cl_worst: dict | None = None, lifted: Lifted | None = None):
    """The ``margins`` rows (one per leg, scheduled time and lifted restrictions, with margins and flags),
    the sweep records and each row's lifted restrictions (ids joined by commas: the totals' join key)."""
    import pandas as pd

    trains_of: dict[tuple, list[str]] = {}
    for lg in legs:
        trains_of.setdefault((lg.direction, lg.train_type, lg.origin, lg.destination,
                              round(lg.scheduled_s, 6), lifted_of(lg, lifted)), []).append(lg.train_id)
    recs, sweep, row_lifted = [], [], []
    for r in results:
        base = _leg_columns(line, r)
        row_lifted += [",".join(r.lifted)] * max(len(r.schedules), 1)
        for a, t in zip(r.sweep_adhesion_kmh_s, r.sweep_duration_s):
            sweep.append({"direction": r.direction, "train_type": r.train_type, "origin": r.origin,
                          "destination": r.destination, "adhesion_kmh_s": float(a), "stop_time_s": float(t)})
        if not r.schedules:
            recs.append(base | {"scheduled_running_time_s": math.nan, "n_trains": 0, "train_ids": [],
                                "ratio_on_time": math.nan, "arrival_error_s": math.nan,
                                "arrival_error_degraded_s": math.nan, "energy_at_ratio_kwh": math.nan})
        for sc in r.schedules:
            ids = sorted(trains_of.get((r.direction, r.train_type, r.origin, r.destination,
                                        round(sc["scheduled_s"], 6), r.lifted), []))
            recs.append(base | {"scheduled_running_time_s": sc["scheduled_s"], "n_trains": len(ids),
                                "train_ids": ids, "ratio_on_time": sc["ratio_on_time"],
                                "arrival_error_s": sc["arrival_error_s"],
                                "arrival_error_degraded_s": sc["arrival_error_degraded_s"],
                                "energy_at_ratio_kwh": sc["energy_at_ratio_kwh"]})
    rows = pd.DataFrame.from_records(recs)
    rows["closed_loop_max_error_s"] = [(cl_worst or {}).get((r.direction, r.train_type, r.origin, r.destination),
                                                            math.nan) for r in rows.itertuples(index=False)]
    cols = margin_columns(rows["min_running_time_s"].to_numpy(float),
                          rows["scheduled_running_time_s"].to_numpy(float),
                          rows["degraded_min_running_time_s"].to_numpy(float),
                          rows["slowest_running_time_s"].to_numpy(float), rows["length_m"].to_numpy(float), rule,
                          rows["closed_loop_max_error_s"].to_numpy(float))
    for k, v in cols.items():
        rows[k] = v
    why = np.where(~np.isfinite(rows["min_running_time_s"].to_numpy(float)), "minimum running time unknown",
                   np.where(rows["note"].astype(str) != "", rows["note"].astype(str), "degraded minimum unknown"))
    rows["unassessed_reason"] = np.where(rows["unassessed"].to_numpy(bool), why, "")
    rows["flag_reason"], rows["bad_day_cause"] = flag_reasons(rows, rule.tight_threshold_s,
                                                              rule.arrival_error_threshold_s)
    rows["energy_saved_kwh"] = rows["energy_at_full_ratio_kwh"] - rows["energy_at_ratio_kwh"]
    rows["energy_saved_percent"] = 100.0 * rows["energy_saved_kwh"] / rows["energy_at_full_ratio_kwh"]
    return rows[["line", "direction", "train_type"] + [f.name for f in MARGINS_SCHEMA]], sweep, row_lifted


def _leg_columns(line: Line, r: LegResult) -> dict:
    """The columns of a leg's rows that do not depend on the scheduled time."""
    return {
        "line": line.line_id, "direction": r.direction, "train_type": r.train_type,
        "origin": r.origin, "destination": r.destination, "passes": list(r.passes),
        "restrictions": list(r.restrictions),
        "length_m": r.length_m, "min_running_time_s": r.min_time_s,
        "degraded_min_running_time_s": r.degraded_min_s, "slowest_running_time_s": r.slowest_time_s,
        "degraded_loss_running_s": r.degraded_loss_running_s, "degraded_loss_stop_s": r.degraded_loss_stop_s,
        "degraded_loss_load_s": r.degraded_loss_load_s, "degraded_loss_traction_s": r.degraded_loss_traction_s,
        "degraded_loss_stop_model_s": r.degraded_loss_stop_model_s,
        "energy_at_full_ratio_kwh": r.energy_full_kwh, "pattern_start_m": r.pattern_start_m,
        "pattern_start_source": r.pattern_source,
        "pattern_start_speed_degraded_kmh": kmh(r.v_pattern_degraded_ms),
        "stop_time_degraded_s": r.stop_time_degraded_s, "stop_time_nominal_s": r.stop_time_nominal_s,
        "adhesion_min_ms2": r.adhesion_min_kmh_s * KMH_S, "adhesion_min_kmh_s": kmh_s(r.adhesion_min_kmh_s * KMH_S),
        "adhesion_loss_s": r.adhesion_loss_s,
        "tables_source": r.tables_source, "note": r.note,
        "unassessed_cause": r.flags[0].kind if r.flags else "",
        "unassessed_scenario": r.flags[0].scenario if r.flags else "",
        "unassessed_position_m": r.flags[0].position_m if r.flags else math.nan,
    }


def _chosen_curves(line: Line, rows, results: Sequence[LegResult], chosen, kw: dict, adh_of: dict | None = None):
    """Run curves of the leg the page draws (``chosen``, else the least remaining margin) and its key; ``adh_of``:
    each train type's adhesion levels (:func:`stops_facts`), as its legs were computed with."""
    pick = None
    has = rows[rows["scheduled_running_time_s"].notna()]
    if chosen is not None:
        tt, o, de = chosen
        m = rows[(rows.train_type == tt) & (rows.origin == o) & (rows.destination == de)]
        if m.empty:
            raise InputError(f"--curves {tt}:{o}-{de}: no such leg in the report; give TYPE:ORIGIN-DESTINATION "
                             "of a leg a train runs (stop to next stop)")
        m = m.sort_values("remaining_margin_s", na_position="last", kind="stable")
        pick = m.iloc[0]
    elif len(has):
        pick = has.sort_values(["remaining_margin_s", "direction", "train_type", "origin"], kind="stable").iloc[0]
    if pick is None:
        return None, None
    k = (pick.direction, pick.train_type, pick.origin, pick.destination)
    s = [] if not np.isfinite(pick.scheduled_running_time_s) else [float(pick.scheduled_running_time_s)]
    done = next(r for r in results if (r.direction, r.train_type, r.origin, r.destination) == k
                and list(r.restrictions) == list(pick.restrictions))
    tabs, energy = given_leg(done.tables, done.energy_a_kwh)
    lr = leg_result(group_window(line, (*k, done.lifted)), k[1], k[2], k[3], s, tables=tabs,
                    energy_a_kwh=energy, record=True,
                    **(kw | {"adhesion_kmh_s": (adh_of or {}).get(k[1], kw["adhesion_kmh_s"])}))
    if lr.curves is None:  # a stalled leg has no bad-day curve to draw
        return None, None
    return lr.curves, {"direction": k[0], "train_type": k[1], "origin": k[2], "destination": k[3],
                       "scheduled_running_time_s": float(pick.scheduled_running_time_s)}


def _conflicts(line: Line, check: bool, conflict_params):
    """The route conflicts of the timetable (None when not checked) and why not, or ""."""
    if not check:
        return None, "not checked (--no-conflicts)"
    if line.network is None:
        return None, "the line database has no track network (nodes.parquet, edges.parquet)"
    from planner.errors import PlannerError
    from planner.datasets.conflicts import conflicts_table

    try:
        return conflicts_table(line, conflict_params), ""
    except PlannerError as e:
        return None, f"the conflict check failed: {e}"
