"""Property tests for stopping patterns on random position-dependent limits (hypothesis).

Safety: every feasible pattern meets every limit on dense samples and ends at the
stop marker; infeasibility is confirmed by rigorous bounds that do not use the
solver: the hardest possible braking from the start (full jerk into the largest
deceleration the position allows) is a lower bound on the speed of *any*
admissible trajectory at every position, and the hardest braking run backwards
from the stop is an upper bound. If the lower bound is above a speed limit, or
above the upper bound, or has not reached zero at the stop marker, no pattern
exists.
"""
from __future__ import annotations

from bisect import bisect_right

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from planner.stopping.pattern import solve_stop

# Tolerances: limits are met with equality at touch points, so the dense-sample
# checks allow round-off only (patterns are exact cubics evaluated in float64).
TOL_V = 1e-7  # m/s
TOL_A = 1e-7  # m/s²
TOL_J = 1e-12  # m/s³ (jerk takes exactly the values -J, 0, +J)
END_X = 1e-3  # m, the "within 1 mm"
END_VA = 1e-9  # m/s, m/s² at the end point
BOUND_DT = 5e-3  # s, step of the bounding integrations (they stay rigorous whatever the step)
BOUND_MARGIN_V = 1e-6  # m/s


def step_value(steps, x):
    """Step function ``[(x_from, value), ...]`` evaluated at positions x (value from x_from on)."""
    xs = np.array([s[0] for s in steps])
    vals = np.array([s[1] for s in steps])
    return vals[np.searchsorted(xs, x, side="right") - 1]


def assert_meets_limits(p, J, decel_limits, speed_limits):
    s = p.sample(min(0.02, p.duration_s / 4000.0) if p.duration_s > 0 else 0.02)
    x, v, a, j = s.x_m, s.v_ms, s.a_ms2, s.j_ms3
    A = step_value(decel_limits, x)
    V = step_value(speed_limits, x)
    assert np.all(v <= V + TOL_V), f"speed over the limit by {np.max(v - V):.3g} m/s"
    assert np.all(-a <= A + TOL_A), f"deceleration over the limit by {np.max(-a - A):.3g} m/s²"
    assert np.all(np.abs(j) <= J + TOL_J)
    assert np.all(a <= TOL_A), "re-acceleration"
    assert np.all(v >= -TOL_V)
    assert np.all(np.diff(x) >= -1e-9), "position not monotone"
    assert abs(x[-1] - p.x_stop_m) <= END_X
    assert abs(v[-1]) <= END_VA and abs(a[-1]) <= END_VA
    assert x[0] == 0.0 and v[0] == pytest.approx(p.v_start_ms) and a[0] == 0.0
    # also at the breakpoints themselves (touch points sit there)
    bx = np.array(p.x_m)
    assert np.all(np.array(p.v_ms) <= step_value(speed_limits, bx) + TOL_V)
    assert np.all(-np.array(p.a_ms2) <= step_value(decel_limits, bx) + TOL_A)


def hardest_braking(v0, X, J, decel_limits, *, backward):
    """Rigorous speed bound from the hardest braking the limits allow, ignoring the other end.

    Forward (from the start, a(0)=0): any admissible trajectory has deceleration
    b(t) <= min(J t, A(x(t))), so at every position its speed is at least that of the
    trajectory braking with exactly that much (comparison in the position domain:
    where it is faster it is also earlier, hence allowed no more deceleration).
    Backward from the stop (a(T)=0) the same gives an upper bound on the speed.
    The step over-estimates the deceleration (jerk ramp at the step end, largest
    limit in the positions the step can reach) and under-advances position, which
    keeps both bounds on the safe side. Returns (x, v) samples of the bound.
    """
    xs_f = [s[0] for s in decel_limits]
    As = [s[1] for s in decel_limits]

    def A_max_between(p0, p1):
        lo, hi = min(p0, p1), max(p0, p1)
        i0 = max(bisect_right(xs_f, lo) - 1, 0)
        i1 = bisect_right(xs_f, hi) - 1
        return max(As[i0: i1 + 1])

    dt = BOUND_DT
    t = d = 0.0
    v = 0.0 if backward else v0
    out_d, out_v = [0.0], [v]
    v_cap = v0 * 1.01 + 1.0
    while d <= X and (v > 0.0 or backward) and (not backward or v <= v_cap) and t < 1e4:
        here = X - d if backward else d
        reach = here - v * dt * 1.01 - 1e-9 if backward else here + v * dt * 1.01 + 1e-9
        b = min(J * (t + dt), A_max_between(here, reach))
        if backward:
            d += v * dt  # speed at the step start: position under-advanced, speed over-estimated
            v += b * dt
        else:
            v = max(v - b * dt, 0.0)
            d += v * dt
        t += dt
        out_d.append(d)
        out_v.append(v)
    d = np.array(out_d)
    v = np.array(out_v)
    return (X - d, v) if backward else (d, v)


def certainly_infeasible(v0, X, J, decel_limits, speed_limits):
    """True when the bounds above prove that no admissible pattern exists."""
    if v0 > speed_limits[0][1]:
        return True
    xf, vlow = hardest_braking(v0, X, J, decel_limits, backward=False)
    if xf[-1] > X and vlow[-1] > BOUND_MARGIN_V:
        return True  # even the hardest braking has not stopped at the marker
    for xk, W in speed_limits:
        if 0.0 < xk < X:
            i = np.searchsorted(xf, xk)  # first bound sample at or after xk: speed there <= v(xk)
            if i < xf.size and vlow[i] > W + BOUND_MARGIN_V:
                return True
    xb, vup = hardest_braking(v0, X, J, decel_limits, backward=True)
    # the upper bound falls towards the stop, so at x it is at most its value at the nearest
    # sample at or before x (no interpolation, which could cut below it)
    order = np.argsort(xb)
    xb, vup = xb[order], vup[order]
    idx = np.searchsorted(xb, xf, side="right") - 1
    up = np.where(idx >= 0, vup[np.maximum(idx, 0)], np.inf)
    return bool(np.any(vlow > up + BOUND_MARGIN_V))


@st.composite
def approaches(draw):
    X = draw(st.floats(50.0, 1200.0))
    v0 = draw(st.floats(1.0, 35.0))
    J = draw(st.floats(0.2, 2.0))
    nd = draw(st.integers(1, 4))
    # breakpoints on a 1 mm grid: shifting floats 1e-16 apart (as one test does) would merge them
    xs = sorted({round(x, 3) for x in draw(st.lists(st.floats(1.0, X - 1.0), min_size=nd - 1, max_size=nd - 1))})
    dl = [(0.0, draw(st.floats(0.25, 1.5)))] + [(x, draw(st.floats(0.25, 1.5))) for x in xs]
    ns = draw(st.integers(1, 4))
    xs = sorted({round(x, 3) for x in draw(st.lists(st.floats(1.0, X - 1.0), min_size=ns - 1, max_size=ns - 1))})
    first = v0 * draw(st.floats(1.0, 1.3)) if draw(st.integers(0, 19)) else v0 * 0.95
    sl = [(0.0, first)] + [(x, draw(st.floats(1.0, 1.2 * v0))) for x in xs]
    return v0, X, J, dl, sl


STEP_DOWN_NEAR_THE_STOP = (5.0, 50.0, 1.0, [(0.0, 1.5)], [(0.0, 5.0), (1.0, 5.0), (46.0, 2.75)])
"""Found by this property on a fresh install (2026-12-05): the construction returned a "feasible" pattern whose
braking acceleration jumped from -0.49 to 0 m/s² and whose position ran back 0.25 m at 47.1 m."""


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(approaches())
@example(STEP_DOWN_NEAR_THE_STOP)
def test_feasible_patterns_meet_every_limit(case):
    v0, X, J, dl, sl = case
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assume(p.feasible)
    assert p.reason == ""
    assert_meets_limits(p, J, dl, sl)
    assert 0.0 <= p.brake_start_m <= X
    assert p.braking_distance_m == pytest.approx(X - p.brake_start_m, abs=1e-9)


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(approaches())
@example(case=(10.0, 50.0, 1.0, [(0.0, 1.0), (1.0, 1.0), (1.001, 1.0)], [(0.0, 10.0)]))
# drawn when another module's constants were in hypothesis's pool: the construction's figure, 677.4179 m,
# given back with 1 µm more was still infeasible by 0.02 µm (its round-off); the bound reported is not
@example(case=(5.0, 657.0, 0.25, [(0.0, 1.25)], [(0.0, 5.0), (1.0, 1.0)]))
def test_declared_infeasible_is_really_infeasible(case):
    """Every infeasible verdict is checked two ways: (1) the needed distance it reports is
    exact for the construction — prepend the missing metres to the approach (same limits)
    and the pattern fits, starting to brake at the very start; (2) the solver-free bounds
    prove it infeasible. (2) cannot prove every case: the bounds ignore the easing-off
    before a standstill and between restrictions, so cases short by less than that
    easing-off distance are only checked by (1)."""
    v0, X, J, dl, sl = case
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assume(not p.feasible)
    assert p.reason
    if v0 > sl[0][1]:
        assert "above the speed limit" in p.reason
        return
    lack = p.braking_distance_m - X
    assert lack > 0.0 and f"needs {p.braking_distance_m:.1f} m" in p.reason
    d = lack + 1e-6
    q = solve_stop(v0, X + d, jerk_max=J, decel_limits=[(0.0, dl[0][1])] + [(x + d, a) for x, a in dl[1:]],
                   speed_limits=[(0.0, sl[0][1])] + [(x + d, w) for x, w in sl[1:]])
    assert q.feasible and q.brake_start_m == pytest.approx(0.0, abs=1e-4)
    # easing off from the full deceleration takes at most A/J seconds at the start speed
    slack = max(a for _, a in dl) / J * v0
    if lack > slack:
        assert certainly_infeasible(v0, X, J, dl, sl)


def test_infeasible_verdicts_are_mostly_proved_by_the_bounds():
    """Deterministic census: of the infeasible verdicts on seeded random approaches, count
    those the solver-free bounds prove; the bounds are relaxations, so a handful near the
    threshold stay unproved, but none may be a *feasible* case: the converse is checked
    too — whenever the bounds prove infeasibility, the solver must not return a pattern."""
    rng = np.random.default_rng(7)
    n_inf = n_proved = 0
    for _ in range(250):
        X = rng.uniform(50, 1200)
        v0 = rng.uniform(1, 35)
        J = rng.uniform(0.2, 2.0)
        nd = rng.integers(1, 5)
        xs = np.sort(rng.uniform(1, X - 1, nd - 1))
        dl = [(0.0, rng.uniform(0.25, 1.5))] + [(float(x), rng.uniform(0.25, 1.5)) for x in xs]
        ns = rng.integers(1, 5)
        xs = np.sort(rng.uniform(1, X - 1, ns - 1))
        sl = [(0.0, v0 * rng.uniform(1.0, 1.3))] + [(float(x), rng.uniform(1.0, 1.2 * v0)) for x in xs]
        p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
        proved = certainly_infeasible(v0, X, J, dl, sl)
        if proved:
            assert not p.feasible, (v0, X, J, dl, sl)
        if not p.feasible:
            n_inf += 1
            n_proved += proved
    print(f"infeasible verdicts: {n_inf}, proved by the bounds: {n_proved}")
    assert n_inf >= 30 and n_proved >= 0.9 * n_inf


@settings(max_examples=150, deadline=None)
@given(approaches(), st.floats(0.5, 0.95))
# found by the search: the limit binds in neither (the jerk caps the braking at 0.707 m/s²), yet the
# entry into the 1 m/s restriction was chosen to 0.1 % of its range, 1.7e-5 s apart; now to round-off
@example(case=(2.0, 50.0, 0.5, [(0.0, 1.5)], [(0.0, 2.0), (5.0, 1.0)]), factor=0.5)
def test_less_deceleration_never_makes_it_faster(case, factor):
    """Scaling every deceleration limit down shrinks the admissible set, so the minimum
    time cannot fall and a feasible case can become infeasible, never the reverse."""
    v0, X, J, dl, sl = case
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    q = solve_stop(v0, X, jerk_max=J, decel_limits=[(x, a * factor) for x, a in dl], speed_limits=sl)
    if q.feasible:
        assert p.feasible
        assert q.duration_s >= p.duration_s - 1e-9


def test_a_halved_deceleration_limit_that_never_binds_changes_nothing():
    """Found by the property above with random examples: a step-down 3 m after the pattern start
    that cannot be met at a = 0 (jerk 0.25 m/s³) is entered still braking. A limit that does not bind
    (peak 0.49 m/s²) cannot change the minimum time; it did by 0.097 s while the entry deceleration was
    chosen to Brent's tolerance, and the optimum here is on the edge of the entries whose braking fits
    (the duration is not flat there), now found to round-off."""
    v0, X, J, sl = 1.5, 50.0, 0.25, [(0.0, 1.5), (3.0, 1.0)]
    p = solve_stop(v0, X, jerk_max=J, decel_limits=[(0.0, 1.0)], speed_limits=sl)
    q = solve_stop(v0, X, jerk_max=J, decel_limits=[(0.0, 0.5)], speed_limits=sl)
    assert p.feasible and q.feasible and max(abs(a) for a in q.a_ms2) < 0.5
    assert q.duration_s >= p.duration_s - 1e-9, (p.duration_s, q.duration_s)


def test_the_needed_distance_is_exact_when_a_step_down_starts_in_the_first_metre():
    """Found by test_declared_infeasible_is_really_infeasible: a step-down 1 m after the start
    (17 -> 16 m/s) that cannot be met at a = 0 was reported as needing 222.7 m, about 8 m too many
    (the missing metres put in front, the pattern started braking 8 m in): the step-down is met while
    still braking, an entry the construction had only with a cruise after it."""
    v0, X, J = 17.0, 177.0, 0.5
    sl = [(0.0, 17.0), (1.0, 16.0), (96.0, 11.0)]
    p = solve_stop(v0, X, jerk_max=J, decel_limits=[(0.0, 1.0)], speed_limits=sl)
    assert not p.feasible
    d = p.braking_distance_m - X + 1e-6
    q = solve_stop(v0, X + d, jerk_max=J, decel_limits=[(0.0, 1.0)],
                   speed_limits=[(0.0, 17.0)] + [(x + d, w) for x, w in sl[1:]])
    assert q.feasible and q.brake_start_m == pytest.approx(0.0, abs=1e-4), q.brake_start_m


def test_a_pattern_whose_pieces_do_not_join_is_refused_loudly():
    """The solver's own check: no pattern rather than a wrong one; the verdict says where and why, so the night
    flags the stop (no_stop) and no bundle carries the pattern."""
    v0, X, J, dl, sl = STEP_DOWN_NEAR_THE_STOP
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assert not p.feasible
    assert "pieces do not join at x=47.1 m" in p.reason


@pytest.mark.xfail(strict=True, reason="solver defect: at a speed step-down 4 m before a 50 m stop the construction "
                   "loses a node's continuity (caught and refused, see the test above); a valid pattern exists")
def test_the_step_down_near_the_stop_has_a_pattern():
    v0, X, J, dl, sl = STEP_DOWN_NEAR_THE_STOP
    # one that exists, slower than the minimum: brake at 1.5 m/s² from 5 m/s to 2.75 m/s before 46 m, then stop
    assert solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl).feasible
