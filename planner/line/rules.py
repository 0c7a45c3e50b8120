"""Stage 2 of validation: the row and cross-table rules of a line database (docs/line-database.md).

Each rule is a small function registered with :func:`rule`, naming the tables it
needs; it runs only when all of them passed stage 1 (:mod:`planner.line.conform`)
and yields every :class:`~planner.errors.Violation` it finds (file, row, column,
what to write instead).

Takes :class:`~planner.line.conform.TableView` s; gives violations.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

import numpy as np

from planner.errors import Violation
from planner.line.units import KMH, KMH_S2
from planner.line.schema import (
    BEACON_KINDS,
    CRUISE_MODES,
    DIRECTIONS,
    LIMIT_DIRECTIONS,
    MAX_ROWS_PER_M,
    NODE_KINDS,
    PATH_ID_COLUMNS,
    RUNNING_SIDES,
    SCHEMA_VERSION,
    TABLES,
    TRACK_DIRECTIONS,
)
from planner.io.paths import PATH_ID_RULE, is_path_id
from planner.line.conform import TableView, fmt


# --------------------------------------------------------------------------- stage 2: rules
@dataclass(eq=False)
class Db:
    """What the rules see: the conforming tables and the line folder's name."""

    folder_name: str
    tables: dict[str, TableView]
    present: frozenset[str]

    def line_range(self) -> tuple[float, float] | None:
        """(start_m, end_m) of the line when line.parquet is usable and start < end."""
        line = self.tables.get("line")
        if line is None or line.n != 1 or not line.good[0]:
            return None
        a, b = float(line["start_m"][0]), float(line["end_m"][0])
        return (a, b) if a < b else None

    def station_positions(self) -> dict[str, float]:
        st = self.tables["stations"]
        pos: dict[str, float] = {}
        for i in st.rows():  # first row wins for a duplicate id (reported by station_rules)
            pos.setdefault(st["station_id"][i], float(st["position_m"][i]))
        return pos


Rule = Callable[[Db], Iterable[Violation]]


RULES: list[tuple[tuple[str, ...], Rule]] = []


ADVICE: list[tuple[tuple[str, ...], Rule]] = []
"""Rules whose findings are warnings: legitimate on some railways, so reported, never refused."""


def rule(*needs: str, warning: bool = False) -> Callable[[Rule], Rule]:
    """Register a rule that runs when every table in ``needs`` passed stage 1 (``warning``: into ADVICE)."""

    def deco(fn: Rule) -> Rule:
        (ADVICE if warning else RULES).append((needs, fn))
        return fn

    return deco


# ---- generic checks, used by several tables
def unique(t: TableView, column: str) -> Iterator[Violation]:
    seen: dict[str, int] = {}
    for i in t.rows():
        v = t[column][i]
        if v == "":
            yield t.err(i, column, f"{column} is empty")
        elif v in seen:
            yield t.err(i, column, f"duplicate {column} {v!r}; also in row {seen[v]}")
        else:
            seen[v] = i


def one_of(t: TableView, column: str, allowed: tuple[str, ...]) -> Iterator[Violation]:
    for i in t.rows():
        v = t[column][i]
        if v not in allowed:
            yield t.err(i, column, f"{v!r} is not one of {', '.join(allowed)}")


def _where(t: TableView, bad: np.ndarray) -> list[int]:
    """Usable rows where the boolean array ``bad`` holds, in file order (vectorised: large tables)."""
    return [int(i) for i in np.flatnonzero(t.good & bad)]


def _num(t: TableView, column: str) -> np.ndarray:
    return np.asarray(t[column], dtype=np.float64)


def inside(db: Db, t: TableView, *columns: str) -> Iterator[Violation]:
    rng = db.line_range()
    if rng is None:
        return
    a, b = rng
    for c in columns:
        x = _num(t, c)
        with np.errstate(invalid="ignore"):
            bad = ~((a <= x) & (x <= b))
        for i in _where(t, bad):
            yield t.err(i, c, f"{fmt(t[c][i])} is outside the line's chainage range "
                              f"[{fmt(a)}, {fmt(b)}] (line.parquet start_m/end_m)")


def start_before_end(t: TableView) -> Iterator[Violation]:
    start, end = _num(t, "start_m"), _num(t, "end_m")
    with np.errstate(invalid="ignore"):
        bad = ~(start < end)
    for i in _where(t, bad):
        yield t.err(i, "end_m", f"end_m {fmt(t['end_m'][i])} must be greater than "
                                f"start_m {fmt(t['start_m'][i])}")


def sorted_disjoint(t: TableView) -> Iterator[Violation]:
    """Segments sorted by start_m and not overlapping (gaps allowed).

    Each usable row is compared with *prev*, the earlier usable row that ends
    last (the latest such row on ties), vectorised for tables of millions of rows.
    """
    g = np.flatnonzero(t.good)
    if len(g) < 2:
        return
    start, end = _num(t, "start_m"), _num(t, "end_m")
    if len(g) < t.n:  # skip the rows with bad cells (all usable: no copies)
        start, end = start[g], end[g]
    running = np.maximum.accumulate(end)
    pos = np.where(end == running, np.arange(len(g)), 0)  # rows that become prev (end >= every earlier end)
    prev = np.maximum.accumulate(pos)[:-1]  # prev of rows 1..n-1, as positions in g
    unsorted = start[1:] < start[prev]
    overlap = ~unsorted & (start[1:] < end[prev])
    for k in np.flatnonzero(unsorted | overlap):
        i, j = int(g[k + 1]), int(g[prev[k]])
        if unsorted[k]:
            yield t.err(i, "start_m", f"not sorted: starts before row {j}, which starts at "
                                      f"{fmt(t['start_m'][j])}; sort rows by start_m")
        else:
            yield t.err(i, "start_m", f"overlaps row {j}, which ends at {fmt(t['end_m'][j])}")


# ---- line.parquet
@rule("line")
def line_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["line"]
    for i in t.rows():
        # the line id comes from the data, not the folder name: job files name folders
        if t["schema_version"][i] != SCHEMA_VERSION:  # an earlier one was upgraded before (planner.line.upgrade)
            yield t.err(i, "schema_version", f"is {t['schema_version'][i]}; this planner reads schema versions 1 "
                                             f"to {SCHEMA_VERSION}: a newer one needs a newer planner")
    yield from start_before_end(t)
    if t.has("running_side"):
        for i in t.rows():
            v = t["running_side"][i]
            if v is not None and v not in RUNNING_SIDES:
                yield t.err(i, "running_side", f"{v!r} is not one of {', '.join(RUNNING_SIDES)} (or empty)")


# ---- ids that become file names or partition values: one rule (planner.io.paths.PATH_ID_RE)
@rule()
def path_ids(db: Db) -> Iterator[Violation]:
    for table, columns in PATH_ID_COLUMNS.items():
        t = db.tables.get(table)
        if t is None:
            continue
        for c in columns:
            for i in t.rows():
                v = t[c][i]
                if v != "" and not is_path_id(v):  # "" is reported by unique()/line_rules
                    yield t.err(i, c, f"{v!r} cannot name a file or partition; {PATH_ID_RULE}")


# ---- stations.parquet
@rule("stations")
def station_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["stations"]
    yield from unique(t, "station_id")
    prev = None
    for i in t.rows():
        if prev is not None and not t["position_m"][i] > t["position_m"][prev]:
            yield t.err(i, "position_m", f"stations must be sorted by position_m: "
                                         f"{fmt(t['position_m'][i])} is not greater than row {prev}'s "
                                         f"{fmt(t['position_m'][prev])}")
        prev = i


@rule("stations", "line")
def stations_inside(db: Db) -> Iterator[Violation]:
    """The platform centre and both stop markers lie on the line (a station beyond end_m is refused)."""
    yield from inside(db, db.tables["stations"], "position_m", "stop_down_m", "stop_up_m")


# ---- gradients.parquet, curves.parquet
@rule("gradients")
def gradient_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["gradients"]
    yield from start_before_end(t)
    yield from sorted_disjoint(t)


@rule("curves")
def curve_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["curves"]
    yield from start_before_end(t)
    yield from sorted_disjoint(t)


@rule("gradients", "line")
def gradients_inside(db: Db) -> Iterator[Violation]:
    yield from inside(db, db.tables["gradients"], "start_m", "end_m")


@rule("curves", "line")
def curves_inside(db: Db) -> Iterator[Violation]:
    yield from inside(db, db.tables["curves"], "start_m", "end_m")


@rule("line")
def segment_density(db: Db) -> Iterator[Violation]:
    """At most MAX_ROWS_PER_M rows per metre of line in the segment tables (issue 32): a sanity limit.

    A table denser than that is a sampled curve, not a table of segments; the
    limit refuses it before the run spends minutes and gigabytes on it.
    """
    rng = db.line_range()
    if rng is None:
        return
    length = rng[1] - rng[0]
    limit = max(1, math.floor(length * MAX_ROWS_PER_M))
    for name in ("gradients", "curves", "speed_limits"):
        t = db.tables.get(name)
        if t is not None and t.n > limit:
            yield Violation(t.file, None, None,
                            f"has {t.n} rows for a line of {fmt(length)} m; at most {limit} (one row per "
                            f"metre of line) are accepted: a surveyed profile changes every few tens of metres "
                            f"or more; merge neighbouring rows with equal values")


# ---- speed_limits.parquet
@rule("speed_limits")
def speed_limit_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["speed_limits"]
    yield from start_before_end(t)
    yield from one_of(t, "direction", LIMIT_DIRECTIONS)


@rule("speed_limits", "rolling_stock")
def speed_limit_train_types(db: Db) -> Iterator[Violation]:
    t = db.tables["speed_limits"]
    known = set(db.tables["rolling_stock"]["train_type"])
    for i in t.rows():
        tt = t["train_type"][i]
        if tt is not None and tt not in known:
            yield t.err(i, "train_type", f"unknown train type {tt!r} (not in rolling_stock.parquet); "
                                         f"use null for every train type")


# ---- beacons.parquet, signals.parquet
@rule("beacons")
def beacon_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["beacons"]
    yield from unique(t, "beacon_id")
    yield from one_of(t, "direction", DIRECTIONS)
    yield from one_of(t, "kind", BEACON_KINDS)


@rule("beacons", "line")
def beacons_inside(db: Db) -> Iterator[Violation]:
    yield from inside(db, db.tables["beacons"], "position_m")


@rule("signals")
def signal_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["signals"]
    yield from unique(t, "signal_id")
    yield from one_of(t, "direction", DIRECTIONS)


@rule("signals", "line")
def signals_inside(db: Db) -> Iterator[Violation]:
    yield from inside(db, db.tables["signals"], "position_m")


# ---- rolling_stock.parquet, traction.parquet
@rule("rolling_stock")
def rolling_stock_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["rolling_stock"]
    yield from unique(t, "train_type")
    yield from one_of(t, "cruise", CRUISE_MODES)
    for i in t.rows():
        if t["cruise"][i] == "sawtooth" and not t["coast_band_kmh"][i] > 0:
            yield t.err(i, "coast_band_kmh", "must be > 0 for cruise 'sawtooth'")


CRAWL_KMH = 5.0
"""Slowest approach speed the jerk rule assumes [km/h]: a stopping pattern starts at running speed, never below."""


def min_stop_distance_m(v_ms: float, jerk_ms3: float) -> float:
    """Shortest stop from ``v_ms`` (deceleration 0 at both ends) with jerk at most ``jerk_ms3`` [m].

    With no deceleration limit the fastest stop ramps the deceleration up and
    straight back down at ±j: v = j T²/4, so T = 2 sqrt(v/j), and the speed
    falls symmetrically about T/2, so the distance is v T/2 = v sqrt(v/j). Any
    deceleration limit only lengthens it, so this is a lower bound.
    """
    return v_ms * math.sqrt(v_ms / jerk_ms3)


@rule("rolling_stock", "line")
def jerk_allows_a_stop(db: Db) -> Iterator[Violation]:
    """Refuse a jerk limit with which no stopping pattern can exist on this line (issue 21).

    Rule: the shortest jerk-limited stop from CRAWL_KMH (5 km/h),
    v·sqrt(v/j), must fit in the whole line (end_m − start_m). Every stop
    approach is shorter than the line and starts faster than 5 km/h, and the
    shortest stop grows with the speed, so when the rule fails every stopping
    pattern of the train type is impossible (e.g. 1e-9 km/h/s² needs ~98 km).
    """
    rng = db.line_range()
    if rng is None:
        return
    length = rng[1] - rng[0]
    t = db.tables["rolling_stock"]
    v = CRAWL_KMH * KMH
    for i in t.rows():
        j_kmh = float(t["jerk_limit_kmh_s2"][i])
        if not j_kmh > 0:
            continue  # refused by its declared range (stage 1)
        need = min_stop_distance_m(v, j_kmh * KMH_S2)
        if need > length:
            j_min = v ** 3 / length ** 2 / KMH_S2  # solves v sqrt(v/j) = length for j, in km/h/s²
            yield t.err(i, "jerk_limit_kmh_s2",
                        f"{fmt(j_kmh)} km/h/s² makes every stopping pattern impossible: even from "
                        f"{fmt(CRAWL_KMH)} km/h a stop needs {need / 1000:.3g} km, more than the whole line "
                        f"({length / 1000:.3g} km); use at least {j_min:.2g} km/h/s² (ride comfort is "
                        f"typically 1-5 km/h/s²)")


def _traction_curves(t: TableView, usable: bool = True) -> dict[str, list[int]]:
    """Rows of each train type's traction curve, in file order.

    ``usable``: only the curves whose rows are all usable (a curve with a bad
    cell is left to that message, so its shape is not judged without the row).
    """
    curves: dict[str, list[int]] = {}
    for i in range(t.n):
        if t["train_type"][i] is not None:
            curves.setdefault(t["train_type"][i], []).append(i)
    return {k: rows for k, rows in curves.items() if not usable or all(t.good[i] for i in rows)}


@rule("traction")
def traction_shape(db: Db) -> Iterator[Violation]:
    t = db.tables["traction"]
    for tt, rows in _traction_curves(t).items():
        v = t["speed_kmh"]
        if v[rows[0]] != 0:
            yield t.err(rows[0], "speed_kmh", f"the traction curve of {tt!r} must start at 0 km/h, "
                                              f"found {fmt(v[rows[0]])}")
        for a, b in zip(rows[:-1], rows[1:]):
            if not v[b] > v[a]:
                yield t.err(b, "speed_kmh", f"speeds of {tt!r} must be strictly increasing: "
                                            f"{fmt(v[b])} follows {fmt(v[a])} in row {a}")


@rule("traction", "rolling_stock")
def traction_per_train_type(db: Db) -> Iterator[Violation]:
    t, rs = db.tables["traction"], db.tables["rolling_stock"]
    curves, named = _traction_curves(t), _traction_curves(t, usable=False)
    known = set(rs["train_type"])  # a row with a bad cell still names its train type (no follow-up message)
    max_speed = {rs["train_type"][i]: rs["max_speed_kmh"][i] for i in rs.rows()}
    for tt, rows in named.items():
        if tt not in known:
            yield t.err(rows[0], "train_type", f"unknown train type {tt!r} (not in rolling_stock.parquet)")
            continue
        if tt not in max_speed or tt not in curves:
            continue  # its rolling_stock row or a row of its curve has a bad cell, reported there
        top = max(t["speed_kmh"][i] for i in rows)
        if top < max_speed[tt]:
            last = max(rows, key=lambda i: t["speed_kmh"][i])
            yield t.err(last, "speed_kmh", f"the traction curve of {tt!r} ends at {fmt(top)} km/h, below "
                                           f"its max_speed_kmh {fmt(max_speed[tt])}; extend it")
    for i in rs.rows():
        if rs["train_type"][i] not in named:
            yield rs.err(i, "train_type", "has no traction curve in traction.parquet")


# ---- timetable.parquet
def _trains(t: TableView) -> dict[str, list[int]]:
    """Rows of each train whose rows are all usable; a train with a bad cell is left to that message."""
    trains: dict[str, list[int]] = {}
    for i in range(t.n):
        if t["train_id"][i] is not None:
            trains.setdefault(t["train_id"][i], []).append(i)
    return {k: rows for k, rows in trains.items() if all(t.good[i] for i in rows)}


def _ordered_calls(t: TableView, rows: list[int]) -> list[int] | None:
    """Rows of one train ordered by seq, or None when seq is not 0..n-1."""
    order = sorted(rows, key=lambda i: t["seq"][i])
    return order if [t["seq"][i] for i in order] == list(range(len(rows))) else None


@rule("timetable")
def timetable_rows(db: Db) -> Iterator[Violation]:
    t = db.tables["timetable"]
    yield from one_of(t, "direction", DIRECTIONS)


@rule("timetable", "rolling_stock")
def timetable_train_types(db: Db) -> Iterator[Violation]:
    t = db.tables["timetable"]
    known = set(db.tables["rolling_stock"]["train_type"])
    for i in t.rows():
        if t["train_type"][i] not in known:
            yield t.err(i, "train_type", f"unknown train type {t['train_type'][i]!r} "
                                         f"(not in rolling_stock.parquet)")


@rule("timetable", "stations")
def timetable_stations(db: Db) -> Iterator[Violation]:
    t = db.tables["timetable"]
    known = set(db.tables["stations"]["station_id"])
    for i in t.rows():
        if t["station_id"][i] not in known:
            yield t.err(i, "station_id", f"unknown station {t['station_id'][i]!r} (not in stations.parquet)")


@rule("timetable")
def timetable_trains(db: Db) -> Iterator[Violation]:
    """Per train: one type and direction, seq 0..n-1, null times only at the ends, times in order."""
    t = db.tables["timetable"]
    for train, rows in _trains(t).items():
        first = rows[0]
        for c in ("train_type", "direction"):
            for i in rows[1:]:
                if t[c][i] != t[c][first]:
                    yield t.err(i, c, f"train {train!r} has {c} {t[c][first]!r} in row {first}; "
                                      f"one train has one {c}")
        seen: dict[int, int] = {}
        for i in rows:
            s = t["seq"][i]
            if s in seen:
                yield t.err(i, "seq", f"duplicate seq {s} for train {train!r}; also in row {seen[s]}")
            seen.setdefault(s, i)
        calls = _ordered_calls(t, rows)
        if calls is None:
            if len(seen) == len(rows):  # no duplicates (reported above): a gap or a wrong start
                order = sorted(rows, key=lambda r: t["seq"][r])
                bad = next(r for k, r in enumerate(order) if t["seq"][r] != k)
                seqs = ", ".join(str(t["seq"][r]) for r in order)
                yield t.err(bad, "seq", f"seq of train {train!r} must run 0..{len(rows) - 1} "
                                        f"without gaps; found {seqs}")
            continue
        if len(calls) < 2:
            yield t.err(calls[0], "train_id", f"train {train!r} has one call; it needs at least two")
            continue
        yield from _null_times(t, calls)
        yield from _times_in_order(t, calls)


def _null_times(t: TableView, calls: list[int]) -> Iterator[Violation]:
    last = len(calls) - 1
    for k, i in enumerate(calls):
        if k > 0 and math.isnan(t["arrival_s"][i]):
            yield t.err(i, "arrival_s", "null arrival is allowed only at the origin (seq 0)")
        if k < last and math.isnan(t["departure_s"][i]):
            yield t.err(i, "departure_s", f"null departure is allowed only at the terminus (seq {last})")


def _times_in_order(t: TableView, calls: list[int]) -> Iterator[Violation]:
    """arrival <= departure at each call and departure <= next arrival, over the non-null times."""
    prev = None  # (time, row, column)
    for i in calls:
        for c in ("arrival_s", "departure_s"):
            x = t[c][i]
            if math.isnan(x):
                continue
            if prev is not None and x < prev[0]:
                where = "" if prev[1] == i else f" in row {prev[1]} (seq {t['seq'][prev[1]]})"
                yield t.err(i, c, f"{c} {fmt(x)} is earlier than {prev[2]} {fmt(prev[0])}{where}; "
                                  f"times must not decrease along seq")
            prev = (x, i, c)


@rule("timetable", "stations")
def timetable_direction(db: Db) -> Iterator[Violation]:
    """Consecutive calls run in the train's direction: chainage increases down, decreases up."""
    t = db.tables["timetable"]
    pos = db.station_positions()
    for train, rows in _trains(t).items():
        calls = _ordered_calls(t, rows)
        d = t["direction"][rows[0]]
        if calls is None or d not in DIRECTIONS or any(t["direction"][i] != d for i in rows):
            continue
        sgn = 1 if d == "down" else -1
        for a, b in zip(calls[:-1], calls[1:]):
            sa, sb = t["station_id"][a], t["station_id"][b]
            if sa in pos and sb in pos and not sgn * (pos[sb] - pos[sa]) > 0:
                way, article = ("beyond", "a") if d == "down" else ("before", "an")
                yield t.err(b, "station_id", f"{article} {d} train's calls must follow its direction: station "
                                             f"{sb!r} at {fmt(pos[sb])} m is not {way} the previous call "
                                             f"{sa!r} at {fmt(pos[sa])} m")


# ---- nodes.parquet, edges.parquet
@rule()
def network_files(db: Db) -> Iterator[Violation]:
    for have, lack in (("nodes", "edges"), ("edges", "nodes")):
        if have in db.present and lack not in db.present:
            yield Violation(TABLES[lack].file, None, None,
                            f"is missing but {TABLES[have].file} exists; the track network needs both")


@rule("nodes")
def node_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["nodes"]
    yield from unique(t, "node_id")
    yield from one_of(t, "kind", NODE_KINDS)


@rule("nodes", "stations")
def node_stations(db: Db) -> Iterator[Violation]:
    t = db.tables["nodes"]
    if not t.has("station_id"):
        return
    known = set(db.tables["stations"]["station_id"])
    for i in t.rows():
        s = t["station_id"][i]
        if s is not None and s not in known:
            yield t.err(i, "station_id", f"unknown station {s!r} (not in stations.parquet)")


@rule("edges")
def edge_rules(db: Db) -> Iterator[Violation]:
    t = db.tables["edges"]
    yield from unique(t, "edge_id")
    if t.has("direction"):
        for i in t.rows():
            v = t["direction"][i]
            if v is not None and v not in TRACK_DIRECTIONS:
                yield t.err(i, "direction", f"{v!r} is not one of {', '.join(TRACK_DIRECTIONS)} (or empty: from "
                                            f"the track name)")


@rule("edges", "nodes")
def edge_nodes(db: Db) -> Iterator[Violation]:
    t = db.tables["edges"]
    known = set(db.tables["nodes"]["node_id"])
    for c in ("from_node", "to_node"):
        for i in t.rows():
            if t[c][i] not in known:
                yield t.err(i, c, f"unknown node {t[c][i]!r} (not in nodes.parquet)")
