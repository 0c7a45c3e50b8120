"""Stopping patterns: closed forms, Ruckig exactness, input checks, the deceleration rule."""
from __future__ import annotations

import math
import random

import numpy as np
import pytest

from planner.errors import InfeasibleError, InputError
from planner.stopping.pattern import StopPattern, decel_limit_profile, solve_stop

# Tolerances. The solver is exact (closed-form pieces, roots solved to machine
# precision), so its own checks use round-off sized tolerances; the 1e-3 s
# against Ruckig is the acceptance figure (we see ~1e-13 s).
RUCKIG_TOL_S = 1e-3
ROUNDOFF_S = 1e-9
ROUNDOFF_M = 1e-7


def stop_distance(v, A, J):
    """Shortest stop from cruise at v (a = 0) to v = 0, a = 0 under |a| <= A, |j| <= J [m].

    Trapezoidal deceleration (ramp A/J, hold, ramp) when v >= A²/J, else triangular;
    the deceleration profile is symmetric so the distance is v · T / 2.
    """
    if v >= A * A / J:
        return v * (v / A + A / J) / 2.0
    return v * math.sqrt(v / J)


def stop_time(v, A, J):
    """Duration of that shortest stop [s]."""
    return v / A + A / J if v >= A * A / J else 2.0 * math.sqrt(v / J)


def solve1(v0, X, J, A, V=None):
    return solve_stop(v0, X, jerk_max=J, decel_limits=[(0.0, A)], speed_limits=[(0.0, V if V else v0)])


# --------------------------------------------------------------------------------------
# closed forms
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "v0, A, J",
    [(20.0, 1.0, 0.8), (25.0, 0.9, 0.5), (2.0, 1.0, 0.8), (0.5, 1.2, 2.0), (1.25, 1.0, 0.8)],  # last: v = A²/J
)
def test_closed_form_cruise_then_brake(v0, A, J):
    d = stop_distance(v0, A, J)
    X = d + 123.0
    p = solve1(v0, X, J, A)
    assert p.feasible and p.reason == ""
    assert p.brake_start_m == pytest.approx(123.0, abs=ROUNDOFF_M)
    assert p.braking_distance_m == pytest.approx(d, abs=ROUNDOFF_M)
    assert p.duration_s == pytest.approx(123.0 / v0 + stop_time(v0, A, J), abs=ROUNDOFF_S)
    # structure: cruise, -J, (hold), +J
    assert p.j_ms3[0] == 0.0 and p.j_ms3[1] == -J and p.j_ms3[-1] == J
    assert min(p.a_ms2) == pytest.approx(-min(A, math.sqrt(v0 * J)), rel=1e-12)


def test_no_cruise_when_exactly_the_stopping_distance():
    v0, A, J = 18.0, 0.8, 0.6
    p = solve1(v0, stop_distance(v0, A, J), J, A)
    assert p.feasible
    assert p.brake_start_m == pytest.approx(0.0, abs=ROUNDOFF_M)
    assert p.j_ms3[0] == -J  # braking from the first instant


def test_start_below_the_limit_cruises_at_start_speed():
    # v_start below the line limit: no re-acceleration, so the same as a limit equal to v_start
    a = solve_stop(15.0, 400.0, jerk_max=0.7, decel_limits=[(0.0, 0.9)], speed_limits=[(0.0, 30.0)])
    b = solve1(15.0, 400.0, 0.7, 0.9)
    assert a.duration_s == pytest.approx(b.duration_s, abs=ROUNDOFF_S)
    assert max(a.v_ms) == pytest.approx(15.0)


def test_standing_start():
    p = solve1(0.0, 0.0, 0.5, 1.0, V=10.0)
    assert p.feasible and p.duration_s == 0.0
    s = p.sample(0.1)
    assert s.t_s.tolist() == [0.0] and s.v_ms.tolist() == [0.0]
    q = solve1(0.0, 10.0, 0.5, 1.0, V=10.0)
    assert not q.feasible and "re-acceleration" in q.reason


# --------------------------------------------------------------------------------------
# exactness against Ruckig (position-independent limits)
# --------------------------------------------------------------------------------------


def ruckig_duration(v0, X, V, A, J):
    """Ruckig's time-optimal duration (offline ``calculate``), 1 DoF, rest-to-rest in acceleration."""
    ruckig = pytest.importorskip("ruckig")
    otg = ruckig.Ruckig(1)
    inp = ruckig.InputParameter(1)
    inp.current_position = [0.0]
    inp.current_velocity = [v0]
    inp.current_acceleration = [0.0]
    inp.target_position = [X]
    inp.target_velocity = [0.0]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [V]
    inp.max_acceleration = [A]
    inp.min_acceleration = [-A]
    inp.max_jerk = [J]
    traj = ruckig.Trajectory(1)
    result = otg.calculate(inp, traj)
    assert result in (ruckig.Result.Working, ruckig.Result.Finished)
    return traj.duration


def test_matches_ruckig_on_random_position_independent_cases():
    """Ruckig solves the same problem without our "no re-acceleration" rule: given room it
    would accelerate up to max_velocity. Starting exactly at max_velocity (cruising at the
    limit) removes that freedom — with v_start = V the time-optimal profile is cruise then
    brake in both formulations. A third of the cases start below the line limit; for those
    Ruckig's max_velocity is set to v_start, which is the effective limit of our problem
    (speed never rises), so again both problems coincide. Only feasible cases (x_stop at
    least the shortest stopping distance) are compared: below it Ruckig overshoots and backs up.
    """
    rng = random.Random(20240605)
    worst = 0.0
    n = 0
    for k in range(300):
        A = rng.uniform(0.3, 1.4)
        J = rng.uniform(0.2, 2.0)
        v0 = rng.uniform(1.0, 36.0) if k % 5 else rng.uniform(0.05, A * A / J)  # some triangular stops
        V_line = v0 if k % 3 else v0 * rng.uniform(1.0, 1.5)
        d = stop_distance(v0, A, J)
        X = d * (1.0 + (0.0 if k % 7 == 0 else rng.uniform(0.0, 2.0)))
        p = solve_stop(v0, X, jerk_max=J, decel_limits=[(0.0, A)], speed_limits=[(0.0, V_line)])
        assert p.feasible, (v0, X, A, J)
        t_ref = ruckig_duration(v0, X, v0, A, J)
        worst = max(worst, abs(p.duration_s - t_ref))
        assert p.duration_s == pytest.approx(t_ref, abs=RUCKIG_TOL_S), (v0, X, A, J)
        n += 1
    assert n >= 200
    print(f"ruckig: {n} cases, max |dT| = {worst:.2e} s")


# --------------------------------------------------------------------------------------
# infeasible requests
# --------------------------------------------------------------------------------------


def test_too_short_says_how_much_is_needed():
    v0, A, J = 22.2, 0.8, 0.6
    d = stop_distance(v0, A, J)
    p = solve1(v0, 0.9 * d, J, A)
    assert not p.feasible
    # the closed form, plus the stated allowance for round-off (10 µm and 1e-8 of it): a bound, never short
    assert d < p.braking_distance_m <= d + 1e-5 + 1e-8 * d + 1e-9
    assert f"needs {d:.1f} m" in p.reason and f"only {0.9 * d:.1f} m" in p.reason
    assert math.isnan(p.duration_s) and p.n_pieces == 0
    with pytest.raises(InfeasibleError):
        p.sample(0.1)


def test_start_above_the_first_limit_is_infeasible():
    p = solve_stop(20.0, 1000.0, jerk_max=0.5, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 19.0)])
    assert not p.feasible and "above the speed limit" in p.reason


def test_restriction_too_close_is_infeasible_and_needed_distance_is_consistent():
    """A 10 m/s restriction 100 m ahead of a 25 m/s start cannot be met; the needed distance
    is exactly what the approach lacks: prepend that much at the start and it fits."""
    J, A = 0.6, 0.9
    dl = [(0.0, A)]
    sl = [(0.0, 25.0), (100.0, 10.0)]
    p = solve_stop(25.0, 800.0, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assert not p.feasible
    lack = p.braking_distance_m - 800.0
    assert lack > 0
    # the restriction alone needs more than 100 m even at full deceleration from the start
    s = (A / J)
    need = 25.0 * s - J * s ** 3 / 6.0 + ((25.0 - A * A / (2 * J)) ** 2 - 10.0 ** 2) / (2 * A)
    assert need > 100.0
    q = solve_stop(25.0, 800.0 + lack + 1e-6, jerk_max=J, decel_limits=dl,
                   speed_limits=[(0.0, 25.0), (100.0 + lack + 1e-6, 10.0)])
    assert q.feasible and q.brake_start_m == pytest.approx(0.0, abs=1e-5)


def test_zero_speed_limit_before_the_stop():
    p = solve_stop(10.0, 500.0, jerk_max=0.5, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 10.0), (200.0, 0.0)])
    assert not p.feasible and "0 km/h" in p.reason


@pytest.mark.parametrize("v0, X, sl", [
    (22.2, 100.0, [(0.0, 25.0)]),                 # needs more room
    (20.0, 1000.0, [(0.0, 19.0)]),                # start above the first limit
    (10.0, 500.0, [(0.0, 10.0), (200.0, 0.0)]),   # a zero limit before the stop
    (0.0, 500.0, [(0.0, 10.0)]),                  # standing, no re-acceleration
])
def test_an_infeasible_verdict_is_the_constructors_own(v0, X, sl):
    """solve_stop fills an infeasible StopPattern without its constructor (speed): it must be the object the
    constructor makes from the same values, field for field and in field order, frozen, equal and hashable
    alike."""
    p = solve_stop(v0, X, jerk_max=0.6, decel_limits=[(0.0, 0.8)], speed_limits=sl)
    q = StopPattern(False, p.reason, v_start_ms=v0, x_stop_m=X, jerk_max_ms3=0.6,
                    **({"braking_distance_m": p.braking_distance_m} if "needs" in p.reason else {}))
    assert not p.feasible and p.reason
    assert list(vars(p).items()) == list(vars(q).items())
    assert p == q and hash(p) == hash(q)
    with pytest.raises(Exception):
        p.reason = ""  # type: ignore[misc]


def test_a_solved_pattern_reads_as_the_constructors_own():
    """solve_stop's pattern builds its fields from the solver's output when they are first read
    (planner.stopping.result): whichever field is read first, and read or not before it is pickled,
    copied, cached or replaced, it is the pattern the constructor makes from the closed form. v0 = 20 m/s,
    X = 400 m, J = 0.8 m/s³, A = 1 m/s²: cruise to 187.5 m, ramp 1.25 s, hold to 0.625 m/s, ramp 1.25 s
    (every time and speed exact in binary)."""
    import copy
    import dataclasses
    import pickle

    from planner.job.cache import decode, encode

    def solve():
        return solve_stop(20.0, 400.0, jerk_max=0.8, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 25.0)])

    ramp = 0.8 * 1.25 ** 3 / 6.0  # the distance the ramps lose to, or gain on, a jump in deceleration
    q = solve()
    assert q.t_s == (0.0, 9.375, 10.625, 29.375, 30.625) and q.v_ms == (20.0, 20.0, 19.375, 0.625, 0.0)
    assert q.a_ms2 == (0.0, 0.0, -1.0, -1.0, 0.0) and q.j_ms3 == (0.0, -0.8, 0.0, 0.8)
    assert q.x_m == pytest.approx((0.0, 187.5, 187.5 + 20.0 * 1.25 - ramp, 400.0 - ramp, 400.0), abs=1e-12)
    assert (q.duration_s, q.brake_start_m, q.braking_distance_m) == (30.625, 187.5, 212.5)
    ref = StopPattern(*(getattr(q, f.name) for f in dataclasses.fields(StopPattern)))
    names = [f.name for f in dataclasses.fields(StopPattern)]

    def breakpoints_first():
        p = solve()
        return p if p.j_ms3 else None

    def numbers_first():
        p = solve()
        return p if p.feasible else None

    def in_order():
        p = solve()
        for name in names:
            getattr(p, name)
        assert list(vars(p).items()) == list(vars(ref).items())
        return p

    ways = [breakpoints_first, numbers_first, in_order, lambda: pickle.loads(pickle.dumps(solve())),
            lambda: copy.copy(solve()), lambda: copy.deepcopy(solve()), lambda: decode(encode(solve())),
            lambda: dataclasses.replace(solve()), lambda: pickle.loads(pickle.dumps(numbers_first()))]
    for way in ways:
        p = way()
        assert type(p) is StopPattern and p.n_pieces == 4
        assert dataclasses.astuple(p) == dataclasses.astuple(ref) and p == ref and hash(p) == hash(ref)
        assert repr(p) == repr(ref)
    with pytest.raises(dataclasses.FrozenInstanceError):
        solve().duration_s = 1.0  # type: ignore[misc]


# --------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(jerk_max=-0.5), "jerk_max"),
        (dict(jerk_max=0.0), "jerk_max"),
        (dict(jerk_max=float("nan")), "jerk_max"),
        (dict(v_start=-1.0), "v_start"),
        (dict(x_stop=-5.0), "x_stop"),
        (dict(decel_limits=[]), "decel_limits is empty"),
        (dict(decel_limits=[(10.0, 1.0)]), "first step must start at 0.0"),
        (dict(decel_limits=[(0.0, 1.0), (200.0, 0.8), (100.0, 0.9)]), "decel_limits\\[2\\].*sort"),
        (dict(decel_limits=[(0.0, 1.0), (0.0, 0.9)]), "not after"),
        (dict(decel_limits=[(0.0, 1.0), (100.0, 0.0)]), "x_from=100.0 m: decel_ms2 must be > 0"),
        (dict(speed_limits=[(0.0, -3.0)]), "speed_ms must be >= 0"),
        (dict(speed_limits=[(5.0, 20.0)]), "first step must start at 0.0"),
        (dict(speed_limits=[(0.0,)]), "pairs"),
        (dict(speed_limits=5.0), "pairs"),
    ],
)
def test_bad_input_raises_input_error(kwargs, match):
    args = dict(v_start=10.0, x_stop=300.0, jerk_max=0.5, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 20.0)])
    args.update(kwargs)
    v0, X = args.pop("v_start"), args.pop("x_stop")
    with pytest.raises(InputError, match=match):
        solve_stop(v0, X, **args)


def test_sample_rejects_bad_dt():
    p = solve1(10.0, 300.0, 0.5, 1.0)
    for dt in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="dt_s"):
            p.sample(dt)


# --------------------------------------------------------------------------------------
# sampling
# --------------------------------------------------------------------------------------


def test_sample_is_exact_and_includes_the_end_point():
    v0, A, J = 20.0, 1.0, 0.8
    p = solve1(v0, 400.0, J, A)
    s = p.sample(0.7)
    assert s.t_s[0] == 0.0 and s.t_s[-1] == p.duration_s
    assert np.all(np.diff(s.t_s) > 0)
    assert s.x_m[-1] == pytest.approx(400.0, abs=1e-9) and abs(s.v_ms[-1]) < 1e-12 and abs(s.a_ms2[-1]) < 1e-12
    # inside the constant-deceleration phase the closed form of the braking curve holds:
    # v² = v1² - 2 A (x - x1) with (x1, v1) where the hold starts
    t1, t2 = p.t_s[2], p.t_s[3]
    m = (s.t_s > t1) & (s.t_s < t2)
    v1, x1 = p.v_ms[2], p.x_m[2]
    assert np.allclose(s.v_ms[m] ** 2, v1 ** 2 - 2 * A * (s.x_m[m] - x1), atol=1e-9)
    # derivative consistency (finite differences of the exact samples, step tiny)
    fine = p.sample(1e-3)
    dv = np.gradient(fine.x_m, fine.t_s)
    assert np.max(np.abs(dv - fine.v_ms)[2:-2]) < 1e-4


def test_pattern_is_frozen_and_breakpoints_are_consistent():
    p = solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=[(0.0, 0.9), (300.0, 0.7)],
                   speed_limits=[(0.0, 22.0), (420.0, 12.0)])
    assert isinstance(p, StopPattern) and p.feasible
    with pytest.raises(Exception):
        p.duration_s = 1.0  # type: ignore[misc]
    n = p.n_pieces
    assert len(p.t_s) == len(p.x_m) == len(p.v_ms) == len(p.a_ms2) == n + 1
    for k in range(n):  # each cubic piece lands exactly on the next breakpoint
        d = p.t_s[k + 1] - p.t_s[k]
        j = p.j_ms3[k]
        assert p.a_ms2[k] + j * d == pytest.approx(p.a_ms2[k + 1], abs=1e-9)
        assert p.v_ms[k] + p.a_ms2[k] * d + j * d * d / 2 == pytest.approx(p.v_ms[k + 1], abs=1e-8)
        x_end = p.x_m[k] + p.v_ms[k] * d + p.a_ms2[k] * d * d / 2 + j * d ** 3 / 6
        assert x_end == pytest.approx(p.x_m[k + 1], abs=1e-6)
        assert j in (-0.6, 0.0, 0.6)


# --------------------------------------------------------------------------------------
# the deceleration rule
# --------------------------------------------------------------------------------------


def test_decel_profile_rule_and_merging():
    prof = decel_limit_profile(1.0, 0.8, [(0.0, 0.0), (100.0, -10.0), (180.0, -10.0), (250.0, 5.0), (300.0, 5.0)])
    # min(comfort, adhesion) = 0.8; -10 ‰ takes g/100 away, +5 ‰ adds g/200 (g = 9.80665 m/s², no
    # rotating mass); equal neighbours merged
    assert prof == [(0.0, 0.8), (100.0, pytest.approx(0.8 - 0.0980665)), (250.0, pytest.approx(0.8 + 0.04903325))]
    # the weight M g s acts on the inertial mass M (1 + ρ), as in the run curves
    prof = decel_limit_profile(1.0, 0.8, [(0.0, 0.0), (100.0, -10.0)], rotating_mass_factor=0.1)
    assert prof == [(0.0, 0.8), (100.0, pytest.approx(0.8 - 0.0980665 / 1.1))]
    assert decel_limit_profile(0.7, 0.9, []) == [(0.0, 0.7)]
    assert decel_limit_profile(0.9, 0.7) == [(0.0, 0.7)]


def test_decel_profile_rejects_a_gradient_that_leaves_nothing():
    with pytest.raises(InputError, match="x_from=120.0 m"):
        decel_limit_profile(0.9, 0.69, [(0.0, 0.0), (120.0, -75.0)])


@pytest.mark.parametrize(
    "args, match",
    [
        ((0.0, 0.8, [(0.0, 0.0)]), "comfort_ms2"),
        ((1.0, -0.8, [(0.0, 0.0)]), "adhesion_ms2"),
        ((1.0, 0.8, [(10.0, 0.0)]), "first segment must start at 0.0"),
        ((1.0, 0.8, [(0.0, 0.0), (50.0, 1.0), (20.0, 2.0)]), "sort"),
        ((1.0, 0.8, [(0.0, float("inf"))]), "not finite"),
    ],
)
def test_decel_profile_input_errors(args, match):
    with pytest.raises(InputError, match=match):
        decel_limit_profile(*args)


def test_lower_adhesion_brakes_earlier_and_takes_longer():
    grads = [(0.0, 0.0), (150.0, -8.0), (320.0, 3.0)]
    prev = None
    for adhesion_kmh_s in np.arange(3.5, 2.45, -0.1):
        dl = decel_limit_profile(3.6 / 3.6, adhesion_kmh_s / 3.6, grads)
        p = solve_stop(70 / 3.6, 520.0, jerk_max=0.6, decel_limits=dl, speed_limits=[(0.0, 80 / 3.6)])
        assert p.feasible
        if prev is not None:
            assert p.duration_s >= prev.duration_s - ROUNDOFF_S
            assert p.brake_start_m <= prev.brake_start_m + ROUNDOFF_M
        prev = p


@pytest.mark.parametrize(
    "dl, sl",
    [
        ([(0.0, 0.8), (50.0, 1.0)], [(0.0, 20.0)]),  # a deceleration step the cruise passes
        ([(0.0, 1.0)], [(0.0, 20.0), (60.0, 25.0), (100.0, 22.0)]),  # speed steps above v_start
    ],
)
def test_brake_start_is_where_deceleration_begins_after_non_binding_steps(dl, sl):
    """Limit changes that the cruise at v_start passes without braking (a deceleration step
    before the brake start, speed limits above v_start) do not move the brake start: it is
    the closed-form one of the last region, 212.5 m before the stop (v (v/A + A/J) / 2)."""
    v0, X, J, A = 20.0, 400.0, 0.8, 1.0
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    d = stop_distance(v0, A, J)
    assert p.feasible
    assert p.brake_start_m == pytest.approx(X - d, abs=ROUNDOFF_M)
    assert p.braking_distance_m == pytest.approx(d, abs=ROUNDOFF_M)
    assert p.duration_s == pytest.approx((X - d) / v0 + stop_time(v0, A, J), abs=ROUNDOFF_S)
    s = p.sample(0.01)
    assert np.all(s.a_ms2[s.x_m < p.brake_start_m - 1e-6] == 0.0)


def test_step_functions_as_tuples_or_arrays_solve_the_same_as_lists():
    """The fast path converts two lists in one call; other sequences take the checked path. Two
    numpy arrays must never be added elementwise (``a + b``) on the way in."""
    dl = [(0.0, 0.9), (150.0, 0.7)]
    sl = [(0.0, 25.0), (300.0, 15.0)]
    ref = solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=dl, speed_limits=sl)
    assert ref.feasible
    for conv in (tuple, np.array, lambda s: [list(p) for p in s], lambda s: iter(s)):
        p = solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=conv(dl), speed_limits=conv(sl))
        assert p == ref, conv
    # rows the fast path packs no floats from (it takes tuples of two floats' worth) read as the
    # checked path reads them: the first two items of each row, numbers given as text
    for rows in ([(0.0, 0.9, 99.0), (150.0, 0.7, -1.0)], [{0: 0.0, 1: 0.9}, (150.0, 0.7)],
                 [("0", "0.9"), (150.0, "0.7")]):
        assert solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=rows, speed_limits=sl) == ref, rows
    with pytest.raises(InputError, match="pairs"):  # a set has no first item: never read in some order
        solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=[{0.0, 0.9}], speed_limits=sl)
    # integers and numpy scalars are numbers like any other
    q = solve_stop(np.float64(22.0), 600, jerk_max=0.6, decel_limits=[(0, 0.9), (150, 0.7)],
                   speed_limits=[(0, 25), (300, 15)])
    assert q == ref
    with pytest.raises(InputError, match="x_stop must be >= 0"):
        solve_stop(22.0, -1.0, jerk_max=0.6, decel_limits=[(0.0,)], speed_limits=sl)  # order: x_stop first
    with pytest.raises(InputError, match=r"decel_limits\[1\] x_from=0.0 m is not after"):
        solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=((0.0, 0.9), (0.0, 0.8)), speed_limits=[(0.0,)])


def test_the_kernel_compiles_on_the_first_solve_only_and_once_per_function():
    """Importing the solver must not compile it (some seconds: CLI commands that never solve a stop
    would pay it), and every compiled function has its one signature: a constant argument used to
    compile one copy per value, which tripled the compile time."""
    import subprocess
    import sys

    code = "import sys, planner.stopping.pattern; print('planner.stopping.kernel' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False"]

    from numba.core.registry import CPUDispatcher

    from planner.stopping import construct, kernel, pieces

    solve1(20.0, 500.0, 0.8, 1.0)
    solve_stop(22.0, 600.0, jerk_max=0.6, decel_limits=[(0.0, 0.9), (300.0, 0.7)],
               speed_limits=[(0.0, 25.0), (200.0, 15.0), (450.0, 20.0)])
    compiled = [f for m in (pieces, construct, kernel) for f in vars(m).values() if isinstance(f, CPUDispatcher)]
    assert len(compiled) >= 20
    assert {f.py_func.__name__: len(f.signatures) for f in compiled if len(f.signatures) != 1} == {}
