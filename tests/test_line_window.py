"""Line.window and Line.station through the line's look-up index give what their rules say.

The rules, written out here on their own: a window holds every restriction that reaches into
``(lo, hi)`` (``end > lo`` and ``start < hi``, whole, in the line's order) and every beacon strictly
inside it; a station is found by its exact id, else by the one id that matches ignoring case.
"""
from __future__ import annotations

import pickle
from dataclasses import replace
from pathlib import Path

import pytest

import planner
from planner.errors import UnknownNameError
from planner.line.model import Beacon, SpeedLimit

SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"


@pytest.fixture(scope="module")
def sample():
    return planner.load_line(SAMPLE)


def _legs(line):
    for tt in line.train_types:
        for d in ("down", "up"):
            for a, b in line.interstations(d):
                yield tt.train_type, a.station_id, b.station_id


def test_every_window_of_the_sample_holds_what_reaches_into_it(sample):
    n = 0
    for tt, o, d in _legs(sample):
        lo, hi = sample.window_m(o, d, tt)
        w = sample.window(o, d, tt)
        assert w.speed_limits == tuple(s for s in sample.speed_limits if s.end_m > lo and s.start_m < hi)
        assert w.beacons == tuple(b for b in sample.beacons if lo < b.position_m < hi)
        n += 1
    assert n == 66


def test_restrictions_and_beacons_on_the_window_edges(sample):
    tt = sample.train_types[0].train_type
    a, b = sample.interstations("down")[2]
    lo, hi = sample.window_m(a.station_id, b.station_id, tt)
    lim = lambda s, e, row: SpeedLimit(s, e, 10.0, "both", None, "permanent", False, row)  # noqa: E731
    limits = (lim(lo - 50, lo, 900), lim(lo - 50, lo + 1e-9, 901), lim(hi, hi + 50, 902),
              lim(hi - 1e-9, hi + 50, 903), lim(lo - 10, hi + 10, 904))
    bea = lambda x, i: Beacon(f"X{i}", x, "down", "other", "", False)  # noqa: E731
    beacons = (bea(lo, 1), bea(hi, 2), bea(lo + 1e-9, 3), bea(hi - 1e-9, 4))
    line = replace(sample, speed_limits=sample.speed_limits + limits, beacons=sample.beacons + beacons)
    w = line.window(a.station_id, b.station_id, tt)
    assert [s.row for s in w.speed_limits if s.row >= 900] == [901, 903, 904]
    assert [x.beacon_id for x in w.beacons if x.beacon_id.startswith("X")] == ["X3", "X4"]
    # the line it was made from is unchanged, and so are its own windows (its index is its own)
    assert sample.window(a.station_id, b.station_id, tt).speed_limits == tuple(
        s for s in sample.speed_limits if s.end_m > lo and s.start_m < hi)


def test_station_look_up_exact_then_ignoring_case(sample):
    sid = sample.stations[3].station_id
    assert sample.station(sid) is sample.stations[3]
    assert sample.station(sid.lower()) is sample.stations[3]
    with pytest.raises(UnknownNameError, match="unknown station"):
        sample.station("NO-SUCH-STATION")


def test_a_line_pickles_without_its_index(sample):
    sample.window(*_first(sample))  # the index is made
    assert b"_Index" not in pickle.dumps(sample)


def _first(line):
    tt, o, d = next(_legs(line))
    return o, d, tt
