"""Flags that say what they mean: *impossible* (below the minimum) apart from *short on a bad day*.

Before, a leg scheduled 0.5 s under its minimum and a leg with 19.8 s of margin that is 0.2 s short
on the bad day were both ``infeasible``, with the same red badge, and a margin going from 7.1 s to
-0.5 s changed no flag. The numbers below are made up so that each case has one answer.
"""
from __future__ import annotations

import dataclasses
import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from planner.report.changes import LineChanges, _leg_changes
from planner.report.leg_flags import FLAGS, flag_reasons, main_cause
from planner.report.margin_datasets import datasets
from planner.report.margin_rule import MarginRule, margin_columns
from planner.report.margins import compute_margins

# minimum 100 s and bad-day minimum 120 s on every leg; scheduled times:
SCHED = {"below the minimum": 99.5, "0.2 s short on the bad day": 119.8, "exactly the minimum": 100.0,
         "3 s left": 123.0, "10 s left": 130.0}


def _cols():
    n = len(SCHED)
    return margin_columns([100.0] * n, list(SCHED.values()), [120.0] * n, [300.0] * n, [2000.0] * n,
                          MarginRule(tight_threshold_s=5.0))


def test_impossible_and_short_on_the_bad_day_are_told_apart():
    c = _cols()
    got = {k: {f for f in ("impossible", "short_bad_day", "infeasible", "tight") if c[f][i]}
           for i, k in enumerate(SCHED)}
    assert got == {"below the minimum": {"impossible", "infeasible"},
                   "0.2 s short on the bad day": {"short_bad_day", "infeasible"},
                   "exactly the minimum": {"short_bad_day", "infeasible"},  # meets the minimum, not the bad day
                   "3 s left": {"tight"}, "10 s left": set()}


def test_flag_reasons_say_how_far_and_why():
    c = _cols()
    shares = {"degraded_loss_load_s": 9.0, "degraded_loss_traction_s": 6.0, "degraded_loss_stop_s": 4.0,
              "degraded_loss_stop_model_s": 1.0}  # add up to 120 - 100
    rows = pd.DataFrame({"scheduled_running_time_s": list(SCHED.values()), "min_running_time_s": 100.0,
                         "degraded_min_running_time_s": 120.0, "slowest_running_time_s": 300.0,
                         "closed_loop_max_error_s": np.nan, "unassessed_reason": "", **shares, **c})
    reason, cause = flag_reasons(rows, 5.0, 10.0)
    assert reason[0].startswith("impossible: scheduled 99.5 s, 0.5 s below the minimum running time 100.0 s")
    assert reason[1] == ("short on a bad day by 0.2 s: margin 19.8 s, the bad day costs 20.0 s (load 9.0, "
                         "traction 6.0, adhesion 4.0, stop model 1.0 s), most of it the load")
    assert reason[3].startswith("tight: 3.0 s left on a bad day (below 5 s)")
    assert reason[4] == ""
    assert cause == ["", "load", "load", "load", ""]  # the cause is said where the bad day decides the flag
    assert main_cause([1.0, 2.0, 5.0, 4.0]) == "adhesion" and main_cause([-1.0, 0.0, np.nan, 0.0]) == ""


def _margin_row(margin_s, remaining_s, **flags):
    return {"direction": "down", "train_type": "T", "origin": "A", "destination": "B", "passes": [],
            "scheduled_running_time_s": 107.1, "train_ids": ["1"], "min_running_time_s": 107.1 - margin_s,
            "margin_s": margin_s, "remaining_margin_s": remaining_s, **flags}


def _diff(old, new):
    ch = LineChanges("tiny", "r1", "r2")
    _leg_changes(ch, pd.DataFrame([old]), pd.DataFrame([new]), {}, 0.5, lambda r: (None, None, 0.0))
    return {(r["field"], r["after"]): r["detail"] for r in ch.of("flag")}


def test_a_margin_going_below_zero_is_a_flag_change():
    # 7.1 s of margin, 2.9 s short on a bad day (it costs 10 s) -> the minimum itself grows by 7.6 s
    before = _margin_row(7.1, -2.9, impossible=False, short_bad_day=True, infeasible=True, tight=False,
                         unreachable=False, inaccurate=False, unassessed=False)
    after = _margin_row(-0.5, -10.5, impossible=True, short_bad_day=False, infeasible=True, tight=False,
                        unreachable=False, inaccurate=False, unassessed=False)
    got = _diff(before, after)
    assert got == {("impossible", "True"): "leg T down A→B (scheduled 107.1 s): impossible appeared "
                                           "(margin 7.1 → -0.5 s)",
                   ("short_bad_day", "False"): "leg T down A→B (scheduled 107.1 s): short on a bad day cleared "
                                               "(bad-day margin -2.9 → -10.5 s)"}
    # a run from before the split has only `infeasible`: its impossible and short are derived, the same change
    old = {k: v for k, v in before.items() if k not in ("impossible", "short_bad_day")}
    assert _diff(old, after) == got
    # null (unknown: the leg is unassessed) is no change of short_bad_day; unassessed itself appears
    una = after | {"impossible": False, "margin_s": 7.1, "short_bad_day": None, "infeasible": None,
                   "unassessed": True}
    assert set(_diff(before, una)) == {("unassessed", "True")}


def test_datasets_leave_only_the_unknown_flags_null():
    rows = pd.DataFrame({
        "min_running_time_s": [100.0, 100.0, np.nan], "unassessed": [False, True, True],
        "impossible": [False, True, False], "short_bad_day": [True, False, False],
        "infeasible": [True, True, False], "tight": [False, False, False], "n_trains": [1, 1, 1]})
    totals = pd.DataFrame({c: [0] for c in ("n_trains", "n_legs", "n_supplement_short", "n_impossible",
                                             "n_short_bad_day", "n_infeasible", "n_tight", "n_unreachable",
                                             "n_unassessed", "n_inaccurate")} | {"first_departure_s": [21600.0]})
    t = datasets(SimpleNamespace(rows=rows, totals=totals))["margins"]
    assert t.column("impossible").to_pylist() == [False, True, None]  # needs only the minimum
    assert t.column("short_bad_day").to_pylist() == [True, None, None]
    assert t.column("infeasible").to_pylist() == [True, True, None]  # impossible decides it on an unassessed leg
    assert t.column("tight").to_pylist() == [False, None, None]


def test_an_edited_timetable_below_the_minimum_is_impossible_on_every_page(tmp_path):
    from test_margins import APPROACH, SMALL_GRID, TRAINS, closed_form_line, row, t_run

    from planner.pages.margin_report import render_html
    from planner.pages.overview import render_overview

    # L1's first leg S0 -> S1: 100 s -> 80 s, below the closed-form minimum L/V + V = 81.78 s
    l1 = TRAINS[0]
    calls = list(l1.calls)
    calls[1] = dataclasses.replace(calls[1], arrival_s=80.0)
    edited = (dataclasses.replace(l1, calls=tuple(calls)),) + TRAINS[1:]
    rep = compute_margins(closed_form_line(edited), train_types=["T"], adhesion_kmh_s="3.0:3.5:0.5",
                          approach_m=APPROACH, conflicts=False, ratios=SMALL_GRID)
    r = row(rep, "down", "S0", "S1")
    tmin = t_run(1500.0, 1.0)
    assert bool(r.impossible) and not bool(r.short_bad_day) and bool(r.infeasible)
    assert f"{tmin - 80.0:.1f} s below the minimum running time {tmin:.1f} s" in r.flag_reason
    tot = rep.totals.set_index(["level", "train_id"]).loc[("train", "L1")]
    assert (tot.n_impossible, tot.n_short_bad_day, tot.n_infeasible) == (1, 0, 1)
    page = render_html(rep, {})
    cards = dict((label.split(":")[0], int(n)) for n, label in
                 re.findall(r"<div class='n'>(\d+)</div><div class='l'>([^<]+)</div>", page))
    assert cards["legs impossible"] == 1 and cards["legs short on a bad day"] == 2
    assert page.count("class='badge b-impossible'>impossible<") == 2  # the flagged legs and every leg
    assert page.count("class='badge b-short_bad_day'>short on a bad day<") == 4
    # the run overview: one card per flag, the margin report's first
    flags = {f: int(rep.rows[f].sum()) for f in FLAGS} | {"conflicts": 0}
    ov = render_overview(tmp_path, {"run_id": "r1", "flags": flags, "lines": []})
    shown = re.findall(r"<div class='n'>(\d+)</div><div class='l'>([^<]+)</div>", ov)
    assert [lab.split(":")[0] for _, lab in shown][:3] == ["legs unassessed", "legs impossible",
                                                          "legs short on a bad day"]
    assert ("1", "legs impossible: scheduled below the minimum running time (no driving makes it)") in shown


@pytest.mark.parametrize("flag", FLAGS)
def test_every_flag_has_its_column_and_count(flag):
    from planner.report.margin_datasets import MARGIN_TOTALS_SCHEMA, MARGINS_SCHEMA

    assert flag in MARGINS_SCHEMA.names and f"n_{flag}" in MARGIN_TOTALS_SCHEMA.names


def test_a_flagged_value_is_never_shown_as_zero():
    # a leg 0.03 s below its minimum is impossible by its sign; 0.1 s rounding would read "0.0 s below", which
    # contradicts the flag: the text keeps the first significant digit instead
    sched = {"3 cs below": 99.97, "4 cs short": 119.96}
    c = {"impossible": np.array([True, False]), "short_bad_day": np.array([False, True]),
         "infeasible": np.array([True, True]), "tight": np.array([False, False])}
    rows = pd.DataFrame({"scheduled_running_time_s": list(sched.values()), "min_running_time_s": 100.0,
                         "degraded_min_running_time_s": 120.0, "slowest_running_time_s": 300.0,
                         "closed_loop_max_error_s": np.nan, "unassessed_reason": "",
                         "margin_s": [-0.03, 19.96], "remaining_margin_s": [-20.03, -0.04],
                         "degraded_loss_load_s": 20.0, "degraded_loss_traction_s": 0.0,
                         "degraded_loss_stop_s": 0.0, "degraded_loss_stop_model_s": 0.0, **c})
    reason, _ = flag_reasons(rows, 5.0, 10.0)
    assert reason[0].startswith("impossible: scheduled 100.0 s, 0.03 s below the minimum running time 100.0 s")
    assert reason[1].startswith("short on a bad day by 0.04 s: margin 20.0 s")
