"""ATS-P data: pattern start, overwrite flags, beacon correction flags (planner.bundle.atsp)."""
from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.bundle import atsp
from planner.line import testing
from planner.bundle.assemble import line_tables
from test_bundle_support import make_line

KMH = 1 / 3.6


# --- pattern distance --------------------------------------------------------------
def test_pattern_distance_closed_form_in_railway_units():
    # d = (V² − v²) / (2 · 3.6 · β) with V, v in km/h and β in km/h/s (classic running-theory form).
    d = atsp.pattern_distance_m(100 * KMH, 60 * KMH, 2.5 * KMH)
    assert d == pytest.approx((100**2 - 60**2) / (2 * 3.6 * 2.5), rel=1e-12)


def test_pattern_distance_matches_a_braking_simulation():
    """Integrate dv/dt = −b from v_high until v_low; the distance run is the pattern length."""
    v_high, v_low, b = 110 * KMH, 35 * KMH, 2.9 * KMH
    dt = 1e-4
    # Exact per step for constant deceleration (trapezoid is exact for linear v(t)); the last
    # partial step is cut so that v lands on v_low.
    t_end = (v_high - v_low) / b
    n = int(t_end / dt)
    t = np.append(np.arange(n + 1) * dt, t_end)
    v = v_high - b * t
    x = np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t))
    assert atsp.pattern_distance_m(v_high, v_low, b) == pytest.approx(x, rel=1e-9)


@given(st.floats(1, 60), st.floats(0.5, 60), st.floats(0.1, 2.0))
def test_train_braking_from_pattern_start_reaches_the_limit_at_the_restriction(v_high, v_low, b):
    d = atsp.pattern_distance_m(v_high, v_low, b)
    if v_low >= v_high:
        assert d == 0.0
    else:
        # v² = v_high² − 2 b d at the restriction start.
        assert np.sqrt(v_high**2 - 2 * b * d) == pytest.approx(v_low, rel=1e-9, abs=1e-9)


def test_pattern_distance_vectorised_and_rejects_bad_decel():
    d = atsp.pattern_distance_m(np.array([30.0, 30.0]), np.array([10.0, 40.0]), 1.0)
    assert d.tolist() == [400.0, 0.0]
    with pytest.raises(ValueError):
        atsp.pattern_distance_m(30.0, 10.0, 0.0)


def test_running_coordinates_round_trip():
    x = np.array([0.0, 120.5, 4000.0])
    for d in ("down", "up"):
        assert np.array_equal(atsp.to_chainage(atsp.to_running(x, d), d), x)
    assert np.all(np.diff(atsp.to_running(x, "up")) < 0)


# --- overwrite --------------------------------------------------------------------
def reference_overwrites(feed, until, active):
    n = len(feed)
    hit = [[i != j and active[i] and active[j] and feed[i] <= feed[j] < until[i] for j in range(n)]
           for i in range(n)]
    conflict = [any(hit[i][j] or hit[j][i] for i in range(n)) for j in range(n)]
    return hit, conflict


def test_overwrite_examples():
    # A: fed 0, held until 100. B fed at 50 (inside A's window) overwrites A. C fed at 300: free.
    ow, c = atsp.overwrite_conflicts([0.0, 50.0, 300.0], [100.0, 150.0, 400.0])
    assert ow.tolist() == [-1, 0, -1] and c.tolist() == [True, True, False]
    # Fed exactly when A's window closes: no overwrite (half-open window).
    ow, c = atsp.overwrite_conflicts([0.0, 100.0], [100.0, 150.0])
    assert c.tolist() == [False, False]
    # Same feed point: each overwrites the other.
    ow, c = atsp.overwrite_conflicts([10.0, 10.0], [50.0, 60.0])
    assert c.tolist() == [True, True]
    # An inactive restriction (no pattern) takes no part.
    ow, c = atsp.overwrite_conflicts([0.0, 50.0], [100.0, 150.0], [True, False])
    assert c.tolist() == [False, False] and ow.tolist() == [-1, -1]
    # Three nested: C fed while A and B are both held overwrites the later-fed B.
    ow, _ = atsp.overwrite_conflicts([0.0, 20.0, 40.0], [100.0, 100.0, 100.0])
    assert ow.tolist() == [-1, 0, 1]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 50), st.integers(0, 30), st.booleans()), min_size=0, max_size=8))
def test_overwrite_matches_pairwise_definition(rows):
    feed = np.array([float(f) for f, _, _ in rows])
    until = feed + np.array([float(h) for _, h, _ in rows])
    active = np.array([a for _, _, a in rows], dtype=bool)
    ow, c = atsp.overwrite_conflicts(feed, until, active)
    hit, conflict = reference_overwrites(feed.tolist(), until.tolist(), active.tolist())
    assert c.tolist() == conflict
    for j in range(len(rows)):
        cands = [i for i in range(len(rows)) if hit[i][j]]
        if not cands:
            assert ow[j] == -1
        else:
            assert ow[j] in cands and feed[ow[j]] == max(feed[i] for i in cands)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 100), st.integers(1, 60)), min_size=0, max_size=7))
def test_overwrite_with_hold_until_start_is_the_briefs_rule(rows):
    """Held only up to the restriction start, a pair conflicts iff the next restriction (in
    running order of the starts) has its pattern start before the previous one's start
    (docs/design.md §3 wording). Patterns have positive length here (d ≥ 1 m)."""
    entry = np.array([float(e) for e, _ in rows])
    start = entry - np.array([float(d) for _, d in rows])
    _, c = atsp.overwrite_conflicts(start, entry)
    order = sorted(range(len(rows)), key=lambda k: entry[k])
    expect = [False] * len(rows)
    for a, b in itertools.combinations(order, 2):  # a not after b in running order
        if start[b] < entry[a]:
            expect[a] = expect[b] = True
    assert c.tolist() == expect


# --- beacon correction flags ------------------------------------------------------------
def test_correction_usable_examples():
    assert atsp.correction_usable(["A", "A", "B", "C", "C", "C", "D", "A"]).tolist() == [
        False, False, True, False, False, False, True, True]
    assert atsp.correction_usable([]).tolist() == []
    assert atsp.correction_usable(["X"]).tolist() == [True]


@given(st.lists(st.sampled_from("ABC"), max_size=12))
def test_correction_usable_is_false_exactly_in_runs(tel):
    expect = []
    for _, grp in itertools.groupby(tel):
        k = len(list(grp))
        expect += [k == 1] * k
    assert atsp.correction_usable(tel).tolist() == expect


# --- telegrams ----------------------------------------------------------------------
def test_telegram_rounds_towards_the_safe_side():
    assert atsp.restriction_telegram(60.0, 355.56, 400.0) == "P060D00355L00400"
    assert atsp.restriction_telegram(59.9, 355.0, 400.2) == "P059D00355L00401"
    assert atsp.restriction_telegram(45.0 * KMH * 3.6, 12.0, 160.0) == "P045D00012L00160"
    with pytest.raises(ValueError):
        atsp.restriction_telegram(0.0, 10.0, 10.0)


# --- on a line (the bundle's restriction / atsp / beacon tables) -------------------------
def test_line_tables_down_e10_closed_form():
    t = line_tables(make_line(), "down", "E10")
    r = t["restrictions"].to_pylist()
    a = {x["restriction_id"]: x for x in t["atsp"].to_pylist()}
    # v_high = min(line 100, vehicle 110) km/h; β = 2.5 km/h/s.
    d = lambda v: (100**2 - v**2) / (2 * 3.6 * 2.5)  # noqa: E731
    assert [x["restriction_id"] for x in r] == ["R0", "R1", "R2", "R3"]
    for x, (start, v) in zip(r, [(1000, 60), (1400, 45), (3000, 80), (4200, 70)]):
        assert x["entry_m"] == start
        assert x["pattern_distance_m"] == pytest.approx(d(v), rel=1e-12)
        assert x["pattern_start_m"] == pytest.approx(start - d(v), rel=1e-12)
        assert x["onboard_max_kmh"] == pytest.approx(v - 3.0)
    assert sorted(a) == ["R0", "R1", "R3"]  # R2 has a ground beacon
    assert a["R0"]["telegram"] == "P060D00355L00400"  # 300 m + 100 m train
    assert a["R0"]["feed_m"] == pytest.approx(1000 - d(60))
    # R1's pattern (1400 − 443.1 = 956.9 m) starts before R0's start (1000 m): overwrite.
    assert a["R1"]["overwrites"] == "R0" and a["R0"]["overwrite_conflict"] and a["R1"]["overwrite_conflict"]
    assert not a["R3"]["overwrite_conflict"]
    assert [x["correction_usable"] for x in t["beacons"].to_pylist()] == [False, False, True, True]


def test_line_tables_up_enters_at_end_and_patterns_start_beyond_it():
    t = line_tables(make_line(), "up", "E6")
    r = {x["restriction_id"]: x for x in t["restrictions"].to_pylist()}
    # v_high = min(100, 90) km/h; β = 3.0 km/h/s; an up train enters [1000, 1300] at 1300.
    d = (90**2 - 60**2) / (2 * 3.6 * 3.0)
    assert r["R0"]["entry_m"] == 1300.0 and r["R0"]["clear_m"] == 1000.0 - 60.0
    assert r["R0"]["pattern_start_m"] == pytest.approx(1300.0 + d)
    assert [x["beacon_id"] for x in t["beacons"].to_pylist()] == ["U1", "U2"]
    assert [x["seq"] for x in t["restrictions"].to_pylist()] == [0, 1, 2, 3]
    assert [x["restriction_id"] for x in t["restrictions"].to_pylist()] == ["R3", "R2", "R1", "R0"]


def test_restriction_above_approach_speed_needs_no_pattern_and_clipped_feed():
    ln = testing.line(length_m=3000.0, max_speed_kmh=100.0, limits=[(100.0, 200.0, 40.0), (1000.0, 1200.0, 120.0)])
    ln = dataclasses.replace(ln, speed_limits=tuple(dataclasses.replace(s, has_beacon=False)
                                                    for s in ln.speed_limits))
    t = line_tables(ln, "down", "T")
    r = {x["restriction_id"]: x for x in t["restrictions"].to_pylist()}
    assert not r["R1"]["pattern_needed"] and r["R1"]["pattern_distance_m"] == 0.0
    (a,) = t["atsp"].to_pylist()
    assert a["restriction_id"] == "R0" and a["feed_clipped"]
    assert a["feed_m"] == 0.0 and a["distance_m"] == 100.0 and a["pattern_start_m"] < 0.0
