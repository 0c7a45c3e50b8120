"""Five train types from public parameters (tests/public_trains.py) on a long, steep, beacon-less line of ours.

What the braking defaults of a commuter EMU used to decide, the train's own physics decides now: every
stopping pattern is feasible from the start the physics gives, the bad day is never faster than nominal,
and a timetable at the minimum + 8 % is flagged only where the bad day's load and traction cost more
than 8 % on the climbs (a physical verdict), never because of a stop.
"""
from __future__ import annotations

import pytest

from public_trains import public_trains, steep_line
from planner.line.units import KMH_S
from planner.report.leg_margin import leg_result
from planner.stopping.sweep import adhesion_levels, approach_patterns

LEVELS_MS2 = [a * KMH_S for a in adhesion_levels("2.5:3.5:0.1")]
LEGS = [("S0", "S1"), ("S1", "S2"), ("S2", "S1"), ("S1", "S0")]
NO_LOAD_CHANGE = {"OSRD_FAST", "OSRD_FAST_095", "TR_IC"}  # no passenger load: the bad day is traction × 0.9 only


@pytest.fixture(scope="module")
def line():
    return steep_line()


@pytest.mark.parametrize("tt", [t.train_type for t in public_trains()])
def test_every_stop_is_feasible_and_the_bad_day_never_faster(line, tt):
    for o, d in LEGS:
        ap = approach_patterns(line, tt, o, d, LEVELS_MS2)
        assert ap.tasc_beacon_id == "" and ap.n_feasible == len(ap.patterns), (o, d, ap.warnings)
        r = leg_result(line, tt, o, d, [])
        assert r.pattern_source == "physics" and r.note == "", (o, d, r.note)  # the start was never moved back
        assert r.pattern_start_m == pytest.approx(ap.approach_start_m)
        assert r.degraded_min_s >= r.min_time_s, (o, d)
        assert r.degraded_loss_stop_s >= 0.0 and r.degraded_loss_stop_model_s >= 0.0, (o, d)
        # min + 8 %: a stop never eats the 8 %; trains without a load change keep it on every leg
        assert r.degraded_loss_stop_s + r.degraded_loss_stop_model_s < 0.08 * r.min_time_s, (o, d)
        if tt in NO_LOAD_CHANGE:
            assert 1.08 * r.min_time_s >= r.degraded_min_s, (o, d)
