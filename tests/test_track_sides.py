"""Track directions in the line database: the edges' direction column, the source's own direction attribute,
and the running side (right- or left-hand) that names two parallel mains signalled alike both ways.

The topologies are drawn by hand in metres: down is +x, so a track at y = +10 m lies left of one at y = 0
for a down train. Every expectation follows from that picture and the rule 'facing down, the track on the
running side is the down main'.
"""
from __future__ import annotations

import dataclasses

import pyarrow.parquet as pq
import pytest

from planner.errors import SourceError
from planner.line.importers.network import Topology, network_tables
from planner.line.importers.sides import _metres
from planner.line.loader import load_line
from planner.network.routes import TrackGraph, plan_routes, track_direction

ON_LINE = {"P": (0.0, 1), "A": (500.0, 1), "Q": (2500.0, 1)}


def _pair(a_signals: tuple[int, int], b_signals: tuple[int, int], b_y: float = 10.0) -> Topology:
    """The line P (0–500 m) A (500–2500) Q (2500–3000) along y = 0; B beside A at y = ``b_y``, joined to the
    line by switches S1 (500 m) and S2 (2500 m). ``*_signals``: (facing down, facing up) on A and B."""
    sig = lambda t, n, along: [(t, 100.0 + 300.0 * k, along) for k in range(n)]  # noqa: E731
    return Topology(
        {"P": 500.0, "A": 2000.0, "Q": 500.0, "B": 2000.0},
        joins=[("S1", "switch", [("P", 500.0, 0), ("A", 0.0, 1), ("B", 0.0, 1)]),
               ("S2", "switch", [("A", 2000.0, 0), ("B", 2000.0, 0), ("Q", 0.0, 1)])],
        signals=sig("A", a_signals[0], True) + sig("A", a_signals[1], False)
        + sig("B", b_signals[0], True) + sig("B", b_signals[1], False),
        geo={"P": [[0, 0], [500, 0]], "A": [[500, 0], [2500, 0]], "Q": [[2500, 0], [3000, 0]],
             "B": [[500, b_y], [2500, b_y]]})


def _ways(topo: Topology, side: str | None = None, notes: list | None = None) -> tuple[dict, str | None]:
    _, edges = network_tables(topo, ON_LINE, "X", [] if notes is None else notes, side)
    # edge ids are '<source track>:<piece>'
    return {e.split(":")[0]: d for e, d in zip(edges["edge_id"], edges["direction"])}, edges.attrs["running_side"]


def test_two_mains_signalled_alike_both_ways_stay_both_without_a_running_side():
    ways, side = _ways(_pair((2, 2), (2, 2)))
    assert side is None
    assert (ways["A"], ways["B"]) == ("both", "both")


@pytest.mark.parametrize("side, a, b", [("left", "up", "down"), ("right", "down", "up")])
def test_the_running_side_names_two_mains_signalled_alike(side, a, b):
    # B lies at y = +10 m: left of A for a down train. Left-hand running: B is the down main.
    notes: list[str] = []
    ways, used = _ways(_pair((2, 2), (2, 2)), side, notes)
    assert used == side
    assert (ways["A"], ways["B"]) == (a, b)
    assert any("named by the running side" in n for n in notes)


def test_the_running_side_comes_from_the_data_where_a_down_and_an_up_track_run_side_by_side():
    # A signalled down, B (left of A) up: the down track lies right of the up one, so the railway runs right
    notes: list[str] = []
    ways, side = _ways(_pair((3, 0), (0, 3)), None, notes)
    assert side == "right" and (ways["A"], ways["B"]) == ("down", "up")
    assert any(n.startswith("running side right (from the data") for n in notes)
    # B on the other side of A: the same signals now say left-hand running
    _, side = _ways(_pair((3, 0), (0, 3), b_y=-10.0))
    assert side == "left"


def test_signals_that_tell_are_never_overruled_by_the_running_side():
    ways, _ = _ways(_pair((3, 0), (0, 3)), "left")   # given left, though B (up by its signals) lies left
    assert (ways["A"], ways["B"]) == ("down", "up")


def test_tracks_too_far_apart_or_too_short_are_not_side_by_side():
    ways, _ = _ways(_pair((2, 2), (2, 2), b_y=120.0), "left")       # 120 m apart: another line, not a main
    assert (ways["A"], ways["B"]) == ("both", "both")
    short = _pair((2, 2), (2, 2))
    short.lengths.update(A=200.0, B=200.0)                          # a crossover's legs, not mains
    ways, _ = _ways(short, "left")
    assert (ways["A"], ways["B"]) == ("both", "both")


def test_the_sources_own_direction_attribute_wins():
    # railML <track mainDir="down"> on B: against its positions, which grow with the chainage: an up track
    topo = _pair((3, 0), (3, 0))
    topo.main_dir["B"] = "against"
    ways, _ = _ways(topo)
    assert (ways["A"], ways["B"]) == ("down", "up")


def test_longitude_and_latitude_become_metres():
    # 0.0001 degrees of latitude at 49.5 N is 11.06 m; of longitude 111,320 · cos(49.5°) · 0.0001 = 7.23 m
    xy = _metres({"t": [[-0.4, 49.5], [-0.3999, 49.5001]]})["t"]
    dx, dy = xy[1] - xy[0]
    assert dy == pytest.approx(11.0574, rel=1e-6)
    assert dx == pytest.approx(111_320 * 0.6494480483301837 * 1e-4, rel=1e-4)


# ---- the route search reads the column
def test_the_direction_column_is_what_the_track_names_said(sample_line):
    """Rename every track of the sample's network to a name that says nothing (T1, T2, ...) and carry its
    direction in the column: every train's route is the same node for node."""
    net = sample_line.network
    names = {t: f"T{k}" for k, t in enumerate(sorted({e.track for e in net.edges}))}
    edges = tuple(dataclasses.replace(e, track=names[e.track], direction=track_direction(e.track))
                  for e in net.edges)
    nodes = tuple(dataclasses.replace(n, track=names.get(n.track)) if n.track else n for n in net.nodes)
    renamed = dataclasses.replace(sample_line, network=dataclasses.replace(net, nodes=nodes, edges=edges))
    before, after = plan_routes(sample_line), plan_routes(renamed)
    assert before.keys() == after.keys()
    assert all(before[t].nodes == after[t].nodes for t in before)
    # without the column the names say 'both' everywhere, and trains of both ways take the same mains
    blank = tuple(dataclasses.replace(e, direction=None) for e in edges)
    neutral = plan_routes(dataclasses.replace(sample_line, network=dataclasses.replace(net, nodes=nodes,
                                                                                       edges=blank)))
    assert any(before[t].nodes != neutral[t].nodes for t in before)
    assert TrackGraph(renamed).edge_dir == [track_direction(e.track) for e in sorted(net.edges,
                                                                                      key=lambda e: e.edge_id)]


def test_a_bad_direction_is_refused_in_one_line(tmp_path, sample_dir):
    import shutil

    import pyarrow as pa

    d = tmp_path / "line"
    shutil.copytree(sample_dir, d)
    t = pq.read_table(d / "edges.parquet")
    t = t.append_column("direction", pa.array(["sideways"] + [None] * (t.num_rows - 1), pa.string()))
    pq.write_table(t, d / "edges.parquet")
    with pytest.raises(Exception) as e:
        load_line(d)
    text = str(e.value)
    assert "edges.parquet" in text and "direction" in text and "'sideways' is not one of down, up, both" in text


def test_running_side_from_extra_is_checked():
    from planner.line.importers.common import Extras, ImportSummary, line_table

    s = ImportSummary("x")
    s.extra = Extras(path="x.toml", line={"running_side": "middle"})
    with pytest.raises(SourceError, match="running_side = 'middle'; write 'right' or 'left'"):
        line_table("L", 0.0, 1000.0, s)
    s.extra = Extras(path="x.toml", line={"running_side": "left"})
    assert line_table("L", 0.0, 1000.0, s)["running_side"][0] == "left"


def test_a_csv_import_carries_the_direction_column(tmp_path, sample_dir, sample_line):
    """The sample's network through CSV with its tracks renamed T1, T2, ... and a direction column: the routes
    are the sample's own."""
    import csv

    from planner.line.importers.csv import export_csv, import_csv

    export_csv(sample_dir, tmp_path / "csv")
    path = tmp_path / "csv" / "edges.csv"
    rows = list(csv.reader(path.open()))
    head, body = rows[0], rows[1:]
    k = head.index("track")
    names = {t: f"T{n}" for n, t in enumerate(sorted({r[k] for r in body}))}
    body = [r[:k] + [names[r[k]]] + r[k + 1:] + [track_direction(r[k])] for r in body]
    with path.open("w", newline="") as f:
        csv.writer(f).writerows([head + ["direction"]] + body)
    nodes = tmp_path / "csv" / "nodes.csv"
    rows = list(csv.reader(nodes.open()))
    j = rows[0].index("track")
    with nodes.open("w", newline="") as f:
        csv.writer(f).writerows([rows[0]] + [r[:j] + [names.get(r[j], r[j])] + r[j + 1:] for r in rows[1:]])
    import_csv(tmp_path / "csv", tmp_path / "line")
    line = load_line(tmp_path / "line")
    assert {e.direction for e in line.network.edges} == {"down", "up", "both"}
    before, after = plan_routes(sample_line), plan_routes(line)
    assert all(before[t].nodes == after[t].nodes for t in before)


# ---- what the source does not say: --extra [track_directions], and stop nodes beside the line
def test_track_directions_from_extra_beat_the_signals_and_a_wrong_id_is_refused():
    topo = _pair((2, 2), (2, 2))
    topo.given_dir.update(A="down", B="up")  # RailCOMPLETE's mains: signalled alike, no mainDir, no coordinates
    notes: list[str] = []
    ways, _ = _ways(topo, None, notes)
    assert (ways["A"], ways["B"]) == ("down", "up")
    assert any("2 source track(s) as [track_directions] says" in n for n in notes)
    topo = _pair((3, 0), (0, 3))
    topo.given_dir["B"] = "both"  # given 'both' stays both, whatever the signals and the running side say
    ways, _ = _ways(topo, "left")
    assert ways["B"] == "both"
    topo.given_dir["Z9"] = "up"
    with pytest.raises(SourceError, match=r"\[track_directions\]: Z9 name\(s\) no track of the source"):
        _ways(topo)


def test_a_station_added_by_position_gets_a_stop_on_each_main_beside_the_line():
    """Station S at 1,500 m (no platform in the source): a stop node on the line's track A and one on B beside
    it, at the same chainage; none on P or Q (the line's own) twice, none on a track shorter than a main."""
    from planner.line.importers.stop_nodes import stops_on_line

    topo = _pair((2, 2), (2, 2))
    notes: list[str] = []
    stops_on_line(topo, ON_LINE, [("S", 1500.0)], notes)
    nodes, edges = network_tables(topo, ON_LINE, "X", notes)
    s = nodes[nodes["station_id"] == "S"]
    assert sorted(s["position_m"]) == [1500.0, 1500.0]
    on = {e.split(":")[0] for e, a, b in zip(edges["edge_id"], edges["from_node"], edges["to_node"])
          if set(s["node_id"]) & {a, b}}
    assert on == {"A", "B"}
    assert any("and on the tracks beside it there (S: B)" in n for n in notes)
    short = _pair((2, 2), (2, 2))
    short.lengths.update(A=200.0, B=200.0)
    stops_on_line(short, {"P": (0.0, 1), "A": (500.0, 1), "Q": (700.0, 1)}, [("S", 600.0)], [])
    assert [p[2] for p in short.points if p[4] == "S"] == ["A"]
