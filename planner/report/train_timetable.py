"""Running-time table per train: every station of its path, scheduled against computed times.

What a planner reads as OpenTrack's timetable output or OSRD's simulation table:
for every timetabled train, every call of its path (stops and passes) with

* the **scheduled** arrival, departure and passing times (the timetable);
* the **computed** ones: each leg (stop to next stop) run from its scheduled
  departure at the ratio the on-board logic picks for an on-time departure
  (``ratio_on_time`` of the ``margins`` dataset: the nearest table (a) time to
  the scheduled one), so a computed arrival is where the train would be if it
  left on time and held that ratio; departures are the scheduled ones (a
  train leaves on time, and a leg's computed times never carry a delay of the
  leg before);
* the **minimum** run (ratio 1.0: table (a)'s first row), the same way;
* the **running-time supplement** of each section (call to call): scheduled
  section time − minimum section time; the supplements of a leg add up to its
  margin (scheduled − minimum running time);
* the leg's margin, bad-day margin and flags, from ``margins``,
  on the row of the stop that ends the leg.

Nothing here has physics of its own: the ratio and the leg's figures are the
margin report's rows; the times at the passed stations come from the one
run-curve integrator (:func:`planner.physics.run_curve.simulate`) on the leg's
track at the table conditions (load 0, traction × 1), i.e. table (a)'s runs at
those two ratios recorded along the way. The same recorded runs draw the
speed–distance charts (:mod:`planner.pages.speed_chart`).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
import pyarrow as pa

from planner.errors import PlannerError
from planner.io.parquet import declare, write_partitioned

TIMETABLE_SCHEMA = declare(
    [
        ("train_id", pa.string(), "train number"),
        ("seq", pa.int32(), "call order along the train's path, from 0"),
        ("station_id", pa.string(), "station id"),
        ("station_name", pa.string(), "station name"),
        ("position_m", pa.float64(), "chainage of the station [m]"),
        ("activity", pa.string(), "'departs' (first call), 'stops', 'passes' or 'arrives' (last call)"),
        ("scheduled_arrival", pa.string(), "scheduled arrival or passing time HH:MM:SS (past 24 after midnight); null at the first call"),
        ("scheduled_departure", pa.string(), "scheduled departure or passing time HH:MM:SS; null at the last call"),
        ("computed_arrival", pa.string(),
         "arrival or passing time of the run at the leg's ratio_on_time from the leg's scheduled departure, HH:MM:SS"),
        ("computed_departure", pa.string(), "computed departure HH:MM:SS: the scheduled one (an on-time departure); "
                                            "at a pass, the computed passing time"),
        ("minimum_arrival", pa.string(), "arrival or passing time of the minimum run (ratio 1.0) from the leg's "
                                         "scheduled departure, HH:MM:SS"),
        ("scheduled_arrival_s", pa.float64(), "scheduled_arrival in seconds after midnight of the timetable day [s]"),
        ("scheduled_departure_s", pa.float64(), "scheduled_departure in seconds after midnight [s]"),
        ("computed_arrival_s", pa.float64(), "computed_arrival in seconds after midnight [s]"),
        ("computed_departure_s", pa.float64(), "computed_departure in seconds after midnight [s]"),
        ("minimum_arrival_s", pa.float64(), "minimum_arrival in seconds after midnight [s]"),
        ("section_scheduled_s", pa.float64(),
         "scheduled time of the section from the previous call (its departure or pass) to this one [s]; null at the first call"),
        ("section_minimum_s", pa.float64(), "minimum running time of that section (ratio 1.0) [s]"),
        ("supplement_s", pa.float64(),
         "running-time supplement of the section: section_scheduled_s - section_minimum_s [s]; the supplements of a "
         "leg add up to its margin"),
        ("supplement_percent", pa.float64(), "supplement_s as a percentage of section_minimum_s [%]"),
        ("leg_origin", pa.string(), "the stop where the leg this call belongs to starts (null at the first call)"),
        ("ratio_on_time", pa.float64(), "the leg's ratio at an on-time departure (margins.ratio_on_time)"),
        ("leg_scheduled_running_time_s", pa.float64(), "at the stop ending a leg: its scheduled running time [s]"),
        ("leg_min_running_time_s", pa.float64(), "at the stop ending a leg: its minimum running time, table (a) [s]"),
        ("leg_margin_s", pa.float64(), "at the stop ending a leg: scheduled - minimum running time (margins.margin_s) [s]"),
        ("leg_remaining_margin_s", pa.float64(),
         "at the stop ending a leg: scheduled - bad-day minimum (margins.remaining_margin_s) [s]; null: unassessed"),
        ("leg_flag", pa.string(), "at the stop ending a leg: its worst margin-report flag, or 'ok'"),
        ("chart", pa.string(), "the leg's speed-distance chart page, relative to the run folder"),
        ("predicted_arrival", pa.string(), "predicted arrival HH:MM:SS: the day as it will run, every delay carried "
                                           "forward (delay_events; docs/robustness.md); null at a pass and the first call"),
        ("predicted_departure", pa.string(), "predicted departure HH:MM:SS, never before the predicted arrival + the "
                                             "minimum dwell; null at a pass and the last call"),
        ("predicted_arrival_s", pa.float64(), "predicted_arrival in seconds after midnight [s]"),
        ("predicted_departure_s", pa.float64(), "predicted_departure in seconds after midnight [s]"),
        ("delay_s", pa.float64(), "predicted − scheduled time at the stop: the arrival's, at the first call the "
                                  "departure's [s]; null at a pass"),
        ("delay_cause", pa.string(), "why the train is later here than at its call before (its own leg, the minimum "
                                     "dwell, or held by which train where); empty when the delay only carries on"),
    ],
    name="train_timetable",
    description="Running-time table per train: scheduled, computed (on-time ratio) and minimum times at every call.",
)
SCHEMAS = {"train_timetable": TIMETABLE_SCHEMA}
CHARTS_DIR = "charts"
"""Folder of the speed–distance chart pages in a run (``charts/<line>/<leg>.html``)."""


def clock(t: float) -> str | None:
    """Seconds after midnight → ``HH:MM:SS`` (hours past 24 after midnight); None when unknown."""
    if t is None or not math.isfinite(t):
        return None
    n = int(round(t))
    return f"{n // 3600:02d}:{n // 60 % 60:02d}:{n % 60:02d}"


def leg_key(direction: str, train_type: str, origin: str, destination: str, scheduled_s: float,
            lifted: tuple[str, ...] = ()) -> tuple:
    """A margins row's leg: direction, type, stops, scheduled time and, for the row of trains that pass while
    some of the day's temporary restrictions are lifted, their ids (:mod:`planner.report.margin_legs`)."""
    key = (direction, train_type, origin, destination, round(float(scheduled_s), 6))
    return key + (tuple(lifted),) if lifted else key


def leg_line(line, key: tuple):
    """The line the run of leg ``key`` is on: the day's line, less the restrictions its key lifts."""
    from planner.line.operating_day import without_temporary

    return without_temporary(line, key[5]) if len(key) > 5 else line


def row_lifted(line, row: dict, window=None) -> tuple[str, ...]:
    """The temporary restrictions reaching a margins row's leg that its ``restrictions`` leave out; ``window``: the
    line's window of an interstation (``Line.window``'s arguments), default ``line.window``."""
    from planner.report.margin_legs import applied_restrictions

    got = row.get("restrictions")
    if got is None:  # a run before the column: every restriction applied
        return ()
    d, t = row["direction"], row["train_type"]
    have = {str(x) for x in got}
    win = (window or line.window)(row["origin"], row["destination"], t)
    return tuple(x for x in applied_restrictions(win, d, t) if x not in have)


def chart_name(line_id: str, key: tuple) -> str:
    """Relative path (from the run folder) of a leg's chart page."""
    import hashlib

    from planner.io.paths import check_path_id, is_path_id

    d, t, o, de, s = key[:5]
    s_txt = f"{s:.0f}" if float(s).is_integer() else f"{s:.1f}"
    off = "".join(f"_without-{x}" for x in (key[5] if len(key) > 5 else ()))
    name = f"{d}_{t}_{o}-{de}_{s_txt}s{off}"
    if not is_path_id(name):  # station ids may be any text (unicode, '/', '<'): a digest names the leg
        leg = hashlib.sha256("\0".join((o, de) + (key[5] if len(key) > 5 else ())).encode()).hexdigest()[:12]
        name = f"{d}_{t}_leg-{leg}_{s_txt}s"
    return f"{CHARTS_DIR}/{check_path_id(line_id, 'line id')}/{check_path_id(name, 'chart name')}.html"


@dataclass
class LegRun:
    """A leg's two recorded runs: at the on-time ratio (row 0) and the minimum, ratio 1.0 (row 1)."""

    key: tuple
    ratio: float
    position_m: np.ndarray  # chainage of each grid node
    t_s: np.ndarray  # (2, m) time since departure [s]
    v_ms: np.ndarray  # (2, m) speed [m/s]
    vmax_ms: np.ndarray  # on-board maximum per node [m/s]
    row: dict  # the margins row

    @property
    def span_m(self) -> tuple[float, float]:
        """The lowest and highest chainage of the run [m]."""
        return float(np.min(self.position_m)), float(np.max(self.position_m))

    def end_s(self, run: int) -> float:
        """Running time of run ``run`` to the arrival stop marker [s]."""
        return float(self.t_s[run][-1])

    def time_at(self, chainage_m, run: int):
        """Time since departure when the front passes ``chainage_m`` (a number, or an array of them) [s]."""
        x, t = self.position_m, self.t_s[run]
        if len(x) > 1 and x[-1] < x[0]:  # an up run: chainage falls along the grid (monotone, so reversed is sorted)
            x, t = x[::-1], t[::-1]
        got = np.interp(chainage_m, x, t)
        return float(got) if np.ndim(got) == 0 else got

    def times(self, chainages_m: np.ndarray) -> "LegTimes":
        """What the tables page and the chart pages read of the two runs, at those of the given chainages (sorted)
        that lie inside the run and at its two ends (a time outside the run is the time at its nearer end, as
        :meth:`time_at` gives it)."""
        lo, hi = self.span_m
        x = np.unique(np.concatenate([chainages_m[(chainages_m > lo) & (chainages_m < hi)], [lo, hi]]))
        at = np.array([self.time_at(x, 0), self.time_at(x, 1)]).reshape(2, len(x))
        return LegTimes(self.key, self.ratio, self.row, self.span_m, (self.end_s(0), self.end_s(1)), x, at)


@dataclass
class LegTimes:
    """A leg's two runs as the job's process keeps them (:meth:`LegRun.times`): their ends and the times at the
    line's stations inside the run, without the runs' node arrays (on a line ten times the sample those were a
    hundred megabytes through the job's last steps; the times at every station of the line, 200 MB on a line a
    hundred times the sample). The tables page reads the times from it as from the
    :class:`LegRun` (the same numbers: the same interpolation, made beforehand); the charts' workers record the
    run again."""

    key: tuple
    ratio: float
    row: dict
    span_m: tuple[float, float]
    end: tuple[float, float]
    chainage_m: np.ndarray  # sorted chainages with a time: the line's stations inside the run, and its two ends
    at_s: np.ndarray  # (2, n) the runs' times there [s]

    def end_s(self, run: int) -> float:
        return self.end[run]

    def time_at(self, chainage_m: float, run: int) -> float:
        chainage_m = min(max(chainage_m, self.span_m[0]), self.span_m[1])  # outside the run: its nearer end
        i = int(np.searchsorted(self.chainage_m, chainage_m))
        if i == len(self.chainage_m) or self.chainage_m[i] != chainage_m:
            raise KeyError(f"leg {self.key}: no time kept at chainage {chainage_m} m "
                           "(only at the line's stations inside the run)")
        return float(self.at_s[run, i])


def record_leg(win, key: tuple, row: dict, ds_m: float) -> LegRun:
    """The leg ``key``'s two runs, on ``win``: its line (:func:`leg_line`) windowed to the leg
    (:meth:`planner.line.model.Line.window`, what its tables are computed on), at the row's on-time ratio."""
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings, make_track

    _d, tt, o, de = key[:4]
    track = make_track(win, tt, o, de, settings=SimSettings(ds_m=ds_m))
    ratio = float(row["ratio_on_time"])
    res = simulate(track, win.train_type(tt), np.array([ratio, 1.0]), record=True)
    # copies of the two rows kept: views would hold the run's whole record (five quantities) for every leg
    return LegRun(key, ratio, np.asarray(track.chainage_m, float), np.array(res.t_s, float),
                  np.array(res.v_ms, float), np.asarray(track.vmax_ms, float), row)


def legs(line, margins, window=None) -> Iterator[tuple[tuple, dict]]:
    """Every timetabled leg × scheduled time of a ``margins`` table (pandas) with an on-time ratio: its key and
    its row (``window``: as :func:`row_lifted`'s)."""
    has = margins[margins["scheduled_running_time_s"].notna() & margins["ratio_on_time"].notna()]
    for row in has.to_dict("records"):
        yield leg_key(row["direction"], row["train_type"], row["origin"], row["destination"],
                      row["scheduled_running_time_s"], row_lifted(line, row, window)), row


def leg_window(line, key: tuple, window=None):
    """The window :func:`record_leg` runs leg ``key`` on: its line (:func:`leg_line`) between its two stops;
    ``window``: as :func:`row_lifted`'s, used where the leg runs on ``line`` itself (no restriction lifted)."""
    on = leg_line(line, key)
    return (window if window is not None and on is line else on.window)(key[2], key[3], key[1])


def leg_runs(line, margins, ds_m: float = 1.0) -> dict[tuple, LegRun]:
    """The recorded runs of every timetabled leg × scheduled time of a ``margins`` table (pandas)."""
    return dict(_recorded(planned_legs(line, margins), ds_m))


@dataclass(frozen=True)
class Leg:
    """A timetabled leg × scheduled time before it is run: what its chart's key and page read (its key, on-time
    ratio, margins row and the chainages its run spans, :func:`leg_span`). The job's process knows its legs this
    way; their runs are recorded on the workers (:func:`leg_times_of`)."""

    key: tuple
    ratio: float
    row: dict
    span_m: tuple[float, float]


def leg_span(win, key: tuple) -> tuple[float, float]:
    """The lowest and highest chainage of leg ``key``'s run on its window ``win`` without running it: the
    departure stop marker and the marker plus the leg's length along the direction, the two ends of
    :func:`planner.physics.track.make_track`'s grid (so :attr:`LegRun.span_m` to the bit)."""
    ext = win.run_between(key[2], key[3])
    x0 = float(ext.start_m)
    x1 = float(x0 + ext.sign * ext.length_m)
    return min(x0, x1), max(x0, x1)


def planned_legs(line, margins) -> dict[tuple, tuple[Leg, object]]:
    """Every timetabled leg × scheduled time of a ``margins`` table (pandas) with an on-time ratio, not run:
    its :class:`Leg` and its window (:func:`leg_window`). A leg whose window cannot be made is left out."""
    out = {}
    # the line's window of each interstation and type, made once for this call: its rows (one per scheduled time)
    # and their restrictions share it (made twice per row, it was 1.4 s of the job at 100x)
    window = functools.cache(line.window)
    for key, row in legs(line, margins, window):
        try:
            win = leg_window(line, key, window)
            out[key] = (Leg(key, float(row["ratio_on_time"]), row, leg_span(win, key)), win)
        except PlannerError:
            continue
    return out


def station_chainages(line) -> np.ndarray:
    """The line's station chainages, sorted and unique: where a leg's times are kept (:meth:`LegRun.times`)."""
    return np.unique(np.array([float(s.position_m) for s in line.stations], float))


def leg_times_of(planned: dict[tuple, tuple[Leg, object]], at: np.ndarray, ds_m: float = 1.0
                 ) -> dict[tuple, LegTimes]:
    """The legs ``planned`` (:func:`planned_legs`) run (:func:`record_leg`), each kept as its :class:`LegTimes`
    at the chainages ``at`` inside it (:func:`station_chainages`): a run's node arrays are let go as soon as it
    is summed up. A leg that stalls at its on-time ratio is left out (:func:`_recorded`)."""
    return {key: run.times(at) for key, run in _recorded(planned, ds_m)}


def _recorded(planned: dict[tuple, tuple[Leg, object]], ds_m: float) -> Iterator[tuple[tuple, LegRun]]:
    """Each leg of ``planned`` run on its window (:func:`record_leg`), with its key. A leg that stalls at its
    on-time ratio is left out: it has no computed times, its rows stay null (its chart, drawn on its own worker,
    is left out the same way: :func:`planner.job.train_views._chart_task`)."""
    for key, (leg, win) in planned.items():
        try:
            run = record_leg(win, key, leg.row, ds_m)
        except PlannerError:
            continue
        yield key, run


def leg_times(line, margins, ds_m: float = 1.0) -> dict[tuple, LegTimes]:
    """:func:`leg_runs`, each run kept as its :class:`LegTimes` at the line's stations inside it
    (:func:`leg_times_of` of :func:`planned_legs`)."""
    return leg_times_of(planned_legs(line, margins), station_chainages(line), ds_m)


def _flag(row: dict) -> str:
    """The worst flag of a margins row given as a dict (null flags, an unassessed leg's, count as unset)."""
    from types import SimpleNamespace

    from planner.report.leg_flags import FLAGS, flag_of

    return flag_of(SimpleNamespace(**{f: row.get(f) for f in FLAGS}))


def row_fields() -> tuple[str, ...]:
    """The fields of a margins row that :func:`timetable_rows` reads (beside the run's own: its key and ratio):
    what a section's tables unit digests of each leg's row (:func:`planner.job.train_views.timetable_units`)."""
    from planner.report.leg_flags import FLAGS

    return ("train_ids", "scheduled_running_time_s", "min_running_time_s", "margin_s", "remaining_margin_s") + FLAGS


def timetable_rows(line, runs: dict[tuple, LegRun | LegTimes], train_types=None, predicted=None) -> list[dict]:
    """One record per call of every train (columns of :data:`TIMETABLE_SCHEMA` plus direction, train_type),
    of the given train types (default every one). ``predicted``: the predicted day's events (the ``delay_events``
    frame), or None (the predicted columns are null)."""
    pred = predicted_calls(predicted)
    nan = math.nan
    recs = []
    # a leg with a row for the trains that pass while a restriction is lifted: each train its own row's run
    own = {(k[:5], tid): r for k, r in runs.items()
           for tid in (r.row.get("train_ids") if r.row.get("train_ids") is not None else ())}
    for tr in line.trains:
        if train_types is not None and tr.train_type not in train_types:
            continue
        last = len(tr.calls) - 1
        leg_of = {}  # call index -> (start call index, end call index, the leg's key)
        for a, b, key in train_legs(tr):
            for k in range(a + 1, b + 1):
                leg_of[k] = (a, b, key)
        prev_sched = prev_min = nan
        for k, c in enumerate(tr.calls):
            st = line.station(c.station_id)
            act = "departs" if k == 0 else "arrives" if k == last else "stops" if c.stops else "passes"
            arr_s = nan if k == 0 else float(c.arrival_s)
            dep_s = nan if k == last else float(c.departure_s)
            rec = {"direction": tr.direction, "train_type": tr.train_type, "train_id": tr.train_id, "seq": k,
                   "station_id": c.station_id, "station_name": st.name, "position_m": float(st.position_m),
                   "activity": act, "scheduled_arrival_s": arr_s, "scheduled_departure_s": dep_s,
                   "computed_arrival_s": nan, "computed_departure_s": dep_s, "minimum_arrival_s": nan,
                   "section_scheduled_s": nan, "section_minimum_s": nan, "supplement_s": nan,
                   "supplement_percent": nan, "leg_origin": None, "ratio_on_time": nan,
                   "leg_scheduled_running_time_s": nan, "leg_min_running_time_s": nan, "leg_margin_s": nan,
                   "leg_remaining_margin_s": nan, "leg_flag": None, "chart": None}
            if k in leg_of:
                a, b, key = leg_of[k]
                ca = tr.calls[a]
                dep0 = float(ca.departure_s)
                run = own.get((key, tr.train_id), runs.get(key))
                rec["leg_origin"] = ca.station_id
                if run is not None:
                    end = k == b
                    # the stop itself: the run's end (the stop marker); a pass: the front at the station
                    t_r = run.end_s(0) if end else run.time_at(st.position_m, 0)
                    t_m = run.end_s(1) if end else run.time_at(st.position_m, 1)
                    rec["computed_arrival_s"] = dep0 + t_r
                    rec["minimum_arrival_s"] = dep0 + t_m
                    if not end:
                        rec["computed_departure_s"] = dep0 + t_r
                    rec["ratio_on_time"] = run.ratio
                    rec["chart"] = chart_name(line.line_id, run.key)
                    sec_min = t_m - (0.0 if k - 1 == a else prev_min)
                    sec_sched = float(c.arrival_s) - prev_sched
                    rec["section_scheduled_s"] = sec_sched
                    rec["section_minimum_s"] = sec_min
                    rec["supplement_s"] = sec_sched - sec_min
                    rec["supplement_percent"] = 100.0 * (sec_sched - sec_min) / sec_min if sec_min > 0 else nan
                    prev_min = t_m
                    if end:
                        row = run.row
                        rec["leg_scheduled_running_time_s"] = float(row["scheduled_running_time_s"])
                        rec["leg_min_running_time_s"] = float(row["min_running_time_s"])
                        rec["leg_margin_s"] = float(row["margin_s"])
                        rm = row.get("remaining_margin_s")
                        rec["leg_remaining_margin_s"] = float(rm) if rm is not None else nan
                        rec["leg_flag"] = _flag(row)
            prev_sched = dep_s if k != last else nan
            p_arr, c_arr = pred.get((tr.train_id, c.seq, "arrival"), (nan, ""))
            p_dep, c_dep = pred.get((tr.train_id, c.seq, "departure"), (nan, ""))
            rec["predicted_arrival_s"], rec["predicted_departure_s"] = p_arr, p_dep
            rec["delay_s"] = (p_arr - arr_s if not math.isnan(p_arr) else p_dep - dep_s
                              if not math.isnan(p_dep) else nan)  # the one NaN: records compare equal
            rec["delay_cause"] = "; ".join(x for x in (c_arr, c_dep) if x)
            for col in ("scheduled_arrival", "scheduled_departure", "computed_arrival", "computed_departure",
                        "minimum_arrival", "predicted_arrival", "predicted_departure"):
                rec[col] = clock(rec[col + "_s"])
            recs.append(rec)
    return recs


def train_legs(train) -> list[tuple[int, int, tuple]]:
    """A train's legs, stop to next stop: the two calls' indices and the leg's key (:func:`leg_key`, without the
    restrictions lifted: the first five fields of a margins row's key)."""
    stops = train.stop_indices()
    out = []
    for a, b in zip(stops[:-1], stops[1:]):
        ca, cb = train.calls[a], train.calls[b]
        out.append((a, b, leg_key(train.direction, train.train_type, ca.station_id, cb.station_id,
                                  float(cb.arrival_s) - float(ca.departure_s))))
    return out


def predicted_calls(events) -> dict:
    """``(train_id, call seq, "arrival" | "departure")`` → (predicted time [s], cause) of a ``delay_events`` frame."""
    if events is None or not len(events):
        return {}
    return {(t, int(q), e): (float(p), c) for t, q, e, p, c in
            zip(events["train_id"], events["seq"], events["event"], events["predicted_s"], events["cause"])}


def timetable_table(line, runs: dict[tuple, LegRun], train_types=None, records: list[dict] | None = None) -> pa.Table:
    """The ``train_timetable`` rows of a line with the partition columns (``line, direction, train_type``);
    ``records``: what :func:`timetable_rows` gives for the same arguments, when already made (not changed here)."""
    import pandas as pd

    recs = timetable_rows(line, runs, train_types) if records is None else records
    if not recs:  # no train runs (an operating day without service, or no train of these types): no rows
        keys = [pa.field(c, pa.string()) for c in ("line", "direction", "train_type")]
        return pa.schema(keys + list(TIMETABLE_SCHEMA)).empty_table()
    df = pd.DataFrame.from_records(recs)
    df.insert(0, "line", line.line_id)
    df["seq"] = df["seq"].astype("int32")
    return pa.Table.from_pandas(df, preserve_index=False)


def write_timetable(line, runs: dict[tuple, LegRun], out_dir: str | Path, train_types=None,
                    records: list[dict] | None = None) -> list[Path]:
    """Write the ``train_timetable`` dataset of a line (its trains of ``train_types``, default all) under
    ``out_dir``; the files written. ``records``: as for :func:`timetable_table`."""
    return write_timetable_table(timetable_table(line, runs, train_types, records), out_dir)


def write_timetable_table(table: pa.Table, out_dir: str | Path) -> list[Path]:
    """Write rows of :func:`timetable_table` (a line's, or its sections' put together in any order: each file's rows
    are sorted by train and call) as the ``train_timetable`` dataset under ``out_dir``; the files written."""
    return write_partitioned(table, Path(out_dir), "train_timetable", schema=TIMETABLE_SCHEMA,
                             sort_by=("train_id", "seq"))


__all__ = ["TIMETABLE_SCHEMA", "SCHEMAS", "CHARTS_DIR", "clock", "leg_key", "chart_name", "LegRun", "LegTimes",
           "Leg", "leg_runs", "leg_span", "leg_times", "leg_times_of", "leg_window", "legs",
           "planned_legs", "station_chainages", "record_leg", "row_fields", "timetable_rows", "train_legs",
           "timetable_table", "write_timetable", "write_timetable_table"]
