"""Conflicts by place, counts that add up, the largest listed fairly, and the minimum headway per resource.

Three trains at the junction of tests/test_network.py (P at 0 m and Q at 100 m merge at switch J at
500 m, then main track M to C at 2000 m; stations S0 0 m, S1 100 m, S2 2000 m), constant 20 m/s,
lead 30 s (setting 10 + approach 20), release 5 s, train length 100 m. Windows, worked by hand
(start = entry − 30, end = tail clear + 5, tail clear = front 100 m past the exit, at most the arrival):

    T1 dep P 0:    P–J [−30, 35]   J [−5, 35]    J–c [−5, 105]
    T2 dep Q 20:   Q–J [−10, 50]   J [10, 50]    J–c [10, 120]
    T3 dep P 115:  P–J [85, 150]   J [110, 150]  J–c [110, 220]

Overlaps: T1/T2 on J (25 s) and J–c (95 s); T2/T3 on J–c (10 s); T1/T3 none.
So: 2 conflicts, between 2 train pairs, on 2 resources (J, J–c), in 3 rows.
"""
from __future__ import annotations

import pandas as pd
import pytest

from planner.datasets.conflicts import _summary, conflict_list, largest, place_text
from test_network import J_EDGES, J_NODES, NAN, TOL_S, check, make_line, train


def three_trains():
    t1 = train("T1", "down", [("S0", NAN, 0.0, True), ("S2", 100.0, NAN, True)])
    t2 = train("T2", "down", [("S1", NAN, 20.0, True), ("S2", 115.0, NAN, True)])
    t3 = train("T3", "down", [("S0", NAN, 115.0, True), ("S2", 215.0, NAN, True)])
    return make_line([0.0, 100.0, 2000.0], J_NODES, J_EDGES, [t1, t2, t3])


@pytest.fixture(scope="module")
def rep():
    return check(three_trains())


def test_counts_add_up_on_a_case_counted_by_hand(rep):
    c = rep.conflicts
    assert len(c) == 3
    assert sorted(c["conflict_id"].unique()) == [1, 2]  # numbered from 1, in time order (T1/T2 from −5 s first)
    first = c[c.conflict_id == 1]
    assert set(first.train_a) == {"T1"} and set(first.train_b) == {"T2"} and sorted(first.resource_id) == ["J", "J-c"]
    second = c[c.conflict_id == 2]
    assert list(second.resource_id) == ["J-c"] and list(second.train_a) == ["T2"] and list(second.train_b) == ["T3"]
    s = rep.summary
    assert (s["conflicts"], s["pairs"], s["resources"], s["rows"]) == (2, 2, 2, 3)
    assert "conflicts: 2 conflicts between 2 train pairs on 2 resources;" in "\n".join(rep.summary_lines())


def test_each_conflict_names_station_track_and_km(rep):
    c = rep.conflicts.set_index(["conflict_id", "resource_id"])
    # J at 500 m: nearest station S1 (100 m), 400 m away; J–c spans 500–2000 m, S2's position included.
    assert c.loc[(1, "J"), "station_id"] == "S1" and c.loc[(1, "J"), "station_distance_m"] == pytest.approx(400.0)
    jc = c.loc[(1, "J-c")]
    assert (jc.station_id, jc.station_name, jc.station_distance_m, jc.track) == ("S2", "Station 2", 0.0, "M")
    assert (jc.from_m, jc.to_m) == (500.0, 2000.0)
    assert place_text(jc) == "Station 2 (S2) track M, km 0.500–2.000"
    assert place_text(c.loc[(1, "J")]).startswith("0.4 km from Station 1 (S1)")
    # a conflict over several resources: named by its first (station, track), km over all of them
    assert "at J (0.4 km from Station 1 (S1) track A, km 0.500–2.000) and 1 more resource" in rep.summary["worst"][0]


def test_conflict_headways_explain_the_overlap_and_the_delay(rep):
    c = rep.conflicts.set_index(["conflict_id", "resource_id"])
    # headway = b_start − a_start; minimum headway = a's window length; the wait b needs = min − headway
    for key, head, mini in (((1, "J"), 15.0, 40.0), ((1, "J-c"), 15.0, 110.0), ((2, "J-c"), 100.0, 110.0)):
        assert c.loc[key, "headway_s"] == pytest.approx(head, abs=TOL_S)
        assert c.loc[key, "min_headway_s"] == pytest.approx(mini, abs=TOL_S)
    assert c.loc[(1, "J-c"), "delay_s"] == pytest.approx(110.0 - 15.0, abs=TOL_S)
    assert c.loc[(2, "J-c"), "delay_s"] == pytest.approx(110.0 - 100.0, abs=TOL_S)
    # the conflict list carries the headways of the resource behind the delay
    lst = conflict_list(rep.conflicts)
    assert lst.loc[1, "headway_s"] == pytest.approx(15.0) and lst.loc[1, "min_headway_s"] == pytest.approx(110.0)


def test_minimum_headway_per_resource_by_hand(rep):
    h = rep.headways.set_index("resource_id")
    assert sorted(h.index) == ["J", "J-c", "p-J"]  # q–J is used by T2 alone
    # P–J: T1 [−30, 35] then T3 [85, 150]: headway 115, minimum 65 (T1's window), buffer 50.
    # J: tightest T1→T2: headway 15, minimum 40, buffer −25 (T2→T3: 110 − 50 = 60).
    # J–c: T1→T2 buffer 10 − 105 = −95; T2→T3 110 − 120 = −10 (T3 measured against the later of T1's, T2's ends).
    for rid, n, a, b, head, mini in (("p-J", 2, "T1", "T3", 115.0, 65.0), ("J", 3, "T1", "T2", 15.0, 40.0),
                                     ("J-c", 3, "T1", "T2", 15.0, 110.0)):
        r = h.loc[rid]
        assert (r.n_trains, r.train_a, r.train_b) == (n, a, b), rid
        assert r.headway_s == pytest.approx(head, abs=TOL_S) and r.min_headway_s == pytest.approx(mini, abs=TOL_S)
        assert r.buffer_s == pytest.approx(head - mini, abs=TOL_S)
    assert h.loc["J-c", "station_id"] == "S2" and h.loc["p-J", "station_id"] == "S1"
    assert "tightest headway: J-c" in "\n".join(rep.summary_lines())


def test_a_long_window_overlapping_two_later_ones_is_the_tightest_pair():
    # T3 on J–c measured against T2 (ends 120), not its neighbour by opening alone: move T2 later so that
    # T1 [−5, 105], T2 [30, 140] (dep 40), T3 [110, 220]: T3's buffer is 110 − 140 = −30 against T2.
    ln = three_trains()
    import dataclasses
    t2 = train("T2", "down", [("S1", NAN, 40.0, True), ("S2", 135.0, NAN, True)])
    ln = dataclasses.replace(ln, trains=(ln.trains[0], t2, ln.trains[2]))
    h = check(ln).headways.set_index("resource_id")
    r = h.loc["J-c"]
    # T1→T2: 30 − 105 = −75 is tighter than T2→T3 −30
    assert (r.train_a, r.train_b) == ("T1", "T2") and r.buffer_s == pytest.approx(-75.0, abs=TOL_S)


def test_largest_delays_break_ties_by_time_not_by_round_off():
    # sixteen equal delays that differ by round-off, the later ones a hair larger: the earliest five are listed
    rows = [dict(conflict_id=k + 1, train_a=f"A{k}", train_b=f"B{k}", rule="timetable-order", decision="",
                 delay_s=4.367637099359854 if k < 6 else 4.367637099363492, deadlock=False, overlap_s=4.4,
                 resource_kind="section", resource_id="U1-012/1", interlocking="IXL-B", track="U1",
                 station_id="TKD", station_name="Takadai", station_distance_m=0.0, from_m=11100.0, to_m=11405.0,
                 overlap_start_s=25000.0 + 1440.0 * k, overlap_end_s=25004.4 + 1440.0 * k,
                 headway_s=120.0, min_headway_s=124.4) for k in range(16)]
    rows[9]["delay_s"] = 9.0  # one really larger, late in the day
    c = conflict_list(pd.DataFrame(rows))
    assert list(largest(c, 5).index) == [1, 2, 3, 4, 10]
    s = _summary([], [], [], pd.DataFrame(rows))
    assert (s["conflicts"], s["pairs"], s["resources"]) == (16, 16, 1)
    assert [x.split(":")[0] for x in s["worst"]] == ["#1", "#2", "#3", "#4", "#10"]


def test_a_conflict_that_appears_says_where(rep):
    from planner.report.changes import LineChanges, _conflict_changes

    ch = LineChanges("test", "r1", "r2")
    _conflict_changes(ch, rep.conflicts.iloc[0:0], rep.conflicts[rep.conflicts.conflict_id == 2])
    (row,) = ch.of("conflict")
    assert row["detail"].startswith("conflict T2 before T3 at J-c (Station 2 (S2) track M, km 0.500–2.000) appeared")
    # a run written before the place columns existed: the resource alone, no error
    old = rep.conflicts.drop(columns=["station_id", "station_name", "station_distance_m", "track"])
    ch = LineChanges("test", "r1", "r2")
    _conflict_changes(ch, old.iloc[0:0], old[old.conflict_id == 2])
    assert ch.of("conflict")[0]["detail"].startswith("conflict T2 before T3 at J-c appeared")


def test_headways_dataset_is_written_with_its_schema(rep, tmp_path):
    import pyarrow.parquet as pq

    from planner.datasets.conflicts import HEADWAYS_SCHEMA, write_conflicts

    write_conflicts(rep, tmp_path / "a")
    write_conflicts(rep, tmp_path / "b")
    f = tmp_path / "a" / "headways" / "line=test" / "part-0.parquet"
    assert f.read_bytes() == (tmp_path / "b" / "headways" / "line=test" / "part-0.parquet").read_bytes()
    t = pq.read_table(f)
    assert t.num_rows == 3 and t.column_names == [x.name for x in HEADWAYS_SCHEMA]
    assert t.schema.field("min_headway_s").metadata[b"description"]
    c = pq.read_table(tmp_path / "a" / "conflicts" / "line=test" / "part-0.parquet").to_pandas()
    assert {"station_id", "station_name", "station_distance_m", "track", "headway_s", "min_headway_s"} <= set(c.columns)


def test_graph_page_of_a_run_written_before_the_place_columns(rep):
    from planner.report.train_graph import GraphData
    from planner.pages.train_graph import page_payload

    old = rep.conflicts.drop(columns=["station_id", "station_name", "station_distance_m", "track",
                                      "headway_s", "min_headway_s"])
    data = GraphData("test", "Test", 0.0, 2000.0, [], [], None, old)
    cons = page_payload(data)["conflicts"]
    assert len(cons) == 3 and all(c[11] == "" and c[12] is None for c in cons)
    new = page_payload(GraphData("test", "Test", 0.0, 2000.0, [], [], None, rep.conflicts))["conflicts"]
    assert new[-1][11] == "Station 2 (S2) track M, km 0.500–2.000" and new[-1][12:] == [100, 110]
