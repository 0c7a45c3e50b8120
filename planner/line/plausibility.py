"""Rules across tables that a run needs to be physically possible (issues 32 and 33).

Registered with :func:`planner.line.rules.rule` like every other rule of stage 2
(:mod:`planner.line.validate` imports this module so that they run):

- a standing train's tail must stand on the line (an error), and a train longer
  than its platform is reported as a warning (legitimate with selective door
  opening);
- the on-board speed margin must leave a positive speed under every limit the
  train type meets.

Any positive brake rate is accepted, whatever the gradients: on a climb that slows
the train more than its braking curve asks, the run follows the curve with less
brake, or under power (a run below its ceiling powers); on a descent whose pull its
brake cannot overcome, no stopping pattern stops it there, which is a verdict on
that leg (``no_stop``), not bad input. A rule that refused such a brake (and
advised a stronger one, an optimistic braking distance) was removed.

Each is a value that passes its column's range but fails with another table; the
run would otherwise stop late, in the middle of a computation.
"""
from __future__ import annotations

from typing import Iterator

from planner.errors import Violation
from planner.line.conform import TableView, fmt
from planner.line.rules import Db, _ordered_calls, _trains, rule
from planner.line.schema import DIRECTIONS


def _standing_calls(t: TableView, db: Db) -> Iterator[tuple[str, str, float, int, str]]:
    """(train, direction, train length [m], row, station) of every call where a train stands.

    A train stands at its origin, its terminus and every call with ``stops``;
    only trains whose rows, train type and direction are usable.
    """
    rs = db.tables["rolling_stock"]
    length = {rs["train_type"][i]: float(rs["length_m"][i]) for i in rs.rows()}
    for train, rows in _trains(t).items():
        calls = _ordered_calls(t, rows)
        d, tt = t["direction"][rows[0]], t["train_type"][rows[0]]
        if calls is None or d not in DIRECTIONS or tt not in length:
            continue
        for k, i in enumerate(calls):
            if k == 0 or k == len(calls) - 1 or t["stops"][i]:
                yield train, d, length[tt], i, t["station_id"][i]


@rule("timetable", "stations", "rolling_stock", "line")
def tail_on_the_line(db: Db) -> Iterator[Violation]:
    """A standing train's tail lies inside the line's chainage range (issue 33: impossible geometry).

    The front stands at the stop marker of its direction, the body one train
    length behind it (lower chainage for down, higher for up). A tail beyond
    start_m/end_m stands on track the database does not describe: gradients and
    curves there would silently count as level and straight.
    """
    rng = db.line_range()
    if rng is None:
        return
    a, b = rng
    t, st = db.tables["timetable"], db.tables["stations"]
    marker = {}
    for i in st.rows():
        marker.setdefault(st["station_id"][i], (float(st["stop_down_m"][i]), float(st["stop_up_m"][i])))
    for train, d, length, i, station in _standing_calls(t, db):
        if station not in marker:
            continue
        front = marker[station][0 if d == "down" else 1]
        tail = front - length if d == "down" else front + length
        if (tail >= a) if d == "down" else (tail <= b):
            continue  # the front's own position is stations_inside's to judge
        end, col = (a, "start_m") if d == "down" else (b, "end_m")
        yield t.err(i, "station_id",
                    f"train {train!r} ({fmt(length)} m long) stands with its front at {station}'s {d} stop marker "
                    f"{fmt(front)} m, so its tail is at {fmt(tail)} m, beyond the line's {col} {fmt(end)} "
                    f"(line.parquet); extend the line database to {fmt(tail)} m, move the stop marker, or run a "
                    f"shorter train type")


@rule("timetable", "stations", "rolling_stock", warning=True)
def train_fits_platform(db: Db) -> Iterator[Violation]:
    """Warn where a train stands at a platform shorter than itself (issue 33).

    Legitimate on real railways (selective door opening, door cut: only the
    doors along the platform open), so a warning, not an error: the planner's
    physics does not depend on the platform length.
    """
    t, st = db.tables["timetable"], db.tables["stations"]
    platform = {}
    for i in st.rows():
        platform.setdefault(st["station_id"][i], float(st["platform_length_m"][i]))
    for train, d, length, i, station in _standing_calls(t, db):
        if station in platform and length > platform[station]:
            yield t.err(i, "stops",
                        f"train {train!r} ({fmt(length)} m long) stands at {station}, whose platform is "
                        f"{fmt(platform[station])} m (stations.parquet platform_length_m); fine where only the "
                        f"doors along the platform open, else lengthen the platform or shorten the train")


@rule("rolling_stock", "speed_limits", "line")
def margin_leaves_a_speed(db: Db) -> Iterator[Violation]:
    """speed_margin_kmh is below the lowest limit the train type meets (line, vehicle, restrictions).

    The on-board maximum is that limit minus the margin (:func:`planner.physics.speed_profile.onboard_max_ms`);
    at or below zero no run exists.
    """
    ln, rs, sl = db.tables["line"], db.tables["rolling_stock"], db.tables["speed_limits"]
    if ln.n != 1 or not ln.good[0]:
        return
    line_max = float(ln["max_speed_kmh"][0])
    for i in rs.rows():
        tt, margin = rs["train_type"][i], float(rs["speed_margin_kmh"][i])
        lowest, where = min(line_max, float(rs["max_speed_kmh"][i])), "the line's or its own maximum speed"
        for j in sl.rows():
            if sl["train_type"][j] in (None, tt) and float(sl["limit_kmh"][j]) < lowest:
                lowest, where = float(sl["limit_kmh"][j]), f"speed_limits.parquet row {j}"
        if margin >= lowest:
            yield rs.err(i, "speed_margin_kmh",
                         f"{fmt(margin)} km/h leaves no on-board speed under {fmt(lowest)} km/h ({where}); "
                         f"use a margin below it")
