"""On-board maximum speed profile and braking curves (planner.physics.speed_profile)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from planner.physics import speed_profile
from planner.line import testing
from planner.errors import InfeasibleError
from planner.line.model import SpeedLimit
from planner.physics.track import make_track
from planner.line.units import KMH


def test_restriction_held_until_tail_clears_down_and_up():
    tt = testing.train_type(length_m=100.0)
    line = testing.line(length_m=4000, limits=[(1500, 1800, 40)], train_types=[tt])
    down = speed_profile.restriction_spans(line, tt, "down", 0.0)[0]
    assert (down.s_from_m, down.s_exit_m, down.s_to_m) == (1500, 1800, 1900)
    # up from chainage 4000: entered at 1800 (s = 2200), cleared when the front reaches 1400 (s = 2600)
    up = speed_profile.restriction_spans(line, tt, "up", 4000.0)[0]
    assert (up.s_from_m, up.s_exit_m, up.s_to_m) == (2200, 2500, 2600)


def test_onboard_max_profile_on_track():
    tt = testing.train_type(length_m=100.0, max_speed_kmh=90, speed_margin_kmh=5)
    line = testing.line(length_m=4000, max_speed_kmh=100, limits=[(1500, 1800, 40)], train_types=[tt])
    tr = make_track(line, "T", "S0", "S1")
    v = tr.vmax_ms / KMH

    def at(s):
        return v[np.argmin(np.abs(tr.s_m - s))]

    assert at(1000) == pytest.approx(85)  # vehicle maximum 90 − margin 5
    assert at(1500) == pytest.approx(35)  # the restriction applies at its start node
    assert at(1899) == pytest.approx(35)
    assert at(1900) == pytest.approx(35)  # node at the tail clearing: lower of both sides
    assert at(1901) == pytest.approx(85)
    assert at(1499) == pytest.approx(85)
    for s in (1500, 1800, 1900):
        assert np.any(np.abs(tr.s_m - s) < 1e-9)  # breakpoints are exact nodes


def test_restrictions_filtered_by_direction_and_type():
    tt = testing.train_type("A")
    line = testing.line(train_types=[tt, testing.train_type("B")])
    line = type(line)(**{**line.__dict__, "speed_limits": (
        SpeedLimit(500, 600, 30 * KMH, "down", None, "civil", True, 0),
        SpeedLimit(700, 800, 30 * KMH, "both", "B", "civil", True, 1),
        SpeedLimit(900, 1000, 30 * KMH, "up", None, "civil", True, 2),
    )})
    rows = [sp.row for sp in speed_profile.restriction_spans(line, tt, "down", 0.0)]
    assert rows == [0]
    rows = [sp.row for sp in speed_profile.restriction_spans(line, tt, "up", 3000.0)]
    assert rows == [2]


def test_margin_leaving_no_speed_is_infeasible():
    with pytest.raises(InfeasibleError, match="speed_margin_kmh"):
        speed_profile.onboard_max_ms(np.array([1.0]), [], 10 * KMH, 100 * KMH, 10 * KMH)


def _naive_ceiling(s, target, b):
    c2 = np.square(target).copy()
    for k in range(len(s) - 2, -1, -1):
        c2[k] = min(c2[k], c2[k + 1] + 2 * b * (s[k + 1] - s[k]))
    return c2


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.floats(0.1, 50), min_size=2, max_size=60),
    speeds=st.lists(st.floats(1, 40), min_size=61, max_size=61),
    b=st.floats(0.2, 1.5),
)
def test_braking_ceiling_equals_backward_recursion(steps, speeds, b):
    s = np.concatenate([[0.0], np.cumsum(steps)])
    target = np.asarray(speeds[: len(s)])
    got = speed_profile.braking_ceiling_sq(s, target, b)
    np.testing.assert_allclose(got, _naive_ceiling(s, target, b), rtol=1e-12, atol=1e-9)
    # 2-D, one row per ratio
    two = speed_profile.braking_ceiling_sq(s, np.stack([target, 0.5 * target]), b)
    np.testing.assert_allclose(two[1], _naive_ceiling(s, 0.5 * target, b), rtol=1e-12, atol=1e-9)


def test_braking_curve_closed_form():
    # 20 m/s until a drop to 10 m/s at 500 m, b = 1 m/s²: the curve starts (400 − 100)/2 = 150 m before
    s = np.linspace(0, 1000, 1001)
    target = np.where(s < 500, 20.0, 10.0)
    c2 = speed_profile.ceiling_sq(s, target, 1.0, 1000.0, 0.5)
    expect = np.minimum(np.where(s < 500, np.minimum(400.0, 100 + 2 * (500 - s)), 100.0), 2 * 0.5 * (1000 - s))
    np.testing.assert_allclose(c2, expect, rtol=1e-12, atol=1e-9)
    assert c2[-1] == 0.0


def test_node_values_take_lower_side():
    np.testing.assert_array_equal(speed_profile.node_values(np.array([3.0, 1.0, 2.0])), [3, 1, 1, 2])
