"""Evaluation points: departure, point after departure, flagged beacons between the stop markers."""
import dataclasses

import pytest

from planner import testing
from planner.errors import InputError
from planner.eval_points import evaluation_points, interstation_length_m
from planner.model import Beacon


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
