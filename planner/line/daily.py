"""The daily feed of a line: temporary speed restrictions and the timetable's calendar.

The line database (its folder's ``*.parquet``) is the **static line**: it
changes when the railway is rebuilt, and its digest keys the cache of every
unit. What changes from one day to the next lives apart, in a **daily feed**
folder that the job names (``[day] feeds``, docs/operating-day.md), so that
adding tonight's slow order does not change the static line's digest and every
unit that no restriction reaches stays cached:

- ``restrictions.parquet``: temporary speed restrictions with their validity
  in the line's local time (:data:`FEED_TABLES`);
- ``calendar.parquet`` and ``calendar_dates.parquet``: services by weekday
  within a date range, and dated exceptions (GTFS ``calendar.txt`` /
  ``calendar_dates.txt`` semantics);
- ``train_services.parquet``: the service each timetable train belongs to.

Every table is optional; a feed without calendar tables runs every timetable
train every day. The loader validates a feed against its line with the rules
and the one-line messages of the line database (:class:`planner.errors.Violation`:
file, row, column, fix) and returns frozen dataclasses in SI: speeds in m/s,
validity as UTC epoch seconds beside the local text the operator wrote.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from datetime import date, datetime
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from planner.errors import InputError, LineValidationError, Violation
from planner.io.parquet import read_file
from planner.io.paths import PATH_ID_RULE, is_path_id
from planner.line.conform import TableView, conform, fmt
from planner.line.model import Line, SpeedLimit
from planner.line.operating_day import TEMPORARY_KIND, local_instant, local_text, whole_day, zone
from planner.line.schema import LIMIT_DIRECTIONS, TableSpec, _schema
from planner.line.units import KMH, kmh

S, D, I32, B = pa.string(), pa.float64(), pa.int32(), pa.bool_()
WEEKDAYS = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")
EXCEPTION_ADDED, EXCEPTION_REMOVED = 1, 2

_LOCAL = ("local date-time in the line's time zone, ISO 8601 without offset (2026-11-30T01:00)")
_DATE = "date YYYY-MM-DD"

FEED_TABLES: dict[str, TableSpec] = {t.name: t for t in [
    TableSpec("restrictions", _schema("restrictions", [
        ("restriction_id", S, "unique restriction id; names it in reports and bundles (PATH_ID_RE)"),
        ("start_m", D, "restricted stretch start chainage [m]"),
        ("end_m", D, "restricted stretch end chainage [m]; > start_m, inside the line"),
        ("limit_kmh", D, "temporary speed limit [km/h]; > 0 and below the line maximum"),
        ("direction", S, "both, down or up"),
        ("track", S, "track (edges.parquet track) the stretch lies on: the restriction reaches the trains whose "
                     "route runs on that track there (the other main, a loop, a platform track); null = every "
                     "track at that chainage (optional column)", True),
        ("train_type", S, "train type it applies to; null = every train type", True),
        ("valid_from", S, f"in force from this {_LOCAL}"),
        ("valid_until", S, f"in force until (exclusive) this {_LOCAL}; after valid_from"),
        ("reason", S, "why: track renewal, rail defect, works, ..."),
        ("has_beacon", B, "a temporary ATS-P beacon sends its pattern; false: the on-board DB feeds it"),
    ]), required=False, row_id=("restriction_id",), optional_columns=frozenset({"track"})),
    TableSpec("calendar", _schema("calendar", [
        ("service_id", S, "unique service id (a day type: weekday, weekend, ...)"),
        *[(d, B, f"the service runs on {d.capitalize()}s") for d in WEEKDAYS],
        ("start_date", S, f"first {_DATE} of the service"),
        ("end_date", S, f"last {_DATE} of the service (inclusive); not before start_date"),
    ]), required=False, row_id=("service_id",)),
    TableSpec("calendar_dates", _schema("calendar_dates", [
        ("service_id", S, "service id (may be one that only calendar_dates defines)"),
        ("date", S, f"the {_DATE} of the exception"),
        ("exception_type", I32, "1 = the service is added on this date, 2 = removed (GTFS)"),
    ]), required=False, row_id=("service_id", "date")),
    TableSpec("train_services", _schema("train_services", [
        ("train_id", S, "timetable train (references timetable.parquet of the line)"),
        ("service_id", S, "its service (references calendar or calendar_dates)"),
    ]), required=False, row_id=("train_id",)),
]}
"""Every table of a daily feed by name; the file is ``<name>.parquet``."""


# --------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class TemporaryRestriction:
    """A temporary speed restriction on [start_m, end_m], in force [valid_from_s, valid_until_s).

    ``valid_from``/``valid_until`` are the local text as written; ``*_s`` the
    instants (UTC epoch seconds). ``row`` is the 0-based row in restrictions.parquet.
    """

    restriction_id: str
    start_m: float
    end_m: float
    limit_ms: float
    direction: str
    train_type: str | None
    valid_from: str
    valid_until: str
    valid_from_s: int
    valid_until_s: int
    reason: str
    has_beacon: bool
    row: int = -1
    track: str | None = None
    """The track the stretch lies on (edges.parquet ``track``), or None: every track at that chainage."""

    def as_speed_limit(self) -> SpeedLimit:
        """The restriction as a line speed limit (kind ``temporary``): what the physics sees while in force.

        Named by its id (``row`` -1): its place in the feed keys nothing, so a restriction added before
        it does not change the cache key of the units it reaches."""
        return SpeedLimit(self.start_m, self.end_m, self.limit_ms, self.direction, self.train_type,
                          TEMPORARY_KIND, self.has_beacon, -1, self.restriction_id)

    def record(self, window=None) -> dict:
        """Plain data (railway units at the edge) for manifests and reports."""
        out = {"restriction_id": self.restriction_id, "start_m": self.start_m, "end_m": self.end_m,
               "limit_kmh": round(kmh(self.limit_ms), 9), "direction": self.direction,
               "train_type": self.train_type, "valid_from": self.valid_from, "valid_until": self.valid_until,
               "reason": self.reason, "has_beacon": self.has_beacon}
        if self.track is not None:  # only where named: records of a feed without tracks are as they were
            out["track"] = self.track
        if window is not None:
            out["whole_day"] = whole_day(self, window)
        return out


@dataclass(frozen=True)
class Service:
    """One calendar row: runs on the flagged weekdays (Monday first) within [start_date, end_date]."""

    service_id: str
    weekdays: tuple[bool, bool, bool, bool, bool, bool, bool]
    start_date: date
    end_date: date


@dataclass(frozen=True)
class Calendar:
    """The timetable's calendar: services, dated exceptions (1 added, 2 removed), train → service."""

    services: dict[str, Service]
    exceptions: dict[tuple[str, date], int]
    train_service: dict[str, str]


@dataclass(frozen=True)
class DailyFeed:
    """A validated daily feed of one line."""

    path: str
    time_zone: str
    restrictions: tuple[TemporaryRestriction, ...] = ()
    calendar: Calendar | None = None
    notes: tuple[str, ...] = field(default=(), compare=False)


# --------------------------------------------------------------------------- parsing cells
def parse_local(text: str, *, late: bool, tz: str) -> tuple[int | None, str | None]:
    """(instant, None) for a local date-time text, or (None, what is wrong and how to fix it)."""
    try:
        t = datetime.fromisoformat(text.strip())
    except ValueError:
        return None, f"{text!r} is not a date-time; write {_LOCAL}"
    if len(text.strip()) <= 10:
        return None, f"{text!r} has no time of day; write e.g. {text.strip()}T00:00"
    if t.tzinfo is not None:
        return None, f"{text!r} has a UTC offset; write the local time in {zone(tz).key} without offset"
    s = local_instant(t, tz, late=late)
    if s is None:
        return None, f"{text!r} does not exist in {zone(tz).key} (the clocks jump over it); write a time after the jump"
    return s, None


def parse_date(text: str) -> tuple[date | None, str | None]:
    try:
        if len(text) != 10:
            raise ValueError
        return date.fromisoformat(text), None
    except ValueError:
        return None, f"{text!r} is not a date; write YYYY-MM-DD"


# --------------------------------------------------------------------------- rules
def check_restrictions(v: TableView, line: Line, tz: str) -> tuple[list[TemporaryRestriction], list[Violation]]:
    """The restrictions of a conforming table and every broken rule (same rules as speed_limits, plus validity)."""
    out: list[TemporaryRestriction] = []
    bad: list[Violation] = []
    seen: dict[str, int] = {}
    types = {t.train_type for t in line.train_types}
    tracks = {e.track for e in line.network.edges} if line.network is not None else set()
    vmax = round(kmh(line.max_speed_ms), 9)  # back in the unit it was written in (100/3.6*3.6 may miss 100)
    for i in v.rows():
        errs = len(bad)
        rid = v["restriction_id"][i]
        if not is_path_id(rid):
            bad.append(v.err(i, "restriction_id", f"{rid!r} cannot name a restriction; {PATH_ID_RULE}"))
        elif rid in seen:
            bad.append(v.err(i, "restriction_id", f"duplicate id (also row {seen[rid]}); give each restriction "
                                                  f"its own id"))
        seen.setdefault(rid, i)
        a, b = float(v["start_m"][i]), float(v["end_m"][i])
        if not a < b:
            bad.append(v.err(i, "end_m", f"end_m {fmt(b)} must be greater than start_m {fmt(a)}"))
        if a < line.start_m or b > line.end_m:
            col = "start_m" if a < line.start_m else "end_m"
            bad.append(v.err(i, col, f"stretch {fmt(a)}–{fmt(b)} m is outside the line "
                                     f"{fmt(line.start_m)}–{fmt(line.end_m)} m; give chainages of this line"))
        lim = float(v["limit_kmh"][i])
        if not lim > 0:
            bad.append(v.err(i, "limit_kmh", f"{fmt(lim)} km/h: a limit must be positive"))
        elif not lim < vmax:
            bad.append(v.err(i, "limit_kmh", f"{fmt(lim)} km/h is not below the line maximum {fmt(vmax)} km/h: "
                                             f"it restricts nothing; lower it or delete the row"))
        d = v["direction"][i]
        if d not in LIMIT_DIRECTIONS:
            bad.append(v.err(i, "direction", f"{d!r}; write one of {', '.join(LIMIT_DIRECTIONS)}"))
        track = v["track"][i] if v.has("track") else None
        if track is not None and track not in tracks:
            bad.append(v.err(i, "track", f"{track!r} is not a track of the line's network"
                                         + (f" ({', '.join(sorted(tracks)[:8])}{' …' if len(tracks) > 8 else ''})"
                                            if tracks else " (the line has no track network)")
                                         + "; give an edges.parquet track, or leave it empty for every track"))
        tt = v["train_type"][i]
        if tt is not None and tt not in types:
            bad.append(v.err(i, "train_type", f"unknown train type {tt!r}; the line has {', '.join(sorted(types))} "
                                              f"(or leave it empty for every train type)"))
        f_s, f_err = parse_local(v["valid_from"][i], late=False, tz=tz)
        u_s, u_err = parse_local(v["valid_until"][i], late=True, tz=tz)
        for col, e in (("valid_from", f_err), ("valid_until", u_err)):
            if e:
                bad.append(v.err(i, col, e))
        if f_s is not None and u_s is not None and not f_s < u_s:
            bad.append(v.err(i, "valid_until", f"{v['valid_until'][i]} is not after valid_from "
                                               f"{v['valid_from'][i]}; a restriction must end after it starts"))
        if len(bad) == errs:
            out.append(TemporaryRestriction(rid, a, b, lim * KMH, d, tt, v["valid_from"][i], v["valid_until"][i],
                                            f_s, u_s, v["reason"][i], bool(v["has_beacon"][i]), i, track))
    return out, bad


def _check_calendar(v: TableView) -> tuple[dict[str, Service], list[Violation]]:
    services: dict[str, Service] = {}
    bad: list[Violation] = []
    for i in v.rows():
        sid = v["service_id"][i]
        if not sid.strip():
            bad.append(v.err(i, "service_id", "empty id; name the service"))
            continue
        if sid in services:
            bad.append(v.err(i, "service_id", "duplicate service id; one row per service (dated changes go "
                                              "in calendar_dates)"))
            continue
        a, ea = parse_date(v["start_date"][i])
        b, eb = parse_date(v["end_date"][i])
        for col, e in (("start_date", ea), ("end_date", eb)):
            if e:
                bad.append(v.err(i, col, e))
        if a and b and b < a:
            bad.append(v.err(i, "end_date", f"{b} is before start_date {a}"))
        elif a and b:
            services[sid] = Service(sid, tuple(bool(v[d][i]) for d in WEEKDAYS), a, b)
    return services, bad


def _check_exceptions(v: TableView) -> tuple[dict[tuple[str, date], int], list[Violation]]:
    exc: dict[tuple[str, date], int] = {}
    bad: list[Violation] = []
    for i in v.rows():
        sid, d = v["service_id"][i], None
        d, e = parse_date(v["date"][i])
        if e:
            bad.append(v.err(i, "date", e))
        t = v["exception_type"][i]
        if t not in (EXCEPTION_ADDED, EXCEPTION_REMOVED):
            bad.append(v.err(i, "exception_type", f"{t}; write 1 (service added on this date) or 2 (removed)"))
        elif d is not None:
            if (sid, d) in exc:
                bad.append(v.err(i, "date", f"a second exception for service {sid} on {d}; keep one"))
            exc[(sid, d)] = t
    return exc, bad


def _check_train_services(v: TableView, line: Line, known: set[str]) -> tuple[dict[str, str], list[Violation]]:
    trains = [t.train_id for t in line.trains]
    ids = set(trains)
    out: dict[str, str] = {}
    bad: list[Violation] = []
    listed = set(v["train_id"])  # a train on a bad row is reported there, not again as missing
    for i in v.rows():
        tid, sid = v["train_id"][i], v["service_id"][i]
        if tid not in ids:
            bad.append(v.err(i, "train_id", f"train {tid!r} is not in the line's timetable; delete the row or "
                                            f"add the train to timetable.parquet"))
        elif tid in out:
            bad.append(v.err(i, "train_id", "a second service for this train; a train belongs to one service"))
        elif sid not in known:
            bad.append(v.err(i, "service_id", f"unknown service id {sid!r}; define it in calendar or "
                                              f"calendar_dates ({', '.join(sorted(known)) or 'none defined'})"))
        else:
            out[tid] = sid
    missing = [t for t in trains if t not in listed]
    if missing:
        bad.append(Violation(v.file, None, "train_id", f"{len(missing)} timetable train(s) have no service, "
                                                       f"first {missing[0]}; add a row for each"))
    return out, bad


# --------------------------------------------------------------------------- loading
def read_feed_tables(feed_dir: Path) -> tuple[dict[str, TableView], list[Violation]]:
    """Each present feed table, checked against its declared schema (stage 1 of the line's validation)."""
    views: dict[str, TableView] = {}
    bad: list[Violation] = []
    for name, spec in FEED_TABLES.items():
        f = feed_dir / spec.file
        if not f.exists():
            continue
        try:
            table = read_file(f)
        except (pa.ArrowException, OSError, ValueError) as e:
            bad.append(Violation(spec.file, None, None, f"cannot be read as Parquet ({e}); rewrite the file"))
            continue
        view, problems = conform(spec, table)
        bad += problems
        if view is not None:
            views[name] = view
    return views, bad


def check_feed(feed_dir: str | Path, line: Line, tz: str,
               views: dict[str, TableView]) -> tuple[DailyFeed, list[Violation]]:
    """The feed built from conforming ``views`` and every rule it breaks."""
    bad: list[Violation] = []
    restrictions: list[TemporaryRestriction] = []
    if "restrictions" in views:
        restrictions, bad = check_restrictions(views["restrictions"], line, tz)
    services: dict[str, Service] = {}
    exceptions: dict[tuple[str, date], int] = {}
    if "calendar" in views:
        services, b = _check_calendar(views["calendar"])
        bad += b
    if "calendar_dates" in views:
        exceptions, b = _check_exceptions(views["calendar_dates"])
        bad += b
    calendar, notes = None, []
    has_calendar = "calendar" in views or "calendar_dates" in views
    if "train_services" in views:
        known = set(services) | {s for s, _ in exceptions}
        train_service, b = _check_train_services(views["train_services"], line, known)
        bad += b
        calendar = Calendar(services, exceptions, train_service)
        if not has_calendar:
            bad.append(Violation(FEED_TABLES["calendar"].file, None, None, "train_services.parquet names services "
                                 "but the feed has no calendar.parquet or calendar_dates.parquet; add them"))
    elif has_calendar:
        bad.append(Violation(FEED_TABLES["train_services"].file, None, None, "missing: the feed has a calendar "
                             "but does not say which service each timetable train belongs to; add the file"))
    else:
        notes.append(f"{feed_dir}: no calendar: every timetable train runs every day")
    return DailyFeed(str(feed_dir), tz, tuple(restrictions), calendar, tuple(notes)), bad


def load_feed(feed_dir: str | Path, line: Line, tz: str) -> DailyFeed:
    """Read and validate the daily feed ``feed_dir`` of ``line`` with local times in ``tz``.

    Raises
    ------
    InputError
        The folder does not exist, or ``tz`` is not a time zone.
    LineValidationError
        Any broken rule; every violation is listed (file, row, column, fix).
    """
    p = Path(feed_dir)
    if not p.is_dir():
        raise InputError(f"{feed_dir}: daily feed folder not found; create it (e.g. `planner restrictions "
                         f"import FILE --line LINE --feed {feed_dir}`) or remove it from [day] feeds")
    try:
        zone(tz)
    except ValueError as e:
        raise InputError(f"{feed_dir}: {e}") from None
    views, bad = read_feed_tables(p)
    feed, more = check_feed(p, line, tz, views)
    bad += more
    if bad:
        raise LineValidationError(str(feed_dir), bad)
    return feed


def restrictions_table(rows: list[dict]) -> pa.Table:
    """restrictions.parquet's table from row dicts (declared columns, declared order); the optional ``track``
    column only when a row names a track, so a feed without one is written as before the column existed."""
    spec = FEED_TABLES["restrictions"]
    schema = spec.schema
    for name in sorted(spec.optional_columns):
        if all(r.get(name) is None for r in rows):
            schema = schema.remove(schema.get_field_index(name))
    return pa.Table.from_pylist([{f.name: r.get(f.name) for f in schema} for r in rows], schema=schema)


def restriction_rows(feed: DailyFeed) -> list[dict]:
    """The feed's restrictions back as row dicts of restrictions.parquet (for appending)."""
    return [r.record() for r in feed.restrictions]


__all__ = ["FEED_TABLES", "Calendar", "DailyFeed", "Service", "TemporaryRestriction", "check_feed",
           "check_restrictions", "load_feed", "local_text", "parse_local", "read_feed_tables",
           "restriction_rows", "restrictions_table"]
