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


def _dictionary(t: pa.Table, batches: int = 3) -> pa.Table:
    """``t`` with its text columns dictionary-encoded, as ``verify`` reads a member, in ``batches`` record batches
    each with its own dictionary (listed in an order of its own, with a value repeated and one no row uses)."""
    import pyarrow.compute as pc

    step = -(-t.num_rows // batches)
    out = []
    for i in range(batches):
        part = t.slice(i * step, step)
        cols = []
        for c in part.columns:
            if pa.types.is_string(c.type):
                values = sorted({x for x in c.to_pylist()}, reverse=bool(i % 2)) + ["unused"]
                values = values[:1] + values  # the first value twice: rows use the second copy
                idx = pa.array([values.index(x, 1) for x in c.to_pylist()], pa.int32())
                cols.append(pa.DictionaryArray.from_arrays(idx, pa.array(values)))
            else:
                cols.append(pc.cast(c, c.type).combine_chunks())
        out.append(pa.RecordBatch.from_arrays(cols, names=part.column_names))
    return pa.Table.from_batches(out)


def test_distinct_rows_of_dictionary_columns_are_the_rows_distinct_values():
    """The distinct rows of dictionary-encoded columns (a member as verify reads it) are those of the same rows
    as plain text: made from the indices, whatever each batch's dictionary and its order, repeats or unused values;
    a float column beside them too."""
    import numpy as np

    rng = np.random.default_rng(7)
    n = 5000
    t = _t(origin=[f"S{i}" for i in rng.integers(0, 9, n)], destination=[f"S{i}" for i in rng.integers(0, 9, n)],
           eval_point_id=[f"dep+{i}" for i in rng.integers(0, 40, n) * 10], ratio=rng.integers(5, 11, n) / 10)
    d = _dictionary(t)
    assert pa.types.is_dictionary(d.schema.field("origin").type) and d.num_rows == n
    for names in (("origin", "destination", "eval_point_id"), ("origin", "destination", "ratio"), ("origin",)):
        want = set(zip(*(t.column(c).to_pylist() for c in names)))
        assert _distinct(d, *names) == want
        assert len(want) > 1


def test_keys_of_a_dictionary_column_are_checked_by_the_values_its_rows_use():
    """A dictionary-encoded key column passes when every row is the bundle's target, whatever else its dictionary
    lists; one row of another direction is named, as on plain text."""
    from planner.bundle.contents import check_keys

    t = _t(direction=["down"] * 6, origin=["A"] * 6)
    check_keys("table_d", _dictionary(t), "L", "down", "E10", "test")  # "unused" is listed, no row holds it
    bad = _t(direction=["down"] * 5 + ["up"], origin=["A"] * 6)
    with pytest.raises(PlannerError, match=r"table_d column direction holds \['up'\], expected only 'down'"):
        check_keys("table_d", _dictionary(bad), "L", "down", "E10", "test")
    with pytest.raises(PlannerError, match=r"table_d column direction holds \['None'\]"):
        check_keys("table_d", _t(direction=pa.array(["down", None]).dictionary_encode()), "L", "down", "E10", "test")
