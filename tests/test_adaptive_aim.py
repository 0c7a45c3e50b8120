"""The adaptive mode aims early before the last evaluation point (issue 22).

Near the stop a train can lose time (a lower ratio) but seldom gain any, so an
error of the tables before the last point is final when it makes the train late.
For a sawtooth vehicle such errors exceed a second: the remaining time from a
point is not continuous in the ratio chosen there. On the sample line, E6
KWB->HGO, ratio steps of 2.5 %, beacons only, designated 209 s, the adaptive
mode aiming on time arrived 1.27 s late (the issue asks for at most 1 s).
"""
from __future__ import annotations

import numpy as np
import pytest

from planner.physics.run_curve import RunState, simulate
from planner.physics.track import SimSettings, make_track
from planner.report.eval_study import GRIDS


@pytest.fixture(scope="module")
def kwb_hgo(sample_line):
    from planner.tables.build import interstation_tables
    from planner.tables.ratios import ratio_grid

    line = sample_line
    grid = ratio_grid(GRIDS["2.5 %"], line_max_speed_ms=line.max_speed_ms)
    tabs = interstation_tables(line, "E6", "KWB", "HGO", grid, eval_interval_m=None).onboard()
    return line, tabs


def test_the_remaining_time_jumps_where_the_tables_interpolate(kwb_hgo):
    """The case itself, from the simulator alone: the train runs ratio 0.6937 from departure and
    0.6875 from D-SIG-008 (what the mode chose when it aimed on time), then constant ratios from
    D-SIG-009, 1,213 m before the stop. Between ratios 0.684 and 0.6865 the remaining time drops
    by more than 2 s (the coasting train starts to meet its band's lower edge and powers again),
    so no ratio arrives within 1 s of a wanted time in the middle of that gap, whatever a table
    says (the tables said 79.2 s at 0.6841, and the run arrived 1.27 s late)."""
    line, tabs = kwb_hgo
    train = line.train_type("E6")
    pts = list(tabs.eval_distance_m)
    k8, k9 = tabs.eval_point_ids.index("D-SIG-008"), tabs.eval_point_ids.index("D-SIG-009")
    assert k9 == len(pts) - 2 and pts[-1] - pts[k9] == pytest.approx(1213.0 - 325.0, abs=1.0)
    track = make_track(line, "E6", "KWB", "HGO", settings=SimSettings(), nodes_m=pts)
    res = simulate(track, train, np.array([0.6937]), changes=[(pts[k8], np.array([0.6875]))],
                   snapshots_m=[pts[k9]])
    snap = res.snapshots[pts[k9]]
    ratios = np.array([0.684, 0.6865])
    start = RunState(s_m=np.full(2, pts[k9]), t_s=np.zeros(2), v_ms=np.repeat(snap.v_ms, 2),
                     phase=np.repeat(snap.phase, 2), ratio=np.repeat(snap.ratio, 2),
                     w_ms2=np.repeat(snap.w_ms2, 2), coasting=np.repeat(snap.coasting, 2))
    slow, fast = simulate(track, train, ratios, start=start).time_s
    assert slow - fast > 2.0, (slow, fast)


def test_adaptive_arrives_within_a_second_on_the_case_that_was_late(kwb_hgo):
    """Closed loop over the whole sweep of designated times (minimum … minimum + 60 s), nominal
    train: every run within the issue's 1 s (the 209 s run was 1.27 s late aiming on time)."""
    from planner.tables.closed_loop import closed_loop_interstation

    line, tabs = kwb_hgo
    r = closed_loop_interstation(line, "E6", tabs, scenario="nominal", mode="adaptive")
    ok = r.feasible
    assert ok.sum() > 50 and 209.0 in r.designated_s[ok]
    err = r.error_s[ok]
    assert np.abs(err).max() <= 1.0, (r.designated_s[ok][np.argmax(np.abs(err))], np.abs(err).max())
