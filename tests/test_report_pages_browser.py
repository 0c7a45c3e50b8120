"""The margin report, the running-time tables and the speed–distance charts in a real browser (issue 36).

What a planner trips over on these pages, each checked where a person sees it, in Debian's ``chromium``
(``tests/browser.py``): a page wider than the window (at 1400 px no table may be wider than its box, at
1000 px the page itself may not scroll sideways), ``-0.0`` printed, flagged legs that do not say which
trains run them, hover notes promised but missing, no run id or operating day on a page, and the day's
temporary speed restrictions drawn as if they were permanent.
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from browser import Browser, find_chromium

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="needs chromium (apt-get install chromium)")

RUN = "r0007-0123456789"
DAY = {"day": "2026-11-30", "time_zone": "Asia/Tokyo", "start_hour": 3, "start": "2026-11-30T03:00:00+09:00",
       "end": "2026-12-01T03:00:00+09:00"}
DAY_WORDS = "operating day Monday 2026-11-30, 03:00 to 03:00 the next day (Asia/Tokyo)"  # 2026-11-30 is a Monday
NEG_ZERO = re.compile(r"(?<![\d.])[-−]0\.0+(?![\d])")
"""``-0.0``, ``−0.00``: a sign on a value shown as zero."""


@pytest.fixture(scope="module")
def wide():
    with Browser(1400, 900) as b:
        yield b


@pytest.fixture(scope="module")
def narrow():
    with Browser(1000, 900) as b:
        yield b


def _clean(page) -> None:
    assert page.errors == [] and page.failed == [], (page.errors, page.failed)


def _fits(page, width: int) -> None:
    """No sideways page scroll at ``width``, and nothing but a table in its scroll box wider than the page."""
    assert page.eval("innerWidth") == width
    assert page.eval("document.documentElement.scrollWidth") <= width
    over = page.eval("[...document.querySelectorAll('main > *:not(.tw), .fig svg')].filter(e => "
                     "e.getBoundingClientRect().right > innerWidth + 0.5).map(e => e.tagName + '.' + e.className)")
    assert over == []


@pytest.fixture(scope="module")
def report():
    """The closed-form line's margins (tests/test_margins.py: two infeasible legs, a tight one, an unreachable
    one, a leg passing a station), with what the sample's widest rows have: three flags and a short supplement
    on one leg, many trains on it, and a margin a few hundredths of a second below zero on another."""
    from planner.report.margins import compute_margins
    from test_margins import APPROACH, closed_form_line

    rep = compute_margins(closed_form_line(), adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH, conflicts=False)
    rows = rep.rows.copy()
    bad = rows.index[rows.infeasible.astype(bool)]  # impossible or short on a bad day
    assert len(bad) >= 1
    k = bad[0]
    rows.at[k, "inaccurate"] = True
    rows.at[k, "supplement_met"] = False
    rows.at[k, "train_ids"] = np.array([f"{n}D" for n in range(1001, 1019, 2)], dtype=object)  # 9 trains
    rows.at[k, "n_trains"] = 9
    ok = rows.index[~rows.infeasible.astype(bool) & ~rows.unassessed.astype(bool)]
    rows.at[ok[0], "margin_s"] = -0.032
    rows.at[ok[0], "margin_percent"] = -0.011
    rows.at[ok[0], "arrival_error_s"] = -0.04
    return dataclasses.replace(rep, rows=rows)


@pytest.fixture(scope="module")
def report_page(report, tmp_path_factory):
    from planner.pages.margin_report import render_html, stop_markers
    from planner.pages.run_head import nav_html
    from test_margins import closed_form_line

    nav = nav_html([("overview", "../index.html"), ("running-time tables", "../timetable/t_timetable.html")], RUN, DAY)
    path = tmp_path_factory.mktemp("report") / "margins.html"
    path.write_text(render_html(report, stop_markers(closed_form_line()), nav=nav,
                                trains_href="../timetable/t_timetable.html"), encoding="utf-8")
    return path


@pytest.mark.parametrize("width", [1400, 1000])
def test_margin_report_fits_the_window(report_page, wide, narrow, width):
    page = (wide if width == 1400 else narrow).open(report_page)
    _clean(page)
    _fits(page, width)
    # every table fits its box: at 1400 px nothing scrolls sideways, not even inside a table's box
    boxes = page.eval("[...document.querySelectorAll('.tw')].map(b => [b.scrollWidth, b.clientWidth])")
    assert len(boxes) >= 4
    assert all(s <= c + 1 for s, c in boxes), boxes


def test_margin_report_says_no_minus_zero_and_names_the_trains_of_flagged_legs(report, report_page, wide):
    from planner.report.leg_flags import any_flag

    page = wide.open(report_page)
    text = page.eval("document.body.textContent")  # the charts' SVG text too
    assert not NEG_ZERO.search(text), NEG_ZERO.search(text)
    # the run and its operating day, above the title
    assert page.eval("document.querySelector('main > p.nav').innerText").endswith(f"run {RUN} · {DAY_WORDS}")
    # each flagged leg names its trains, linked to their running-time tables; past six, "… N more" names all on hover
    sched = report.rows[report.rows.scheduled_running_time_s.notna()]
    flagged = sched[any_flag(sched) & ~sched.unassessed.astype(bool)]
    shown = page.eval("[...document.querySelectorAll('table.flagged .ids')].map(s => [s.innerText,"
                      " [...s.querySelectorAll('a')].map(a => a.getAttribute('href')),"
                      " (s.querySelector('.more') || {}).title || ''])")
    assert len(shown) == len(flagged) >= 3
    expect = sorted(", ".join(map(str, ids)) for ids in flagged.train_ids)
    named = []
    for words, hrefs, title in shown:
        ids = [h.split("#train-")[1] for h in hrefs]
        assert hrefs == [f"../timetable/t_timetable.html#train-{t}" for t in ids] and 1 <= len(ids) <= 6
        assert words.startswith("trains: " + ", ".join(ids))
        if title:
            assert words.endswith(f"… {len(title.split(', ')) - 6} more") and title.startswith(", ".join(ids))
        named.append(title or ", ".join(ids))
    assert sorted(named) == expect
    assert "… 3 more" in " ".join(w for w, _, _ in shown)  # the leg of nine trains


def test_every_leg_row_has_the_hover_note_the_page_promises(report, report_page, wide):
    page = wide.open(report_page)
    caption = page.eval("[...document.querySelectorAll('p.caption')].map(p => p.innerText).join(' ')")
    assert "Hover a row for the trains that run it" in caption
    titles = page.eval("[...document.querySelectorAll('h2 ~ .tw tr')].filter(r => r.cells.length > 5"
                       " && r.cells[1].innerText.match(/^(down|up)$/)).map(r => r.title)")
    expect = [f"{len(x)} train{'s' if len(x) != 1 else ''}: " + ", ".join(x[:12]) + (f" … {len(x) - 12} more"
              if len(x) > 12 else "") for x in report.rows.train_ids]
    assert sorted(t.split("; ")[0] for t in titles) == sorted(expect)


@pytest.fixture(scope="module")
def run_pages(tmp_path_factory):
    """A run folder's running-time tables and charts of the tiny line (tests/linedb.py) on a day with a temporary
    restriction TSR-T1 (40 km/h, km 0.600–0.900, down) on train 101's leg A → B, written by the nightly job's code."""
    from types import SimpleNamespace

    from planner import load_line
    from planner.job.config import Job
    from planner.job.train_views import train_views
    from planner.line.daily import TemporaryRestriction
    from planner.line.units import KMH
    from planner.report.margins import compute_margins
    from linedb import write_line_db

    tmp = tmp_path_factory.mktemp("run")
    static = load_line(write_line_db(tmp / "tiny", nodes=None, edges=None))
    tsr = TemporaryRestriction("TSR-T1", 600.0, 900.0, 40.0 * KMH, "down", None, "2026-11-29T14:20",
                               "2026-12-02T16:00", 0, 1, "rail defect", False)
    line = dataclasses.replace(static, speed_limits=static.speed_limits + (tsr.as_speed_limit(),))
    job = Job(str(tmp / "job.toml"), str(tmp))
    job = dataclasses.replace(job, parallel=dataclasses.replace(job.parallel, n_jobs=1))
    from planner.job.cache import Cache
    from planner.job.units import Progress, Runner

    runner = Runner(job, Cache(tmp / "cache"), Progress(enabled=False))  # the job's units, cached
    run = tmp / RUN
    train_views(job, line, run, compute_margins(line, conflicts=False), runner, SimpleNamespace(rows={}),
                run_id=RUN, day=DAY)
    return run, static, line


@pytest.mark.parametrize("width", [1400, 1000])
def test_timetable_and_chart_pages_name_the_run_and_fit(run_pages, wide, narrow, width):
    run, _, _ = run_pages
    b = wide if width == 1400 else narrow
    for path in (run / "timetable" / "tiny_timetable.html", run / "charts" / "tiny" / "down_EMU10_A-B_200s.html"):
        page = b.open(path)
        _clean(page)
        _fits(page, width)
        nav = page.eval("document.querySelector('main > p.nav').innerText")
        assert nav.endswith(f"run {RUN} · {DAY_WORDS}"), nav
        assert not NEG_ZERO.search(page.eval("document.body.textContent"))
        boxes = page.eval("[...document.querySelectorAll('.tw')].map(b => [b.scrollWidth, b.clientWidth])")
        assert all(s <= c + 1 for s, c in boxes), boxes  # the tables fit at 1000 px too


def test_chart_shows_the_days_temporary_restriction_apart_from_the_permanent_limits(run_pages, wide):
    from planner.pages.speed_chart import _limit_steps, temporary_limits

    run, static, line = run_pages
    page = wide.open(run / "charts" / "tiny" / "down_EMU10_A-B_200s.html")
    _clean(page)
    svg_text = page.eval("[...document.querySelectorAll('.fig svg text')].map(t => t.textContent).join('|')")
    assert "TSR-T1" in svg_text and "40 km/h" in svg_text  # on the chart, at the restriction
    legend = page.eval("document.querySelector('.fig .legend').innerText")
    assert "temporary speed restriction" in legend and "permanent speed limit" in legend  # apart, in the legend
    caption = page.eval("[...document.querySelectorAll('p.caption')].map(p => p.innerText).join(' ')")
    assert "TSR-T1 40 km/h on km 0.600–0.900" in caption
    # the permanent limit line is the static line's: the restriction does not dip it
    for a, b in zip(_limit_steps(line, "down", "EMU10", 0.0, 2600.0), _limit_steps(static, "down", "EMU10", 0.0, 2600.0)):
        assert np.array_equal(a, b)
    assert [s.restriction_id for s in temporary_limits(line, "down", "EMU10", 0.0, 2600.0)] == ["TSR-T1"]
    assert temporary_limits(line, "up", "EMU6", 0.0, 5000.0) == []  # down only
    # a leg it does not reach says so
    other = wide.open(run / "charts" / "tiny" / "down_EMU10_B-C_270s.html")
    assert "TSR-T1" not in other.eval("document.body.textContent")
    assert "No temporary speed restriction of the day is in force on this leg" in other.eval("document.body.innerText")


def test_overview_says_the_operating_day_and_the_run_date(wide, tmp_path):
    from planner.pages.overview import write_overview

    run = tmp_path / RUN
    run.mkdir()
    manifest = {"run_id": RUN, "run_date": "2026-11-27", "operating_day": DAY, "job": "nightly", "lines": []}
    page = wide.open(write_overview(run, manifest))
    _clean(page)
    _fits(page, 1400)
    assert page.eval("document.querySelector('p.date').innerText") == (
        "O" + DAY_WORDS[1:] + " · run date 2026-11-27 (every dataset's run_date= folder)")
