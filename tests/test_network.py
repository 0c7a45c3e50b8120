"""Route search, arrival prediction, blocking-time windows and conflicts on tiny hand-built networks.

Every expected time below is worked out by hand from constant-speed runs
(front at chainage x reached at t_dep + |x − x_dep| / v) and the blocking-time
rule: window = [entry − setting − approach, tail clear + release], tail clear
= front one train length past the exit.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.line import testing
from planner.errors import InputError, PlannerError
from planner.line.model import Call, Edge, Network, Node, Train
from planner.datasets.conflicts import check_conflicts, write_conflicts
from planner.network.arrivals import build_trajectory, stretched_curve
from planner.network.priority import would_deadlock
from planner.network.routes import (
    RouteNotFoundError,
    TrackGraph,
    overtaken_calls,
    plan_routes,
    track_direction,
)
from planner.network.windows import BlockingParams, find_overlaps

NAN = float("nan")
V = 20.0  # constant test speed [m/s]
L = 100.0  # testing.train_type() default length [m]
P = BlockingParams(setting_s=10.0, approach_s=20.0, release_s=5.0)  # lead 30 s, release 5 s
TOL_S = 1e-7
"""Times are sums of a handful of exact binary fractions and divisions by 20: round-off only."""


def const_curves(line, v=V):
    """Run curves at constant speed v between stop markers (two samples: linear is exact)."""

    def curves(train_type, origin, destination, scheduled_s):
        d = line.direction_between(origin, destination)
        a, b = line.station(origin).stop_m(d), line.station(destination).stop_m(d)
        return stretched_curve(np.array([a, b]), np.array([0.0, abs(b - a) / v]), scheduled_s)

    return curves


def train(tid, direction, calls):
    """calls: (station_id, arrival_s, departure_s, stops)."""
    return Train(tid, "T", direction, tuple(Call(i, s, a, d, st) for i, (s, a, d, st) in enumerate(calls)))


def make_line(stations, nodes, edges, trains):
    ln = testing.line(length_m=max(stations), stations=stations)
    net = Network(tuple(Node(*n) if len(n) == 4 else Node(n[0], n[1], n[2], n[3], station_id=n[4], track=n[5])
                        for n in nodes),
                  tuple(Edge(e[0], e[1], e[2], abs(e[3]), e[4]) for e in edges))
    return dataclasses.replace(ln, network=net, trains=tuple(trains))


def edges_between(nodes, pairs, track):
    pos = {n[0]: n[2] for n in nodes}
    return [(f"{a}-{b}", a, b, abs(pos[b] - pos[a]), track) for a, b in pairs]


# --- junction: P (0, track A) and Q (100, track B) merge at switch J (500), then main to C (2000)
J_NODES = [
    ("p", "stop", 0.0, "IL1", "S0", "A"),
    ("q", "stop", 100.0, "IL1", "S1", "B"),
    ("J", "switch", 500.0, "IL1"),
    ("c", "stop", 2000.0, "IL1", "S2", "M"),
]
J_EDGES = (edges_between(J_NODES, [("p", "J")], "A") + edges_between(J_NODES, [("q", "J")], "B")
           + edges_between(J_NODES, [("J", "c")], "M"))


def junction(t2):
    t1 = train("T1", "down", [("S0", NAN, 0.0, True), ("S2", 100.0, NAN, True)])
    t2_ = train("T2", "down", [("S1", NAN, t2, True), ("S2", t2 + 95.0, NAN, True)])
    return make_line([0.0, 100.0, 2000.0], J_NODES, J_EDGES, [t1, t2_])


def check(line, params=P):
    return check_conflicts(line, params, curves=const_curves(line))


def test_junction_overlap_is_reported_exactly():
    # T1: front at J 500/20 = 25 s, tail clear (front at 600) 30 s → J window [25−30, 30+5] = [−5, 35].
    # T2 (dep 20): front at J 20+400/20 = 40 → [10, 20+25+5 = 50].     Overlap on J: 35 − 10 = 25 s.
    # Section J–c: T1 [−5, arrival 100 + 5 = 105], T2 [10, 115 + 5 = 120]. Overlap 105 − 10 = 95 s.
    rep = check(junction(20.0))
    c = rep.conflicts.set_index("resource_id")
    assert sorted(c.index) == ["J", "J-c"]
    assert c.loc["J", "resource_kind"] == "node" and c.loc["J-c", "resource_kind"] == "section"
    assert c.loc["J", "overlap_s"] == pytest.approx(25.0, abs=TOL_S)
    assert c.loc["J-c", "overlap_s"] == pytest.approx(95.0, abs=TOL_S)
    assert c.loc["J", "overlap_start_s"] == pytest.approx(10.0, abs=TOL_S)
    # One conflict; no boundary in common → the train leaving the shared section first (T1, 105 < 120) goes first,
    # and T2 must wait until each of its windows opens after T1's closes: max(35 − 10, 105 − 10) = 95 s.
    assert c["conflict_id"].nunique() == 1
    assert set(c["train_a"]) == {"T1"} and set(c["train_b"]) == {"T2"}
    assert set(c["rule"]) == {"leaves-first"}
    assert c["delay_s"].iloc[0] == pytest.approx(95.0, abs=TOL_S)
    assert not c["deadlock"].any()


def test_junction_moved_apart_by_more_than_the_overlap_is_clear():
    assert len(check(junction(20.0 + 95.0 + 0.5)).conflicts) == 0
    # ... and just less than that leaves only the section, with the remaining second.
    c = check(junction(20.0 + 94.0)).conflicts
    assert list(c["resource_id"]) == ["J-c"]
    assert c["overlap_s"].iloc[0] == pytest.approx(1.0, abs=TOL_S)


def test_delaying_by_the_decided_delay_resolves_the_conflict():
    d = check(junction(20.0)).conflicts["delay_s"].iloc[0]
    assert len(check(junction(20.0 + d)).conflicts) == 0  # windows touch, no longer overlap


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 200.0))
def test_junction_overlap_matches_closed_form(t2):
    # J: [−5, 35] vs [t2 − 10, t2 + 30]; J–c: [−5, 105] vs [t2 − 10, t2 + 100].
    c = check(junction(t2)).conflicts.set_index("resource_id")["overlap_s"]
    for rid, ov in (("J", min(35.0, t2 + 30.0) - max(-5.0, t2 - 10.0)),
                    ("J-c", min(105.0, t2 + 100.0) - max(-5.0, t2 - 10.0))):
        if ov > 1e-6:
            assert c[rid] == pytest.approx(ov, abs=TOL_S)
        elif ov < -1e-6:
            assert rid not in c.index


def test_parameters_change_the_overlap_as_the_blocking_time_model_says():
    # Longer setting (+7 s) opens T2's windows 7 s earlier; longer release (+3 s) closes T1's 3 s later.
    p = BlockingParams(setting_s=17.0, approach_s=20.0, release_s=8.0)
    c = check(junction(20.0), p).conflicts.set_index("resource_id")
    assert c.loc["J", "overlap_s"] == pytest.approx(25.0 + 7.0 + 3.0, abs=TOL_S)


# --- single track S0 (0) – W1 (300) – W2 (1700) – S1 (2000), one track "1" used both ways
S_NODES = [
    ("a", "stop", 0.0, "IL1", "S0", "1"),
    ("W1", "switch", 300.0, "IL1"),
    ("W2", "switch", 1700.0, "IL2"),
    ("b", "stop", 2000.0, "IL2", "S1", "1"),
]
S_EDGES = edges_between(S_NODES, [("a", "W1"), ("W1", "W2"), ("W2", "b")], "1")


def single_track(up_dep):
    t1 = train("T1", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, NAN, True)])
    t2 = train("T2", "up", [("S1", NAN, up_dep, True), ("S0", up_dep + 100.0, NAN, True)])
    return make_line([0.0, 2000.0], S_NODES, S_EDGES, [t1, t2])


def test_opposing_trains_on_single_track_are_a_deadlock():
    # T2 (up, dep 50) claims b–W2 at 50−30 = 20 and W2 at 50+15−30 = 35 before T1 (down) claims W2 at
    # 85−30 = 55, while T1 holds W1–W2 since 15−30 = −15: each holds what the other needs.
    rep = check(single_track(50.0))
    c = rep.conflicts
    assert len(c) > 0 and c["deadlock"].all() and set(c["rule"]) == {"no-deadlock"}
    assert c["conflict_id"].nunique() == 1
    # Stretch windows: T1 [0−30, 100+5] = [−30, 105], T2 [20, 150+5]. T1 leaves first; T2 waits
    # before the stretch until T1 has released it: 105 − 20 = 85 s.
    assert set(c["train_a"]) == {"T1"} and set(c["train_b"]) == {"T2"}
    assert c["delay_s"].iloc[0] == pytest.approx(85.0, abs=TOL_S)
    assert "single-track" in c["decision"].iloc[0]
    assert len(check(single_track(50.0 + 85.0)).conflicts) == 0


def test_opposing_train_that_finds_the_stretch_claimed_just_waits():
    # T2 dep 130: T1 has claimed every resource by 55 s; T2's first claim (b–W2 at 100) finds T1 there
    # (until 105) and waits 5 s before entering; it holds nothing T1 needs: no deadlock.
    c = check(single_track(130.0)).conflicts
    assert len(c) == 1 and not c["deadlock"].any()
    assert c["resource_id"].iloc[0] == "W2-b" and c["overlap_s"].iloc[0] == pytest.approx(5.0, abs=TOL_S)
    assert c["rule"].iloc[0] == "leaves-first" and c["train_a"].iloc[0] == "T1"


def test_would_deadlock_closed_cases():
    # Two resources; A runs 0 → 1, B runs 1 → 0.
    # A holds r0 from 0, B holds r1 from 0, both ask for the other's at 10: deadlock.
    assert would_deadlock([0, 10], [20, 30], [10, 0], [30, 20])
    # A has both before B asks: B waits, no deadlock.
    assert not would_deadlock([0, 1], [20, 30], [50, 40], [60, 55])
    # Disjoint in time: nothing.
    assert not would_deadlock([0, 1], [5, 6], [20, 10], [30, 25])


# --- same direction through an interlocking boundary: S0 (0) – B (1000, boundary) – S1 (3000)
B_NODES = [
    ("a", "stop", 0.0, "IL1", "S0", "D1"),
    ("B", "boundary", 1000.0, "IL1"),
    ("b", "stop", 3000.0, "IL2", "S1", "D1"),
]


def same_direction(boundary=True):
    nodes = B_NODES if boundary else [B_NODES[0], ("B", "switch", 1000.0, "IL1"), B_NODES[2]]
    edges = edges_between(nodes, [("a", "B"), ("B", "b")], "D1")
    slow = train("SLOW", "down", [("S0", NAN, 0.0, True), ("S1", 300.0, NAN, True)])
    fast = train("FAST", "down", [("S0", NAN, 60.0, True), ("S1", 160.0, NAN, True)])
    return make_line([0.0, 3000.0], nodes, edges, [slow, fast])


def speed_curves(line):
    """SLOW runs at 10 m/s (300 s), FAST at 30 m/s (100 s): the run curve is stretched to the schedule."""
    return const_curves(line, v=30.0)


def test_same_direction_through_a_boundary_keeps_the_timetable_order():
    line = same_direction(boundary=True)
    c = check_conflicts(line, P, curves=speed_curves(line)).conflicts
    assert len(c) > 0 and c["conflict_id"].nunique() == 1
    # FAST would leave the shared section first, but SLOW departs first, and they share boundary B.
    assert set(c["train_a"]) == {"SLOW"} and set(c["rule"]) == {"timetable-order"}
    # Delay: FAST's windows must open after SLOW's close. Section B–b: SLOW [100−30, 300+5],
    # FAST [60+1000/30−30, ...] → 305 − (93.333… − 30) = 241.666… s; section a–B: SLOW [−30, 110+5]
    # (tail clear at 1100 m), FAST [30, ...] → 85 s. The larger one is the delay.
    assert c["delay_s"].iloc[0] == pytest.approx(305.0 - (60.0 + 1000.0 / 30.0 - 30.0), abs=TOL_S)


def test_same_direction_without_a_common_boundary_lets_the_first_to_leave_go_first():
    line = same_direction(boundary=False)
    c = check_conflicts(line, P, curves=speed_curves(line)).conflicts
    assert set(c["train_a"]) == {"FAST"} and set(c["rule"]) == {"leaves-first"}


# --- routes
def loop_line(fast_pass_s):
    """Down main D1 with a loop D2 at S1 (1000): switches at 800 and 1200."""
    nodes = [
        ("a", "stop", 0.0, "IL1", "S0", "D1"),
        ("w1", "switch", 800.0, "IL1"),
        ("m", "stop", 1000.0, "IL1", "S1", "D1"),
        ("l", "stop", 1000.0, "IL1", "S1", "D2"),
        ("w2", "switch", 1200.0, "IL1"),
        ("c", "stop", 2000.0, "IL1", "S2", "D1"),
    ]
    edges = (edges_between(nodes, [("a", "w1"), ("w1", "m"), ("m", "w2"), ("w2", "c")], "D1")
             + edges_between(nodes, [("w1", "l"), ("l", "w2")], "D2"))
    local = train("LOC", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, 400.0, True), ("S2", 500.0, NAN, True)])
    fast = train("EXP", "down", [("S0", NAN, 150.0, True), ("S1", fast_pass_s, fast_pass_s, False),
                                 ("S2", fast_pass_s + 60.0, NAN, True)])
    return make_line([0.0, 1000.0, 2000.0], nodes, edges, [local, fast])


def test_overtaken_local_takes_the_loop_and_the_fast_train_the_main():
    line = loop_line(250.0)
    assert overtaken_calls(line.trains) == {"LOC": {1}}
    r = plan_routes(line)
    assert r["LOC"].nodes == ("a", "w1", "l", "w2", "c") and r["LOC"].loop_calls == (1,)
    assert r["EXP"].nodes == ("a", "w1", "m", "w2", "c")
    assert r["LOC"].stop_nodes == {0: "a", 1: "l", 2: "c"}


@given(st.lists(st.tuples(st.integers(0, 12), st.integers(0, 6), st.booleans(), st.sampled_from(["down", "up"])),
                min_size=1, max_size=14))
@settings(max_examples=80, deadline=None)
def test_overtaken_calls_by_their_definition(calls):
    """Each train calls at S0, S1 (arrival, dwell, stops or passes) and S2; a stop at S1 is overtaken when a train of
    its direction is there strictly inside its stand (arrives after it arrives and leaves before it leaves). Whole
    seconds, so arrivals tie often."""
    trains = [train(f"T{i}", dr, [("S0", NAN, 0.0, True), ("S1", float(a), float(a + (w if stops else 0)), stops),
                                  ("S2", 100.0, NAN, True)]) for i, (a, w, stops, dr) in enumerate(calls)]
    want = {}
    for t in trains:
        c = t.calls[1]
        a, d = c.arrival_s, c.departure_s
        if c.stops and d > a and any(u.train_id != t.train_id and u.direction == t.direction
                                     and a < u.calls[1].arrival_s and u.calls[1].departure_s < d for u in trains):
            want[t.train_id] = {1}
    assert overtaken_calls(trains) == want


def test_local_not_overtaken_stays_on_the_main():
    line = loop_line(450.0)  # passes after the local has left
    assert overtaken_calls(line.trains) == {}
    assert plan_routes(line)["LOC"].nodes == ("a", "w1", "m", "w2", "c")


def test_route_crosses_interlocking_boundaries():
    r = plan_routes(same_direction(boundary=True))["SLOW"]
    assert r.nodes == ("a", "B", "b") and r.edges == ("a-B", "B-b")


def test_double_track_keeps_to_its_own_direction():
    # D1 and U1 side by side with a crossover; the down train must not wander onto U1.
    nodes = [
        ("ad", "stop", 0.0, "IL1", "S0", "D1"), ("au", "stop", 0.0, "IL1", "S0", "U1"),
        ("x1", "switch", 300.0, "IL1"), ("x2", "switch", 400.0, "IL1"),
        ("y1", "switch", 500.0, "IL1"), ("y2", "switch", 600.0, "IL1"),
        ("bd", "stop", 1000.0, "IL1", "S1", "D1"), ("bu", "stop", 1000.0, "IL1", "S1", "U1"),
    ]
    edges = (edges_between(nodes, [("ad", "x1"), ("x1", "y1"), ("y1", "bd")], "D1")
             + edges_between(nodes, [("au", "x2"), ("x2", "y2"), ("y2", "bu")], "U1")
             + edges_between(nodes, [("x1", "x2"), ("y1", "y2")], "X"))
    t_dn = train("D", "down", [("S0", NAN, 0.0, True), ("S1", 60.0, NAN, True)])
    t_up = train("U", "up", [("S1", NAN, 0.0, True), ("S0", 60.0, NAN, True)])
    line = make_line([0.0, 1000.0], nodes, edges, [t_dn, t_up])
    r = plan_routes(line)
    assert r["D"].nodes == ("ad", "x1", "y1", "bd")
    assert r["U"].nodes == ("bu", "y2", "x2", "au")
    assert len(check(line).conflicts) == 0  # same times, different tracks


def test_no_route_names_the_train_and_the_last_reachable_node():
    nodes = S_NODES
    edges = edges_between(nodes, [("a", "W1"), ("W2", "b")], "1")  # W1–W2 missing
    line = make_line([0.0, 2000.0], nodes, edges, [single_track(50.0).trains[0]])
    with pytest.raises(RouteNotFoundError) as e:
        plan_routes(line)
    msg = str(e.value)
    assert isinstance(e.value, PlannerError)
    assert "train T1" in msg and "the route reaches W1 at chainage 300.0 m, 1700.0 m before that stop" in msg
    assert "S1 (stop nodes b at 2000.0 m)" in msg and "the network goes no further that way from there" in msg


def test_no_route_names_the_node_nearest_the_stop_not_the_far_end_of_the_line():
    """An up train whose destination stop node is cut off: the search runs on past it to the buffer stop at the
    line's start on another track. The message names where the train's own route stops short of the stop and
    where the network goes from there (it said: last reachable node buffer at chainage 0.0 m)."""
    nodes = [("buf", "end", 0.0, "IL1"), ("a", "stop", 50.0, "IL1", "S0", "U"), ("W", "switch", 1000.0, "IL1"),
             ("b", "stop", 2000.0, "IL1", "S1", "U")]
    edges = edges_between(nodes, [("b", "W")], "U") + edges_between(nodes, [("W", "buf")], "1")  # W-a missing
    t = train("U1", "up", [("S1", NAN, 0.0, True), ("S0", 100.0, NAN, True)])
    line = make_line([0.0, 2000.0], nodes, edges, [t])
    with pytest.raises(RouteNotFoundError) as e:
        plan_routes(line)
    msg = str(e.value)
    assert ("the route reaches W at chainage 1000.0 m, 950.0 m before that stop; from there the network goes on "
            "only to buf (track 1, 0.0 m)") in msg, msg


def test_an_unroutable_train_is_left_out_and_the_others_are_routed_as_without_it():
    """With ``unrouted``, the train the network cannot carry is listed with its reason and the others get the
    routes of a timetable without it (overtaking judged again without it)."""
    good = single_track(50.0)
    cut = train("T3", "down", [("S0", NAN, 10.0, True), ("S2", 110.0, NAN, True)])  # S2: its stop node is cut off
    nodes = S_NODES + [("z", "stop", 2500.0, "IL2", "S2", "1")]  # on no edge: unreachable
    bad = make_line([0.0, 2000.0, 2500.0], nodes, S_EDGES, [*good.trains, cut])
    unrouted: dict = {}
    routes = plan_routes(bad, unrouted=unrouted)
    assert list(unrouted) == ["T3"] and "train T3 (down): no route" in unrouted["T3"]
    assert list(routes) == ["T1", "T2"]
    alone = plan_routes(make_line([0.0, 2000.0, 2500.0], nodes, S_EDGES, list(good.trains)))
    assert [(r.nodes, r.edges, r.stop_nodes, r.loop_calls) for r in routes.values()] == \
        [(r.nodes, r.edges, r.stop_nodes, r.loop_calls) for r in alone.values()]


def test_monotone_route_never_runs_back():
    # The only way from a to b would be via a node behind the origin: no route.
    nodes = [("a", "stop", 500.0, "IL1", "S0", "1"), ("z", "switch", 100.0, "IL1"),
             ("b", "stop", 2000.0, "IL1", "S1", "1")]
    edges = edges_between(nodes, [("a", "z"), ("z", "b")], "1")
    t = train("T9", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, NAN, True)])
    line = make_line([500.0, 2000.0], nodes, edges, [t])
    with pytest.raises(RouteNotFoundError, match=r"train T9.*the route reaches a at chainage 500\.0 m.*goes no "
                                                 r"further that way from there \(and back to z"):
        plan_routes(line)


# --- arrival prediction
def test_front_time_at_nodes_with_stretch_and_dwell():
    # S0 (0) → S1 (1000, dwell 100→130) → S2 (2000). Curve at 20 m/s takes 50 s; schedule 100 s per
    # interstation → uniform stretch × 2: front at 500 m at 50 s, at S1 arrival 100, leaves at 130.
    line = testing.line(length_m=2000.0, stations=[0.0, 1000.0, 2000.0])
    t = train("T", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, 130.0, True), ("S2", 230.0, NAN, True)])
    traj = build_trajectory(line, t, const_curves(line))
    got = traj.front_time([0.0, 500.0, 1000.0, 1500.0, 2000.0])
    assert got == pytest.approx([0.0, 50.0, 100.0, 180.0, 230.0], abs=TOL_S)
    assert traj.front_time([2100.0])[0] == math.inf
    # The front moves on past S1 when it departs (130); elsewhere it passes when it arrives.
    assert traj.front_leaves([-50.0, 0.0, 500.0, 1000.0, 1500.0, 2000.0]) == pytest.approx(
        [0.0, 0.0, 50.0, 130.0, 180.0, 230.0], abs=TOL_S)
    assert traj.front_leaves([2100.0])[0] == math.inf


def test_front_leaves_a_stop_at_departure_despite_round_off_where_curves_meet():
    # Two curves that meet at the stop marker 1000 m only up to round-off (1000 + 4.5e-13 and 1000):
    # a stop node at exactly 1000 is still left at the departure (130), not at the arrival (100).
    from planner.network.arrivals import Trajectory

    u = np.array([0.0, 1000.0 + 4.5e-13, 1000.0, 2000.0])
    t = np.array([0.0, 100.0, 130.0, 230.0])
    traj = Trajectory("T", "down", np.maximum.accumulate(u), t)
    assert traj.front_leaves([1000.0, 1000.0 - 1e-3])[0] == pytest.approx(130.0, abs=TOL_S)
    assert traj.front_leaves([1000.0 - 1e-3])[0] == pytest.approx(100.0 - 1e-4, abs=1e-9)  # passed before it
    assert traj.front_leaves([1500.0])[0] == pytest.approx(180.0, abs=TOL_S)
    up = Trajectory("U", "up", np.array([-2000.0, -1000.0, -1000.0, 0.0]), t)
    assert up.front_leaves([1000.0, 2000.0, 0.0, -10.0]) == pytest.approx([130.0, 0.0, 230.0, math.inf])


def test_up_train_prediction_runs_towards_lower_chainage():
    line = testing.line(length_m=2000.0, stations=[0.0, 2000.0])
    t = train("U", "up", [("S1", NAN, 10.0, True), ("S0", 110.0, NAN, True)])
    traj = build_trajectory(line, t, const_curves(line))
    assert traj.front_time([2000.0, 1500.0, 0.0]) == pytest.approx([10.0, 35.0, 110.0], abs=TOL_S)


def test_late_curve_is_not_compressed_and_lateness_is_absorbed_by_the_dwell():
    # Curve takes 50 s, schedule gives 40 s: arrival 50 (late), departs at the scheduled 60 anyway.
    line = testing.line(length_m=2000.0, stations=[0.0, 1000.0, 2000.0])
    t = train("T", "down", [("S0", NAN, 0.0, True), ("S1", 40.0, 60.0, True), ("S2", 110.0, NAN, True)])
    traj = build_trajectory(line, t, const_curves(line))
    assert traj.front_time([1000.0, 1500.0]) == pytest.approx([50.0, 85.0], abs=TOL_S)


# --- sweep
@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 100), st.integers(1, 40), st.integers(0, 4)),
                min_size=0, max_size=40))
def test_sweep_finds_exactly_the_brute_force_pairs(ws):
    res = np.array([w[0] for w in ws], dtype=np.int64)
    s = np.array([float(w[1]) for w in ws])
    e = s + np.array([float(w[2]) for w in ws])
    own = np.array([w[3] for w in ws], dtype=np.int64)
    i, j = find_overlaps(res, s, e, own)
    got = {tuple(sorted(p)) for p in zip(i.tolist(), j.tolist())}
    want = {(a, b) for a in range(len(ws)) for b in range(a + 1, len(ws))
            if res[a] == res[b] and own[a] != own[b] and min(e[a], e[b]) - max(s[a], s[b]) > 1e-9}
    assert got == want and len(got) == len(i)


# --- parameters, outputs
def test_params_from_job_table():
    p = BlockingParams.from_dict({"enabled": True, "setting_s": 12, "approach_s": 25.5, "release_s": 4})
    assert (p.setting_s, p.approach_s, p.release_s, p.lead_s) == (12.0, 25.5, 4.0, 37.5)
    with pytest.raises(InputError, match="settin_s"):
        BlockingParams.from_dict({"settin_s": 1})
    with pytest.raises(InputError, match="release_s"):
        BlockingParams.from_dict({"release_s": -1})
    assert BlockingParams() == BlockingParams.from_dict({})


def test_track_direction_convention():
    assert [track_direction(t) for t in ("D1", "U2", "1", "X", None)] == ["down", "up", "both", "both", "both"]


def test_write_datasets_partitioned_and_deterministic(tmp_path):
    rep = check(junction(20.0))
    write_conflicts(rep, tmp_path / "a")
    write_conflicts(rep, tmp_path / "b")
    f = tmp_path / "a" / "conflicts" / "line=test" / "part-0.parquet"
    assert f.read_bytes() == (tmp_path / "b" / "conflicts" / "line=test" / "part-0.parquet").read_bytes()
    t = pq.read_table(f)
    assert t.num_rows == 2 and "overlap_s" in t.column_names
    assert t.schema.field("overlap_s").metadata[b"description"]
    occ = pq.read_table(tmp_path / "a" / "occupation" / "line=test" / "direction=down" / "train_type=T" / "part-0.parquet")
    # T1: a–J... p–J, J, J–c; T2: q–J, J, J–c.
    assert occ.num_rows == 6
    row = occ.to_pandas().query("train_id == 'T1' and resource_id == 'J'").iloc[0]
    assert (row.start_s, row.end_s) == pytest.approx((-5.0, 35.0), abs=TOL_S)
    assert row.clearing_s == pytest.approx(L / V, abs=TOL_S)


def test_no_conflicts_still_writes_an_empty_conflicts_file(tmp_path):
    rep = check(junction(500.0))
    write_conflicts(rep, tmp_path)
    assert pq.read_table(tmp_path / "conflicts" / "line=test" / "part-0.parquet").num_rows == 0


def test_missing_network_is_a_clear_error():
    with pytest.raises(InputError, match="nodes.parquet"):
        TrackGraph(testing.line())


# --- run curves from the simulator
def test_simulator_curves_pick_the_ratio_that_meets_the_schedule():
    from planner.network.arrivals import SimulatorCurves
    from planner.physics.track import SimSettings
    from planner.api import running_time

    line = testing.line(length_m=1500.0)
    src = SimulatorCurves(line, ratios=(1.0, 0.8, 0.6), ds_m=5.0)
    ref = running_time(line, "T", "S0", "S1", ratio=0.8, settings=SimSettings(ds_m=5.0))
    x, t = src("T", "S0", "S1", ref.time_s)  # exactly the time of a grid ratio: that run
    assert x == pytest.approx(ref.curve["position_m"].to_numpy())
    assert t == pytest.approx(ref.curve["time_s"].to_numpy(), abs=1e-9)
    # Between two ratios: ends exactly at the schedule, monotone, between the neighbours' curves.
    fast = running_time(line, "T", "S0", "S1", ratio=1.0, settings=SimSettings(ds_m=5.0)).curve["time_s"].to_numpy()
    sched = 0.5 * (ref.time_s + fast[-1])
    x, t = src("T", "S0", "S1", sched)
    assert t[-1] == pytest.approx(sched, abs=1e-9) and np.all(np.diff(t) >= 0)
    assert np.all(t >= fast - 1e-9) and np.all(t <= ref.curve["time_s"].to_numpy() + 1e-9)
    # Faster than possible: the ratio-1.0 curve, unchanged (the train runs late).
    assert src("T", "S0", "S1", fast[-1] - 10.0)[1] == pytest.approx(fast, abs=1e-9)
    assert src.simulated == 1  # one batch for the interstation


def test_sections_are_split_at_the_block_signals_of_their_direction():
    # One D1 edge 0–2000 with a down block signal at 1000 (and an up one at 1500, which a down track
    # ignores). Leader dep 0, follower dep 60, both 20 m/s, L = 100 m:
    #   block 1 [0, 1000]:    leader [−30, front at 1100 = 55, +5 = 60],   follower [30, 120] → 30 s
    #   block 2 [1000, 2000]: leader [50−30, 100+5] = [20, 105],          follower [80, 165] → 25 s
    # (unsplit it would be one section with [−30, 105] vs [30, 165] → 75 s.)
    from planner.line.model import Signal

    nodes = [("a", "stop", 0.0, "IL1", "S0", "D1"), ("b", "stop", 2000.0, "IL1", "S1", "D1")]
    lead = train("L", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, NAN, True)])
    foll = train("F", "down", [("S0", NAN, 60.0, True), ("S1", 160.0, NAN, True)])
    line = make_line([0.0, 2000.0], nodes, edges_between(nodes, [("a", "b")], "D1"), [lead, foll])
    line = dataclasses.replace(line, signals=(Signal("s1", 1000.0, "down"), Signal("s2", 1500.0, "up")))
    c = check(line).conflicts.set_index("resource_id")
    assert sorted(c.index) == ["a-b/1", "a-b/2"]
    assert c.loc["a-b/1", "overlap_s"] == pytest.approx(30.0, abs=TOL_S)
    assert c.loc["a-b/2", "overlap_s"] == pytest.approx(25.0, abs=TOL_S)
    assert (c.loc["a-b/2", "from_m"], c.loc["a-b/2", "to_m"]) == (1000.0, 2000.0)
    assert set(c["train_a"]) == {"L"} and c["delay_s"].iloc[0] == pytest.approx(30.0, abs=TOL_S)


# --- windows at an intermediate stop (issue 14, defect 4)
# S0 (0) – m (1000, stop of S1) – c (2000), one track "1"; block signals split a–m at 950 (both directions)
# so the 100 m train standing at m fills a–m/2 [950, 1000] and reaches 50 m back into a–m/1.
# T runs 0 → S1 arr 100, dep 400 → S2 arr 500: the 50 s curve (20 m/s) is stretched to the 100 s
# schedule, so the front runs at 10 m/s: it is at x at t_dep + |x − x_dep| / 10.
DWELL_NODES = [("a", "stop", 0.0, "IL1", "S0", "1"), ("m", "stop", 1000.0, "IL1", "S1", "1"),
               ("c", "stop", 2000.0, "IL1", "S2", "1")]
DWELL_EDGES = edges_between(DWELL_NODES, [("a", "m"), ("m", "c")], "1")


def dwell_line(direction="down", others=()):
    from planner.line.model import Signal

    order = ("S0", "S1", "S2") if direction == "down" else ("S2", "S1", "S0")
    t = train("T", direction, [(order[0], NAN, 0.0, True), (order[1], 100.0, 400.0, True),
                               (order[2], 500.0, NAN, True)])
    line = make_line([0.0, 1000.0, 2000.0], DWELL_NODES, DWELL_EDGES, [t, *others])
    signals = (Signal("sd", 950.0, "down"),) if direction == "down" else (Signal("su", 1050.0, "up"),)
    return dataclasses.replace(line, signals=signals)


def windows_of(rep, tid="T"):
    occ = rep.occupation.query("train_id == @tid").set_index("resource_id")
    return {r: (row.start_s, row.end_s) for r, row in occ.iterrows()}, occ


def test_section_after_an_intermediate_stop_opens_at_departure_minus_lead():
    # Down: the front enters m–c when it leaves S1 at 400 (not when it arrives at 100):
    #   m–c opens 400 − 30 = 370 and closes at the arrival 500 (+ terminal 0) + 5 = 505.
    # The origin's first section opens at departure − lead likewise: a–m/1 at 0 − 30.
    w, occ = windows_of(check(dwell_line("down")))
    assert w["m-c"] == pytest.approx((370.0, 505.0), abs=TOL_S)
    assert occ.loc["m-c", "entry_s"] == pytest.approx(400.0, abs=TOL_S)
    assert w["a-m/1"][0] == pytest.approx(-30.0, abs=TOL_S)


def test_section_after_an_intermediate_stop_opens_at_departure_minus_lead_up():
    # Up (S2 2000 → S1 1000 → S0 0; up signal at 1050 splits m–c): a–m is entered at the departure from S1.
    w, _ = windows_of(check(dwell_line("up")))
    assert w["a-m"] == pytest.approx((370.0, 505.0), abs=TOL_S)
    assert w["m-c/2"][0] == pytest.approx(-30.0, abs=TOL_S)


def test_sections_the_train_stands_in_stay_claimed_through_the_dwell():
    # The train stands with its front at m (1000) and its tail at 900 from 100 to 400. Both sections
    # under it are claimed over the whole dwell: they close when the tail clears their exit.
    #   a–m/1 [0, 950]:    opens −30, tail clears 950 when the front is at 1050: 400 + 5 = 405 → 410
    #   a–m/2 [950, 1000]: opens 95 − 30 = 65, tail clears 1000 at front 1100: 400 + 10 = 410 → 415
    w, occ = windows_of(check(dwell_line("down")))
    assert w["a-m/1"] == pytest.approx((-30.0, 410.0), abs=TOL_S)
    assert w["a-m/2"] == pytest.approx((65.0, 415.0), abs=TOL_S)
    assert occ.loc["a-m/2", "exit_s"] == pytest.approx(100.0, abs=TOL_S)  # the front reaches the stop at arrival
    for r in ("a-m/1", "a-m/2"):
        assert w[r][0] <= 100.0 and w[r][1] >= 400.0


def test_train_leaving_the_platform_ahead_before_the_arrival_is_no_conflict():
    # P starts from S1's stop node at 60 and runs to S2 (arr 160, 10 m/s): m–c [60 − 30, 160 + 5] = [30, 165].
    # T arrives at S1 at 100 but enters m–c only at its departure 400: [370, 505]; no overlap.
    # (Windows opened at T's arrival, [70, 505], would report a 95 s conflict.)
    p = train("P", "down", [("S1", NAN, 60.0, True), ("S2", 160.0, NAN, True)])
    rep = check(dwell_line("down", [p]))
    assert windows_of(rep, "P")[0]["m-c"] == pytest.approx((30.0, 165.0), abs=TOL_S)
    assert len(rep.conflicts) == 0
    # Moved so that P clears m–c after 370, the remaining overlap is a conflict of exactly that size.
    p2 = train("P", "down", [("S1", NAN, 300.0, True), ("S2", 400.0, NAN, True)])
    c = check(dwell_line("down", [p2])).conflicts
    assert list(c["resource_id"]) == ["m-c"] and c["overlap_s"].iloc[0] == pytest.approx(405.0 - 370.0, abs=TOL_S)


# --- double track whose own main is used both ways (OSRD's ``B:`` naming) beside the up main
BU_NODES = [
    ("a", "stop", 0.0, "IL1", "S0", "B:main"), ("c", "stop", 0.0, "IL1", "S0", "U:2"),
    ("X1", "switch", 300.0, "IL1"), ("Y1", "switch", 400.0, "IL1"),
    ("Y2", "switch", 1600.0, "IL1"), ("X2", "switch", 1700.0, "IL1"),
    ("b", "stop", 2000.0, "IL1", "S1", "B:main"),  # the only platform at S1 is on the both-ways main
]
BU_EDGES = (edges_between(BU_NODES, [("a", "X1"), ("X1", "X2"), ("X2", "b")], "B:main")
            + edges_between(BU_NODES, [("c", "Y1"), ("Y1", "Y2")], "U:2")
            + edges_between(BU_NODES, [("X1", "Y1")], "B:x1") + edges_between(BU_NODES, [("Y2", "X2")], "B:x2"))


def _both_ways_main(up_dep=0.0):
    down = train("T1", "down", [("S0", NAN, 0.0, True), ("S1", 200.0, NAN, True)])
    up = train("T2", "up", [("S1", NAN, up_dep, True), ("S0", up_dep + 200.0, NAN, True)])
    return make_line([0.0, 2000.0], BU_NODES, BU_EDGES, [down, up])


def test_a_track_used_both_ways_is_the_route_only_where_the_own_main_is_not():
    """An up train on a double line whose own main is named both-ways (B:) beside the up main (U:) crosses to
    the up main at the first crossover and back where its stop needs it; it ran on the down train's main."""
    r = plan_routes(_both_ways_main())
    assert r["T1"].nodes == ("a", "X1", "X2", "b")
    assert r["T2"].nodes == ("b", "X2", "Y2", "Y1", "c")


def test_one_train_each_way_on_double_track_meet_no_conflict():
    """The trains pass each other mid-line: routed on the same main they would meet head on."""
    chk = check_conflicts(_both_ways_main(up_dep=0.0), {"setting_s": 10.0, "approach_s": 20.0, "release_s": 5.0})
    assert chk.summary["conflicts"] == 0 and chk.summary["deadlocks"] == 0


# --- a station whose only platform on a down-named track is a dead end the down train cannot run into
#     a (S0, 0) – b (S1, 1000, the main, named up by its own signals) – X (1200) – z (S2, 2000); stub d (S1, 1100)
#     leaves X backwards: a down train reaches d only by reversing at X
STUB_NODES = [
    ("a", "stop", 0.0, "IL1", "S0", "U:main"), ("b", "stop", 1000.0, "IL1", "S1", "U:main"),
    ("X", "switch", 1200.0, "IL1"), ("d", "stop", 1100.0, "IL1", "S1", "D:stub"),
    ("z", "stop", 2000.0, "IL1", "S2", "U:main"),
]
STUB_EDGES = (edges_between(STUB_NODES, [("a", "b"), ("b", "X"), ("X", "z")], "U:main")
              + edges_between(STUB_NODES, [("X", "d")], "D:stub"))


def test_a_platform_named_for_the_other_direction_is_taken_where_the_own_one_cannot_be_reached():
    """OSRD's small_infra: two trains were unrouted because only the platforms of tracks named for their direction
    were tried at a station, and those were out of reach without reversing."""
    down = train("T1", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, 130.0, True), ("S2", 230.0, NAN, True)])
    r = plan_routes(make_line([0.0, 1000.0, 2000.0], STUB_NODES, STUB_EDGES, [down]))
    assert r["T1"].nodes == ("a", "b", "X", "z")


@given(st.lists(st.one_of(st.floats(-500.0, 12_000.0, allow_nan=False), st.sampled_from([0.0, 5e-324, 1e-300])),
                min_size=1, max_size=8), st.data())
@settings(max_examples=60, deadline=None)
def test_resource_station_is_the_nearest_by_its_definition(sample_line, positions, data):
    """Every resource's station against the definition (the station nearest the extent; of those it spans the
    one nearest the middle; then the lower chainage; then the first listed), over all stations, on the sample
    with its stations moved to arbitrary chainages, some of them the same or as far from an extent to the last bit."""
    from planner.network.routes import KIND_NODE, KIND_SECTION, TrackGraph

    line = sample_line
    pos = [data.draw(st.sampled_from(positions)) for _ in line.stations]
    moved = dataclasses.replace(line, stations=tuple(dataclasses.replace(s, position_m=p)
                                                     for s, p in zip(line.stations, pos)))
    g = TrackGraph(moved)
    for kind, count in ((KIND_NODE, len(g.node_ids)), (KIND_SECTION, len(g.piece_edge))):
        for i in range(count):
            lo, hi = g.resource_extent(kind, i)
            gap = [max(lo - s.position_m, s.position_m - hi, 0.0) for s in moved.stations]
            key = [(d, abs(s.position_m - 0.5 * (lo + hi)), s.position_m) for d, s in zip(gap, moved.stations)]
            k = key.index(min(key))
            assert g.resource_station(kind, i) == (moved.stations[k].station_id, gap[k])

