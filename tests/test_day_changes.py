"""The changes against the previous operating day: restrictions added, lifted, changed and kept, trains added
and cancelled, their effects; the section of the restrictions page and the overview's paragraph.

Days, validities and calendars are built by hand around two windows (Sunday 2026-11-29 and Monday
2026-11-30, 03:00 to 03:00 in Tokyo), so what is added or lifted is known by construction.
"""
from __future__ import annotations

import json
import textwrap
from datetime import date

import pandas as pd
import pytest

from linedb import quick_job, write_line_db
from planner.line.daily import Calendar, Service, TemporaryRestriction
from planner.line.loader import load_line
from planner.line.operating_day import DayInputs, operating_day, trains_running
from planner.line.units import KMH
from planner.report.day_changes import calendar_covers, compare_days, counts, flagged_legs

TZ = "Asia/Tokyo"
SUN = operating_day(date(2026, 11, 29), TZ, 3)
MON = operating_day(date(2026, 11, 30), TZ, 3)
H = 3600


def tsr(rid: str, t0: int, t1: int, kmh: float = 45.0, a: float = 1000.0, b: float = 1400.0) -> TemporaryRestriction:
    return TemporaryRestriction(rid, a, b, kmh * KMH, "both", None, f"from {t0}", f"until {t1}", t0, t1, "test",
                                False)


def in_force(day, rs):
    return tuple(r for r in rs if r.valid_from_s < day.end_s and r.valid_until_s > day.start_s)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    return load_line(write_line_db(tmp_path_factory.mktemp("l") / "tiny"))


def calendar(weekdays_of_101=(True,) * 5 + (False, False), start=date(2026, 11, 1)) -> Calendar:
    """101 (EMU10 A→B→C, stops at B) in service ``wk``; 202 (EMU6 C→A, passes B) every day."""
    return Calendar({"wk": Service("wk", tuple(weekdays_of_101), start, date(2026, 12, 31)),
                     "all": Service("all", (True,) * 7, start, date(2026, 12, 31))}, {},
                    {"101": "wk", "202": "all"})


def test_restrictions_added_lifted_and_kept_by_their_validity(tiny):
    rs = [tsr("BOTH", SUN.start_s - H, MON.end_s + H),            # the whole of both days
          tsr("GONE", SUN.start_s + H, MON.start_s),               # ends as Monday starts: Sunday only
          tsr("NEW", MON.start_s + 5 * H, MON.start_s + 6 * H),    # a night possession on Monday
          tsr("PM", SUN.start_s + 11 * H, MON.end_s + 9 * H)]      # from Sunday afternoon
    ids = ("101", "202")
    prev, today = DayInputs(SUN, in_force(SUN, rs), ids), DayInputs(MON, in_force(MON, rs), ids)
    c = compare_days(prev, today, tiny)
    assert [r["restriction_id"] for r in c["restrictions_added"]] == ["NEW"]
    assert [r["restriction_id"] for r in c["restrictions_lifted"]] == ["GONE"]
    assert c["restrictions_changed"] == []
    assert c["restrictions_kept"] == [{"restriction_id": "BOTH", "whole_day_before": True, "whole_day_after": True},
                                      {"restriction_id": "PM", "whole_day_before": False, "whole_day_after": True}]
    assert c["restrictions_added"][0]["whole_day"] is False and c["restrictions_lifted"][0]["whole_day"] is False
    assert (c["previous_day"], c["previous_weekday"]) == ("2026-11-29", "Sunday")
    assert counts(c) == {"restrictions_added": 1, "restrictions_lifted": 1, "restrictions_changed": 0,
                         "trains_added": 0, "trains_cancelled": 0}


def test_a_restriction_in_force_both_days_with_another_limit_is_changed(tiny):
    old = tsr("R", SUN.start_s - H, MON.end_s + H, kmh=45.0)
    new = tsr("R", SUN.start_s - H, MON.end_s + H, kmh=25.0, b=1500.0)
    c = compare_days(DayInputs(SUN, (old,), ()), DayInputs(MON, (new,), ()), tiny)
    (x,) = c["restrictions_changed"]
    assert x["fields"] == ["end_m", "limit_kmh"] and (x["before"]["limit_kmh"], x["after"]["limit_kmh"]) == (45, 25)
    assert not c["restrictions_added"] and not c["restrictions_lifted"] and not c["restrictions_kept"]


def test_trains_added_on_a_weekday_and_cancelled_on_saturday_with_their_legs(tiny):
    cal = calendar()
    ids = [t.train_id for t in tiny.trains]

    def day(w):
        return DayInputs(w, (), trains_running(cal, w.day, ids))

    c = compare_days(day(SUN), day(MON), tiny, cal.train_service)
    t = c["trains_added"]
    # 101 runs Monday to Friday only: added on Monday; 202 runs every day: neither
    assert (t["count"], t["train_ids"]) == (1, ["101"]) and c["trains_cancelled"]["count"] == 0
    assert t["by_service"] == [{"service_id": "wk", "train_type": "EMU10", "trains": 1}]
    # 101 stops at A, B and C: two legs
    assert t["legs"] == [{"train_type": "EMU10", "direction": "down", "origin": "A", "destination": "B", "trains": 1},
                         {"train_type": "EMU10", "direction": "down", "origin": "B", "destination": "C", "trains": 1}]
    fri, sat = (operating_day(date(2026, 12, d), TZ, 3) for d in (4, 5))
    c = compare_days(day(fri), day(sat), tiny, cal.train_service)
    assert c["trains_cancelled"]["train_ids"] == ["101"] and c["trains_added"]["count"] == 0
    # 202 passes B: one leg C→A
    c = compare_days(DayInputs(SUN, (), ("101",)), DayInputs(MON, (), ("202",)), tiny, cal.train_service)
    assert c["trains_added"]["legs"] == [{"train_type": "EMU6", "direction": "up", "origin": "C", "destination": "A",
                                          "trains": 1}]
    assert c["trains_cancelled"]["train_ids"] == ["101"]


def test_the_first_day_of_a_feed_does_not_compare_the_trains(tiny):
    cal = calendar(start=date(2026, 11, 30))  # the feed's services start on Monday
    assert not calendar_covers(cal, SUN.day) and calendar_covers(cal, MON.day) and calendar_covers(None, SUN.day)
    dated = Calendar(cal.services, {("wk", date(2026, 11, 29)): 1}, cal.train_service)
    assert calendar_covers(dated, SUN.day)  # a dated exception speaks of the day
    c = compare_days(DayInputs(SUN, (), ()), DayInputs(MON, (), ("101", "202")), tiny, cal.train_service,
                     prev_covered=False)
    assert c["trains_compared"] is False and c["trains_added"] is None and "2026-11-29" in c["note"]
    assert counts(c)["trains_added"] == 0


def test_the_effects_are_the_restrictions_losses_lost_when_added_regained_when_lifted(tiny):
    from planner.job.day import day_line
    from planner.report.restriction_effects import restriction_losses

    new = tsr("NEW", MON.start_s, MON.end_s, kmh=30.0)              # 1000–1400 m: between A (200) and B (2500)
    gone = tsr("GONE", SUN.start_s, SUN.end_s, kmh=30.0, a=3500.0, b=3900.0)  # between B and C
    lt = restriction_losses(day_line(tiny, DayInputs(MON, (new,), ())))
    lp = restriction_losses(day_line(tiny, DayInputs(SUN, (gone,), ())))
    c = compare_days(DayInputs(SUN, (gone,), ()), DayInputs(MON, (new,), ()), tiny, losses_prev=lp,
                     losses_today=lt)
    added, lifted = c["restrictions_added"][0]["legs"], c["restrictions_lifted"][0]["legs"]
    # both directions, both train types, each on the one interstation its stretch lies in
    assert {(g["train_type"], g["origin"], g["destination"]) for g in added} == {
        ("EMU10", "A", "B"), ("EMU10", "B", "A"), ("EMU6", "A", "B"), ("EMU6", "B", "A")}
    assert {(g["origin"], g["destination"]) for g in lifted} == {("B", "C"), ("C", "B")}
    # a 30 km/h stretch of 400 m costs time on every leg it reaches: at least the stretch at 30 km/h against
    # the same stretch at the line's 100 km/h
    bound = 400.0 / (30 * KMH) - 400.0 / (100 * KMH)
    assert all(g["time_s"] >= bound for g in added + lifted)


def test_the_legs_of_added_trains_that_are_flagged():
    rows = pd.DataFrame([dict(train_type="E", direction="down", origin="A", destination="B", train_ids=["1", "9"],
                              impossible=True, tight=True),
                         dict(train_type="E", direction="down", origin="B", destination="C", train_ids=["1"],
                              impossible=False, tight=False),
                         dict(train_type="E", direction="up", origin="B", destination="A", train_ids=["8"],
                              impossible=False, tight=True)])
    c = {"trains_added": {"train_ids": ["1", "2"]}}
    assert flagged_legs(c, rows, ("impossible", "tight")) == [
        {"train_type": "E", "direction": "down", "origin": "A", "destination": "B", "flag": "impossible",
         "trains": ["1"]}]
    assert flagged_legs(c, None, ("impossible",)) == [] and flagged_legs({"trains_added": None}, rows, ()) == []


def test_the_summary_names_the_restrictions_and_counts_the_trains():
    from planner.pages.day_changes import summary

    r = [{"restriction_id": f"R{i}"} for i in range(6)]
    c = {"restrictions_added": r[:1], "restrictions_lifted": r, "restrictions_changed": [], "trains_compared": True,
         "trains_added": {"count": 2, "flagged_legs": [{"flag": "impossible"}, {"flag": "short_bad_day"},
                                                       {"flag": "impossible"}]},
         "trains_cancelled": {"count": 1}}
    assert summary(c) == ("R0 added; R0, R1, R2, R3 and 2 more lifted; 2 trains added (3 of their legs flagged: "
                          "2 impossible, 1 short on a bad day), 1 train cancelled")
    assert summary({"trains_compared": False}) == "no restriction added or lifted; trains not compared"


def test_a_line_without_a_feed_has_no_section():
    from planner.pages.day_changes import overview_html, section_html

    assert section_html(None) == "" and section_html({"restrictions": []}) == ""
    bare = {"line_id": "x", "feed": None, "restrictions": [], "trains_running": 2}
    fed = {"line_id": "y", "feed": "feeds/y", "restrictions": [], "trains_running": 2,
           "changes": {"previous_day": "2026-11-29", "previous_weekday": "Sunday", "trains_compared": True}}
    day = {"day": "2026-11-30", "start_hour": 3, "time_zone": TZ, "lines": [bare, fed]}
    page = overview_html(day)
    assert "x</b>: no daily feed" in page and page.count("Since ") == 1 and "Since Sunday 2026-11-29" in page
    # a job without feeds plans the static line: no operating day to explain
    assert overview_html({**day, "lines": [bare]}) == "" and overview_html(None) == ""


def test_a_run_shows_the_changes_on_the_restrictions_page_and_the_overview(tmp_path):
    """End to end on the tiny line: a restriction from Monday 04:00 and a weekday train are new against
    Sunday; the other train runs every day."""
    from planner.job.config import load_job
    from planner.job.pipeline import run_job
    from test_daily_feed import OK, write_feed

    write_line_db(tmp_path / "lines" / "tiny", nodes=None, edges=None)
    flags = dict(monday=True, tuesday=True, wednesday=True, thursday=True, friday=True)
    write_feed(tmp_path / "feeds" / "tiny", restrictions=[{**OK, "valid_from": "2026-11-30T04:00"}],
               calendar=[dict(service_id="wk", **flags, saturday=False, sunday=False, start_date="2026-11-01",
                              end_date="2026-12-31"),
                         dict(service_id="all", **flags, saturday=True, sunday=True, start_date="2026-11-01",
                              end_date="2026-12-31")],
               train_services=[dict(train_id="101", service_id="wk"), dict(train_id="202", service_id="all")])
    job = tmp_path / "job.toml"
    job.write_text(quick_job([tmp_path / "lines" / "tiny"], tmp_path / "out") + textwrap.dedent(f"""
        [day]
        day = "2026-11-30"
        time_zone = "{TZ}"
        feeds = ["{tmp_path / 'feeds' / 'tiny'}"]
    """))
    run_job(load_job(job), show_progress=False)
    run = tmp_path / "out" / "latest"
    (rec,) = json.loads((run / "manifest.json").read_text())["operating_day"]["lines"]
    c = rec["changes"]
    assert [r["restriction_id"] for r in c["restrictions_added"]] == ["R1"] and not c["restrictions_lifted"]
    assert c["trains_added"]["train_ids"] == ["101"] and c["trains_cancelled"]["count"] == 0
    assert "flagged_legs" in c["trains_added"] and "restrictions_effect" in rec
    page = (run / "report" / "tiny_restrictions.html").read_text()
    assert "Since the previous operating day (Sunday 2026-11-29)</h2>" in page
    assert "R1 added; 1 train added" in page and "EMU10</b>: A→B +" in page
    overview = (run / "index.html").read_text()
    assert "Operating day Monday 2026-11-30" in overview
    assert "Since Sunday 2026-11-29: R1 added; 1 train added" in overview
    assert "href='report/tiny_restrictions.html#changes'" in overview
