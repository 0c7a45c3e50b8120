"""Evaluation points: departure, point after departure, odometer points at a regular interval,
flagged beacons between the stop markers."""
import dataclasses
import math

import numpy as np
import pytest

from planner.line import testing
from planner.errors import InputError
from planner.tables.eval_points import evaluation_points, interstation_length_m
from planner.line.model import Beacon


def _line():
    ln = testing.line(length_m=5000.0, stations=[100.0, 2600.0, 4900.0])
    beacons = (
        Beacon("B1", 900.0, "down", "signal", "t1", True),
        Beacon("B2", 1700.0, "down", "pattern_update", "t2", True),
        Beacon("B3", 1200.0, "down", "tasc", "t3", False),       # not an evaluation point
        Beacon("B4", 2000.0, "up", "signal", "t4", True),         # read only running up
        Beacon("B5", 2600.0, "down", "signal", "t5", True),       # on the stop marker: not strictly between
        Beacon("B6", 300.0, "down", "signal", "t6", True),        # exactly 200 m after departure
        Beacon("B7", 100.0, "up", "signal", "t7", True),          # on the up arrival marker
        Beacon("B8", 4000.0, "up", "signal", "t8", True),
    )
    return dataclasses.replace(ln, beacons=beacons)


def test_down_points():
    pts = evaluation_points(_line(), "S0", "S1")
    assert [p.eval_point_id for p in pts] == ["dep", "dep+200", "B1", "B2"]
    # running distance from the departure marker at 100 m
    assert [p.s_m for p in pts] == [0.0, 200.0, 800.0, 1600.0]
    assert [p.position_m for p in pts] == [100.0, 300.0, 900.0, 1700.0]


def test_up_points_mirror_chainage():
    ln = _line()
    pts = evaluation_points(ln, "S1", "S0")
    assert [p.eval_point_id for p in pts] == ["dep", "dep+200", "B4"]
    assert [p.s_m for p in pts] == [0.0, 200.0, 600.0]
    assert [p.position_m for p in pts] == [2600.0, 2400.0, 2000.0]
    assert interstation_length_m(ln, "S1", "S0") == 2500.0
    pts = evaluation_points(ln, "S2", "S1")
    assert [(p.eval_point_id, p.s_m) for p in pts] == [("dep", 0.0), ("dep+200", 200.0), ("B8", 900.0)]


def test_configurable_after_departure():
    ln = _line()
    assert [p.eval_point_id for p in evaluation_points(ln, "S0", "S1", after_departure_m=350)] == [
        "dep", "B6", "dep+350", "B1", "B2"]
    assert [p.eval_point_id for p in evaluation_points(ln, "S0", "S1", after_departure_m=None)] == [
        "dep", "B6", "B1", "B2"]
    # longer than the interstation: left out
    assert [p.eval_point_id for p in evaluation_points(ln, "S1", "S2", after_departure_m=2300)] == ["dep"]
    with pytest.raises(InputError):
        evaluation_points(ln, "S0", "S1", after_departure_m=-5)


# --- points at a regular interval (issue 22) --------------------------------------------------
def _ids_s(pts):
    return [(p.eval_point_id, p.s_m, p.kind) for p in pts]


def test_interval_points_closed_form_down():
    """S0 -> S1 is 2500 m from the marker at 100 m: with a = 200 m and I = 500 m the odometer points
    are at a + k I = 700, 1200, 1700, 2200 m (2700 m is past the stop), among the beacons."""
    pts = evaluation_points(_line(), "S0", "S1", interval_m=500)
    assert _ids_s(pts) == [
        ("dep", 0.0, "departure"), ("dep+200", 200.0, "after_departure"), ("dep+700", 700.0, "interval"),
        ("B1", 800.0, "beacon"), ("dep+1200", 1200.0, "interval"), ("B2", 1600.0, "beacon"),
        ("dep+1700", 1700.0, "interval"), ("dep+2200", 2200.0, "interval")]
    assert [p.position_m for p in pts] == [100.0 + p.s_m for p in pts]


def test_interval_points_closed_form_up():
    """Running up, chainage falls: position = stop marker (2600 m) - s."""
    pts = evaluation_points(_line(), "S1", "S0", interval_m=1000)
    assert _ids_s(pts) == [("dep", 0.0, "departure"), ("dep+200", 200.0, "after_departure"),
                           ("B4", 600.0, "beacon"), ("dep+1200", 1200.0, "interval"),
                           ("dep+2200", 2200.0, "interval")]
    assert [p.position_m for p in pts] == [2600.0, 2400.0, 2000.0, 1400.0, 400.0]


def test_interval_without_point_after_departure_counts_from_departure():
    pts = evaluation_points(_line(), "S1", "S2", after_departure_m=None, interval_m=1000)  # 2300 m
    assert _ids_s(pts) == [("dep", 0.0, "departure"), ("dep+1000", 1000.0, "interval"),
                           ("dep+2000", 2000.0, "interval")]


def test_interval_count_and_spacing_on_long_runs():
    """n = ceil((L - a) / I) - 1 points, every one I after the previous, none on or past the stop."""
    ln = testing.line(length_m=20000.0, stations=[0.0, 13700.0])
    for iv in (50.0, 200.0, 333.0, 1000.0, 6850.0):
        pts = [p for p in evaluation_points(ln, "S0", "S1", interval_m=iv) if p.kind == "interval"]
        s = [p.s_m for p in pts]
        assert len(s) == math.ceil((13700.0 - 200.0) / iv) - 1, iv
        assert s[0] == 200.0 + iv and max(s) < 13700.0
        assert np.allclose(np.diff(s), iv)
    # a point that would fall exactly on the arrival marker is not a point (13700 = 200 + 27 x 500)
    pts = evaluation_points(ln, "S0", "S1", interval_m=500.0)
    assert pts[-1].s_m == 13200.0


def test_interval_point_on_a_beacon_is_one_point():
    """B1 is 800 m after departure = 200 + 600: one decision there, listed once (the odometer point,
    which comes first in the precedence departure, after departure, interval, beacon)."""
    pts = evaluation_points(_line(), "S0", "S1", interval_m=600)
    assert [p.eval_point_id for p in pts] == ["dep", "dep+200", "dep+800", "dep+1400", "B2", "dep+2000"]


def test_no_interval_is_beacons_only():
    ln = _line()
    base = evaluation_points(ln, "S0", "S1")
    assert evaluation_points(ln, "S0", "S1", interval_m=None) == base
    assert evaluation_points(ln, "S0", "S1", interval_m=0) == base
    assert all(p.kind != "interval" for p in base)
    # an interval longer than the rest of the interstation adds nothing
    assert evaluation_points(ln, "S0", "S1", interval_m=5000) == base


@pytest.mark.parametrize("bad", [-500.0, 10.0, 49.9, float("nan"), float("inf")])
def test_bad_interval_is_refused(bad):
    with pytest.raises(InputError, match="at least 50 m"):
        evaluation_points(_line(), "S0", "S1", interval_m=bad)


def test_beacon_named_like_an_odometer_point_is_refused():
    ln = _line()
    ln = dataclasses.replace(ln, beacons=ln.beacons + (Beacon("dep+700", 1500.0, "down", "signal", "t9", True),))
    with pytest.raises(InputError, match="beacon_id 'dep\\+700'.*rename the beacon"):
        evaluation_points(ln, "S0", "S1", interval_m=500)
