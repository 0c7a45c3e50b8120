"""The operating day: its window in time, what is in force in it, which trains run.

Pure functions of dates, time zones and the daily feed's dataclasses
(:mod:`planner.line.daily`); no files, no clock. Instants are UTC epoch
seconds (int), the one time scale inside the planner; local times appear only
where they enter (the feed's text) and leave (manifest, reports), always through
:func:`local_instant` and :func:`local_text`.

An **operating day** D with start hour h runs from h:00 local time on D to
h:00 local time on D + 1 (a railway's day ends in the small hours, after the
last train: ``start_hour = 3`` by default). On the days the clocks change it
lasts 23 or 25 hours: the window is computed from the local wall-clock times,
never as start + 86400 s.

Timetable times (``arrival_s``/``departure_s``, seconds after midnight, may
exceed 86400) are counted, as in GTFS, from "noon minus 12 h" of the service
day, so a train at 08:00 is at 08:00 on a day the clocks changed at 02:00
(:func:`timetable_instant`).

Examples
--------
>>> w = operating_day(date(2026, 3, 28), "Europe/Berlin", 3)   # the night the clocks go forward
>>> (w.end_s - w.start_s) / 3600
23.0
"""
from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as dataclass_replace
from datetime import date, datetime, time, timedelta, timezone
from typing import TYPE_CHECKING, Iterable
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

if TYPE_CHECKING:  # the feed's dataclasses and the line; this module only reads their fields
    from planner.line.daily import Calendar, TemporaryRestriction
    from planner.line.model import Line

UTC = timezone.utc
TEMPORARY_KIND = "temporary"
"""``kind`` of a temporary restriction seen as a :class:`planner.line.model.SpeedLimit`."""
DEFAULT_START_HOUR = 3
"""Hour (local) at which an operating day starts and the previous one ends."""


def zone(name: str) -> ZoneInfo:
    """The IANA time zone ``name`` (e.g. ``Asia/Tokyo``); ValueError naming it when unknown."""
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError):
        raise ValueError(f"unknown time zone {name!r}; give an IANA name such as Asia/Tokyo or "
                         f"Europe/Berlin") from None


def _exists(local: datetime) -> bool:
    """Whether a naive local wall-clock time exists in its zone (it does not in a spring-forward gap)."""
    back = local.astimezone(UTC).astimezone(local.tzinfo)
    return back.replace(tzinfo=None, fold=0) == local.replace(tzinfo=None, fold=0)


def local_instant(local: datetime, tz: str | ZoneInfo, *, late: bool = False) -> int | None:
    """UTC epoch seconds of the naive local date-time ``local`` in ``tz``.

    Parameters
    ----------
    local : datetime
        Wall-clock time without offset.
    tz : str or ZoneInfo
        The line's time zone.
    late : bool
        For a time that occurs twice (the hour the clocks go back): False takes
        the first occurrence, True the second. A restriction's start takes the
        first and its end the second, so an ambiguous validity errs long (safe).

    Returns
    -------
    int or None
        The instant, or None when the time does not exist (the clocks jump over it).
    """
    z = tz if isinstance(tz, ZoneInfo) else zone(tz)
    t = local.replace(tzinfo=z, fold=1 if late else 0)
    if not _exists(t):
        return None
    return int(t.astimezone(UTC).timestamp())


def local_text(instant_s: int, tz: str | ZoneInfo) -> str:
    """An instant as local ISO 8601 with its offset, e.g. ``2026-11-30T03:00:00+09:00``."""
    z = tz if isinstance(tz, ZoneInfo) else zone(tz)
    return datetime.fromtimestamp(instant_s, UTC).astimezone(z).isoformat()


def _day_start(day: date, z: ZoneInfo, start_hour: int) -> int:
    """The instant day ``day`` starts: ``start_hour``:00 local, or the first local time after it that
    exists when the clocks jump over it (gaps are whole quarter hours in every zone of the tz database)."""
    t = datetime.combine(day, time(start_hour))
    for _ in range(4 * 3 + 1):
        s = local_instant(t, z)
        if s is not None:
            return s
        t += timedelta(minutes=15)
    raise ValueError(f"no local time exists near {start_hour}:00 on {day} in {z.key}")  # pragma: no cover


@dataclass(frozen=True)
class OperatingDay:
    """One operating day's window [start_s, end_s) and where it came from.

    Attributes
    ----------
    day : date
        The operating day (the date its window starts on).
    time_zone : str
        IANA name of the line's time zone.
    start_hour : int
        Local hour the day starts and ends at.
    start_s, end_s : int
        Window start (inclusive) and end (exclusive), UTC epoch seconds [s].
    """

    day: date
    time_zone: str
    start_hour: int
    start_s: int
    end_s: int

    @property
    def length_s(self) -> int:
        """Length of the day [s]: 86400, or 82800 / 90000 when the clocks change in it."""
        return self.end_s - self.start_s

    @property
    def start_local(self) -> str:
        return local_text(self.start_s, self.time_zone)

    @property
    def end_local(self) -> str:
        return local_text(self.end_s, self.time_zone)

    def contains(self, instant_s: float) -> bool:
        return self.start_s <= instant_s < self.end_s

    def record(self) -> dict:
        """Plain data for manifests: the day, its zone and its window, local and UTC."""
        return {"day": self.day.isoformat(), "time_zone": self.time_zone, "start_hour": self.start_hour,
                "start": self.start_local, "end": self.end_local, "start_utc_s": self.start_s,
                "end_utc_s": self.end_s, "length_h": self.length_s / 3600}


def operating_day(day: date | str, tz: str, start_hour: int = DEFAULT_START_HOUR) -> OperatingDay:
    """The window of operating day ``day`` in time zone ``tz``: ``start_hour``:00 local to the same next day.

    >>> w = operating_day("2026-10-24", "Europe/Berlin", 3)   # the clocks go back on 25 October 2026
    >>> w.length_s / 3600, w.start_local, w.end_local
    (25.0, '2026-10-24T03:00:00+02:00', '2026-10-25T03:00:00+01:00')
    """
    d = date.fromisoformat(day) if isinstance(day, str) else day
    if not 0 <= start_hour <= 23:
        raise ValueError(f"start_hour must be a whole hour 0..23, found {start_hour}")
    z = zone(tz)
    return OperatingDay(d, z.key, start_hour, _day_start(d, z, start_hour),
                        _day_start(d + timedelta(days=1), z, start_hour))


def current_operating_day(now_s: float, tz: str, start_hour: int = DEFAULT_START_HOUR) -> date:
    """The operating day in progress at instant ``now_s``: before ``start_hour`` it is still yesterday's."""
    z = zone(tz)
    local = datetime.fromtimestamp(now_s, UTC).astimezone(z)
    d = local.date()
    return d if now_s >= _day_start(d, z, start_hour) else d - timedelta(days=1)


def next_operating_day(now_s: float, tz: str, start_hour: int = DEFAULT_START_HOUR) -> date:
    """The operating day after the one in progress at ``now_s``: what a job run in the evening plans."""
    return current_operating_day(now_s, tz, start_hour) + timedelta(days=1)


def timetable_instant(day: date, tz: str | ZoneInfo, seconds: float) -> float:
    """UTC epoch seconds of a timetable time ``seconds`` after midnight of service day ``day``.

    As in GTFS, the time is measured from noon minus 12 h, so it is the
    wall-clock time on days without a clock change and stays right on the days
    with one (a train at 08:00 runs at 08:00 local).
    """
    z = tz if isinstance(tz, ZoneInfo) else zone(tz)
    noon = datetime.combine(day, time(12), tzinfo=z).astimezone(UTC).timestamp()
    return noon - 12 * 3600 + seconds


# --------------------------------------------------------------------------- what is in force
def in_force(r: "TemporaryRestriction", start_s: float, end_s: float) -> bool:
    """Whether restriction ``r`` is in force at any instant of [start_s, end_s)."""
    return r.valid_from_s < end_s and r.valid_until_s > start_s


def restrictions_in_force(restrictions: Iterable["TemporaryRestriction"],
                          window: OperatingDay) -> tuple["TemporaryRestriction", ...]:
    """The restrictions in force at some instant of the operating day, in feed order.

    A restriction that ends exactly when the day starts, or starts exactly when
    it ends, is not in it (validity and window are both half-open).
    """
    return tuple(r for r in restrictions if in_force(r, window.start_s, window.end_s))


def whole_day(r: "TemporaryRestriction", window: OperatingDay) -> bool:
    """Whether ``r`` is in force for the whole operating day (else only for part of it)."""
    return r.valid_from_s <= window.start_s and r.valid_until_s >= window.end_s


def reaches(r: "TemporaryRestriction", direction: str, train_type: str) -> bool:
    """Whether ``r`` concerns a train of ``train_type`` running ``direction`` (down/up)."""
    return r.direction in ("both", direction) and (r.train_type is None or r.train_type == train_type)


def leg_restrictions(restrictions: Iterable["TemporaryRestriction"], window: OperatingDay, line: "Line",
                     train_type: str, direction: str, origin: str, destination: str,
                     departure_s: float | None = None, arrival_s: float | None = None) -> tuple:
    """The temporary restrictions that apply to a train on one leg: **the** per-train rule (margins,
    conflicts and the train graph all take it from here).

    A restriction applies to a train of ``train_type`` running ``direction`` from stop ``origin`` to the
    next stop ``destination`` when

    - it reaches the leg: its stretch overlaps what the run can see (:meth:`Line.window_m`: the stop
      markers widened by a train length; the same test :meth:`Line.window` slices the line with), for
      that direction and train type (:func:`reaches`); and
    - it is in force **by the time the train passes**: at some instant of the train's time on the leg,
      [departure from ``origin``, arrival at ``destination``] (timetable times of the operating day,
      :func:`timetable_instant`). A leg lasts minutes and the whole leg is taken, so a restriction that
      starts or ends while the train is on the leg applies (the safe side at the boundary).

    A restriction in force for the whole operating day (:func:`whole_day`) applies to every train of
    the day without looking at its times, so a day whose restrictions are all whole-day computes
    exactly as the whole-day rule did. With ``departure_s`` None the times are not looked at: the
    restrictions that reach the leg at some time of the day (what the day's line has on it).

    Returns
    -------
    tuple of TemporaryRestriction
        In the order given.
    """
    lo, hi = line.window_m(origin, destination, train_type)
    near = [r for r in restrictions if reaches(r, direction, train_type) and r.end_m > lo and r.start_m < hi]
    if departure_s is None or all(whole_day(r, window) for r in near):
        return tuple(near)
    t0 = timetable_instant(window.day, window.time_zone, departure_s)
    t1 = timetable_instant(window.day, window.time_zone, arrival_s if arrival_s is not None else departure_s)
    return tuple(r for r in near if whole_day(r, window) or (r.valid_from_s <= t1 and r.valid_until_s > t0))


def without_temporary(line: "Line", ids: Iterable[str]) -> "Line":
    """``line`` without the temporary restrictions whose id is in ``ids`` (the line's own limits and the
    other temporary ones stay): the line a train sees while those are lifted."""
    drop = set(ids)
    if not drop:
        return line
    return dataclass_replace(line, speed_limits=tuple(s for s in line.speed_limits
                                                      if s.kind != TEMPORARY_KIND or s.restriction_id not in drop))


# --------------------------------------------------------------------------- the day's timetable
def service_runs(calendar: "Calendar", service_id: str, day: date) -> bool:
    """GTFS semantics: the weekday flag within [start_date, end_date], then the day's exception:
    type 1 adds the service on that date, type 2 removes it."""
    exc = calendar.exceptions.get((service_id, day))
    if exc is not None:
        return exc == 1
    s = calendar.services.get(service_id)
    return s is not None and s.start_date <= day <= s.end_date and s.weekdays[day.weekday()]


def trains_running(calendar: "Calendar | None", day: date, train_ids: Iterable[str]) -> tuple[str, ...]:
    """The trains of ``train_ids`` (timetable order) whose service runs on ``day``.

    With no calendar (a line without a daily feed) every timetable train runs every day.
    """
    ids = tuple(train_ids)
    if calendar is None:
        return ids
    return tuple(t for t in ids if service_runs(calendar, calendar.train_service[t], day))


@dataclass(frozen=True)
class DayInputs:
    """What is in force on one operating day of one line: what the pipeline computes with.

    Attributes
    ----------
    window : OperatingDay
        The day and its window.
    restrictions : tuple of TemporaryRestriction
        The temporary restrictions in force at some instant of the window, in feed order.
    trains : tuple of str
        The timetable trains that run that day, in timetable order.
    cancelled : tuple of str
        The timetable trains that do not run that day.
    notes : tuple of str
        What a planner should know (no service that day, no feed, ...).
    """

    window: OperatingDay
    restrictions: tuple
    trains: tuple[str, ...]
    cancelled: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def record(self) -> dict:
        """Plain data for the run's manifest."""
        w = self.window
        return {"restrictions": [r.record(w) for r in self.restrictions],
                "trains_running": len(self.trains), "trains_not_running": list(self.cancelled)}


__all__ = ["DEFAULT_START_HOUR", "DayInputs", "OperatingDay", "TEMPORARY_KIND",
           "current_operating_day", "in_force", "leg_restrictions", "local_instant", "local_text",
           "next_operating_day", "operating_day", "reaches", "restrictions_in_force", "service_runs",
           "timetable_instant", "trains_running", "whole_day", "without_temporary", "zone"]


def day_over(day: dict, now_s: float) -> str:
    """A sentence when the operating day of the run's record (:func:`day_record`) ended before ``now_s`` (the
    run's build time, UTC epoch seconds): its bundles are valid only in that day's window, so every vehicle
    refuses them; "" otherwise (or without a day)."""
    end = day.get("end_utc_s") if day else None
    if end is None or now_s < end:
        return ""
    return (f"the operating day planned, {day['day']} ({day.get('start')} to {day.get('end')}), ended before this run "
            "was built: its bundles are valid only in that window, so every vehicle refuses them; plan a day to "
            "come ([day] day, or --day)")
