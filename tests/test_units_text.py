"""Times and adhesion as a person reads them: h:mm:ss totals, HH:MM:SS clock times, km/h/s levels."""
from __future__ import annotations

import math

import pandas as pd

from planner.line.units import clock, hms, kmh_s, percent


def test_durations_and_clock_times():
    assert hms(258929) == "71:55:29"  # 71 h 55 min 29 s: 71*3600 + 55*60 + 29
    assert hms(-83.4, sign=True) == "−0:01:23" and hms(0.4, sign=True) == "+0:00:00"
    assert hms(59.6) == "0:01:00" and hms(math.nan) == "–"
    assert clock(5 * 3600 + 2 * 60 + 25) == "05:02:25" and clock(25 * 3600 + 600) == "25:10:00"
    assert clock(None) == "" and clock(math.nan) == ""


def test_adhesion_levels_come_back_as_written():
    for level in (0.81, 1.9, 2.5, 2.6, 3.2, 3.7):
        assert kmh_s(level / 3.6) == level


def test_report_totals_are_h_mm_ss():
    from planner.pages.margin_report import totals_table

    row = dict(level="line", direction="down", train_type="all", n_trains=178, n_legs=2000,
               min_running_time_s=258929.0, scheduled_running_time_s=300000.0, margin_s=41071.0,
               margin_percent=15.9, remaining_margin_s=-83.0, min_remaining_margin_s=-0.5, n_infeasible=1, n_impossible=0, n_short_bad_day=1,
               n_tight=0, n_unreachable=0, n_supplement_short=0, energy_saved_kwh=10.0)
    html = totals_table(pd.DataFrame([row]))
    assert "<td>71:55:29</td><td>83:20:00</td><td>11:24:31</td>" in html
    assert "<td>−0:01:23</td>" in html and "258929" not in html


def test_numbers_shown_as_zero_carry_no_sign():
    """Issue 36: a margin of -0.03 s printed "-0.0"; every page prints it 0.0 (the margin report, the
    running-time tables, the charts and the restrictions page share planner.line.units.fixed)."""
    from planner.line.units import fixed
    from planner.pages.restrictions import _num

    assert [fixed(x) for x in (-0.03, -0.049, 0.04, 0.0, -0.0)] == ["0.0"] * 5
    assert [fixed(x, 1, True) for x in (-0.03, 0.04, 0.05001, -0.05001)] == ["0.0", "0.0", "+0.1", "-0.1"]
    assert fixed(-0.4, 0, True) == "0" and fixed(-57.04) == "-57.0" and fixed(math.nan) == "–"
    assert _num(-0.03) == "0.0" and _num(12.34) == "+12.3" and _num(-0.4, "{:.0f}") == "0" and _num(None) == ""


def test_percent_is_whole_percent_with_a_space():
    """As the pages write ``ratio 100 %``: the on-time ratio beside it the same way."""
    assert percent(0.7) == "70 %"
    assert percent(1.0) == "100 %"
    assert percent(0.655) == "66 %" and percent(0.645) == "64 %"  # halves round to even, as Python formats
    assert percent(0.0) == "0 %" and percent(-0.001) == "0 %"  # never "-0 %"


def test_percent_of_no_value_is_the_dash():
    assert percent(math.nan) == "–" and percent(None) == "–" and percent(math.inf) == "–"


def test_a_flagged_value_is_never_shown_as_zero():
    """A leg 0.03 s short is flagged impossible; the margin report showed it as "0.0 (0.0)"."""
    from planner.line.units import shown
    from planner.pages.margin_report import _f

    assert shown(-0.03) == "-0.03" and shown(-0.03, sign=True) == "-0.03" and shown(0.03, sign=True) == "+0.03"
    assert shown(-0.0004) == "-0.0004" and shown(-0.00001) == "0.0000"  # four decimals at the most
    assert shown(0.0, sign=True) == "0.0" and shown(12.345) == "12.3" and shown(float("nan")) == "–"
    assert _f(-0.03, 1, True) == "-0.03" and _f(-0.0002, 1) == "-0.0002" and _f(None) == "–"
