"""Closed-form and property tests of the time-keeping target speed (docs/design.md §4)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from planner.tables.cruise import braking_pattern_speed, cruise_speed, cruise_speed_limited, profile_time

# Exact arithmetic up to rounding: the closed forms involve one sqrt each.
REL = 1e-9
# The limit-aware solver works on a grid where u² is linear between nodes;
# for constant limits and constant-β braking that is exact, so only the
# root-finding tolerance (1e-10 m/s) and rounding remain.
SOLVER_TOL_MS = 1e-8


def test_cruise_speed_by_hand():
    # t_d = 100 s, x_d = 2000 m, β = 1 m/s²:
    #   v²/2 − 100 v + 2000 = 0  →  v = 100 − sqrt(100² − 4000) = 100 − sqrt(6000)
    v = cruise_speed(100.0, 2000.0, 1.0)
    assert v.shortfall_s == 0.0
    assert v.speed_ms == pytest.approx(100.0 - math.sqrt(6000.0), rel=REL)
    assert v.speed_ms == pytest.approx(22.540333075851663, rel=REL)
    assert v.feasible


def test_cruise_speed_arrives_on_time():
    # Cruise at v, then brake at β onto the marker: time = (x − v²/2β)/v + v/β.
    t_d, x_d, beta = 100.0, 2000.0, 1.0
    v = cruise_speed(t_d, x_d, beta).speed_ms
    assert (x_d - v * v / (2 * beta)) / v + v / beta == pytest.approx(t_d, rel=REL)


def test_cruise_speed_too_little_time_reports_shortfall():
    # Fastest possible from standing on the pattern: sqrt(2 x/β) = sqrt(4000) = 63.2456 s.
    v = cruise_speed(50.0, 2000.0, 1.0)
    assert not v.feasible
    assert v.shortfall_s == pytest.approx(math.sqrt(4000.0) - 50.0, rel=REL)
    assert v.speed_ms == pytest.approx(math.sqrt(2000.0 * 2.0), rel=REL)


def test_cruise_speed_boundary_and_edges():
    # Exactly the minimum time: the double root v = β t_d, on the pattern.
    t = math.sqrt(4000.0)
    v = cruise_speed(t, 2000.0, 1.0)
    assert v.shortfall_s == 0.0 and v.speed_ms == pytest.approx(t, rel=1e-7)
    # At the marker: nothing to run.
    assert cruise_speed(10.0, 0.0, 1.0)[:2] == (0.0, 0.0)
    # No time left but distance left: all of the minimum time is shortfall.
    assert cruise_speed(0.0, 200.0, 1.0).shortfall_s == pytest.approx(20.0, rel=REL)


def test_cruise_speed_broadcasts():
    r = cruise_speed(np.array([100.0, 50.0]), 2000.0, 1.0)
    assert r.speed_ms.shape == (2,)
    np.testing.assert_allclose(r.shortfall_s, [0.0, math.sqrt(4000.0) - 50.0], rtol=REL)


def test_cruise_speed_no_cancellation_for_long_times():
    # t_d² ≫ 2x/β: naive β(t − sqrt(t² − 2x/β)) loses all digits; v → x/t.
    v = cruise_speed(1e8, 1.0, 1.0).speed_ms
    assert v == pytest.approx(1e-8, rel=1e-9)


@given(t=st.floats(1.0, 1e4), x=st.floats(0.1, 1e5), beta=st.floats(0.1, 2.0))
def test_cruise_speed_satisfies_the_quadratic(t, x, beta):
    r = cruise_speed(t, x, beta)
    if t * t >= 2 * x / beta:
        v = r.speed_ms
        assert r.shortfall_s == 0.0
        # x − v²/2β = v (t − v/β), and the cruise part is non-negative.
        assert x - v * v / (2 * beta) == pytest.approx(v * (t - v / beta), rel=1e-7, abs=1e-7 * x)
        assert v <= braking_pattern_speed(x, beta) * (1 + 1e-9)
    else:
        assert r.shortfall_s == pytest.approx(math.sqrt(2 * x / beta) - t, rel=1e-9)


def test_braking_pattern_speed():
    assert braking_pattern_speed(200.0, 1.0) == pytest.approx(20.0, rel=REL)
    assert braking_pattern_speed(-5.0, 1.0) == 0.0


# --- limit-aware version ----------------------------------------------------
def test_profile_time_closed_forms():
    s = np.linspace(0.0, 1000.0, 1001)
    assert profile_time(s, np.full_like(s, 20.0)) == pytest.approx(50.0, rel=REL)
    # Constant-deceleration stop from the pattern: sqrt(2 L / β).
    u = braking_pattern_speed(1000.0 - s, 1.0)
    assert profile_time(s, u) == pytest.approx(math.sqrt(2000.0), rel=REL)
    assert profile_time(s, u, 20.0) == pytest.approx((1000.0 - 200.0) / 20.0 + 20.0, rel=REL)


@pytest.mark.parametrize("grid", ["uniform", "irregular"])
def test_limited_equals_closed_form_when_limit_is_high(grid):
    if grid == "uniform":
        s = np.linspace(0.0, 2000.0, 2001)
    else:
        rng = np.random.default_rng(1)
        s = np.sort(np.concatenate([[0.0, 2000.0], rng.uniform(0.0, 2000.0, 700)]))
    r = cruise_speed_limited(100.0, s, np.full_like(s, 50.0), 1.0)
    assert r.shortfall_s == 0.0
    assert r.speed_ms == pytest.approx(100.0 - math.sqrt(6000.0), abs=SOLVER_TOL_MS)


def test_limited_shortfall_by_hand():
    # Limit 20 m/s everywhere, L = 2000 m, β = 1: fastest = (2000 − 200)/20 + 20 = 110 s.
    s = np.linspace(0.0, 2000.0, 2001)
    r = cruise_speed_limited(50.0, s, np.full_like(s, 20.0), 1.0)
    assert r.shortfall_s == pytest.approx(60.0, rel=REL)
    assert r.speed_ms == pytest.approx(20.0)
    # No limit: fastest is the pattern from standing, sqrt(4000); as the closed form.
    r = cruise_speed_limited(50.0, s, np.full_like(s, 80.0), 1.0)
    assert r.shortfall_s == pytest.approx(cruise_speed(50.0, 2000.0, 1.0).shortfall_s, rel=1e-9)


def test_limited_restriction_below_cruise_by_hand():
    # 10 m/s over [500, 1000] m, 2000 m to the marker, β = 1. For a cruise v > 10:
    #   T(v) = 500/v + 500/10 + (1000 − v²/2)/v + v = 50 + 1500/v + v/2.
    # v = 20 gives 135 s. Restriction edges are given as nodes 1e-6 m apart so
    # the linear-in-v² step between nodes is negligible (< 1e-7 s).
    eps = 1e-6
    s = np.unique(np.concatenate([np.linspace(0.0, 2000.0, 201), [500 - eps, 1000 + eps]]))
    vmax = np.where((s >= 500.0) & (s <= 1000.0), 10.0, 40.0)
    r = cruise_speed_limited(135.0, s, vmax, 1.0)
    assert r.shortfall_s == 0.0
    assert r.speed_ms == pytest.approx(20.0, abs=1e-5)
    # Too little time: fastest is v = 40 up to the pattern: 50 + 1500/40 + 20 = 107.5 s.
    r = cruise_speed_limited(100.0, s, vmax, 1.0)
    assert r.shortfall_s == pytest.approx(7.5, abs=1e-5)


def _dense_time(s, vmax, v, beta, tail_m=0.5):
    """Independent reference: midpoint rule on 1/u, 400 points per interval.

    The last ``tail_m`` metres are on the stopping pattern (1/u is singular at
    the marker), so they are added in closed form, sqrt(2 tail/β).
    """
    L = s[-1]
    total = 0.0
    for a, b0, ua, ub in zip(s[:-1], s[1:], vmax[:-1], vmax[1:]):
        b = min(b0, L - tail_m)
        if b <= a:
            break
        k = 400
        x = a + (np.arange(k) + 0.5) * (b - a) / k
        lim2 = ua * ua + (ub * ub - ua * ua) * (x - a) / (b0 - a)
        u = np.minimum(v, np.sqrt(np.minimum(lim2, 2 * beta * (L - x))))
        total += float(np.sum((b - a) / k / u))
    return total + math.sqrt(2 * tail_m / beta)


@settings(max_examples=40, deadline=None)
@given(
    limits=st.lists(st.floats(5.0, 40.0), min_size=2, max_size=8),
    extra_s=st.floats(0.0, 200.0),
    beta=st.floats(0.3, 1.2),
)
def test_limited_target_takes_exactly_t_d(limits, extra_s, beta):
    # Random step profile on a coarse grid; pick a feasible t_d and check that
    # running at min(v, vmax, pattern) takes t_d by an independent quadrature.
    s = np.linspace(0.0, 800.0, 9 * len(limits))
    vmax = np.asarray(limits)[np.minimum((s / 800.0 * len(limits)).astype(int), len(limits) - 1)]
    t_d = _dense_time(s, vmax, np.inf, beta) + extra_s + 1.0
    r = cruise_speed_limited(t_d, s, vmax, beta)
    assert r.shortfall_s == 0.0
    assert _dense_time(s, vmax, r.speed_ms, beta) == pytest.approx(t_d, rel=1e-4)
    # and monotone: a little faster is quicker, a little slower is slower
    assert _dense_time(s, vmax, r.speed_ms * 1.01, beta) < t_d < _dense_time(s, vmax, r.speed_ms * 0.99, beta)


def test_limited_rejects_bad_grid():
    with pytest.raises(ValueError):
        cruise_speed_limited(10.0, [0.0, 1.0, 1.0], [1.0, 1.0, 1.0], 1.0)
