"""Run comparison pieces: line-table row diffs and the attribution of legs to input changes.

The end-to-end check (an edited restriction named in the next run's changes with the legs it
slowed, by the simulator's own difference) is in tests/test_pipeline.py, which already runs the
job twice around that edit.
"""
from __future__ import annotations

import pandas as pd

from linedb import default_tables
from planner.report.changes import LineChanges, _causes, diff_table


def test_diff_table_names_changed_added_and_removed_rows():
    old = default_tables()["speed_limits"]
    new = old.copy()
    new.loc[new.start_m == 4000.0, "limit_kmh"] = 65.0
    new = pd.concat([new.iloc[1:], pd.DataFrame([(100.0, 150.0, 30.0, "down", None, "station", False)],
                                                 columns=new.columns)])  # drop the first row, add one
    out = diff_table("speed_limits", old, new)
    kinds = sorted((k, (n or o)["start_m"], tuple(c)) for k, o, n, c in out)
    assert kinds == [("added", 100.0, ()), ("changed", 4000.0, ("limit_kmh",)), ("removed", 1200.0, ())]
    assert diff_table("speed_limits", old, old.iloc[::-1]) == []  # order alone is no change


def test_legs_are_traced_to_changes_that_reach_them():
    reach = {0: {"extent": (4000.0, 4200.0), "direction": "up", "train_type": None, "train_id": None, "all": False},
             1: {"extent": None, "direction": None, "train_type": "EMU6", "train_id": None, "all": False},
             2: {"extent": None, "direction": None, "train_type": None, "train_id": "101", "all": False}}
    up = {"direction": "up", "train_type": "EMU10", "train_ids": ["202"]}
    assert _causes(reach, up, 2440.0, 4740.0, 200.0) == [0]
    assert _causes(reach, {**up, "direction": "down"}, 2560.0, 4860.0, 200.0) == []  # other direction
    assert _causes(reach, up, 140.0, 2440.0, 200.0) == []  # more than a train length away
    assert _causes(reach, up, 140.0, 3850.0, 200.0) == [0]  # the tail still on it
    assert _causes(reach, {**up, "train_type": "EMU6", "train_ids": ["101"]}, 140.0, 2440.0, 120.0) == [1, 2]


def test_changes_table_has_the_declared_schema():
    from planner.report.changes import CHANGES_SCHEMA

    ch = LineChanges("tiny", "r1", "r2")
    ch.add("parameter", "tables.ds_m", "job parameter tables.ds_m: 1 → 0.5", field_="ds_m", before=1.0, after=0.5,
           delta=-0.5)
    t = ch.table()
    assert t.schema.remove(t.schema.get_field_index("line")).equals(CHANGES_SCHEMA, check_metadata=False)
    assert t.column("before").to_pylist() == ["1"] and t.column("delta").to_pylist() == [-0.5]


def test_changes_carry_origin_destination_and_train_to_join_on():
    """Leg rows name their stops and conflict rows the waiting train in columns of their own, not only in
    `subject`; the run is `run_id` alone (stamped at publication), no second `run` column."""
    import pandas as pd
    from planner.report.changes import CHANGES_SCHEMA, _conflict_changes, _leg_changes

    assert "run" not in CHANGES_SCHEMA.names
    leg = {"direction": "up", "train_type": "EMU10", "origin": "C", "destination": "B", "passes": [],
           "scheduled_running_time_s": 150.0, "min_running_time_s": 120.0, "margin_s": 30.0,
           "remaining_margin_s": 10.0, "infeasible": False, "tight": False, "unreachable": False, "train_ids": ["202"]}
    old = pd.DataFrame([leg])
    new = pd.DataFrame([{**leg, "min_running_time_s": 125.0, "margin_s": 25.0}])
    ch = LineChanges("tiny", "r1", "r2")
    _leg_changes(ch, old, new, {}, 0.5, lambda r: (2440.0, 4740.0, 200.0))
    con = {"train_a": "101", "train_b": "202", "resource_id": "S1", "delay_s": 12.0, "rule": "timetable-order",
           "direction_b": "up", "from_m": 100.0, "to_m": 200.0}
    _conflict_changes(ch, pd.DataFrame(columns=list(con)), pd.DataFrame([con]))
    t = ch.table().to_pandas()
    legs = t[t.category == "leg"]
    assert list(legs.field) == ["min_running_time_s", "margin_s"]
    assert set(zip(legs.origin, legs.destination)) == {("C", "B")} and legs.train_id.isna().all()
    c = t[t.category == "conflict"].iloc[0]
    assert c.train_id == "202" and pd.isna(c.origin) and pd.isna(c.destination)


def _day_manifest(day: str, restrictions: list[dict], not_running: list[str]) -> dict:
    return {"operating_day": {"day": day, "lines": [{"line_id": "tiny", "restrictions": restrictions,
                                                     "trains_not_running": not_running}]}}


def _tsr(rid, a, b, kmh=45.0, direction="both", **kw):
    return {"restriction_id": rid, "start_m": a, "end_m": b, "limit_kmh": kmh, "direction": direction,
            "train_type": None, "valid_from": "2026-11-30T09:00", "valid_until": "2026-11-30T15:00",
            "has_beacon": False, "whole_day": False, **kw}


def test_the_days_restrictions_and_trains_are_input_changes_that_legs_are_traced_to():
    """Restrictions that came into force, were lifted or changed between the two operating days, and trains that
    run on one day only, are input changes of their own; the legs they reach name them. They were missing: a
    day with a new restriction listed only the parameter day.day, and its slower legs as moved for no reason."""
    from planner.report.changes import _causes
    from planner.report.input_changes import day_input_changes as _day_changes

    old = _day_manifest("2026-12-01", [_tsr("KEPT", 100.0, 200.0), _tsr("GONE", 300.0, 400.0),
                                       _tsr("EDITED", 500.0, 600.0)], ["105"])
    new = _day_manifest("2026-12-02", [_tsr("KEPT", 100.0, 200.0), _tsr("EDITED", 500.0, 600.0, kmh=25.0),
                                       _tsr("NEW", 9000.0, 9300.0, kmh=40.0, direction="up", track="U1")], ["107"])
    ch = LineChanges("tiny", "r1", "r2")
    reach = _day_changes(ch, old, new)
    got = [(r["category"], r["subject"], r["detail"]) for r in ch.rows]
    assert got == [
        ("restriction", "EDITED", "restriction EDITED (500–600 m, 25 km/h, both) changed: limit_kmh 45 → 25"),
        ("restriction", "GONE", "restriction GONE (300–400 m, 45 km/h, both) lifted (operating day 2026-12-01 → "
                                "2026-12-02)"),
        ("restriction", "NEW", "restriction NEW (9000–9300 m, 40 km/h, up, track U1) came into force (operating "
                               "day 2026-12-01 → 2026-12-02)"),
        ("train", "105", "train 105 runs on 2026-12-02 (did not run on 2026-12-01)"),
        ("train", "107", "train 107 does not run on 2026-12-02 (ran on 2026-12-01)")]
    up = {"direction": "up", "train_type": "EMU10", "train_ids": ["105", "202"]}
    assert _causes(reach, up, 8000.0, 9500.0, 200.0) == [2, 3]  # NEW reaches the leg; 105 runs it now
    assert _causes(reach, {**up, "direction": "down", "train_ids": []}, 8000.0, 9500.0, 200.0) == []


def test_the_printed_summary_names_each_leg_and_each_place_once():
    """`planner diff` printed one line per measure and per conflict, each repeating the leg or the place."""
    ch = LineChanges("tiny", "r1", "r2")
    cause = ch.add("restriction", "NEW", "restriction NEW (...) came into force")
    for m, a, b in (("min_running_time_s", 100.0, 110.0), ("margin_s", 10.0, -0.03)):
        ch.add("leg", "EMU10 up C→B (scheduled 110 s)", f"leg EMU10 up C→B (scheduled 110 s): {m} {a} → {b} s",
               field_=m, before=a, after=b, delta=b - a, caused_by=[cause])
    ch.add("flag", "EMU10 up C→B (scheduled 110 s)", "leg EMU10 up C→B (scheduled 110 s): impossible appeared",
           field_="impossible", before=False, after=True, caused_by=[cause])
    for a, b in (("201", "202"), ("203", "204")):
        ch.add("conflict", f"{a}/{b} at W2", f"conflict {a} before {b} at W2 (Bashi (B) track 1, km 1.0–1.1) "
               "appeared (delay 4.4 s, timetable-order)", field_="delay_s", after=4.4)
    lines = ch.summary_lines()
    assert lines[1:] == [
        "  [restriction] restriction NEW (...) came into force",
        "  [leg] EMU10 up C→B (scheduled 110 s): min_running_time_s 100.0 → 110.0 s; margin_s 10.0 → -0.03 s; "
        "impossible appeared; after restriction NEW (#0)",
        "  [conflict] 2 conflicts appeared at W2 (Bashi (B) track 1, km 1.0–1.1): 202 waits 4.4 s for 201, 204 waits "
        "4.4 s for 203"]


def test_rows_differing_counts_rows_as_multisets():
    """Rows in one table and not the other, whole rows as a multiset: counted by hand for small tables, and against
    a Counter of the rows for random ones (duplicates included)."""
    import random
    from collections import Counter

    import pyarrow as pa

    from planner.report.bundle_changes import _rows_differing, _same_groups

    t = lambda rows: pa.table({"a": [r[0] for r in rows], "b": [r[1] for r in rows]})  # noqa: E731
    assert _rows_differing(t([(1, 1.0), (2, 2.0)]), t([(1, 1.0), (2, 2.0)])) == 0
    assert _rows_differing(t([(1, 1.0), (2, 2.0)]), t([(1, 1.0), (2, 2.5)])) == 2  # one row changed: out and in
    assert _rows_differing(t([(1, 1.0), (1, 1.0)]), t([(1, 1.0)])) == 1  # a duplicate dropped
    assert _rows_differing(t([]), t([(1, 1.0)])) == 1
    assert _rows_differing(None, t([(1, 1.0), (2, 2.0)])) == 2
    rnd = random.Random(7)
    for _ in range(50):
        a = [(rnd.randrange(6), rnd.choice([0.5, 1.5])) for _ in range(rnd.randrange(30))]
        b = [(rnd.randrange(6), rnd.choice([0.5, 1.5])) for _ in range(rnd.randrange(30))]
        ca, cb = Counter(a), Counter(b)
        assert _rows_differing(t(a), t(b)) == sum(((ca - cb) + (cb - ca)).values())
        # a bundle's members as they are read: Parquet bytes, a row group at a time (here of 4 rows)
        assert _rows_differing(parquet(t(a)), parquet(t(b))) == sum(((ca - cb) + (cb - ca)).values())
    # most row groups the same bytes in both (an edit touched one dataset file): only the others' rows differ;
    # a row group the other has once less, or moved, is counted as the multisets say
    rows = [(i, float(i % 5)) for i in range(40)]
    edited = rows[:17] + [(17, 9.5)] + rows[18:]
    assert _rows_differing(parquet(t(rows)), parquet(t(edited))) == 2
    same = _same_groups(parquet(t(rows)), parquet(t(edited)))
    assert same == (set(range(10)) - {4}, set(range(10)) - {4})  # only the edited group's rows are read
    assert _rows_differing(parquet(t(rows + rows[:4])), parquet(t(rows))) == 4
    assert _rows_differing(parquet(t(rows[4:8] + rows)), parquet(t(rows + rows[4:8]))) == 0
    assert _rows_differing(parquet(t([])), parquet(t([(1, 1.0)]))) == 1
    assert _rows_differing(None, parquet(t([(1, 1.0), (2, 2.0)]))) == 2


def parquet(table) -> bytes:
    """``table`` as Parquet bytes in row groups of 4 rows."""
    import io

    import pyarrow.parquet as pq

    buf = io.BytesIO()
    pq.write_table(table, buf, row_group_size=4)
    return buf.getvalue()


def test_records_are_the_rows_as_to_dict_gives_them_with_nan_as_none():
    """``_records`` is made a column at a time; each row must still be what ``to_dict("records")`` gives, made plain
    (numpy scalars as Python numbers, arrays as lists) with NaN as None: the same values *and* types, whatever the
    column's dtype (numpy numbers and truth values, pandas' nullable ones, strings with a missing value, lists,
    times)."""
    import math

    import numpy as np

    from planner.report.changes import _plain, _records

    df = pd.DataFrame({
        "f": [1.5, float("nan"), -0.0],
        "i": np.array([1, 2, 3], np.int32),
        "u": np.array([7, 8, 9], np.uint64),
        "b": [True, False, True],
        "ni": pd.array([1, None, 3], dtype="Int64"),
        "nb": pd.array([True, None, False], dtype="boolean"),
        "s": pd.array(["a", None, "c"], dtype="string"),
        "o": ["x", None, float("nan")],
        "lst": [np.array([1.0, 2.0]), np.array([]), None],
        "t": pd.to_datetime(["2026-12-01", None, "2026-12-03"]),
        "ot": pd.Series([np.datetime64("2026-12-01"), np.timedelta64(5, "s"), np.float64(2.5)], dtype=object),
    })
    expected = [{k: (None if isinstance(v, float) and math.isnan(v) else _plain(v)) for k, v in r.items()}
                for r in df.to_dict("records")]
    got = _records(df)
    assert [list(r) for r in got] == [list(r) for r in expected]
    for g, e in zip(got, expected):
        for k in e:
            assert type(g[k]) is type(e[k]), k
            assert g[k] is e[k] or g[k] == e[k] or (pd.isna(g[k]) and pd.isna(e[k])), k
    assert got[1]["f"] is None and got[0]["i"] == 1 and type(got[0]["i"]) is int and got[0]["lst"] == [1.0, 2.0]
    assert _records(df.iloc[:0]) == [] and _records(pd.DataFrame(index=range(2))) == [{}, {}]


def test_rows_made_elsewhere_are_renumbered_after_this_comparisons():
    """The night compares a line's bundles on another worker than its legs: their rows join the line's after its
    own, numbered on from them and named by its base run; a row that names other changes cannot move."""
    import pytest

    legs = LineChanges("tiny", "r1", "r2")
    cause = legs.add("line_table", "speed_limits", "speed_limits row changed")
    legs.add("leg", "A→B", "leg A→B slower", caused_by=[cause])
    bundles = LineChanges("tiny", "r0001", "r2")  # named by its folder there
    bundles.add("bundle", "tiny_down_EMU10.pdb", "bundle tiny_down_EMU10.pdb: 1 table changed")
    bundles.add("bundle", "tiny_up_EMU10.pdb", "bundle tiny_up_EMU10.pdb: 1 table changed")
    legs.extend(bundles.rows)
    assert [r["change_id"] for r in legs.rows] == [0, 1, 2, 3]
    assert [r["subject"] for r in legs.rows[2:]] == ["tiny_down_EMU10.pdb", "tiny_up_EMU10.pdb"]
    assert {r["base_run"] for r in legs.rows} == {"r1"} and legs.rows[1]["caused_by"] == [0]
    assert [r["change_id"] for r in bundles.rows] == [0, 1]  # the other comparison's rows are left as they were
    with pytest.raises(ValueError, match="names other changes"):
        LineChanges("tiny", "r1", "r2").extend(legs.rows[1:2])


def test_two_files_are_compared_a_chunk_at_a_time(tmp_path):
    from planner.report.bundle_changes import _same_bytes

    data = bytes(range(256)) * 40  # 10,240 bytes: ten chunks of 1,024 and a bit
    a, b = tmp_path / "a", tmp_path / "b"
    a.write_bytes(data)
    b.write_bytes(data)
    assert _same_bytes(a, b, chunk=1024)
    for at in (0, 1023, 1024, 5000, len(data) - 1):  # one byte differs: first, either side of a chunk's end, last
        b.write_bytes(data[:at] + bytes([data[at] ^ 1]) + data[at + 1:])
        assert not _same_bytes(a, b, chunk=1024), at
    b.write_bytes(data + b"\0")  # one byte longer
    assert not _same_bytes(a, b, chunk=1024) and not _same_bytes(b, a, chunk=1024)
    b.write_bytes(b"")
    assert not _same_bytes(a, b) and _same_bytes(b, tmp_path / "b")


def test_a_lines_bundles_are_its_own_not_those_of_a_line_named_like_it(tmp_path):
    """Line ``a``'s bundles are ``a_<direction>_<type>.pdb``: line ``a_b``'s (``a_b_down_T.pdb``) share the prefix
    ``a_`` but are not ``a``'s."""
    from planner.report.bundle_changes import bundle_changes

    old, new = tmp_path / "r1" / "bundles", tmp_path / "r2" / "bundles"
    old.mkdir(parents=True)
    new.mkdir(parents=True)
    for name in ("a_down_T.pdb", "a_up_T.pdb", "a_b_down_T.pdb", "a_b_up_T.pdb"):
        (new / name).write_bytes(b"a bundle")  # all new: each one an "added" row, read no further
    ch = LineChanges("a", "r1", "r2")
    bundle_changes(ch, tmp_path / "r1", tmp_path / "r2")
    assert [r["subject"] for r in ch.rows] == ["a_down_T.pdb", "a_up_T.pdb"]
    ch = LineChanges("a_b", "r1", "r2")
    bundle_changes(ch, tmp_path / "r1", tmp_path / "r2")
    assert [r["subject"] for r in ch.rows] == ["a_b_down_T.pdb", "a_b_up_T.pdb"]
