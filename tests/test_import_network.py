"""The track network of an imported railjson line, and the conflicts checked on it.

The fixture (written here) is a single-track line with a passing loop:

==========================  ==============================================================
T1  0 … 2000 m              buffer stop at 0, station WEST at 500, detector DT1 at 1800
SW1 at 2000                 point switch: A = T1 END, B1 = T2 BEGIN (main), B2 = T3 BEGIN (loop)
T2  1000 m  (2000 … 3000)   main through MID (part at 500 → chainage 2500)
T3  1040 m  (loop)          MID's second platform at offset 520 → chainage 2000 + 1000·520/1040 = 2500
SW2 at 3000                 point switch: A = T4 BEGIN, B1 = T2 END, B2 = T3 END
T4  0 … 2000 (3000 … 5000)  detector DT4 at 200 (3200), station EAST at 1500 (4500), buffer stop at END
==========================  ==============================================================
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from importsrc import KMH, rolling_stock

from planner.line.importers.network import Topology, network_tables
from planner.line.importers.railjson import import_railjson
from planner.line.loader import load_line


def _port(track, end):
    return {"track": track, "endpoint": end}


def loop_infra() -> dict:
    ts = lambda tid, length: {"id": tid, "length": length, "slopes": [], "curves": []}  # noqa: E731
    return {
        "version": "3.4.12",
        "track_sections": [ts("T1", 2000.0), ts("T2", 1000.0), ts("T3", 1040.0), ts("T4", 2000.0)],
        "switches": [
            {"id": "SW1", "switch_type": "point_switch",
             "ports": {"A": _port("T1", "END"), "B1": _port("T2", "BEGIN"), "B2": _port("T3", "BEGIN")}},
            {"id": "SW2", "switch_type": "point_switch",
             "ports": {"A": _port("T4", "BEGIN"), "B1": _port("T2", "END"), "B2": _port("T3", "END")}},
        ],
        "speed_sections": [{"id": "V100", "speed_limit": 100 * KMH, "track_ranges": [
            {"track": t, "begin": 0.0, "end": n, "applicable_directions": "BOTH"}
            for t, n in (("T1", 2000.0), ("T2", 1000.0), ("T3", 1040.0), ("T4", 2000.0))]}],
        "signals": [
            {"id": "S1", "track": "T1", "position": 1800.0, "direction": "START_TO_STOP"},
            {"id": "S4", "track": "T4", "position": 200.0, "direction": "STOP_TO_START"},
        ],
        "detectors": [{"id": "DT1", "track": "T1", "position": 1800.0},
                      {"id": "DT4", "track": "T4", "position": 200.0}],
        "buffer_stops": [{"id": "BS0", "track": "T1", "position": 0.0},
                         {"id": "BS1", "track": "T4", "position": 2000.0}],
        "operational_points": [
            {"id": "WEST", "parts": [{"track": "T1", "position": 500.0}]},
            {"id": "MID", "parts": [{"track": "T2", "position": 500.0}, {"track": "T3", "position": 520.0}]},
            {"id": "EAST", "parts": [{"track": "T4", "position": 1500.0}]},
        ],
    }


EXTRA = """
[stations.WEST]
stop_down_m = 500.0
stop_up_m = 500.0
[stations.EAST]
stop_down_m = 4500.0
stop_up_m = 4500.0

[[timetable]]
train_id = "D1"
train_type = "EMU"
direction = "down"
seq = 0
station_id = "WEST"
departure_s = "06:00:00"
stops = true
[[timetable]]
train_id = "D1"
train_type = "EMU"
direction = "down"
seq = 1
station_id = "MID"
arrival_s = "06:02:30"
departure_s = "06:02:30"
stops = false
[[timetable]]
train_id = "D1"
train_type = "EMU"
direction = "down"
seq = 2
station_id = "EAST"
arrival_s = "06:05:00"
stops = true

[[timetable]]
train_id = "U1"
train_type = "EMU"
direction = "up"
seq = 0
station_id = "EAST"
departure_s = "05:55:00"
stops = true
[[timetable]]
train_id = "U1"
train_type = "EMU"
direction = "up"
seq = 1
station_id = "MID"
arrival_s = "05:57:30"
departure_s = "05:57:30"
stops = false
[[timetable]]
train_id = "U1"
train_type = "EMU"
direction = "up"
seq = 2
station_id = "WEST"
arrival_s = "06:00:20"
stops = true
"""


def write_loop_line(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "infra.json").write_text(json.dumps(loop_infra()))
    (folder / "emu.json").write_text(json.dumps(rolling_stock()))
    (folder / "extra.toml").write_text(EXTRA)
    out = folder / "line"
    import_railjson(folder / "infra.json", ["WEST", "MID", "EAST"], [folder / "emu.json"], out,
                    extra=folder / "extra.toml", line_id="loop")
    return out


@pytest.fixture(scope="module")
def loop_line(tmp_path_factory):
    return write_loop_line(tmp_path_factory.mktemp("loop"))


def test_nodes_and_edges_of_the_loop_line(loop_line):
    line = load_line(loop_line)
    net = line.network
    assert net is not None
    pos = {n.node_id: (n.kind, n.position_m) for n in net.nodes}
    # hand: chainage = the path's own tracks; the loop's platform in proportion along it
    assert pos == {
        "BS0": ("end", 0.0), "STOP-WEST-T1": ("stop", 500.0), "DT1": ("boundary", 1800.0),
        "SW1": ("switch", 2000.0), "STOP-MID-T2": ("stop", 2500.0), "STOP-MID-T3": ("stop", 2500.0),
        "SW2": ("switch", 3000.0), "DT4": ("boundary", 3200.0), "STOP-EAST-T4": ("stop", 4500.0),
        "BS1": ("end", 5000.0)}
    edges = {(e.from_node, e.to_node): (e.length_m, e.track) for e in net.edges}
    assert edges[("SW1", "STOP-MID-T3")] == (520.0, "B:T3")   # the loop keeps its own length
    assert edges[("STOP-MID-T3", "SW2")] == (520.0, "B:T3")
    assert edges[("SW1", "STOP-MID-T2")] == (500.0, "B:T1")   # the line's tracks are one track
    assert edges[("DT4", "STOP-EAST-T4")] == (1300.0, "B:T1")
    assert len(net.edges) == 10
    stations = {n.station_id for n in net.nodes if n.kind == "stop"}
    assert stations == {"WEST", "MID", "EAST"}


def test_conflict_on_the_single_track_matches_the_hand_overlap(loop_line):
    """D1 leaves WEST at 06:00:00 while U1 arrives there at 06:00:20: the section WEST–DT1 (500–1800 m).

    D1's window opens at its departure − setting (10 s) − approach (20 s) = 21570 s; U1's closes when it
    arrives (its tail never clears a section behind its destination) + release (5 s) = 21625 s. U1
    opens it earlier (its front passes 1800 m at least 1300 m / (100 km/h) = 46.8 s before arriving)
    and D1 closes it later (it needs more than 25 s from standstill to clear 1800 m + its 120 m), so
    the overlap is 21625 − 21570 = 55 s.
    """
    from planner.network.check import check_timetable

    line = load_line(loop_line)
    check = check_timetable(line)
    rows = [r for r in check.conflicts if r["resource_kind"] == "section"
            and (r["from_m"], r["to_m"]) == (500.0, 1800.0)]
    assert len(rows) == 1
    r = rows[0]
    assert {r["train_a"], r["train_b"]} == {"D1", "U1"}
    assert r["overlap_s"] == pytest.approx(55.0, abs=1e-6)
    assert r["overlap_end_s"] == pytest.approx(6 * 3600 + 20 + 5.0, abs=1e-6)
    # both run the main track at MID (nobody overtakes): no loop call
    assert all(not rt.loop_calls for rt in check.routes.values())
    assert all("STOP-MID-T3" not in rt.nodes for rt in check.routes.values())


def test_a_siding_is_left_out_with_a_note():
    topo = Topology({"A": 1000.0, "S": 300.0},
                    joins=[("P", "switch", [("A", 400.0, 0), ("S", 0.0, 1)])], points=[])
    notes: list[str] = []
    nodes, edges = network_tables(topo, {"A": (0.0, 1)}, "X", notes)
    # the siding's switch is mid-track (no track end of A): S leaves A at 400 but is not oriented
    assert set(edges["track"]) == {"B:A"}
    assert any("left out" in n and "S" in n for n in notes)


def test_a_link_joins_two_tracks_into_one_edge():
    topo = Topology({"A": 1000.0, "B": 500.0},
                    joins=[("L", "link", [("A", 1000.0, 0), ("B", 0.0, 1)])],
                    points=[("P1", "boundary", "A", 600.0, None)])
    notes: list[str] = []
    nodes, edges = network_tables(topo, {"A": (0.0, 1), "B": (1000.0, 1)}, "X", notes)
    assert list(nodes["node_id"]) == ["A.BEGIN", "P1", "B.END"]
    assert np.allclose(nodes["position_m"], [0.0, 600.0, 1500.0])
    assert list(edges["length_m"]) == [600.0, 900.0]    # 400 m of A + 500 m of B, no node at the link


RAILML_LOOP = """<?xml version="1.0" encoding="UTF-8"?>
<railml xmlns="http://www.railml.org/schemas/2013" version="2.2">
 <infrastructure id="is">
  <tracks>
   <track id="trM">
    <trackTopology>
     <trackBegin id="bM" pos="0"><bufferStop id="BS0"/></trackBegin>
     <trackEnd id="eM" pos="5000"><openEnd id="oM"/></trackEnd>
     <connections>
      <switch id="SW1" pos="2000"><connection id="cS1" ref="cLb" orientation="outgoing" course="left"/></switch>
      <switch id="SW2" pos="3000"><connection id="cS2" ref="cLe" orientation="incoming" course="left"/></switch>
     </connections>
     <crossSections>
      <crossSection id="x1" pos="500" ocpRef="WEST"/><crossSection id="x2" pos="2500" ocpRef="MID"/>
      <crossSection id="x3" pos="4500" ocpRef="EAST"/>
     </crossSections>
    </trackTopology>
    <ocsElements>
     <trainDetectionElements><trainDetector id="DT1" pos="1800"/></trainDetectionElements>
     <signals><signal id="S1" pos="1800" dir="up" type="main"/><signal id="S4" pos="3200" dir="down" type="main"/></signals>
    </ocsElements>
   </track>
   <track id="trL">
    <trackTopology>
     <trackBegin id="bL" pos="0"><connection id="cLb" ref="cS1"/></trackBegin>
     <trackEnd id="eL" pos="1040"><connection id="cLe" ref="cS2"/></trackEnd>
     <crossSections><crossSection id="x4" pos="520" ocpRef="MID"/></crossSections>
    </trackTopology>
   </track>
  </tracks>
  <trackGroups><line id="L"><trackRef ref="trM" sequence="1"/></line></trackGroups>
  <operationControlPoints>
   <ocp id="WEST" name="West"/><ocp id="MID" name="Mid"/><ocp id="EAST" name="East"/>
  </operationControlPoints>
 </infrastructure>
</railml>
"""


def test_railml_switches_and_connections_make_the_same_loop(tmp_path):
    from planner.line.importers.railml import import_railml

    (tmp_path / "loop.railml").write_text(RAILML_LOOP)
    (tmp_path / "emu.json").write_text(json.dumps(rolling_stock()))
    (tmp_path / "extra.toml").write_text("[line]\nmax_speed_kmh = 100.0\n" + EXTRA)
    import_railml(tmp_path / "loop.railml", "L", [tmp_path / "emu.json"], tmp_path / "line",
                  extra=tmp_path / "extra.toml")
    net = load_line(tmp_path / "line").network
    pos = {n.node_id: (n.kind, n.position_m) for n in net.nodes}
    assert pos == {
        "BS0": ("end", 0.0), "STOP-WEST-trM": ("stop", 500.0), "DT1": ("boundary", 1800.0),
        "SW1": ("switch", 2000.0), "STOP-MID-trM": ("stop", 2500.0), "STOP-MID-trL": ("stop", 2500.0),
        "SW2": ("switch", 3000.0), "STOP-EAST-trM": ("stop", 4500.0), "oM": ("end", 5000.0)}
    loop = sorted(e.length_m for e in net.edges if e.track.endswith("trL#0"))
    assert loop == [520.0, 520.0]
    # the same trains conflict on the same section by the same 55 s as on the railjson line
    from planner.network.check import check_timetable

    rows = [r for r in check_timetable(load_line(tmp_path / "line")).conflicts
            if (r["from_m"], r["to_m"]) == (500.0, 1800.0)]
    assert [round(r["overlap_s"], 6) for r in rows] == [55.0]


def _two_tracks(orient_b: str) -> str:
    track = lambda tid, sw, orient, extra="": f"""
   <track id="{tid}"><trackTopology>
     <trackBegin id="b{tid}" pos="0"><openEnd id="{tid}-begin"/></trackBegin>
     <trackEnd id="e{tid}" pos="3000"><openEnd id="{tid}-end"/></trackEnd>
     <connections><switch id="{sw}" pos="{1000 if tid == 'trA' else 1100}">
      <connection id="c{sw}" ref="c{'X2' if sw == 'X1' else 'X1'}" orientation="{orient}"/></switch></connections>
     {extra}</trackTopology></track>"""  # noqa: E731
    cs = '<crossSections><crossSection id="x1" pos="500" ocpRef="WEST"/><crossSection id="x2" pos="2500" ocpRef="EAST"/></crossSections>'
    return RAILML_LOOP.split("<tracks>")[0] + "<tracks>" + track("trA", "X1", "outgoing", cs) + \
        track("trB", "X2", orient_b) + "\n  </tracks>" + RAILML_LOOP.split("</tracks>")[1].replace(
            'ref="trM"', 'ref="trA"').replace('<ocp id="MID" name="Mid"/>', "")


@pytest.mark.parametrize("orient_b, begin_m, end_m", [
    ("incoming", -100.0, 2900.0),   # trB runs the same way as trA: its switch at 1100 m of it meets trA's at 1000 m
    ("outgoing", 2100.0, -900.0),   # both branches leave towards their trackEnd: trB runs the other way
])
def test_railml_switch_to_switch_crossover_orients_the_other_track(tmp_path, orient_b, begin_m, end_m):
    from planner.line.importers.network import network_tables, railml_topology
    from planner.line.importers.railml import _Doc

    (tmp_path / "x.railml").write_text(_two_tracks(orient_b))
    doc = _Doc(tmp_path / "x.railml")

    class T:  # the importer's view of the line's one track
        id, begin, offset = "trA", 0.0, 0.0

    topo, on_line = railml_topology(doc, [T], {"WEST": "WEST", "EAST": "EAST"})
    nodes, _ = network_tables(topo, on_line, "L", [])
    pos = dict(zip(nodes["node_id"], nodes["position_m"]))
    assert pos["X1"] == 1000.0 and "X2" not in pos           # one node for the two switches
    assert (pos["trB-begin"], pos["trB-end"]) == (begin_m, end_m)


def test_a_detector_where_two_tracks_are_linked_stays_a_boundary():
    topo = Topology({"A": 1000.0, "B": 500.0},
                    joins=[("L", "link", [("A", 1000.0, 0), ("B", 0.0, 1)])],
                    points=[("D", "boundary", "B", 0.0, None)])
    nodes, edges = network_tables(topo, {"A": (0.0, 1), "B": (1000.0, 1)}, "X", [])
    assert list(zip(nodes["node_id"], nodes["kind"], nodes["position_m"])) == [
        ("A.BEGIN", "end", 0.0), ("D", "boundary", 1000.0), ("B.END", "end", 1500.0)]
    assert sorted(edges["length_m"]) == [500.0, 1000.0]


def test_railml_line_tracks_without_a_connection_are_joined_with_a_note(tmp_path):
    from planner.line.importers.network import network_tables, railml_topology
    from planner.line.importers.railml import _Doc

    text = RAILML_LOOP.replace('<trackEnd id="eL" pos="1040"><connection id="cLe" ref="cS2"/></trackEnd>',
                               '<trackEnd id="eL" pos="1040"><openEnd id="oL"/></trackEnd>')
    text = text.replace('<trackBegin id="bL" pos="0"><connection id="cLb" ref="cS1"/></trackBegin>',
                        '<trackBegin id="bL" pos="0"><openEnd id="bLo"/></trackBegin>')
    text = text.replace('<switch id="SW1" pos="2000"><connection id="cS1" ref="cLb" orientation="outgoing" '
                        'course="left"/></switch>', "")
    text = text.replace('<switch id="SW2" pos="3000"><connection id="cS2" ref="cLe" orientation="incoming" '
                        'course="left"/></switch>', "")
    (tmp_path / "x.railml").write_text(text)

    class M:
        id, begin, offset = "trM", 0.0, 0.0

    class L:  # the loop track, as if the line ran on from trM's end over it
        id, begin, offset = "trL", 0.0, 5000.0

    notes: list[str] = []
    topo, on_line = railml_topology(_Doc(tmp_path / "x.railml"), [M, L], {"WEST": "WEST"}, notes)
    nodes, edges = network_tables(topo, on_line, "L", notes)
    assert any("trM and trL follow each other" in n for n in notes)
    pos = dict(zip(nodes["node_id"], nodes["position_m"]))
    assert pos["oL"] == 6040.0 and "oM" not in pos      # one piece of track 0 … 6040 m, no end between
    assert edges["length_m"].sum() == 6040.0


def test_a_station_added_by_position_gets_a_stop_node_on_the_line(tmp_path):
    """A station the source has no platform for ([stations.X] position_m in --extra) still gets a stop node,
    on the line's own track at its chainage: without it a train calling there could not be routed and the
    night would fail on a line the import accepted (seen on OSRD's one_line infra)."""
    import pyarrow.parquet as pq

    folder = tmp_path / "src"
    folder.mkdir()
    (folder / "infra.json").write_text(json.dumps(loop_infra()))
    (folder / "emu.json").write_text(json.dumps(rolling_stock()))
    (folder / "extra.toml").write_text(EXTRA + '\n[stations.HALT]\nposition_m = 1200.0\n')
    s = import_railjson(folder / "infra.json", ["WEST", "MID", "EAST"], [folder / "emu.json"], tmp_path / "line",
                        extra=folder / "extra.toml", line_id="loop")
    nodes = pq.read_table(tmp_path / "line" / "nodes.parquet").to_pandas()
    halt = nodes[nodes["station_id"] == "HALT"]
    st = pq.read_table(tmp_path / "line" / "stations.parquet").to_pandas().set_index("station_id").loc["HALT"]
    assert sorted(zip(halt["kind"], halt["position_m"])) == sorted({("stop", st.stop_down_m), ("stop", st.stop_up_m)})
    assert st.stop_down_m != st.stop_up_m  # one node at each stop marker
    assert any("HALT" in n and "stop node" in n for n in s.notes)


def test_a_platform_at_a_detector_is_a_stop_node():
    """A stop at the very position of a detector keeps its station (the node is the stop): OSRD's one_line
    infra has its stations at detectors, and a stop folded into the detector's boundary left a train with
    nowhere to stop, failing the night."""
    from planner.line.importers.network import Topology, network_tables

    topo = Topology({"t": 1000.0})
    topo.points += [("det", "boundary", "t", 500.0, None), ("STOP-S", "stop", "t", 500.0, "S"),
                    ("buffer", "end", "t", 0.0, None), ("STOP-T", "stop", "t", 0.0, "T")]  # a terminus at its buffer
    nodes, _ = network_tables(topo, {"t": (0.0, 1)}, "L", [])
    for x, sid in ((500.0, "S"), (0.0, "T")):
        at = nodes[nodes["position_m"] == x]
        assert list(zip(at["kind"], at["station_id"])) == [("stop", sid)]


def test_a_station_whose_only_platform_is_a_switch_gets_stops_at_its_markers():
    """OSRD's overlapping_routes infra has an operational point on a switch: the switch keeps its node, and
    the station gets its stop nodes at its stop markers instead (else no train could stop there)."""
    from planner.line.importers.network import Topology, network_tables, stops_on_line

    topo = Topology({"a": 1000.0, "b": 500.0})
    topo.joins.append(("sw", "switch", [("a", 1000.0, 0), ("b", 0.0, 1)]))
    topo.points.append(("STOP-S-a", "stop", "a", 1000.0, "S"))
    notes: list[str] = []
    stops_on_line(topo, {"a": (0.0, 1), "b": (1000.0, 1)}, [("S", 1100.0), ("S", 900.0)], notes)
    nodes, _ = network_tables(topo, {"a": (0.0, 1), "b": (1000.0, 1)}, "L", notes)
    assert sorted(nodes[nodes["station_id"] == "S"]["position_m"]) == [900.0, 1100.0]
    assert nodes[nodes["position_m"] == 1000.0]["kind"].tolist() == ["switch"]


def _double_line(l2_signals: int) -> Topology:
    """A double line whose imported path changes main at a scissors crossover X at 1000 m.

    The path runs L1 (0 … 1000, three signals facing down) then L2 (1000 … 2000, ``l2_signals`` facing up);
    beside them M1 (three facing up) and M2 (three facing down). Counted over the path alone the line's
    signals face both ways alike.
    """
    along = lambda t, n, a: [(t, 100.0 + 200.0 * k, a) for k in range(n)]  # noqa: E731
    return Topology({"L1": 1000.0, "L2": 1000.0, "M1": 1000.0, "M2": 1000.0},
                    joins=[("X", "switch", [("L1", 1000.0, 0), ("M1", 1000.0, 0), ("L2", 0.0, 1), ("M2", 0.0, 1)])],
                    points=[], signals=along("L1", 3, True) + along("L2", l2_signals, False)
                    + along("M1", 3, False) + along("M2", 3, True))


def test_each_main_of_a_double_line_is_named_by_its_own_signals():
    # OSRD's small_infra: the path took the down main, then the up main; named by the whole path's signals
    # (three each way: 'B'), both directions' trains were routed head on along it (three false deadlocks)
    _, edges = network_tables(_double_line(3), {"L1": (0.0, 1), "L2": (1000.0, 1)}, "X", [])
    assert set(edges["track"]) == {"D:L1", "U:L1", "U:M1", "D:M2"}   # the path's tracks: one group, each its way


def test_a_short_track_with_few_signals_keeps_the_lines_direction():
    # L2 has one signal facing up: too few to name it; the path's count (3 down, 1 up) does: down
    _, edges = network_tables(_double_line(1), {"L1": (0.0, 1), "L2": (1000.0, 1)}, "X", [])
    assert set(edges["track"]) == {"D:L1", "U:M1", "D:M2"}
