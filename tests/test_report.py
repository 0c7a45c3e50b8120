"""The margin HTML page: self-contained, deterministic, flagged rows first, every section present."""
from __future__ import annotations

import dataclasses
import re
import stat

import pandas as pd
import pytest

from planner.report.margins import compute_margins
from planner.pages.margin_report import render_html, stop_markers, write_html
from test_margins import APPROACH, closed_form_line


@pytest.fixture(scope="module")
def line():
    return closed_form_line()


@pytest.fixture(scope="module")
def report(line):
    return compute_margins(line, adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH, conflicts=False)


@pytest.fixture(scope="module")
def page(report, line):
    return render_html(report, stop_markers(line))


def test_deterministic(report, line, page):
    assert render_html(report, stop_markers(line)) == page
    assert not re.search(r"20\d\d-\d\d-\d\d", page)  # no dates anywhere (SVG metadata included)


def test_self_contained(page):
    low = page.lower()
    for bad in ("<script", "<link", " src=", "@import", "url(http", "url(\"http", "href=\"http", "href='http"):
        assert bad not in low, bad
    # the only absolute URLs are XML namespaces / RDF identifiers inside the inline SVGs
    for m in re.finditer(r"https?://[^\s\"'<>]+", page):
        ctx = page[max(0, m.start() - 40):m.start()]
        assert "xmlns" in ctx or "rdf:" in ctx or "resource=" in ctx, ctx


def test_sections_and_charts(page):
    for title in ("Running-time margins", "Margin per interstation along the line", "Run curves:",
                  "Stopping time against adhesion", "Every leg", "Totals per train", "How the numbers are made"):
        assert title in page
    assert page.count("<div class='fig'><svg") == 4  # margin chart per direction, run curves, adhesion (legends: HTML)
    assert "down: S0 → S2, running left to right" in page
    assert "up: S2 → S0, running left to right" in page


def test_headline_counts(report, page):
    # two legs short on a bad day (82 s and 140 s: above their minimum, 81.8 s and 135.8 s, below the bad-day
    # minimum), none impossible, one tight, one unreachable in the closed-form timetable
    cards = re.findall(r"<div class='n'>(\d+)</div><div class='l'>([^<]+)</div>", page)
    got = {label.split(":")[0]: int(n) for n, label in cards}
    assert got["legs short on a bad day"] == 2 and got["legs impossible"] == 0
    assert got["legs tight"] == 1 and got["legs unreachable"] == 1


def test_flagged_rows_first(page):
    table = page[page.index("<h2 id='legs'>Every leg</h2>"):page.index("Totals per train")]
    first_flag = table.index("Flagged legs (4)")
    others = table.index("Other legs (1)")
    assert first_flag < others
    flagged_part = table[first_flag:others]
    assert len(re.findall(r"<tr class='(short_bad_day|tight|unreachable)'", flagged_part)) == 4
    # least remaining margin first: up S2→S1 (82 − 91.7 s), S0→S2 (140 − 145.7), S1→S2 (+3.3), S1→S0 (+198)
    pos = [flagged_part.index(x) for x in ("S2 → S1", "S0 → S2", "S1 → S2", "S1 → S0")]
    assert pos == sorted(pos)
    assert "S0 → S1" in table[others:]


def test_conflicts_section(report, line):
    con = pd.DataFrame([dict(line="test", conflict_id=1, train_a="L1", train_b="R1", direction_a="down",
                             direction_b="down", resource_kind="section", resource_id="E1", interlocking="IXL1",
                             track="D1", station_id="S0", station_name="Start", station_distance_m=0.0,
                             from_m=0.0, to_m=100.0, a_start_s=10.0, a_end_s=50.0, b_start_s=40.0, b_end_s=90.0,
                             overlap_start_s=40.0, overlap_end_s=50.0, overlap_s=10.0, headway_s=30.0,
                             min_headway_s=40.0, rule="timetable-order",
                             decision="L1 first", delay_s=10.0, deadlock=False, stretch="")])
    page = render_html(dataclasses.replace(report, conflicts=con), stop_markers(line))
    sec = page[page.index("<h2 id='conflicts'>Route conflicts</h2>"):]
    assert "1 conflict between 1 pairs of trains on 1 resource (1 timetable-order)" in sec
    assert "Start (S0) track D1, km 0.000–0.100" in sec  # where: station, track, km
    assert "<td>30.0</td><td>40.0</td>" in sec  # headway, minimum headway
    assert "L1 first" in sec
    page = render_html(dataclasses.replace(report, conflicts=None, conflicts_note="no network"), stop_markers(line))
    assert "Not checked: no network" in page
    page = render_html(dataclasses.replace(report, conflicts=con.iloc[0:0]), stop_markers(line))
    assert "found no overlapping occupation windows" in page


def test_write_html_atomic_readable(report, line, tmp_path):
    p = write_html(report, line, tmp_path / "out" / "margins.html")
    assert p.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert stat.S_IMODE(p.stat().st_mode) == 0o644
    assert [x.name for x in p.parent.iterdir()] == ["margins.html"]  # no temp file left


def _shown_cost(cell: str) -> tuple[float, list[float]]:
    """``14.8 = 6.9 + 3.0 + 5.5 − 0.6`` → (14.8, [6.9, 3.0, 5.5, -0.6])."""
    total, rhs = cell.split(" = ")
    terms = re.findall(r"([+−]?)\s*(\d+\.\d)", rhs)
    return float(total), [(-1 if sign == "−" else 1) * float(x) for sign, x in terms]


def flagged_costs(page: str) -> list[tuple[float, list[float]]]:
    """The bad-day cost cells of the page's flagged-legs table."""
    table = page.split("<h3 id='flagged'>Flagged legs", 1)[1].split("</table>", 1)[0]
    return [_shown_cost(c) for c in re.findall(r"<td[^>]*>(-?\d+\.\d = [^<]+)</td>", table)]


def test_flagged_bad_day_cost_adds_up_as_shown(report, page):
    """Issue 17: the shown shares (load + traction + stop + stop model) add up to the shown cost, every flagged leg."""
    assert "load + traction + stop + stop model" in page
    costs = flagged_costs(page)
    assert len(costs) == 4  # two infeasible, one tight, one unreachable
    for total, terms in costs:
        assert len(terms) == 4
        assert round(sum(terms), 6) == total
    assert any(t[3] != 0.0 for _, t in costs)  # the stop model share is there to be seen


def test_shares_add_up_after_rounding():
    """Rounding each share on its own would show 0.1 + 0.1 + 0.1 = 0.2 (or 0.3 = 0.2)."""
    from planner.pages.margin_report import added_up

    rng = __import__("numpy").random.default_rng(17)
    for _ in range(2000):
        parts = list(rng.uniform(-3.0, 9.0, size=4))
        total, shown = added_up(float(sum(parts)), parts)
        assert round(sum(shown), 6) == total
        assert all(abs(a - b) < 0.1 + 1e-9 for a, b in zip(shown, parts))
    assert added_up(0.15, [0.05, 0.05, 0.05]) == (0.1, [0.1, 0.0, 0.0])
