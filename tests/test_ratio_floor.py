"""The ratio grid's floor per train and leg: ratio × the train's highest on-board maximum on the leg = 20 km/h.

Before, the floor came from the line maximum: a 36 km/h train on a 120 km/h line got a slowest column
of 20/120 × 36 = 6 km/h targets (2.4 km/h after the margin); 16 km took 24,040 s.
"""
from __future__ import annotations

import pytest

from planner.line import testing
from planner.line.units import KMH
from planner.tables.build import interstation_tables
from planner.tables.ratios import leg_max_speed_ms, leg_ratio_grid


def test_a_36_kmh_train_is_never_tabled_below_20_kmh():
    slow = testing.train_type("SLOW", max_speed_kmh=36.0)
    line = testing.line(length_m=16_500.0, stations=[0.0, 16_000.0], max_speed_kmh=120.0, train_types=[slow])
    grid = leg_ratio_grid(None, line, "SLOW", "S0", "S1")
    assert grid[-1] == pytest.approx(20.0 / 36.0, abs=1e-6)
    it = interstation_tables(line, "SLOW", "S0", "S1", grid)
    slowest = float(it.time_a_s[-1])
    # at 20 km/h (5.556 m/s) nearly all the way: 2880 s, plus seconds of accelerating and braking at 1 m/s²
    assert 16_000.0 / (20.0 * KMH) < slowest < 16_000.0 / (20.0 * KMH) + 10.0


def test_the_floor_follows_the_leg_restrictions_and_the_speed_margin():
    tt = testing.train_type("T", max_speed_kmh=110.0, speed_margin_kmh=3.0)
    line = testing.line(length_m=6000.0, stations=[0.0, 2000.0, 5000.0], max_speed_kmh=120.0, train_types=[tt],
                        limits=[(2000.0, 6000.0, 60.0)])
    assert leg_max_speed_ms(line, "T", "S0", "S1") == pytest.approx(107.0 * KMH)   # min(120, 110) − 3
    assert leg_ratio_grid(None, line, "T", "S0", "S1")[-1] == pytest.approx(20.0 / 107.0, abs=1e-6)
    assert leg_max_speed_ms(line, "T", "S1", "S2") == pytest.approx(57.0 * KMH)    # the 60 km/h restriction − 3
    assert leg_ratio_grid(None, line, "T", "S1", "S2")[-1] == pytest.approx(20.0 / 57.0, abs=1e-6)
    assert leg_ratio_grid(None, line, "T", "S1", "S2", 40.0 * KMH)[-1] == pytest.approx(40.0 / 57.0, abs=1e-6)
