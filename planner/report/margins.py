"""Margin-time report: how much running-time supplement each interstation has, and how much it needs (DESIGN §6).

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
the timetable gets two rows.

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
  ``degraded_loss_stop_s`` (the stop). The three add up to degraded − the
  nominal run's time. It is built in two parts:

  1. the degraded run at ratio 1.0 from departure to the **pattern start**,
     where the on-board stopping control takes over: the TASC beacon of the
     arrival stop in that direction, or ``approach_m`` (550 m) before the
     stop marker where there is none (:func:`planner.stopping.approach.approach_start`,
     the one definition the stopping-pattern sweep uses too), simulated with
     the run-curve integrator;
  2. plus the duration of the minimum-time jerk-limited stopping pattern
     (:func:`planner.stopping.pattern.solve_stop`) from the degraded speed there, at
     the lowest adhesion: deceleration limit ``min(comfort, adhesion)`` plus
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
  the nominal approach speed (DESIGN §5: "the margin report uses the growth
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
* **flags**: ``infeasible`` — scheduled below the degraded minimum;
  ``tight`` — not infeasible, but the remaining margin is below
  ``tight_threshold_s``; ``unreachable`` — scheduled above the slowest table
  time (lowest ratio), so the vehicle cannot stretch the run that long;
  ``unassessed`` — the minimum or the degraded minimum could not be computed
  (e.g. no stopping pattern at the lowest adhesion from any start), with
  ``unassessed_reason``: then ``infeasible`` and ``tight`` are unknown, written
  as null in the dataset, and the report lists the leg first.

Totals (dataset ``margin_totals``, :func:`margin_totals`): per train (sum
over its legs), per direction × train type, and per direction over all train
types (``train_type = "all"``), each with flag counts.

Layout
------
The first part is pure (plain numbers and arrays in, columns out): the rule,
rounding, margins and flags, totals. The second gathers the inputs with the
simulator, the tables (read from ``--tables`` or computed), the stopping
patterns and the closed loop (:func:`compute_margins`). Table (b) rows that
are not given are computed on demand (:class:`LazyTableB`): the closed loop
at one designated time needs one row per evaluation point, not n_r².
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pyarrow as pa

from planner.io.parquet import declare, write_partitioned
from planner.errors import InputError
from planner.line.model import DIRECTIONS, Line, sign
from planner.stopping.approach import DEFAULT_APPROACH_M, approach_start
from planner.stopping.sweep import DEFAULT_ADHESION_KMH_S, adhesion_levels
from planner.line.units import KMH_S

ROUND_UNIT_S = 10.0
"""Timetable unit the minimum running time is rounded up to [s]."""
TIME_TOL_S = 1e-6
"""Two times closer than this [s] are equal (flags, rounding): far below the integrator's 0.05 s."""
PATTERN_BACKOFF_M = 25.0
"""Step [m] by which the pattern start moves back when the lowest adhesion cannot stop in time."""
ALL_TYPES = "all"
"""``train_type`` partition value of the per-direction totals over every train type."""


# =====================================================================================
# Pure part: rule, rounding, margins and flags, totals
# =====================================================================================

@dataclass(frozen=True)
class MarginRule:
    """What the report asks of a timetable (job file ``[margins]``).

    Attributes
    ----------
    supplement_percent : float
        Required supplement as a percentage of the minimum running time [%].
    supplement_min_per_100km : float
        ... plus this many minutes per 100 km of leg length [min/100 km].
    tight_threshold_s : float
        A remaining margin (scheduled − degraded minimum) below this is ``tight`` [s].
    degraded_load : float
        Load factor of the degraded conditions (1.0 = full).
    degraded_traction : float
        Traction factor of the degraded conditions (0.9 = weak catenary).
    bad_day_load, bad_day_traction, bad_day_adhesion : bool
        Which effects the bad day (degraded scenario) includes. An effect that
        is off takes its nominal value: load 0, traction × 1.0, and the
        stopping brake of the running-time tables instead of a low-adhesion
        stopping pattern.
    degraded_adhesion_kmh_s : float
        Adhesion-limited deceleration of the bad day's stop [km/h/s]; 0 = the
        lowest level of the adhesion sweep.
    """

    supplement_percent: float = 3.0
    supplement_min_per_100km: float = 1.0
    tight_threshold_s: float = 5.0
    degraded_load: float = 1.0
    degraded_traction: float = 0.9
    bad_day_load: bool = True
    bad_day_traction: bool = True
    bad_day_adhesion: bool = True
    degraded_adhesion_kmh_s: float = 0.0

    def __post_init__(self):
        for name in ("supplement_percent", "supplement_min_per_100km", "tight_threshold_s", "degraded_load",
                     "degraded_adhesion_kmh_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"[margins] {name} must be a number ≥ 0, found {v!r}")
        if self.degraded_load > 1:
            raise InputError(f"[margins] degraded_load must lie between 0 (empty) and 1 (full), "
                             f"found {self.degraded_load!r}")
        if not (math.isfinite(self.degraded_traction) and 0 < self.degraded_traction <= 2):
            raise InputError(f"[margins] degraded_traction must lie in (0, 2], found {self.degraded_traction!r}")

    @property
    def bad_load(self) -> float:
        """Load factor of the bad day as configured (0, the tables' load, when the effect is off)."""
        return self.degraded_load if self.bad_day_load else 0.0

    @property
    def bad_traction(self) -> float:
        """Traction factor of the bad day as configured (1.0 when the effect is off)."""
        return self.degraded_traction if self.bad_day_traction else 1.0

    def bad_adhesion_kmh_s(self, sweep_kmh_s) -> float | None:
        """Adhesion of the bad day's stop [km/h/s]: the configured value or the sweep's lowest; None when off."""
        if not self.bad_day_adhesion:
            return None
        return float(self.degraded_adhesion_kmh_s) if self.degraded_adhesion_kmh_s > 0 else float(
            np.min(np.asarray(sweep_kmh_s, dtype=float)))

    def describe(self, sweep_kmh_s) -> str:
        """The bad day in words, e.g. ``load 100 %, traction × 0.9, adhesion 2.5 km/h/s``."""
        parts = [f"load {self.degraded_load:.0%}" if self.bad_day_load else "load off (empty)",
                 f"traction ×{self.degraded_traction:g}" if self.bad_day_traction else "traction off (×1)"]
        a = self.bad_adhesion_kmh_s(sweep_kmh_s)
        parts.append(f"adhesion {a:g} km/h/s" if a is not None else "adhesion off (stopping brake)")
        return ", ".join(parts)

    @classmethod
    def from_section(cls, section) -> "MarginRule":
        """From a :class:`planner.job.config.MarginsSection` (or anything with the same attributes)."""
        return cls(**{f: getattr(section, f) for f in cls.__dataclass_fields__})

    def required_supplement_s(self, min_time_s, length_m):
        """Supplement the rule asks for [s].

        ``S = p/100 · T_min + m · 60 · L / 100 000`` with p = ``supplement_percent``,
        m = ``supplement_min_per_100km``, T_min [s], L [m].

        Examples
        --------
        >>> round(MarginRule().required_supplement_s(100.0, 50_000.0), 6)
        33.0
        """
        t = np.asarray(min_time_s, dtype=float)
        L = np.asarray(length_m, dtype=float)
        return self.supplement_percent / 100.0 * t + self.supplement_min_per_100km * 60.0 * L / 100_000.0


def round_up_s(t_s, unit_s: float = ROUND_UNIT_S):
    """Round a running time up to the timetable unit (10 s) [s].

    A time within :data:`TIME_TOL_S` above a multiple stays on it (so 130.0
    computed as 130.0000000001 is 130, not 140).

    Examples
    --------
    >>> round_up_s(135.78), round_up_s(130.0), round_up_s(130.2)
    (140.0, 130.0, 140.0)
    """
    t = np.asarray(t_s, dtype=float)
    out = np.ceil((t - TIME_TOL_S) / unit_s) * unit_s
    return float(out) if out.ndim == 0 else out


def margin_columns(min_time_s, scheduled_s, degraded_min_s, slowest_time_s, length_m,
                   rule: MarginRule = MarginRule()) -> dict[str, np.ndarray]:
    """Margins, supplement and flags of legs, from plain numbers (arrays of equal shape).

    Parameters
    ----------
    min_time_s : array
        Minimum running time (ratio 1.0, nominal) [s].
    scheduled_s : array
        Scheduled running time [s]; NaN where no train runs the leg.
    degraded_min_s : array
        Minimum running time under degraded conditions [s].
    slowest_time_s : array
        Slowest table time (lowest ratio of table (a)) [s].
    length_m : array
        Leg length, stop marker to stop marker [m].
    rule : MarginRule

    Returns
    -------
    dict of ndarray
        ``min_running_time_rounded_s``, ``margin_s`` (scheduled − minimum),
        ``margin_percent`` (of the minimum), ``remaining_margin_s``
        (scheduled − degraded minimum), ``supplement_required_s``,
        ``supplement_met`` (margin ≥ required), ``supplement_shortfall_s``
        (required − margin, ≥ 0), and the flags ``infeasible`` (scheduled <
        degraded minimum), ``tight`` (not infeasible and remaining margin <
        threshold), ``unreachable`` (scheduled > slowest), ``unassessed``
        (minimum or degraded minimum not finite: infeasible and tight cannot
        be decided and are False here; :func:`datasets` writes them as null).
        Times within :data:`TIME_TOL_S` count as equal; infeasible, tight and
        unreachable are False where there is no schedule.
    """
    tmin = np.asarray(min_time_s, dtype=float)
    sched = np.broadcast_to(np.asarray(scheduled_s, dtype=float), tmin.shape)
    deg = np.broadcast_to(np.asarray(degraded_min_s, dtype=float), tmin.shape)
    slow = np.broadcast_to(np.asarray(slowest_time_s, dtype=float), tmin.shape)
    has = np.isfinite(sched)
    margin = sched - tmin
    remaining = sched - deg
    req = np.broadcast_to(rule.required_supplement_s(tmin, length_m), tmin.shape)
    with np.errstate(invalid="ignore"):
        infeasible = has & (sched < deg - TIME_TOL_S)
        return {
            "min_running_time_rounded_s": np.asarray(round_up_s(tmin), dtype=float).reshape(tmin.shape),
            "margin_s": margin,
            "margin_percent": 100.0 * margin / tmin,
            "remaining_margin_s": remaining,
            "supplement_required_s": np.array(req, dtype=float),
            "supplement_met": has & (margin >= req - TIME_TOL_S),
            "supplement_shortfall_s": np.where(has, np.maximum(req - margin, 0.0), np.nan),
            "infeasible": infeasible,
            "tight": has & ~infeasible & (remaining < rule.tight_threshold_s - TIME_TOL_S),
            "unreachable": has & (sched > slow + TIME_TOL_S),
            "unassessed": ~(np.isfinite(tmin) & np.isfinite(deg)),
        }


TOTAL_SUM_COLS = (
    "min_running_time_s", "min_running_time_rounded_s", "scheduled_running_time_s", "margin_s",
    "degraded_min_running_time_s", "remaining_margin_s", "supplement_required_s",
    "energy_at_ratio_kwh", "energy_at_full_ratio_kwh", "energy_saved_kwh",
)
"""Row columns summed into the totals."""
UNKNOWN_WHEN_UNASSESSED = ("degraded_min_running_time_s", "remaining_margin_s")
"""Totals that are NaN (unknown) when any leg summed is unassessed, as are the worst margin and the shortfall."""


def margin_totals(rows, train_legs):
    """Totals per train, per direction × train type and per direction (pure pandas).

    Parameters
    ----------
    rows : pandas.DataFrame
        Margin rows (:func:`compute_margins`), with at least the key columns
        ``direction, train_type, origin, destination, scheduled_running_time_s``,
        the :data:`TOTAL_SUM_COLS` and the flags.
    train_legs : pandas.DataFrame
        One row per train and leg: ``train_id, direction, train_type, origin,
        destination, scheduled_running_time_s, departure_s, leg_seq``.

    Returns
    -------
    pandas.DataFrame
        ``level`` (``train``, ``type``, ``line``), ``train_id`` (null unless
        level train), ``direction``, ``train_type`` (``all`` for level line),
        ``origin``/``destination`` (the train's first and last stop; null
        otherwise), ``first_departure_s``, ``n_trains``, ``n_legs``, the sums
        of :data:`TOTAL_SUM_COLS`, ``margin_percent`` (total margin / total
        minimum), ``min_remaining_margin_s`` (worst leg), ``bad_day_shortfall_s``
        (sum of max(0, −remaining margin) over the legs), ``n_supplement_short``,
        ``n_infeasible``, ``n_tight``, ``n_unreachable``, ``n_unassessed``
        (legs, counted per train run). With an unassessed leg among those
        summed, the degraded-minimum and remaining-margin sums, the worst
        remaining margin and the shortfall are NaN: unknown, not partial.
    """
    import pandas as pd

    key = ["direction", "train_type", "origin", "destination", "scheduled_running_time_s"]
    cols = key + [c for c in TOTAL_SUM_COLS if c not in key] + ["supplement_met", "infeasible", "tight", "unreachable",
                                                                "unassessed"]
    r = rows[rows["scheduled_running_time_s"].notna()][cols]
    legs = train_legs.merge(r, on=key, how="left", validate="many_to_one")
    if legs["min_running_time_s"].isna().any():
        bad = legs[legs["min_running_time_s"].isna()].iloc[0]
        raise ValueError(f"train {bad.train_id}: leg {bad.origin}->{bad.destination} has no margin row")
    legs = legs.assign(short=~legs["supplement_met"].astype(bool),
                       n_inf=legs["infeasible"].astype(int), n_tight=legs["tight"].astype(int),
                       n_unr=legs["unreachable"].astype(int), n_una=legs["unassessed"].astype(int))
    legs = legs.sort_values(["train_id", "leg_seq"], kind="stable")

    def agg(g: pd.DataFrame) -> dict:
        out = {c: float(g[c].sum()) for c in TOTAL_SUM_COLS}
        for c in UNKNOWN_WHEN_UNASSESSED:  # a partial sum would pass for the whole: unknown instead
            out[c] = float(g[c].sum(skipna=False))
        out["margin_percent"] = 100.0 * out["margin_s"] / out["min_running_time_s"]
        out["min_remaining_margin_s"] = float(g["remaining_margin_s"].min(skipna=False))
        out["bad_day_shortfall_s"] = float(np.maximum(-g["remaining_margin_s"].to_numpy(float), 0.0).sum())
        out["n_legs"] = int(len(g))
        out["n_supplement_short"] = int(g["short"].sum())
        out["n_infeasible"] = int(g["n_inf"].sum())
        out["n_tight"] = int(g["n_tight"].sum())
        out["n_unreachable"] = int(g["n_unr"].sum())
        out["n_unassessed"] = int(g["n_una"].sum())
        out["first_departure_s"] = float(g["departure_s"].min())
        return out

    recs = []
    for tid, g in legs.groupby("train_id", sort=True):
        recs.append({"level": "train", "train_id": tid, "direction": g["direction"].iloc[0],
                     "train_type": g["train_type"].iloc[0], "origin": g["origin"].iloc[0],
                     "destination": g["destination"].iloc[-1], "n_trains": 1} | agg(g))
    for (d, t), g in legs.groupby(["direction", "train_type"], sort=True):
        recs.append({"level": "type", "train_id": None, "direction": d, "train_type": t, "origin": None,
                     "destination": None, "n_trains": int(g["train_id"].nunique())} | agg(g))
    for d, g in legs.groupby("direction", sort=True):
        recs.append({"level": "line", "train_id": None, "direction": d, "train_type": ALL_TYPES,
                     "origin": None, "destination": None, "n_trains": int(g["train_id"].nunique())} | agg(g))
    out = pd.DataFrame.from_records(recs, columns=TOTALS_COLUMNS)
    return out


# =====================================================================================
# The timetable as legs
# =====================================================================================

@dataclass(frozen=True)
class TrainLeg:
    """One run of a timetabled train from a stop to its next stop."""

    train_id: str
    train_type: str
    direction: str
    leg_seq: int
    origin: str
    destination: str
    departure_s: float
    arrival_s: float

    @property
    def scheduled_s(self) -> float:
        """Scheduled running time: arrival at the next stop − departure [s]."""
        return self.arrival_s - self.departure_s


def timetable_legs(line: Line) -> list[TrainLeg]:
    """Every stop-to-stop run of the timetable (passes are run through; first and last call are stops).

    Raises
    ------
    InputError
        A leg without a departure or arrival time, or not later than its departure.
    """
    out = []
    for tr in line.trains:
        last = len(tr.calls) - 1
        calls = [c for k, c in enumerate(tr.calls) if c.stops or k in (0, last)]
        for i, (a, b) in enumerate(zip(calls[:-1], calls[1:])):
            leg = TrainLeg(tr.train_id, tr.train_type, tr.direction, i, a.station_id, b.station_id,
                           float(a.departure_s), float(b.arrival_s))
            if not (math.isfinite(leg.scheduled_s) and leg.scheduled_s > 0):
                raise InputError(
                    f"timetable.parquet train {tr.train_id} calls seq {a.seq}->{b.seq} "
                    f"({a.station_id}->{b.station_id}): needs a departure and a later arrival "
                    f"(found departure_s={a.departure_s}, arrival_s={b.arrival_s})")
            out.append(leg)
    return out


def passed_stations(line: Line, origin: str, destination: str) -> tuple[str, ...]:
    """Stations strictly between two stops, in running order."""
    d = line.direction_between(origin, destination)
    a, b = line.station(origin).position_m, line.station(destination).position_m
    lo, hi = min(a, b), max(a, b)
    st = [s for s in line.stations if lo < s.position_m < hi]
    st.sort(key=lambda s: sign(d) * s.position_m)
    return tuple(s.station_id for s in st)


# =====================================================================================
# Gathering the inputs: simulator, tables, stopping patterns, closed loop
# =====================================================================================

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


def _closed_loop(track, train, tables, designated: np.ndarray, rule: MarginRule, record: bool = False):
    """Nominal and bad-day closed-loop runs of the on-board nearest rule, per designated time.

    Returns the departure ratios (n,) and the simulator's BatchResult of 2n
    runs: the n designated times at the tables' conditions, then the same
    under the rule's bad-day load and traction, driven by
    :func:`planner.tables.closed_loop.drive_tables` (the closed-loop proof's own driver).
    """
    from planner.tables.closed_loop import SCENARIOS, Scenario, drive_tables

    bad = Scenario("bad_day", rule.bad_load, rule.bad_traction)
    r0, _, res = drive_tables(track, train, tables, designated, [SCENARIOS["nominal"], bad],
                              ["nearest", "nearest"], record=record)
    return r0[:len(designated)], res


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


def leg_result(line: Line, train_type: str, origin: str, destination: str, scheduled: Sequence[float], *,
               tables=None, energy_a_kwh=None, ratios=None, rule: MarginRule = MarginRule(),
               adhesion_kmh_s=DEFAULT_ADHESION_KMH_S, approach_m: float = DEFAULT_APPROACH_M,
               after_departure_m: float | None = 200.0, eval_interval_m: float | None = None, settings=None,
               closed_loop_errors: dict | None = None, record: bool = False) -> LegResult:
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
        For computed tables (default grid).
    rule : MarginRule
    adhesion_kmh_s : spec or list
        Adhesion sweep [km/h/s] (:func:`adhesion_levels`); the lowest is the degraded level.
    approach_m : float
        Pattern start before the marker where there is no TASC beacon [m].
    after_departure_m : float or None
        Evaluation point after departure for computed tables [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points for computed tables [m]; None: beacons only.
    settings : SimSettings, optional
    closed_loop_errors : dict, optional
        ``{("nominal" | "degraded", designated_s rounded to 1e-6): error_s}`` already
        computed (``--closed-loop``); missing ones are simulated.
    record : bool
        Also return the run curves (minimum, as scheduled for the first
        scheduled time, degraded with its stopping pattern) in ``.curves``.

    Returns
    -------
    LegResult
    """
    from planner.tables.ratios import ratio_grid
    from planner.physics.track import SimSettings, make_track
    from planner.physics.run_curve import simulate
    from planner.tables.build import interstation_tables

    settings = settings or SimSettings()
    train = line.train_type(train_type)
    ext = line.run_between(origin, destination)
    direction, sg, x0, length = ext.direction, ext.sign, ext.start_m, ext.length_m
    if tables is None:
        grid = ratio_grid(ratios, line_max_speed_ms=line.max_speed_ms)
        it = interstation_tables(line, train_type, origin, destination, grid,
                                 after_departure_m=after_departure_m, eval_interval_m=eval_interval_m,
                                 settings=settings)
        tables, energy_a_kwh, tsource = it.onboard(), it.energy_a_kwh, "computed"
    else:
        tsource = "dataset"
        if energy_a_kwh is None:
            energy_a_kwh = np.full(len(tables.ratios), np.nan)
    energy_a = np.asarray(energy_a_kwh, float)
    pts_s = [float(x) for x in tables.eval_distance_m]
    start = approach_start(line, origin, destination, approach_m)
    # at or before the departure marker (approach not shorter than the leg): from the marker, where
    # the train stands and no pattern exists; the note then says the degraded minimum is unknown
    s_p, src = max(start.s_m, 0.0), start.source
    # candidate pattern starts, moving back from s_p, for when the lowest adhesion needs longer
    n_c = int(max(s_p - 0.25 * length, 0.0) // PATTERN_BACKOFF_M) + 1
    cands = [c for c in (s_p - PATTERN_BACKOFF_M * j for j in range(n_c)) if c > 0.0] or [s_p]
    track = make_track(line, train_type, origin, destination, settings=settings, nodes_m=pts_s + cands)
    cands = [float(track.s_m[track.node_index(c)]) for c in cands]

    # ratio 1.0 at the tables' conditions (run 0), the bad day's load and traction (run 1) and its load
    # alone (run 2, to split the bad day's cost by effect), states at the pattern starts
    res = simulate(track, train, np.array([1.0, 1.0, 1.0]), load=np.array([0.0, rule.bad_load, rule.bad_load]),
                   traction_factor=np.array([1.0, rule.bad_traction, 1.0]), snapshots_m=cands, record=record)
    t_end = np.asarray(res.time_s, float)
    if abs(float(tables.ratios[0]) - 1.0) <= 1e-9:
        min_time, e_full = float(tables.time_a_s[0]), float(energy_a[0])
    else:  # a grid without 1.0: the simulated nominal run is the minimum
        min_time, e_full = float(t_end[0]), float(np.asarray(res.energy_kwh)[0])

    adh = np.asarray(adhesion_levels(adhesion_kmh_s), dtype=float)
    a_bad = rule.bad_adhesion_kmh_s(adh)
    a_min = float(adh[0]) if a_bad is None else a_bad
    # degraded minimum: degraded run to the pattern start + pattern at the bad day's adhesion
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
    degraded = t_deg + stop_deg
    # the adhesion effect at the nominal approach speed, every level from one start
    cn, _, v_nom, pn, sp_n, gr_n = _first_pattern(line, train, track, res, 0, cands, a_min * KMH_S)
    sweep = np.full(adh.size, math.nan)
    if pn is not None:
        for i, a in enumerate(adh):
            p = stop_pattern(line, train, track, cn, v_nom, a * KMH_S, sp_n, gr_n)
            sweep[i] = p.duration_s if p.feasible else math.nan
    loss = float(sweep[0] - sweep[-1])

    out = LegResult(
        direction=direction, train_type=train_type, origin=origin, destination=destination,
        passes=passed_stations(line, origin, destination), length_m=float(length), min_time_s=min_time,
        slowest_time_s=float(tables.time_a_s[-1]), energy_full_kwh=e_full, degraded_min_s=degraded,
        degraded_loss_running_s=t_deg - t_nom_c, degraded_loss_stop_s=stop_deg - stop_nom,
        degraded_loss_load_s=t_load_c - t_nom_c, degraded_loss_traction_s=t_deg - t_load_c,
        pattern_start_s_m=float(c), pattern_start_m=float(x0 + sg * c), pattern_source=src,
        v_pattern_degraded_ms=v_deg, stop_time_degraded_s=stop_deg, stop_time_nominal_s=stop_nom,
        adhesion_min_kmh_s=a_min, adhesion_loss_s=loss, sweep_adhesion_kmh_s=adh, sweep_duration_s=sweep,
        note=note, tables_source=tsource, tables=tables, energy_a_kwh=energy_a)

    sched = np.asarray(sorted({float(x) for x in scheduled}), float)
    cl = None
    if sched.size:
        from planner.tables.onboard import NearestRule

        known = closed_loop_errors or {}
        err_nom = np.array([known.get(("nominal", round(t, 6)), math.nan) for t in sched])
        err_deg = np.array([known.get(("degraded", round(t, 6)), math.nan) for t in sched])
        todo = ~(np.isfinite(err_nom) & np.isfinite(err_deg))
        if record:
            todo[:] = True  # the recorded run is wanted whatever the dataset holds
        if todo.any():
            _, cl = _closed_loop(track, train, tables, sched[todo], rule, record=record)
            t_n, t_d = np.split(np.asarray(cl.time_s, float), 2)
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
    if record:
        out.curves = _curves(track, res, c, pat, cl, float(sched[0]) if sched.size else math.nan,
                             whole=a_bad is None)
    return out


def _curves(track, res, c: float, pat, cl, scheduled_s: float, whole: bool = False) -> dict:
    """Run curves of one leg for the report: plain arrays (km/h, s, chainage m).

    ``whole``: the degraded run to the marker (adhesion effect off), not only to the pattern start.
    """
    kc = len(track.chainage_m) - 1 if whole else track.node_index(c)
    out = {
        "position_m": np.asarray(track.chainage_m, float),
        "vmax_kmh": np.asarray(track.vmax_ms, float) * 3.6,
        "min_speed_kmh": res.v_ms[0] * 3.6,
        "min_time_s": res.t_s[0],
        "degraded_position_m": np.asarray(track.chainage_m[: kc + 1], float),
        "degraded_speed_kmh": res.v_ms[1][: kc + 1] * 3.6,
        "degraded_time_s": res.t_s[1][: kc + 1],
        "pattern_start_m": float(track.position_m(c)),
        "scheduled_s": scheduled_s,
    }
    if pat is not None:
        smp = pat.sample(0.2)
        out["pattern_position_m"] = np.asarray(track.position_m(c + smp.x_m), float)
        out["pattern_speed_kmh"] = smp.v_ms * 3.6
        out["pattern_time_s"] = res.t_s[1][kc] + smp.t_s
    if cl is not None:
        out["sched_speed_kmh"] = cl.v_ms[0] * 3.6
        out["sched_time_s"] = cl.t_s[0]
        out["sched_ratio"] = cl.ratio[0]
    return out


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
    """

    line_id: str
    line_name: str
    rule: MarginRule
    adhesion_kmh_s: np.ndarray
    approach_m: float
    rows: object
    totals: object
    sweep: object
    curves: dict | None = None
    chosen: dict | None = None
    conflicts: object = None
    conflicts_note: str = ""
    sources: dict = field(default_factory=dict)


def _leg_task(line, tt, o, d, sched, tabs, energy, kw):
    """joblib worker: one leg (module level, picklable inputs)."""
    return leg_result(line, tt, o, d, sched, tables=tabs, energy_a_kwh=energy, **kw)


def _read_energy(tables_dir: Path, line_id: str, direction: str, train_type: str) -> dict:
    """Table (a) energy per (origin, destination), ratios descending (load_tables does not carry it)."""
    from planner.io.parquet import read_dataset

    ta = read_dataset(tables_dir, "table_a", line=line_id, direction=direction, train_type=train_type).to_pandas()
    out = {}
    for (o, d), a in ta.groupby(["origin", "destination"], sort=False):
        out[(o, d)] = a.sort_values("ratio", ascending=False)["energy_kwh"].to_numpy(float)
    return out


def _closed_loop_index(closed_loop_dir: Path, line_id: str, rule: MarginRule) -> dict:
    """Closed-loop errors (nearest rule) from a ``planner simulate`` folder, by leg, scenario, designated time.

    ``perturbed`` runs stand for the degraded scenario only when their load and
    traction equal the rule's degraded ones.
    """
    from planner.tables.closed_loop import SCENARIOS
    from planner.io.parquet import read_dataset

    try:
        t = read_dataset(closed_loop_dir, "closed_loop", line=line_id).to_pandas()
    except (FileNotFoundError, OSError) as e:
        raise InputError(f"--closed-loop {closed_loop_dir}: cannot read the closed_loop dataset ({e}); "
                         "run `planner simulate` first or leave the option out") from None
    for c in ("scenario", "mode"):
        if c not in t.columns:
            raise InputError(f"--closed-loop {closed_loop_dir}: closed_loop has no {c!r} partition; "
                             "rebuild it with `planner simulate`")
        t[c] = t[c].astype(str)
    t = t[t["mode"] == "nearest"]
    p = SCENARIOS["perturbed"]
    names = {"nominal": "nominal"}
    if (p.load, p.traction_factor) == (rule.bad_load, rule.bad_traction):
        names["perturbed"] = "degraded"
    out = {}
    for r in t.itertuples(index=False):
        if r.scenario in names:
            out[(r.direction, r.train_type, r.origin, r.destination, names[r.scenario],
                 round(float(r.designated_s), 6))] = float(r.error_s)
    return out


def _stops_adhesion(stops_dir: Path, line_id: str) -> np.ndarray:
    """Adhesion levels [km/h/s] of the ``stop_summary`` dataset of a ``planner stops --out`` folder."""
    from planner.io.parquet import read_dataset

    try:
        t = read_dataset(stops_dir, "stop_summary", line=line_id)
    except (FileNotFoundError, OSError, pa.ArrowInvalid) as e:
        raise InputError(f"--stops {stops_dir}: cannot read the stop_summary dataset ({e}); run "
                         "`planner stops LINE --out DIR` first or leave --stops out") from None
    if "adhesion_kmh_s" not in t.column_names or t.num_rows == 0:
        raise InputError(f"--stops {stops_dir}: stop_summary has no adhesion_kmh_s rows for line {line_id}; "
                         "rebuild it with `planner stops`")
    vals = np.asarray(t.column("adhesion_kmh_s").to_numpy(zero_copy_only=False), dtype=float)
    return np.unique(np.round(vals[np.isfinite(vals)], 9))


def compute_margins(
    line: Line,
    *,
    rule: MarginRule = MarginRule(),
    train_types: Sequence[str] | None = None,
    tables_dir: str | Path | None = None,
    stops_dir: str | Path | None = None,
    closed_loop_dir: str | Path | None = None,
    ratios=None,
    adhesion_kmh_s=DEFAULT_ADHESION_KMH_S,
    approach_m: float = DEFAULT_APPROACH_M,
    after_departure_m: float | None = 200.0,
    eval_interval_m: float | None = None,
    chosen: tuple[str, str, str] | None = None,
    conflicts: bool = True,
    conflict_params=None,
    settings=None,
    n_jobs: int = 1,
    progress: Callable[[int, int], None] | None = None,
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
    adhesion_kmh_s : spec or list
        Adhesion sweep [km/h/s]; its lowest level is the degraded one.
    approach_m : float
        Pattern start before the stop marker where there is no TASC beacon [m].
    after_departure_m : float or None
        Evaluation point after departure for computed tables [m].
    eval_interval_m : float or None
        Interval of the odometer evaluation points for computed tables [m]; None: beacons only.
    chosen : (train_type, origin, destination), optional
        Leg whose run curves the report draws; default the row with the least
        remaining margin.
    conflicts : bool
        Check the timetable for route conflicts when the line has a track network.
    conflict_params : mapping or BlockingParams, optional
    settings : SimSettings, optional
    n_jobs : int
        joblib processes over legs (1 = this process).
    progress : callable ``(done, total)``, optional

    Returns
    -------
    MarginReport
    """
    import pandas as pd

    from planner.datasets.tables import load_tables

    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    for t in types:
        line.train_type(t)
    adh = _stops_adhesion(Path(stops_dir), line.line_id) if stops_dir is not None \
        else np.asarray(adhesion_levels(adhesion_kmh_s), dtype=float)
    legs = [lg for lg in timetable_legs(line) if lg.train_type in types]
    sched: dict[tuple, set] = {}
    for t in types:
        for d in DIRECTIONS:
            for a, b in line.interstations(d):
                sched.setdefault((d, t, a.station_id, b.station_id), set())
    for lg in legs:
        sched.setdefault((lg.direction, lg.train_type, lg.origin, lg.destination), set()).add(lg.scheduled_s)

    tabs: dict = {}
    energy: dict = {}
    if tables_dir is not None:
        for t in types:
            for d in DIRECTIONS:
                got = load_tables(tables_dir, line.line_id, d, t)
                en = _read_energy(Path(tables_dir), line.line_id, d, t)
                for (o, de), tb in got.items():
                    tabs[(d, t, o, de)] = tb
                    energy[(d, t, o, de)] = en.get((o, de))
    cl_index = _closed_loop_index(Path(closed_loop_dir), line.line_id, rule) if closed_loop_dir else {}

    kw = dict(ratios=ratios, rule=rule, adhesion_kmh_s=adh, approach_m=approach_m,
              after_departure_m=after_departure_m, eval_interval_m=eval_interval_m, settings=settings)

    def known_errors(key) -> dict:
        return {k[4:]: v for k, v in cl_index.items() if k[:4] == key}

    keys = sorted(sched, key=lambda k: (DIRECTIONS.index(k[0]), k[1],
                                        sign(k[0]) * line.station(k[2]).position_m,
                                        sign(k[0]) * line.station(k[3]).position_m))
    total = len(keys)
    if progress:
        progress(0, total)
    jobs = [(line, k[1], k[2], k[3], sorted(sched[k]), tabs.get(k), energy.get(k),
             kw | {"closed_loop_errors": known_errors(k)}) for k in keys]
    results: list[LegResult] = []
    if n_jobs == 1:
        it = (_leg_task(*j) for j in jobs)
    else:
        from joblib import Parallel, delayed

        it = Parallel(n_jobs=n_jobs, return_as="generator")(delayed(_leg_task)(*j) for j in jobs)
    for res in it:
        results.append(res)
        if progress:
            progress(len(results), total)

    trains_of: dict[tuple, list[str]] = {}
    for lg in legs:
        trains_of.setdefault((lg.direction, lg.train_type, lg.origin, lg.destination,
                              round(lg.scheduled_s, 6)), []).append(lg.train_id)
    recs, sweep = [], []
    for r in results:
        base = {
            "line": line.line_id, "direction": r.direction, "train_type": r.train_type,
            "origin": r.origin, "destination": r.destination, "passes": list(r.passes),
            "length_m": r.length_m, "min_running_time_s": r.min_time_s,
            "degraded_min_running_time_s": r.degraded_min_s, "slowest_running_time_s": r.slowest_time_s,
            "degraded_loss_running_s": r.degraded_loss_running_s, "degraded_loss_stop_s": r.degraded_loss_stop_s,
            "degraded_loss_load_s": r.degraded_loss_load_s, "degraded_loss_traction_s": r.degraded_loss_traction_s,
            "energy_at_full_ratio_kwh": r.energy_full_kwh, "pattern_start_m": r.pattern_start_m,
            "pattern_start_source": r.pattern_source,
            "pattern_start_speed_degraded_kmh": r.v_pattern_degraded_ms * 3.6,
            "stop_time_degraded_s": r.stop_time_degraded_s, "stop_time_nominal_s": r.stop_time_nominal_s,
            "adhesion_min_kmh_s": r.adhesion_min_kmh_s, "adhesion_loss_s": r.adhesion_loss_s,
            "tables_source": r.tables_source, "note": r.note,
        }
        for a, t in zip(r.sweep_adhesion_kmh_s, r.sweep_duration_s):
            sweep.append({"direction": r.direction, "train_type": r.train_type, "origin": r.origin,
                          "destination": r.destination, "adhesion_kmh_s": float(a), "stop_time_s": float(t)})
        if not r.schedules:
            recs.append(base | {"scheduled_running_time_s": math.nan, "n_trains": 0, "train_ids": [],
                                "ratio_on_time": math.nan, "arrival_error_s": math.nan,
                                "arrival_error_degraded_s": math.nan, "energy_at_ratio_kwh": math.nan})
        for sc in r.schedules:
            ids = sorted(trains_of.get((r.direction, r.train_type, r.origin, r.destination,
                                        round(sc["scheduled_s"], 6)), []))
            recs.append(base | {"scheduled_running_time_s": sc["scheduled_s"], "n_trains": len(ids),
                                "train_ids": ids, "ratio_on_time": sc["ratio_on_time"],
                                "arrival_error_s": sc["arrival_error_s"],
                                "arrival_error_degraded_s": sc["arrival_error_degraded_s"],
                                "energy_at_ratio_kwh": sc["energy_at_ratio_kwh"]})
    rows = pd.DataFrame.from_records(recs)
    cols = margin_columns(rows["min_running_time_s"].to_numpy(float),
                          rows["scheduled_running_time_s"].to_numpy(float),
                          rows["degraded_min_running_time_s"].to_numpy(float),
                          rows["slowest_running_time_s"].to_numpy(float), rows["length_m"].to_numpy(float), rule)
    for k, v in cols.items():
        rows[k] = v
    why = np.where(~np.isfinite(rows["min_running_time_s"].to_numpy(float)), "minimum running time unknown",
                   np.where(rows["note"].astype(str) != "", rows["note"].astype(str), "degraded minimum unknown"))
    rows["unassessed_reason"] = np.where(rows["unassessed"].to_numpy(bool), why, "")
    rows["energy_saved_kwh"] = rows["energy_at_full_ratio_kwh"] - rows["energy_at_ratio_kwh"]
    rows["energy_saved_percent"] = 100.0 * rows["energy_saved_kwh"] / rows["energy_at_full_ratio_kwh"]
    rows = rows[["line", "direction", "train_type"] + [f.name for f in MARGINS_SCHEMA]]

    tl = pd.DataFrame.from_records(
        [{"train_id": lg.train_id, "direction": lg.direction, "train_type": lg.train_type, "origin": lg.origin,
          "destination": lg.destination, "scheduled_running_time_s": lg.scheduled_s,
          "departure_s": lg.departure_s, "leg_seq": lg.leg_seq} for lg in legs],
        columns=["train_id", "direction", "train_type", "origin", "destination", "scheduled_running_time_s",
                 "departure_s", "leg_seq"])
    # the same float key on both sides (scheduled times come from the same subtraction)
    totals = margin_totals(rows, tl) if len(tl) else pd.DataFrame(columns=TOTALS_COLUMNS)
    totals.insert(0, "line", line.line_id)

    # the leg whose run curves are drawn
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
    curves = chosen_key = None
    if pick is not None:
        k = (pick.direction, pick.train_type, pick.origin, pick.destination)
        s = [] if not np.isfinite(pick.scheduled_running_time_s) else [float(pick.scheduled_running_time_s)]
        done = next(r for r in results if (r.direction, r.train_type, r.origin, r.destination) == k)
        lr = leg_result(line, k[1], k[2], k[3], s, tables=done.tables, energy_a_kwh=done.energy_a_kwh,
                        record=True, **kw)
        curves = lr.curves
        chosen_key = {"direction": k[0], "train_type": k[1], "origin": k[2], "destination": k[3],
                      "scheduled_running_time_s": float(pick.scheduled_running_time_s)}

    con, note = None, ""
    if conflicts:
        if line.network is None:
            note = "the line database has no track network (nodes.parquet, edges.parquet)"
        else:
            from planner.errors import PlannerError
            from planner.datasets.conflicts import conflicts_table

            try:
                con = conflicts_table(line, conflict_params)
            except PlannerError as e:
                note = f"the conflict check failed: {e}"
    else:
        note = "not checked (--no-conflicts)"
    return MarginReport(
        line_id=line.line_id, line_name=line.name, rule=rule, adhesion_kmh_s=adh, approach_m=approach_m,
        rows=rows.reset_index(drop=True), totals=totals, sweep=pd.DataFrame.from_records(sweep),
        curves=curves, chosen=chosen_key, conflicts=con, conflicts_note=note,
        sources={"tables_dataset": sum(r.tables_source == "dataset" for r in results),
                 "tables_computed": sum(r.tables_source == "computed" for r in results),
                 "closed_loop_dataset": bool(cl_index)},
    )


# =====================================================================================
# Datasets
# =====================================================================================

MARGINS_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure stop (station id) of the leg"),
        ("destination", pa.string(), "next stop (station id); stations in between are passed"),
        ("passes", pa.list_(pa.string()), "stations passed between the two stops, running order (empty: an interstation)"),
        ("length_m", pa.float64(), "leg length, stop marker to stop marker [m]"),
        ("scheduled_running_time_s", pa.float64(),
         "scheduled running time, arrival at the next stop - departure [s]; null: no train of this type runs the leg"),
        ("n_trains", pa.int32(), "timetabled trains with this leg and scheduled time"),
        ("train_ids", pa.list_(pa.string()), "those trains, sorted"),
        ("min_running_time_s", pa.float64(), "minimum running time: ratio 1.0, load 0, traction x 1.0 (table (a)) [s]"),
        ("min_running_time_rounded_s", pa.float64(), "minimum running time rounded up to the 10 s timetable unit [s]"),
        ("margin_s", pa.float64(), "scheduled - minimum running time [s]"),
        ("margin_percent", pa.float64(), "margin as a percentage of the minimum running time [%]"),
        ("degraded_min_running_time_s", pa.float64(),
         "minimum under degraded conditions: full load, weak traction to the pattern start, then the stopping "
         "pattern at the lowest adhesion [s]"),
        ("remaining_margin_s", pa.float64(), "scheduled - degraded minimum: the margin left on a bad day [s]"),
        ("degraded_loss_running_s", pa.float64(),
         "part of degraded - minimum due to load and traction: degraded run's time to the pattern start - nominal run's [s]"),
        ("degraded_loss_stop_s", pa.float64(),
         "part due to the stop at the bad day's adhesion: stop_time_degraded_s - stop_time_nominal_s (the "
         "adhesion effect; with adhesion off, the stopping brake from the degraded approach speed) [s]"),
        ("degraded_loss_load_s", pa.float64(),
         "share of degraded_loss_running_s due to the load: the bad day's load alone, nominal traction [s]"),
        ("degraded_loss_traction_s", pa.float64(),
         "share of degraded_loss_running_s due to weak traction, on top of the load: running - load share [s]"),
        ("supplement_required_s", pa.float64(), "supplement the rule asks for: percent of the minimum + minutes per 100 km [s]"),
        ("supplement_met", pa.bool_(), "margin >= required supplement"),
        ("supplement_shortfall_s", pa.float64(), "required supplement - margin, at least 0 [s]"),
        ("ratio_on_time", pa.float64(), "target-speed ratio the vehicle picks at an on-time departure (nearest table (a) time)"),
        ("arrival_error_s", pa.float64(), "closed-loop arrival error at the scheduled time, nominal; positive = late [s]"),
        ("arrival_error_degraded_s", pa.float64(),
         "closed-loop arrival error at the scheduled time under the degraded load and traction; positive = late [s]"),
        ("energy_at_ratio_kwh", pa.float64(), "table (a) traction energy at ratio_on_time [kWh]"),
        ("energy_at_full_ratio_kwh", pa.float64(), "table (a) traction energy at ratio 1.0 [kWh]"),
        ("energy_saved_kwh", pa.float64(), "energy the margin saves: at ratio 1.0 - at ratio_on_time [kWh]"),
        ("energy_saved_percent", pa.float64(), "energy saved as a percentage of the energy at ratio 1.0 [%]"),
        ("slowest_running_time_s", pa.float64(), "slowest table time (lowest ratio of table (a)) [s]"),
        ("pattern_start_m", pa.float64(), "chainage where the stopping pattern starts in the degraded run [m]"),
        ("pattern_start_source", pa.string(),
         "where that is: 'tasc' beacon, 'approach' distance; '+moved' when the lowest adhesion needed an earlier start"),
        ("pattern_start_speed_degraded_kmh", pa.float64(), "degraded run's speed at the pattern start [km/h]"),
        ("stop_time_degraded_s", pa.float64(), "stopping-pattern duration at the lowest adhesion from that speed [s]"),
        ("stop_time_nominal_s", pa.float64(),
         "nominal stop over the same approach with the bad day's stop model: the stopping pattern from the nominal "
         "minimum run's speed at the highest adhesion of the sweep, or the stopping brake when the adhesion effect "
         "is off [s]"),
        ("adhesion_min_kmh_s", pa.float64(),
         "adhesion of the bad day's stop: [margins] degraded_adhesion_kmh_s, else the sweep's lowest level [km/h/s]"),
        ("adhesion_loss_s", pa.float64(),
         "stopping-pattern duration at the lowest minus at the highest adhesion, nominal approach speed [s]"),
        ("infeasible", pa.bool_(), "flag: scheduled < degraded minimum"),
        ("tight", pa.bool_(), "flag: not infeasible, but remaining margin < tight_threshold_s"),
        ("unreachable", pa.bool_(), "flag: scheduled > slowest table time: the vehicle cannot stretch the run that long"),
        ("unassessed", pa.bool_(),
         "flag: the degraded minimum (or the minimum) could not be computed, see unassessed_reason; infeasible and "
         "tight are then null (unknown), remaining_margin_s null"),
        ("unassessed_reason", pa.string(), "why the leg could not be assessed; empty when assessed"),
        ("tables_source", pa.string(), "'dataset' (--tables) or 'computed'"),
        ("note", pa.string(), "anything unusual about the row, else empty"),
    ],
    name="margins",
    description="Margin-time report: minimum, scheduled and degraded running times per leg and scheduled time (DESIGN §6).",
)

TOTALS_COLUMNS = [
    "level", "train_id", "direction", "train_type", "origin", "destination", "first_departure_s", "n_trains",
    "n_legs", *TOTAL_SUM_COLS, "margin_percent", "min_remaining_margin_s", "bad_day_shortfall_s",
    "n_supplement_short",
    "n_infeasible", "n_tight", "n_unreachable", "n_unassessed",
]
MARGIN_TOTALS_SCHEMA = declare(
    [
        ("level", pa.string(),
         "what the row sums: 'train' (one train's legs), 'type' (every train of a direction x train type), "
         "'line' (every train of a direction; train_type partition 'all'). The levels repeat the same train runs, "
         "so sum within one level only (e.g. where level = 'train')"),
        ("train_id", pa.string(), "the train (level 'train'), else null"),
        ("origin", pa.string(), "the train's first stop (level 'train'), else null"),
        ("destination", pa.string(), "the train's last stop (level 'train'), else null"),
        ("first_departure_s", pa.float64(), "earliest departure of the legs summed [s after midnight]"),
        ("n_trains", pa.int32(), "trains summed"),
        ("n_legs", pa.int32(), "train runs of a leg summed (each train x stop to next stop once)"),
        ("min_running_time_s", pa.float64(), "sum of minimum running times [s]"),
        ("min_running_time_rounded_s", pa.float64(), "sum of the minimum running times rounded up to 10 s each [s]"),
        ("scheduled_running_time_s", pa.float64(), "sum of scheduled running times (dwells excluded) [s]"),
        ("margin_s", pa.float64(), "sum of margins [s]"),
        ("degraded_min_running_time_s", pa.float64(), "sum of degraded minimum running times [s]"),
        ("remaining_margin_s", pa.float64(), "sum of remaining margins under degraded conditions [s]"),
        ("supplement_required_s", pa.float64(), "sum of required supplements [s]"),
        ("energy_at_ratio_kwh", pa.float64(), "sum of traction energy at the on-time ratio [kWh]"),
        ("energy_at_full_ratio_kwh", pa.float64(), "sum of traction energy at ratio 1.0 [kWh]"),
        ("energy_saved_kwh", pa.float64(), "sum of energy saved by the margins [kWh]"),
        ("margin_percent", pa.float64(), "total margin / total minimum running time [%]"),
        ("min_remaining_margin_s", pa.float64(), "smallest remaining margin of any leg summed [s]"),
        ("bad_day_shortfall_s", pa.float64(),
         "sum over the legs of what each lacks on a bad day, max(0, -remaining margin): the time to add [s]"),
        ("n_supplement_short", pa.int32(), "train runs of a leg whose margin is below the required supplement"),
        ("n_infeasible", pa.int32(), "train runs of a leg flagged infeasible"),
        ("n_tight", pa.int32(), "train runs of a leg flagged tight"),
        ("n_unreachable", pa.int32(), "train runs of a leg flagged unreachable"),
        ("n_unassessed", pa.int32(),
         "train runs of a leg flagged unassessed; when > 0 the degraded and remaining sums, worst margin and "
         "shortfall are null"),
    ],
    name="margin_totals",
    description="Margin totals at three levels, told apart by `level`: per train, per direction x train type "
                "and per direction (DESIGN §6). Each level counts every train run once; filter on one level "
                "before summing.",
)
SCHEMAS = {"margins": MARGINS_SCHEMA, "margin_totals": MARGIN_TOTALS_SCHEMA}


def datasets(report: MarginReport) -> dict[str, pa.Table]:
    """The ``margins`` and ``margin_totals`` rows with partition columns."""
    import pandas as pd

    rows = report.rows.copy()
    rows["n_trains"] = rows["n_trains"].astype("int32")
    unknown = rows["unassessed"].to_numpy(bool)
    for c in ("infeasible", "tight"):  # undecidable on an unassessed leg: null, never a false "all clear"
        rows[c] = rows[c].astype("boolean")
        rows.loc[unknown, c] = pd.NA
    t = report.totals.copy()
    for c in ("n_trains", "n_legs", "n_supplement_short", "n_infeasible", "n_tight", "n_unreachable", "n_unassessed"):
        t[c] = t[c].astype("int32")
    return {
        "margins": pa.Table.from_pandas(rows, preserve_index=False),
        "margin_totals": pa.Table.from_pandas(t, preserve_index=False),
    }


def write_margins(report: MarginReport, out_dir: str | Path) -> list[Path]:
    """Write the ``margins`` and ``margin_totals`` datasets under ``out_dir`` (atomic per file, deterministic)."""
    sort = {"margins": ("origin", "destination", "scheduled_running_time_s"),
            "margin_totals": ("level", "train_id")}
    written: list[Path] = []
    for name, table in datasets(report).items():
        written += write_partitioned(table, Path(out_dir), name, schema=SCHEMAS[name], sort_by=sort[name])
    return written
