"""Margins never hide what they cannot compute (issue 21, item 5); validation refuses hopeless jerk limits.

A jerk limit of 1e-9 km/h/s² makes every stopping pattern impossible. Before,
every leg of that train type was published with ``infeasible = false``,
``tight = false`` and a null margin, so ``where infeasible or tight`` listed
none of them. Now validation refuses such a limit where it can tell up front
(the rule in :func:`planner.line.rules.jerk_allows_a_stop`), and a leg whose
bad-day minimum still cannot be computed is ``unassessed`` with a reason, its
``infeasible``/``tight`` null in the dataset, and listed first in the report.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from planner.io.parquet import read_dataset
from planner.errors import LineValidationError
from planner.report.margin_datasets import write_margins
from planner.report.margin_rule import MarginRule, margin_columns
from planner.report.margins import compute_margins
from planner.pages.margin_report import render_html
from test_margins import APPROACH, SMALL_GRID, closed_form_line


# --- validation: the up-front rule -----------------------------------------------------------------
def test_min_stop_distance_matches_a_numeric_integration():
    """v sqrt(v/j): deceleration ramped up and down at ±j (triangle), integrated independently."""
    from planner.line.rules import min_stop_distance_m

    v0, j = 5 / 3.6, 0.3
    T = 2 * math.sqrt(v0 / j)
    t = np.linspace(0.0, T, 200_001)
    a = -j * np.minimum(t, T - t)  # deceleration peaks at T/2
    v = v0 + np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
    x = np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t))
    assert abs(v[-1]) < 1e-6
    assert min_stop_distance_m(v0, j) == pytest.approx(x, rel=1e-6)


def _tiny_with_emu6_jerk(tmp_path, jerk_kmh_s2):
    from linedb import default_tables, write_line_db

    t = default_tables()
    t["rolling_stock"].loc[t["rolling_stock"].train_type == "EMU6", "jerk_limit_kmh_s2"] = jerk_kmh_s2
    return write_line_db(tmp_path / "tiny", rolling_stock=t["rolling_stock"], nodes=None, edges=None)


def test_validation_refuses_a_jerk_limit_that_makes_every_pattern_impossible(tmp_path):
    from planner.line.loader import load_line

    with pytest.raises(LineValidationError) as e:
        load_line(_tiny_with_emu6_jerk(tmp_path, 1e-9))
    v = [x for x in e.value.violations if x.column == "jerk_limit_kmh_s2"]
    assert len(v) == 1 and v[0].file == "rolling_stock.parquet" and v[0].row == 1
    assert "makes every stopping pattern impossible" in v[0].message and "5 km" in v[0].message
    # the tiny line is 5 km: the bound is 3.6 (5/3.6)^3 / 5000^2 = 3.86e-7 km/h/s²; just above passes validation
    line = load_line(_tiny_with_emu6_jerk(tmp_path / "ok", 4e-7))
    assert line.train_type("EMU6").jerk_limit_ms3 == pytest.approx(4e-7 / 3.6)


# --- margins: what validation cannot tell up front -------------------------------------------------
@pytest.fixture(scope="module")
def hopeless():
    """The closed-form line with a jerk limit validation lets through but no pattern survives (1e-3 km/h/s²)."""
    line = closed_form_line()
    tt = dataclasses.replace(line.train_types[0], jerk_limit_ms3=1e-3 / 3.6)
    line = dataclasses.replace(line, train_types=(tt,))
    return compute_margins(line, adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH, conflicts=False,
                           ratios=SMALL_GRID)


def test_every_leg_without_a_pattern_is_unassessed_with_its_reason(hopeless):
    rows = hopeless.rows
    assert len(rows) == 5 and rows.unassessed.all()
    assert rows.degraded_min_running_time_s.isna().all() and rows.remaining_margin_s.isna().all()
    assert all(r.startswith("no stopping pattern at adhesion 3 km/h/s") for r in rows.unassessed_reason)
    tot = hopeless.totals.set_index(["level", "train_id"])
    assert tot.loc[("train", "L1")].n_unassessed == 2 and tot.loc[("train", "R1")].n_unassessed == 1
    for c in ("remaining_margin_s", "degraded_min_running_time_s", "min_remaining_margin_s", "bad_day_shortfall_s"):
        assert hopeless.totals[c].isna().all(), c  # unknown, not a partial sum that looks like a whole
    assert (hopeless.totals.margin_s.notna()).all()  # what is known stays known


def test_unassessed_legs_are_null_not_false_in_the_dataset(hopeless, tmp_path):
    write_margins(hopeless, tmp_path)
    got = read_dataset(tmp_path, "margins")
    assert got.column("unassessed").to_pylist() == [True] * 5
    for c in ("infeasible", "tight"):
        assert got.column(c).null_count == 5, c  # unknown, never a false "all clear"
    duckdb = pytest.importorskip("duckdb")
    q = (f"select count(*) from read_parquet('{tmp_path}/margins/**/*.parquet', hive_partitioning = true) "
         "where {}")
    assert duckdb.sql(q.format("infeasible or tight")).fetchall()[0][0] == 0
    assert duckdb.sql(q.format("unassessed or infeasible or tight")).fetchall()[0][0] == 5  # the README's query
    assert duckdb.sql(q.format("not infeasible")).fetchall()[0][0] == 0


def test_assessed_legs_are_not_unassessed():
    from test_margins import closed_form_line as line

    rep = compute_margins(line(), adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH, conflicts=False,
                          ratios=SMALL_GRID)
    assert not rep.rows.unassessed.any() and (rep.rows.unassessed_reason == "").all()
    assert rep.totals.remaining_margin_s.notna().all() and (rep.totals.n_unassessed == 0).all()
    assert rep.rows.infeasible.any()  # the same line has flagged legs: they are not mistaken for unassessed


def test_margin_columns_mark_an_unknown_degraded_minimum():
    c = margin_columns([80.0, 80.0, math.nan], [100.0, 100.0, 100.0], [90.0, math.nan, 90.0],
                       [300.0] * 3, [1500.0] * 3, MarginRule())
    assert c["unassessed"].tolist() == [False, True, True]
    assert c["infeasible"].tolist() == [False, False, False]


def test_report_lists_unassessed_legs_first(hopeless):
    html = render_html(hopeless, {})
    i = html.index("Unassessed legs (5)")
    assert i < html.index("Flagged legs (0)") < html.index("Other legs (0)")
    assert html.count("b-unassessed'>unassessed<") == 5
    assert "no stopping pattern at adhesion 3 km/h/s" in html[i:]
