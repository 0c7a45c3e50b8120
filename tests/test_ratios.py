"""Ratio grid: default shape, floor handling, spec strings, bad input."""
import numpy as np
import pytest
from hypothesis import given, strategies as st

from planner.errors import InputError
from planner.tables.ratios import DEFAULT_SPEC, FLOOR_MERGE, floor_ratio, ratio_grid

KMH = 1 / 3.6


def test_default_grid_100kmh_line_reaches_floor_on_grid():
    # 20 km/h / 100 km/h = 0.2 lies on the 5 % grid: no extra entry
    g = ratio_grid(line_max_speed_ms=100 * KMH)
    expected = [1.0, 0.9, 0.8, 0.7] + [round(0.65 - 0.05 * i, 2) for i in range(10)]
    np.testing.assert_allclose(g, expected, atol=1e-12)
    assert expected[-1] == 0.2


def test_default_grid_includes_off_grid_floor():
    # 20/120 = 1/6 is not on the 5 % grid: it is appended after 0.2
    g = ratio_grid(line_max_speed_ms=120 * KMH)
    assert g[-2] == pytest.approx(0.2)
    assert g[-1] == pytest.approx(1 / 6, abs=1e-6)
    assert g[-1] * 120 == pytest.approx(20, abs=1e-3)


def test_floor_merged_with_a_grid_ratio_just_above():
    # 20/80.1 = 0.24969: 0.25 lies within FLOOR_MERGE above it and stands for it
    g = ratio_grid(line_max_speed_ms=80.1 * KMH)
    assert g[-1] == pytest.approx(0.25)
    assert 0.25 - floor_ratio(80.1 * KMH) < FLOOR_MERGE


def test_explicit_list_and_spec():
    g = ratio_grid([0.5, 1.0, 0.75, 0.75], line_max_speed_ms=100 * KMH)
    assert g.tolist() == [1.0, 0.75, 0.5]
    g = ratio_grid("1.0:0.5:0.25,0.3", line_max_speed_ms=100 * KMH)
    assert g.tolist() == [1.0, 0.75, 0.5, 0.3]
    # the stop of a piece is included even when the step does not land on it
    assert ratio_grid("1:0.45:0.2", line_max_speed_ms=100 * KMH).tolist() == [1.0, 0.8, 0.6, 0.45]


def test_below_floor_dropped():
    assert ratio_grid("1,0.5,0.1", line_max_speed_ms=100 * KMH).tolist() == [1.0, 0.5]


@pytest.mark.parametrize("spec", ["", "1.0:0.7", "a:b:c", "0.7:1.0:0.1", "1:0.5:0", "1.2", "0.1"])
def test_bad_spec(spec):
    with pytest.raises(InputError):
        ratio_grid(spec, line_max_speed_ms=100 * KMH)


@given(vmax_kmh=st.floats(25, 360), min_kmh=st.floats(5, 40))
def test_grid_properties(vmax_kmh, min_kmh):
    g = ratio_grid(DEFAULT_SPEC, line_max_speed_ms=vmax_kmh * KMH, min_target_speed_ms=min_kmh * KMH)
    floor = floor_ratio(vmax_kmh * KMH, min_kmh * KMH)
    assert g[0] == 1.0
    assert np.all(np.diff(g) < 0)
    assert g[-1] >= floor - 1e-6  # never below the minimum target speed
    assert g[-1] - floor < 0.05  # reaches the floor to within one 5 % step
    steps = -np.diff(g)
    assert np.all(steps <= 0.1 + 1e-9)
    assert np.all(steps[g[1:] < 0.7 - 1e-9] <= 0.05 + 1e-9)
