"""The margin report's datasets: ``margins`` and ``margin_totals`` (schemas, rows, writer), and its inputs.

Takes a :class:`planner.report.margins.MarginReport` and gives Arrow tables with
their declared schemas (units in the column names), written as partitioned
Parquet (:func:`write_margins`). Also reads what the report takes from other
steps' folders: table (a) energy (``planner tables``), the closed-loop errors
(``planner simulate``) and the adhesion levels of the stopping sweep
(``planner stops``).
"""
from __future__ import annotations

import dataclasses

from pathlib import Path

import numpy as np
import pyarrow as pa

from planner.errors import InputError
from planner.io.parquet import declare, read_dataset, write_partitioned
from planner.line.units import KMH_S
from planner.report.margin_rule import COUNTED

MARGINS_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure stop (station id) of the leg"),
        ("destination", pa.string(), "next stop (station id); stations in between are passed"),
        ("passes", pa.list_(pa.string()), "stations passed between the two stops, running order (empty: an interstation)"),
        ("length_m", pa.float64(), "leg length, stop marker to stop marker [m]"),
        ("scheduled_running_time_s", pa.float64(),
         "scheduled running time, arrival at the next stop - departure [s]; null: no train of this type runs the leg"),
        ("n_trains", pa.int32(), "timetabled trains with this leg, scheduled time and restrictions"),
        ("train_ids", pa.list_(pa.string()), "those trains, sorted"),
        ("restrictions", pa.list_(pa.string()),
         "ids of the temporary restrictions (daily feed) this row is computed with: those reaching the leg that "
         "apply to its trains by the time they pass (a leg has a row of its own for trains that run it while "
         "some are lifted); empty without any"),
        ("min_running_time_s", pa.float64(), "minimum running time: ratio 1.0, load 0, traction x 1.0 (table (a)) [s]"),
        ("min_running_time_rounded_s", pa.float64(), "minimum running time rounded up to the 10 s timetable unit [s]"),
        ("margin_s", pa.float64(), "scheduled - minimum running time [s]"),
        ("margin_percent", pa.float64(), "margin as a percentage of the minimum running time [%]"),
        ("degraded_min_running_time_s", pa.float64(),
         "bad-day minimum: the minimum running time under the bad day's conditions (full load, weak traction to "
         "the pattern start, then the stopping pattern at the lowest adhesion) [s]"),
        ("remaining_margin_s", pa.float64(), "bad-day margin: scheduled - bad-day minimum (degraded_min_running_time_s), the margin left on a bad day [s]"),
        ("degraded_loss_running_s", pa.float64(),
         "part of degraded - minimum due to load and traction: degraded run's time to the pattern start - nominal run's [s]"),
        ("degraded_loss_stop_s", pa.float64(),
         "part due to the stop at the bad day's adhesion: stop_time_degraded_s - stop_time_nominal_s (the "
         "adhesion effect; with adhesion off, the stopping brake from the degraded approach speed) [s]"),
        ("degraded_loss_load_s", pa.float64(),
         "share of degraded_loss_running_s due to the load: the bad day's load alone, nominal traction [s]"),
        ("degraded_loss_traction_s", pa.float64(),
         "share of degraded_loss_running_s due to weak traction, on top of the load: running - load share [s]"),
        ("degraded_loss_stop_model_s", pa.float64(),
         "part due to the stop model, not to the bad day: the nominal run to the pattern start plus stop_time_nominal_s "
         "(the stopping pattern) - min_running_time_s (table (a): the constant stopping brake) [s]. load + traction + "
         "stop + stop model = degraded_min_running_time_s - min_running_time_s"),
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
        ("adhesion_min_ms2", pa.float64(),
         "adhesion of the bad day's stop: [margins] degraded_adhesion_kmh_s, else the sweep's lowest level [m/s²]"),
        ("adhesion_min_kmh_s", pa.float64(), "the same in km/h/s, as the job writes it (rounded to 1e-9)"),
        ("adhesion_loss_s", pa.float64(),
         "stopping-pattern duration at the lowest minus at the highest adhesion, nominal approach speed [s]"),
        ("impossible", pa.bool_(),
         "flag: scheduled < minimum running time (margin_s < 0): no driving makes it, on any day; null when the "
         "minimum is unknown"),
        ("short_bad_day", pa.bool_(),
         "flag: not impossible, but scheduled < bad-day minimum: the leg runs late on a bad day, by "
         "-remaining_margin_s; null when unassessed"),
        ("infeasible", pa.bool_(),
         "impossible or short_bad_day (the flag before the two were told apart, kept so that queries and older runs "
         "still compare); null when unassessed and not impossible"),
        ("tight", pa.bool_(), "flag: not infeasible, but bad-day margin < tight_threshold_s"),
        ("unreachable", pa.bool_(), "flag: scheduled > slowest table time: the vehicle cannot stretch the run that long"),
        ("closed_loop_max_error_s", pa.float64(),
         "worst |arrival error| of the closed-loop sweep on this leg (designated times minimum ... + horizon, every "
         "scenario and mode of the job; closed_loop_summary has each) [s]; null: no closed loop for the leg "
         "(e.g. a rapid's leg passing stations, or planner margins without --closed-loop)"),
        ("inaccurate", pa.bool_(),
         "flag: closed_loop_max_error_s > [margins] arrival_error_threshold_s: the on-board logic misses the "
         "designated arrival by that much (e.g. a long leg without evaluation points)"),
        ("unassessed", pa.bool_(),
         "flag: the bad-day minimum (or the minimum) could not be computed, see unassessed_reason; short_bad_day, "
         "infeasible (unless impossible) and tight are then null (unknown), remaining_margin_s null"),
        ("unassessed_reason", pa.string(), "why the leg could not be assessed; empty when assessed"),
        ("flag_reason", pa.string(),
         "every flag of the row in words, '; ' between them, e.g. 'short on a bad day by 0.2 s: margin 19.8 s, the "
         "bad day costs 20.0 s (load 8.1, traction 6.0, adhesion 4.9, stop model 1.0 s), most of it the load'; "
         "empty without a flag"),
        ("bad_day_cause", pa.string(),
         "a leg short on a bad day or tight: the largest share of the bad day's cost, 'load', 'traction', "
         "'adhesion' (the stop at low adhesion) or 'stop_model'; else empty"),
        ("unassessed_cause", pa.string(),
         "the physical verdict behind an unassessed leg: 'stall' (the train cannot climb: tractive effort below "
         "resistance and gradient), 'no_stop' (no stopping pattern stops it at the marker), or empty"),
        ("unassessed_scenario", pa.string(),
         "under which conditions: 'bad_day' (the [margins] bad day) or 'nominal'; empty without a cause"),
        ("unassessed_position_m", pa.float64(),
         "where: chainage of the stall, or of the stop marker the train cannot stop at [m]; null without a cause"),
        ("tables_source", pa.string(), "'dataset' (--tables) or 'computed'"),
        ("note", pa.string(), "anything unusual about the row, else empty"),
    ],
    name="margins",
    description="Margin-time report: minimum, scheduled and degraded running times per leg and scheduled time (docs/design.md §6).",
)

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
        ("first_departure_clock", pa.string(), "the same as a clock time, HH:MM:SS (hours past 24 after midnight, "
                                               "as the timetable writes them)"),
        ("n_trains", pa.int32(), "trains summed"),
        ("n_legs", pa.int32(), "train runs of a leg summed (each train x stop to next stop once)"),
        ("min_running_time_s", pa.float64(), "sum of minimum running times [s]"),
        ("min_running_time_rounded_s", pa.float64(), "sum of the minimum running times rounded up to 10 s each [s]"),
        ("scheduled_running_time_s", pa.float64(), "sum of scheduled running times (dwells excluded) [s]"),
        ("margin_s", pa.float64(), "sum of margins [s]"),
        ("degraded_min_running_time_s", pa.float64(), "sum of bad-day minimum running times [s]"),
        ("remaining_margin_s", pa.float64(), "sum of bad-day margins [s]"),
        ("supplement_required_s", pa.float64(), "sum of required supplements [s]"),
        ("energy_at_ratio_kwh", pa.float64(), "sum of traction energy at the on-time ratio [kWh]"),
        ("energy_at_full_ratio_kwh", pa.float64(), "sum of traction energy at ratio 1.0 [kWh]"),
        ("energy_saved_kwh", pa.float64(), "sum of energy saved by the margins [kWh]"),
        ("margin_percent", pa.float64(), "total margin / total minimum running time [%]"),
        ("min_remaining_margin_s", pa.float64(), "smallest bad-day margin of any leg summed [s]"),
        ("bad_day_shortfall_s", pa.float64(),
         "sum over the legs of what each lacks on a bad day, max(0, -bad-day margin): the time to add [s]"),
        ("n_supplement_short", pa.int32(), "train runs of a leg whose margin is below the required supplement"),
        ("n_impossible", pa.int32(), "train runs of a leg flagged impossible (scheduled below the minimum)"),
        ("n_short_bad_day", pa.int32(), "train runs of a leg flagged short_bad_day (late on a bad day only)"),
        ("n_infeasible", pa.int32(), "train runs of a leg flagged infeasible: n_impossible + n_short_bad_day"),
        ("n_tight", pa.int32(), "train runs of a leg flagged tight"),
        ("n_unreachable", pa.int32(), "train runs of a leg flagged unreachable"),
        ("n_unassessed", pa.int32(),
         "train runs of a leg flagged unassessed; when > 0 the degraded and remaining sums, worst margin and "
         "shortfall are null"),
        ("n_inaccurate", pa.int32(), "train runs of a leg flagged inaccurate (the closed loop misses the arrival)"),
    ],
    name="margin_totals",
    description="Margin totals at three levels, told apart by `level`: per train, per direction x train type "
                "and per direction (docs/design.md §6). Each level counts every train run once; filter on one level "
                "before summing.",
)
SCHEMAS = {"margins": MARGINS_SCHEMA, "margin_totals": MARGIN_TOTALS_SCHEMA}


def datasets(report) -> dict[str, pa.Table]:
    """The ``margins`` and ``margin_totals`` rows with partition columns."""
    import pandas as pd

    rows = report.rows.copy()
    rows["n_trains"] = rows["n_trains"].astype("int32")
    unknown = rows["unassessed"].to_numpy(bool)
    impossible = rows["impossible"].to_numpy(bool)
    no_min = ~np.isfinite(rows["min_running_time_s"].to_numpy(float))
    # undecidable on an unassessed leg: null, never a false "all clear"; impossible needs only the minimum
    for c, unknown_at in (("short_bad_day", unknown), ("infeasible", unknown & ~impossible), ("tight", unknown),
                          ("impossible", no_min)):
        rows[c] = rows[c].astype("boolean")
        rows.loc[unknown_at, c] = pd.NA
    t = report.totals.copy()
    for c in ("n_trains", "n_legs", "n_supplement_short", *(f"n_{f}" for f in COUNTED)):
        t[c] = t[c].astype("int32")
    return {
        "margins": pa.Table.from_pandas(rows, preserve_index=False),
        "margin_totals": pa.Table.from_pandas(_with_clock(t), preserve_index=False),
    }


def _with_clock(totals):
    """The totals with ``first_departure_clock`` beside ``first_departure_s`` (the text a planner reads)."""
    from planner.line.units import clock

    return totals.assign(first_departure_clock=[clock(x) for x in totals["first_departure_s"]])


def write_margins(report, out_dir: str | Path) -> list[Path]:
    """Write the ``margins`` and ``margin_totals`` datasets under ``out_dir`` (atomic per file, deterministic)."""
    sort = {"margins": ("origin", "destination", "scheduled_running_time_s"),
            "margin_totals": ("level", "train_id")}
    written: list[Path] = []
    for name, table in datasets(report).items():
        written += write_partitioned(table, Path(out_dir), name, schema=SCHEMAS[name], sort_by=sort[name])
    return written


# --- inputs from other steps' folders ---------------------------------------------------

def read_energy(tables_dir: Path, line_id: str, direction: str, train_type: str) -> dict:
    """Table (a) energy per (origin, destination), ratios descending (load_tables does not carry it)."""
    ta = read_dataset(tables_dir, "table_a", line=line_id, direction=direction, train_type=train_type).to_pandas()
    out = {}
    for (o, d), a in ta.groupby(["origin", "destination"], sort=False):
        out[(o, d)] = a.sort_values("ratio", ascending=False)["energy_kwh"].to_numpy(float)
    return out


def closed_loop_index(closed_loop_dir: Path, line_id: str, rule, tables: dict | None = None,
                      times=None) -> dict:
    """Closed-loop errors (nearest rule) from a ``planner simulate`` folder, by leg, scenario, designated time
    (rounded to 6 places, as the margins look them up).

    ``perturbed`` runs stand for the degraded scenario only when their load and
    traction equal the rule's degraded ones. ``tables``: the ``closed_loop`` and ``closed_loop_summary``
    Arrow tables themselves (:func:`planner.datasets.closed_loop.datasets`: the rows the folder holds or
    is being written with), read instead of the folder. ``times``: the running times [s] that will be looked
    up (the timetable's scheduled ones); when given, only the designated times equal to one of them (6 places)
    are kept: the closed loop sweeps 61 designated times per leg and the margins look up a few, and on a line
    ten times the sample the whole sweep was 30 MB of the job process's memory.
    """
    import pyarrow.compute as pc

    from planner.tables.closed_loop import SCENARIOS

    if tables is not None:
        t = _line_rows(tables["closed_loop"], line_id)
    else:
        try:
            t = read_dataset(closed_loop_dir, "closed_loop", line=line_id)
        except (FileNotFoundError, OSError) as e:
            raise InputError(f"--closed-loop {closed_loop_dir}: cannot read the closed_loop dataset ({e}); "
                             "run `planner simulate` first or leave the option out") from None
    for c in ("scenario", "mode"):
        if c not in t.column_names:
            raise InputError(f"--closed-loop {closed_loop_dir}: closed_loop has no {c!r} partition; "
                             "rebuild it with `planner simulate`")
    p = SCENARIOS["perturbed"]
    names = {"nominal": "nominal"}
    if (p.load, p.traction_factor) == (rule.bad_load, rule.bad_traction):
        names["perturbed"] = "degraded"
    text = {c: pc.cast(t.column(c), pa.string()) for c in ("scenario", "mode")}
    t = t.filter(pc.and_(pc.equal(text["mode"], "nearest"), pc.is_in(text["scenario"], pa.array(list(names)))))
    wanted = None
    if times is not None:  # first the rows within a microsecond of one (a superset, in numpy), then exactly
        wanted = {round(float(x), 6) for x in times}
        t = t.filter(_near(t.column("designated_s").to_numpy(zero_copy_only=False).astype(float), wanted))
    # a column at a time (a Python object per row was most of the margins' start on the job's critical path)
    keys = [t.column(c).to_pylist() for c in ("direction", "train_type", "origin", "destination")]
    scen = [names[s] for s in pc.cast(t.column("scenario"), pa.string()).to_pylist()]
    designated = [round(x, 6) for x in t.column("designated_s").to_numpy(zero_copy_only=False).astype(float).tolist()]
    err = t.column("error_s").to_numpy(zero_copy_only=False).astype(float).tolist()
    return {(d, tt, o, de, s, x): e for d, tt, o, de, s, x, e in zip(*keys, scen, designated, err)
            if wanted is None or x in wanted}


@dataclasses.dataclass
class ClosedLoopFacts:
    """What the margins read of a line's closed loop, made where its rows are (the nightly job makes them on the
    worker that writes the closed loop's datasets, so the rows never come to the job process)."""

    index: dict = dataclasses.field(default_factory=dict)
    """:func:`closed_loop_index` (at the times the margins look up)."""
    worst: dict = dataclasses.field(default_factory=dict)
    """:func:`closed_loop_worst`."""

    def add(self, tables: dict, line_id: str, rule, times) -> None:
        """Add the facts of the ``closed_loop`` and ``closed_loop_summary`` Arrow tables ``tables``
        (:func:`planner.datasets.closed_loop.datasets`) of some of the line's legs (each leg's rows all in them).
        ``times``: the running times the margins look up (:func:`closed_loop_index`), or each leg's own
        (:func:`planner.report.margin_legs.looked_up_by_leg`): then a leg keeps its errors at its own times only."""
        if tables["closed_loop"].num_columns:  # no column at all: none of these legs has a run
            if isinstance(times, dict):
                own = {leg: {round(float(x), 6) for x in v} for leg, v in times.items()}
                index = closed_loop_index(Path("."), line_id, rule, tables, sorted(set().union(*own.values())))
                self.index.update((k, v) for k, v in index.items() if k[5] in own.get(k[:4], ()))
            else:
                self.index.update(closed_loop_index(Path("."), line_id, rule, tables, times))
        if tables["closed_loop_summary"].num_rows:
            self.worst.update(closed_loop_worst(Path("."), line_id, tables))

    def update(self, other: "ClosedLoopFacts") -> None:
        """Add another part's facts (of other legs)."""
        self.index.update(other.index)
        self.worst.update(other.worst)


def _near(x: np.ndarray, wanted: set) -> np.ndarray:
    """Which of ``x`` lie within 1e-6 of a value of ``wanted``: every one that rounds (6 places) to one of them."""
    w = np.array(sorted(wanted), dtype=float)
    if not w.size:
        return np.zeros(x.shape, dtype=bool)
    i = np.searchsorted(w, x)  # the wanted values either side of each x
    lo, hi = w[np.clip(i - 1, 0, w.size - 1)], w[np.clip(i, 0, w.size - 1)]
    return (np.abs(x - lo) <= 1e-6) | (np.abs(x - hi) <= 1e-6)


def closed_loop_worst(closed_loop_dir: Path, line_id: str, tables: dict | None = None) -> dict:
    """Worst |arrival error| per leg over every scenario and mode of a ``planner simulate`` folder [s],
    by (direction, train type, origin, destination); legs without a feasible run are left out.
    ``tables``: as for :func:`closed_loop_index`."""
    if tables is not None:
        t = _line_rows(tables["closed_loop_summary"], line_id).to_pandas()
    else:
        try:
            t = read_dataset(closed_loop_dir, "closed_loop_summary", line=line_id).to_pandas()
        except (FileNotFoundError, OSError):
            return {}
    if t.empty or "max_abs_error_s" not in t:
        return {}
    t = t[np.isfinite(t["max_abs_error_s"].to_numpy(float))]
    g = t.groupby([t[c].astype(str) for c in ("direction", "train_type", "origin", "destination")])
    return {k: float(v) for k, v in g["max_abs_error_s"].max().items()}


def _line_rows(table: pa.Table, line_id: str) -> pa.Table:
    """The rows of ``line_id`` of an Arrow table with a ``line`` column (what reading the dataset filtered by
    its ``line`` partition gives)."""
    import pyarrow.compute as pc

    mine = pc.equal(table.column("line"), line_id)
    if pc.all(mine, skip_nulls=False).as_py():  # a run's rows are one line's: the table, not a copy (44 MB at 10x)
        return table
    return table.filter(mine)


def stops_adhesion(stops_dir: Path, line_id: str) -> np.ndarray:
    """Adhesion levels [km/h/s] of the ``stop_summary`` dataset of a ``planner stops --out`` folder."""
    return stops_facts(stops_dir, line_id)[0]


def stops_facts(stops_dir: Path, line_id: str) -> tuple[np.ndarray, dict, dict]:
    """The ``stop_summary`` dataset of a ``planner stops --out`` folder: its adhesion levels [km/h/s] (every train
    type's), the approaches it has no pattern for, ``(train_type, direction, origin, station_id)`` → ``(levels
    [km/h/s] without a pattern, the first one's reason, the stop marker's chainage [m])`` (what the bundles hold,
    so the margin report's bad day never stops a train where they cannot: :func:`planner.report.margins.no_stop`),
    and each train type's own levels (capped by its brake), so that no type's bad day takes another's lowest
    level (a freight's 0.82 km/h/s made every passenger leg short on a bad day)."""
    try:
        t = read_dataset(stops_dir, "stop_summary", line=line_id)
    except (FileNotFoundError, OSError, pa.ArrowInvalid) as e:
        raise InputError(f"--stops {stops_dir}: cannot read the stop_summary dataset ({e}); run "
                         "`planner stops LINE --out DIR` first or leave --stops out") from None
    if "adhesion_ms2" not in t.column_names or t.num_rows == 0:
        raise InputError(f"--stops {stops_dir}: stop_summary has no adhesion_ms2 rows for line {line_id}; "
                         "rebuild it with `planner stops`")
    vals = np.asarray(t.column("adhesion_ms2").to_numpy(zero_copy_only=False), dtype=float) / KMH_S
    missing: dict[tuple, tuple[set, str, float]] = {}
    if {"feasible", "train_type", "direction", "origin", "station_id", "reason", "stop_m"} <= set(t.column_names):
        cols = {c: t.column(c).to_pylist() for c in ("train_type", "direction", "origin", "station_id", "reason",
                                                       "stop_m", "feasible")}
        for i in np.flatnonzero(~np.asarray(cols["feasible"], dtype=bool)).tolist():
            key = tuple(str(cols[c][i]) for c in ("train_type", "direction", "origin", "station_id"))
            levels, reason, stop_m = missing.setdefault(key, (set(), str(cols["reason"][i]), float(cols["stop_m"][i])))
            levels.add(round(float(vals[i]), 9))
    by_type: dict[str, np.ndarray] = {}
    if "train_type" in t.column_names:
        types = np.asarray(t.column("train_type").to_pylist(), dtype=object)
        for tt in sorted(set(types.tolist())):
            v = vals[types == tt]
            by_type[str(tt)] = np.unique(np.round(v[np.isfinite(v)], 9))
    # the levels as the job file spells them
    return np.unique(np.round(vals[np.isfinite(vals)], 9)), missing, by_type


def given_leg(tabs, energy):
    """A leg's given tables and table (a) energy: as given, or, given a reference to the tables step's stored result
    (anything with ``load()`` giving :class:`~planner.tables.build.InterstationTables`, e.g. the nightly job's
    :class:`planner.job.units.Stored`), read from it where the leg is computed: the vehicle's view of them
    (``onboard()``, the same numbers as the datasets :func:`given_tables` reads) and their energy per ratio."""
    if tabs is None or not hasattr(tabs, "load"):
        return tabs, energy
    built = tabs.load()
    return built.onboard(), np.asarray(built.energy_a_kwh, float)


def given_tables(line: Line, types: Sequence[str], tables_dir) -> tuple[dict, dict]:
    """The tables and table (a) energy of a ``--tables`` folder, by (direction, type, origin, destination)
    (:func:`compute_margins` reads them, unless given them read beforehand)."""
    from planner.datasets.tables import load_tables
    from planner.line.model import DIRECTIONS

    tabs: dict = {}
    energy: dict = {}
    if tables_dir is None:
        return tabs, energy
    for t in types:
        for d in DIRECTIONS:
            got = load_tables(tables_dir, line.line_id, d, t)
            en = read_energy(Path(tables_dir), line.line_id, d, t)
            for (o, de), tb in got.items():
                tabs[(d, t, o, de)] = tb
                energy[(d, t, o, de)] = en.get((o, de))
    return tabs, energy
