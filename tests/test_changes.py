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
