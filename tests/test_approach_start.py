"""Where a stopping pattern starts without a TASC beacon: from the physics, unless the job or the line sets it.

Closed form on the level, a train cruising at v with deceleration b and jerk J: a jerk-limited stop from
cruise takes ``d = v²/(2b) + v b/(2J)``; the start is ``d`` plus 10 % before the marker.
"""
from __future__ import annotations

from dataclasses import replace

import pandas as pd
import pytest

from linedb import default_tables, write_line_db
from planner import load_line
from planner.errors import InputError, LineValidationError
from planner.line import testing
from planner.line.units import KMH, KMH_S
from planner.stopping.approach import APPROACH_MARGIN, approach_start
from planner.stopping.sweep import adhesion_levels, approach_patterns

LEVELS_MS2 = [a * KMH_S for a in adhesion_levels("2.5:3.5:0.1")]


def _fast():
    """OSRD's fast test stock in round figures: 288 km/h, brake 0.5 m/s², jerk 0.5 m/s³ (the importer's default)."""
    return testing.train_type("FAST", max_speed_kmh=288.0, empty_mass_t=400.0, full_load_mass_t=0.0,
                              max_accel_kmh_s=1.8, service_brake_kmh_s=1.8, stop_brake_kmh_s=1.8,
                              brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8,
                              traction=((0.0, 1000.0), (300.0, 1000.0)))


def _long_line(**kw):
    return testing.line(length_m=40_000.0, stations=[0.0, 39_000.0], max_speed_kmh=300.0,
                        train_types=[_fast()], **kw)


def test_the_start_is_the_jerk_limited_braking_distance_plus_ten_percent():
    v, b, J = 288.0 * KMH, 0.5, 0.5
    d = v * v / (2 * b) + v * b / (2 * J)  # 6400 + 40 = 6440 m
    line = _long_line()
    st = approach_start(line, "S0", "S1", "auto", train_type="FAST", adhesion_ms2=LEVELS_MS2[0])
    assert st.source == "physics" and st.beacon_id == ""
    assert 39_000.0 - st.s_m == pytest.approx((1 + APPROACH_MARGIN) * d, abs=1.2)  # one grid step, × 1.1


def test_a_fast_train_braking_half_a_metre_gets_a_feasible_pattern_at_every_level():
    # before: a fixed 550 m start; "needs 1105.9 m … only 550 m available", every level infeasible
    r = approach_patterns(_long_line(), "FAST", "S0", "S1", LEVELS_MS2)
    assert r.adhesion_ms2 == (0.5,)  # 1.8 km/h/s: every level of 2.5 … 3.5 is above the train's brake
    assert all(p.feasible for p in r.patterns), [p.reason for p in r.patterns]
    assert r.v_start_ms == pytest.approx(80.0, abs=1e-6)
    assert r.approach_length_m > r.patterns[0].braking_distance_m > 6440.0 - 1e-6


def test_a_falling_approach_needs_a_longer_one():
    # -5 ‰ over the last 12 km takes g·0.005 = 0.049 m/s² from the brake: d = v²/(2 (0.5 − 0.049)) + …
    flat = approach_start(_long_line(), "S0", "S1", train_type="FAST")
    fall = approach_start(_long_line(gradients=[(27_000.0, 40_000.0, -5.0)]), "S0", "S1", train_type="FAST")
    b = 0.5 - 9.80665 * 0.005
    d = (80.0 ** 2) / (2 * b) + 80.0 * b / (2 * 0.5)
    assert 39_000.0 - fall.s_m == pytest.approx((1 + APPROACH_MARGIN) * d, abs=1.2)
    assert fall.s_m < flat.s_m


def test_a_slow_train_on_a_short_run_starts_where_it_can():
    # a 36 km/h train: d = 10²/(2 · 0.5) + 10 · 0.5 / (2 · 0.5) = 105 m; the start is 115.5 m before the marker
    tt = replace(_fast(), max_speed_ms=36.0 * KMH)
    line = testing.line(length_m=2000.0, stations=[0.0, 1500.0], max_speed_kmh=300.0, train_types=[tt])
    st = approach_start(line, "S0", "S1", train_type="FAST")
    assert 1500.0 - st.s_m == pytest.approx(1.1 * 105.0, abs=1.2)


def test_a_job_or_a_line_that_sets_approach_m_keeps_it(tmp_path):
    line = _long_line()
    assert approach_start(line, "S0", "S1", 1200.0) == approach_start(line, "S0", "S1", 1200.0, train_type="FAST")
    assert approach_start(line, "S0", "S1", 1200.0).s_m == 39_000.0 - 1200.0
    assert approach_start(line, "S0", "S1", 1200.0).source == "approach"
    own = replace(line, approach_m=800.0)
    assert approach_start(own, "S0", "S1", "auto", train_type="FAST").s_m == 39_000.0 - 800.0
    assert approach_start(own, "S0", "S1", 1200.0).s_m == 39_000.0 - 1200.0  # the job's number wins
    with pytest.raises(InputError, match="auto"):
        approach_start(line, "S0", "S1", -5.0)


def test_the_line_column_is_optional_and_checked(tmp_path):
    t = default_tables("a")
    t["line"]["approach_m"] = [700.0]
    assert load_line(write_line_db(tmp_path / "a", **t)).approach_m == 700.0
    assert load_line(write_line_db(tmp_path / "b", **default_tables("b"))).approach_m is None
    t = default_tables("c")
    t["line"]["approach_m"] = pd.array([None], dtype="Float64")
    assert load_line(write_line_db(tmp_path / "c", **t)).approach_m is None
    t = default_tables("d")
    t["line"]["approach_m"] = [-1.0]
    with pytest.raises(LineValidationError, match="approach_m"):
        load_line(write_line_db(tmp_path / "d", **t))


def test_the_start_is_never_inside_the_runs_braking_for_a_lower_limit():
    """A 160 km/h limit over the last 2 km: going back from the marker, a stop from 160 km/h fits at
    d = 44.4²/(2 · 0.5) + 44.4 · 0.5/(2 · 0.5) = 1997.5 m, and 10 % more put the start 200 m into the run's
    braking from 288 km/h onto the limit, where the run (on its braking curve, no jerk ramp) is faster than any
    pattern can follow: "needs 2221.1 m to stop from 167.8 km/h, only 2197.8 m available", though the brake makes
    the stop. The start is where that braking ends, at the limit; every level has its pattern."""
    v = 160.0 * KMH
    d = v * v / (2 * 0.5) + v * 0.5 / (2 * 0.5)
    assert 1997.0 < d < 1998.0
    line = _long_line(limits=[(37_000.0, 40_000.0, 160.0)])
    st = approach_start(line, "S0", "S1", "auto", train_type="FAST", adhesion_ms2=LEVELS_MS2[0])
    assert 39_000.0 - st.s_m == pytest.approx(2000.0, abs=1.2)  # the limit's start, one grid step
    r = approach_patterns(line, "FAST", "S0", "S1", LEVELS_MS2)
    assert r.v_start_ms == pytest.approx(v, abs=1e-6)
    assert all(p.feasible for p in r.patterns), [p.reason for p in r.patterns]
    assert r.approach_length_m >= r.patterns[0].braking_distance_m > d - 1e-6
