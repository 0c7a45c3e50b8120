"""A train that crawls or stalls on a leg is never the end of the conflict check (one train is never the night).

The sample's down turnout limit at MNT (330-410 m, row 0, 45 km/h) lowered to a crawl: E6's run from MNT up
to SKM then starts its climb at a few km/h. Found on the 10x line (the same row of its fifth copy at 15 and
10 km/h): the check's 10 m step stalled at the grid's slow ratios and the whole night failed with a worker's
StallError, although the running-time tables (1 m step) had the leg with those ratios flagged.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from planner.api import running_time
from planner.network.arrivals import SimulatorCurves, interstation_keys
from planner.network.check import check_timetable


def _with_turnout(line, kmh: float):
    lim = list(line.speed_limits)
    assert (lim[0].start_m, lim[0].end_m, lim[0].direction) == (330.0, 410.0, "down")
    lim[0] = dataclasses.replace(lim[0], limit_ms=kmh / 3.6)
    return dataclasses.replace(line, speed_limits=tuple(lim))


def test_a_crawl_the_coarse_step_stalls_on_is_run_at_the_tables_step(sample_line):
    slow = _with_turnout(sample_line, 8.0)
    check = check_timetable(slow)
    assert len(check.trains) == len(sample_line.trains) and not check.unrouted
    # the curve at ratio 1.0 is the run the public API gives at its own (1 m) step, to the step's round-off
    x, T = SimulatorCurves(slow).table("E6", "MNT", "SKM")
    assert T[0, -1] == pytest.approx(running_time(slow, "E6", "MNT", "SKM", ratio=1.0).time_s, abs=0.5)


def test_a_leg_no_ratio_gets_over_flags_its_trains_and_checks_the_others_as_without_them(sample_line):
    stuck = _with_turnout(sample_line, 5.2)  # 0.2 km/h on board (the 5 km/h margin): E6 stalls at every ratio
    check = check_timetable(stuck)
    over = {t.train_id for t in sample_line.trains if ("E6", "MNT", "SKM") in interstation_keys([t])}
    assert set(check.unrouted) == over and len(over) == 42
    assert all("no run curve MNT->SKM for E6" in why and "stalls" in why for why in check.unrouted.values())
    others = dataclasses.replace(stuck, trains=tuple(t for t in stuck.trains if t.train_id not in over))
    ref = check_timetable(others)
    assert [t.train_id for t in check.trains] == [t.train_id for t in ref.trains]
    for f in dataclasses.fields(check.windows):
        assert np.array_equal(getattr(check.windows, f.name), getattr(ref.windows, f.name)), f.name
    # the train graph draws the others (it failed the night the same way)
    from planner.report.train_graph import train_paths

    drawn = {p.train_id for p in train_paths(stuck)}
    assert drawn == {t.train_id for t in sample_line.trains} - over
