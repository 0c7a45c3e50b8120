"""The operating day's window, what is in force in it and which trains run: closed-form answers.

Clock changes used (tz database, independent of the code under test):
Europe/Berlin 2026: CET→CEST on 29 March at 01:00 UTC, CEST→CET on 25 October at 01:00 UTC.
America/New_York 2026: EST→EDT on 8 March at 07:00 UTC (02:00 local), EDT→EST on 1 November at 06:00 UTC.
Asia/Tokyo: UTC+9 all year.
"""
from __future__ import annotations

from datetime import date, datetime, timedelta, timezone

import pytest

from planner.line.daily import Calendar, Service, TemporaryRestriction
from planner.line.operating_day import (
    current_operating_day,
    local_instant,
    next_operating_day,
    operating_day,
    restrictions_in_force,
    service_runs,
    timetable_instant,
    trains_running,
    whole_day,
)

H = 3600


def utc(*args) -> int:
    return int(datetime(*args, tzinfo=timezone.utc).timestamp())


@pytest.mark.parametrize("tz, day, start_utc, end_utc, hours", [
    # 03:00 CET = 02:00 UTC; next day 03:00 CEST = 01:00 UTC: the spring night is 23 h
    ("Europe/Berlin", "2026-03-28", utc(2026, 3, 28, 2), utc(2026, 3, 29, 1), 23),
    ("Europe/Berlin", "2026-03-29", utc(2026, 3, 29, 1), utc(2026, 3, 30, 1), 24),
    # 03:00 CEST = 01:00 UTC; next day 03:00 CET = 02:00 UTC: the autumn night is 25 h
    ("Europe/Berlin", "2026-10-24", utc(2026, 10, 24, 1), utc(2026, 10, 25, 2), 25),
    ("America/New_York", "2026-03-07", utc(2026, 3, 7, 8), utc(2026, 3, 8, 7), 23),
    ("America/New_York", "2026-10-31", utc(2026, 10, 31, 7), utc(2026, 11, 1, 8), 25),
    ("Asia/Tokyo", "2026-11-30", utc(2026, 11, 29, 18), utc(2026, 11, 30, 18), 24),
])
def test_day_window_and_length_on_clock_changes(tz, day, start_utc, end_utc, hours):
    w = operating_day(day, tz, 3)
    assert (w.start_s, w.end_s) == (start_utc, end_utc)
    assert w.length_s == hours * H
    assert w.start_local.startswith(f"{day}T03:00:00") and w.end_local[11:19] == "03:00:00"


def test_days_tile_the_year_without_gap_or_overlap():
    d0 = date(2026, 1, 1)
    days = [operating_day(d0 + timedelta(days=k), "Europe/Berlin", 3) for k in range(365)]
    assert all(a.end_s == b.start_s for a, b in zip(days, days[1:]))
    lengths = sorted({w.length_s for w in days})
    assert lengths == [23 * H, 24 * H, 25 * H]
    assert sum(w.length_s for w in days) == 365 * 24 * H  # one spring and one autumn change cancel


def test_a_start_hour_the_clocks_skip_starts_the_day_when_they_jump():
    # 02:00 on 29 March 2026 does not exist in Berlin: the day starts at the jump, 01:00 UTC (03:00 CEST)
    w = operating_day("2026-03-29", "Europe/Berlin", 2)
    assert w.start_s == utc(2026, 3, 29, 1)
    assert w.end_s == utc(2026, 3, 30, 0)  # 02:00 CEST
    assert operating_day("2026-03-28", "Europe/Berlin", 2).end_s == w.start_s


def test_next_operating_day_is_after_the_one_in_progress():
    tokyo = lambda *a: utc(*a) - 9 * H  # noqa: E731 - local Tokyo wall time to UTC
    assert next_operating_day(tokyo(2026, 11, 29, 20, 0), "Asia/Tokyo", 3) == date(2026, 11, 30)
    # 02:30 on the 30th is still the night of the 29th's operating day
    assert current_operating_day(tokyo(2026, 11, 30, 2, 30), "Asia/Tokyo", 3) == date(2026, 11, 29)
    assert next_operating_day(tokyo(2026, 11, 30, 2, 30), "Asia/Tokyo", 3) == date(2026, 11, 30)
    assert next_operating_day(tokyo(2026, 11, 30, 3, 0), "Asia/Tokyo", 3) == date(2026, 12, 1)


def test_timetable_times_count_from_noon_minus_12h():
    # New York, 8 March 2026: noon EDT = 16:00 UTC; noon - 12 h = 04:00 UTC; + 08:00 = 12:00 UTC = 08:00 EDT
    assert timetable_instant(date(2026, 3, 8), "America/New_York", 8 * H) == utc(2026, 3, 8, 12)
    # after midnight (25:30) the next calendar day, same offset
    assert timetable_instant(date(2026, 11, 30), "Asia/Tokyo", 25.5 * H) == utc(2026, 11, 30, 16, 30)


def test_twice_occurring_local_time_takes_the_first_or_the_second():
    t = datetime(2026, 10, 25, 2, 30)  # Berlin: 00:30 UTC (CEST) and 01:30 UTC (CET)
    assert local_instant(t, "Europe/Berlin") == utc(2026, 10, 25, 0, 30)
    assert local_instant(t, "Europe/Berlin", late=True) == utc(2026, 10, 25, 1, 30)
    assert local_instant(datetime(2026, 3, 29, 2, 30), "Europe/Berlin") is None


def _r(frm: int, until: int, direction="both", train_type=None) -> TemporaryRestriction:
    return TemporaryRestriction("R", 100.0, 500.0, 45 / 3.6, direction, train_type, "", "", frm, until, "", False)


def test_restrictions_in_force_at_the_window_edges():
    w = operating_day("2026-11-30", "Asia/Tokyo", 3)
    s, e = w.start_s, w.end_s
    ends_at_start, starts_at_end = _r(s - 10 * H, s), _r(e, e + H)
    last_second, first_second = _r(s - H, s + 1), _r(e - 1, e + H)
    whole, inside = _r(s - 1, e), _r(s + H, s + 2 * H)
    got = restrictions_in_force([ends_at_start, starts_at_end, last_second, first_second, whole, inside], w)
    assert got == (last_second, first_second, whole, inside)
    assert [whole_day(r, w) for r in got] == [False, False, True, False]
    assert whole_day(_r(s, e), w)


def test_calendar_gtfs_semantics():
    # 2026-11-30 is a Monday, 2026-12-05 a Saturday
    wk = Service("wk", (True,) * 5 + (False, False), date(2026, 11, 1), date(2026, 12, 31))
    cal = Calendar({"wk": wk}, {("wk", date(2026, 11, 23)): 2, ("wk", date(2026, 12, 5)): 1,
                                ("wk", date(2027, 1, 4)): 1, ("xmas", date(2026, 12, 25)): 1},
                   {"1": "wk", "2": "xmas"})
    assert service_runs(cal, "wk", date(2026, 11, 30))
    assert not service_runs(cal, "wk", date(2026, 11, 29))      # Sunday
    assert not service_runs(cal, "wk", date(2026, 11, 23))      # removed on a Monday
    assert service_runs(cal, "wk", date(2026, 12, 5))           # added on a Saturday
    assert not service_runs(cal, "wk", date(2026, 10, 30))      # a Friday before start_date
    assert service_runs(cal, "wk", date(2027, 1, 4))            # added after end_date
    assert service_runs(cal, "xmas", date(2026, 12, 25)) and not service_runs(cal, "xmas", date(2026, 12, 24))
    assert trains_running(cal, date(2026, 12, 25), ["2", "1"]) == ("2", "1")
    assert trains_running(cal, date(2026, 11, 23), ["2", "1"]) == ()
    assert trains_running(None, date(2026, 11, 23), ["2", "1"]) == ("2", "1")


def test_a_run_that_plans_a_day_already_over_says_so():
    """The sample plans 2026-11-30 whatever the date: a run built after that day's window made bundles every
    vehicle refuses, and said nothing. The run warns (stderr) and the overview has a banner."""
    from planner.line.operating_day import day_over
    from planner.pages.overview import _over

    day = {"day": "2026-11-30", "start": "2026-11-30T03:00:00+09:00", "end": "2026-12-01T03:00:00+09:00",
           "end_utc_s": 1796061600}
    assert day_over(day, 1796061600 - 1) == "" and day_over({}, 1796061600) == ""
    said = day_over(day, 1796061600)
    assert said.startswith("the operating day planned, 2026-11-30 (2026-11-30T03:00:00+09:00 to ")
    assert "every vehicle refuses them" in said
    m = {"operating_day": day, "bundles_release": {"built_at": "2026-12-05T12:00:00Z"}}
    assert "Day already over:" in _over(m) and "2026-11-30" in _over(m)
    assert _over({**m, "bundles_release": {"built_at": "2026-11-30T12:00:00Z"}}) == ""
