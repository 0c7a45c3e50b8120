"""The bundle's cross-checks of the tables and stopping steps' tables (``contents._check_step_tables``):
every (leg, ratio) of tables (b) and (c) is in table (a), every (leg, point) of tables (b) and (d) is an
evaluation point; the first missing one (in sorted order) is named."""
from __future__ import annotations

import pyarrow as pa
import pytest

from planner.bundle.contents import _check_step_tables, _distinct
from planner.errors import PlannerError


def _t(**cols):
    return pa.table(cols)


def test_distinct_rows_as_tuples():
    t = _t(o=["A", "A", "B", None, "A"], r=[1.0, 1.0, 0.9, 0.9, 0.9])
    assert _distinct(t, "o", "r") == {("A", 1.0), ("B", 0.9), (None, 0.9), ("A", 0.9)}


def test_ratio_of_table_b_not_in_table_a():
    ta = _t(origin=["A", "A", "B"], destination=["B", "B", "C"], ratio=[1.0, 0.9, 1.0])
    tb = _t(origin=["A", "B", "B"], destination=["B", "C", "C"], eval_point_id=["p", "q", "q"],
            ratio_before=[1.0, 1.0, 1.0], ratio_after=[0.9, 0.8, 0.7])
    with pytest.raises(PlannerError, match=r"table_b ratio_after 0\.7 for B->C is not in table_a"):
        _check_step_tables({"table_a": ta, "table_b": tb}, "test")
    tb_ok = tb.filter(pa.array([True, False, False]))
    _check_step_tables({"table_a": ta, "table_b": tb_ok}, "test")


def test_point_of_table_d_not_an_evaluation_point():
    ep = _t(origin=["A", "A"], destination=["B", "B"], eval_point_id=["dep", "dep+200"],
            eval_point_kind=["departure", "odometer"])
    td = _t(origin=["A", "A", "A"], destination=["B", "B", "B"], eval_point_id=["dep", "dep+400", "dep+300"])
    with pytest.raises(PlannerError, match=r"table_d evaluation point 'dep\+300' for A->B is not in eval_points"):
        _check_step_tables({"eval_points": ep, "table_d": td, "beacons": _t(beacon_id=pa.array([], pa.string()))},
                           "test")
