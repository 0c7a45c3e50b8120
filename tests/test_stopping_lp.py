"""Optimality of stopping patterns beyond the position-independent case.

An independent optimiser: a time-discretised mixed-integer *linear* programme
(scipy.optimize.milp, HiGHS). The horizon T is split into N equal steps of
piecewise-constant jerk, integrated exactly (the LP dynamics are the same cubic
polynomials, so the only approximation is where jerk may change). Which limit
applies at a sample is decided by binaries ``z[i, k] = 1 <=> x_i >= e_k`` for
every event point ``e_k`` (x is monotone, so ``z`` is monotone in i). The
step-function limits are then linear: ``A(x_i) = A_0 + sum_k (A_k - A_{k-1}) z[i, k]``.

The limits are imposed *conservatively* on every step: the acceleration is
linear in a step and the speed falls, so ``a_i, a_{i+1} >= -min(A(x_i), A(x_{i+1}))``
and ``v_i <= v_cap(x_{i+1})`` make every LP-feasible trajectory truly feasible
(as long as no step spans two event points, which the test checks). Hence the
LP optimum ``T_lp(N)`` is an upper bound on the true minimum time: the solver's
duration must not exceed it (one-sided, rigorous check that no feasible
trajectory beats it), and as N grows ``T_lp(N)`` must come down onto it
(discretisation error O(T/N): a switching instant off the grid costs a fraction
of a step). The minimum T is found by bisection on feasibility to 2e-3 s.

:func:`pinned_lp_feasible` is the same bound with the step in which each event point is crossed
fixed: a pure LP (every limit a bound on one variable), fast on fine grids where the MILP's
binaries time out near the bound; :func:`pinned_lp_min_time` searches the crossing steps near
where the solver's pattern crosses (which only makes the bound tight, never less rigorous). The
random-case property checks the solver against the MILP on approaches with speed steps down and up
and deceleration steps: nothing admissible on its grid is faster.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

scipy_optimize = pytest.importorskip("scipy.optimize")
from hypothesis import HealthCheck, assume, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from scipy.optimize import Bounds, LinearConstraint, linprog, milp  # noqa: E402
from scipy.sparse import coo_matrix, lil_matrix  # noqa: E402

from planner.stopping.pattern import solve_stop  # noqa: E402


def _steps(steps, x_stop):
    events = sorted({x for x, _ in steps if 0.0 < x < x_stop})
    return events


def lp_feasible(T, N, v0, X, J, decel_limits, speed_limits, *, time_limit=60.0, proved=False):
    """Is there a trajectory of duration T on an N-step grid meeting every limit (conservatively)?

    Returns (feasible, x samples) — x samples to check that no step spans two events. ``proved``:
    "no" only when HiGHS proved it (else RuntimeError), not when it ran out of time.
    """
    h = T / N
    events = sorted({x for x, _ in list(decel_limits) + list(speed_limits) if 0.0 < x < X})
    K = len(events)
    # limit values in each region between consecutive events (forward), speed as running minimum
    bounds_x = [0.0] + events
    A_reg, V_reg = [], []
    cap = v0
    for xb in bounds_x:
        A_reg.append([v for x, v in decel_limits if x <= xb][-1])
        cap = min(cap, [v for x, v in speed_limits if x <= xb][-1])
        V_reg.append(cap)
    dA = [A_reg[k] - A_reg[k - 1] for k in range(1, K + 1)]
    dV = [V_reg[k] - V_reg[k - 1] for k in range(1, K + 1)]
    n = N + 1
    # variable layout: x[0..N], v[0..N], a[0..N], j[0..N-1], z[i, k] (i=0..N, k=0..K-1)
    ix, iv, ia, ij = 0, n, 2 * n, 3 * n
    iz = 3 * n + N
    nvar = iz + n * K
    lo, hi = [], []
    M = lil_matrix((8 * N + 3 * n * K + n * K + 16, nvar))
    r = 0

    def add(coefs, lb, ub):
        nonlocal r
        for c, val in coefs:
            M[r, c] += val
        lo.append(lb)
        hi.append(ub)
        r += 1

    for i in range(N):
        # exact integration of a constant-jerk step
        add([(ix + i + 1, 1.0), (ix + i, -1.0), (iv + i, -h), (ia + i, -h * h / 2), (ij + i, -h ** 3 / 6)], 0.0, 0.0)
        add([(iv + i + 1, 1.0), (iv + i, -1.0), (ia + i, -h), (ij + i, -h * h / 2)], 0.0, 0.0)
        add([(ia + i + 1, 1.0), (ia + i, -1.0), (ij + i, -h)], 0.0, 0.0)
        # a_i, a_{i+1} >= -A(x_i) and >= -A(x_{i+1}):  a + A_0 + sum dA z >= 0
        for ai in (i, i + 1):
            for xi in (i, i + 1):
                add([(ia + ai, 1.0)] + [(iz + xi * K + k, dA[k]) for k in range(K)], -A_reg[0], math.inf)
        # v_i <= V(x_{i+1}):  v_i - sum dV z_{i+1} <= V_0
        add([(iv + i, 1.0)] + [(iz + (i + 1) * K + k, -dV[k]) for k in range(K)], -math.inf, V_reg[0])
    big = 2.0 * X + 10.0
    for i in range(n):
        for k in range(K):
            e = events[k]
            # z = 1 -> x >= e ;  z = 0 -> x <= e
            add([(ix + i, 1.0), (iz + i * K + k, -big)], e - big, math.inf)
            add([(ix + i, 1.0), (iz + i * K + k, -big)], -math.inf, e)
            if i < N:
                add([(iz + (i + 1) * K + k, 1.0), (iz + i * K + k, -1.0)], 0.0, math.inf)
    M = M[:r].tocsr()
    lb = np.full(nvar, -np.inf)
    ub = np.full(nvar, np.inf)
    lb[ix:ix + n], ub[ix:ix + n] = 0.0, X
    lb[iv:iv + n], ub[iv:iv + n] = 0.0, v0
    lb[ia:ia + n], ub[ia:ia + n] = -max(A_reg), 0.0
    lb[ij:ij + N], ub[ij:ij + N] = -J, J
    lb[iz:], ub[iz:] = 0.0, 1.0
    # boundary conditions
    lb[ix], ub[ix] = 0.0, 0.0
    lb[iv], ub[iv] = v0, v0
    lb[ia], ub[ia] = 0.0, 0.0
    lb[ix + N], ub[ix + N] = X, X
    lb[iv + N], ub[iv + N] = 0.0, 0.0
    lb[ia + N], ub[ia + N] = 0.0, 0.0
    integrality = np.zeros(nvar)
    integrality[iz:] = 1
    res = milp(
        np.zeros(nvar),
        constraints=LinearConstraint(M, np.array(lo), np.array(hi)),
        bounds=Bounds(lb, ub),
        integrality=integrality,
        options={"time_limit": time_limit},
    )
    if res.status == 0:
        return True, res.x[ix:ix + n]
    if res.status != 2 and proved:
        raise RuntimeError(f"MILP neither solved nor proved infeasible: {res.message}")
    return False, None


def lp_min_time(N, v0, X, J, decel_limits, speed_limits, T_guess, tol=2e-3, bracket=(0.97, 1.03)):
    """Bisection on the horizon for the LP's minimum time (bracket grown until it holds)."""
    lo, hi = bracket[0] * T_guess, bracket[1] * T_guess
    while lp_feasible(lo, N, v0, X, J, decel_limits, speed_limits)[0]:
        lo *= 0.95
    ok, xs = lp_feasible(hi, N, v0, X, J, decel_limits, speed_limits)
    while not ok:
        hi *= 1.05
        ok, xs = lp_feasible(hi, N, v0, X, J, decel_limits, speed_limits)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        ok, x_mid = lp_feasible(mid, N, v0, X, J, decel_limits, speed_limits)
        if ok:
            hi, xs = mid, x_mid
        else:
            lo = mid
    return hi, xs


# --------------------------------------------------------------------------------------
# the comparisons
# --------------------------------------------------------------------------------------

N_STEPS = 140
BISECT_TOL_S = 2e-3  # lp_min_time's bracket width


def lp_tolerance(T, N):
    """Allowed excess of the LP's time over the exact minimum [s].

    The LP is a restriction of the continuous problem (its trajectories are feasible), so
    it can only be slower. It loses time because jerk may change only on its grid: each
    switching instant of the exact optimum (at most ~8 here) lands inside a step of
    length h = T/N, and re-timing a jerk switch by a fraction of a step costs O(h²·J)
    in speed over the rest of the braking; empirically the loss stays below 0.1 h
    (and falls with N, checked below). Plus the bisection bracket.
    """
    return 0.1 * T / N + BISECT_TOL_S


def check_against_lp(v0, X, J, dl, sl, N=N_STEPS):
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assert p.feasible
    T_lp, xs = lp_min_time(N, v0, X, J, dl, sl, p.duration_s, tol=BISECT_TOL_S)
    # the conservative step constraints assume no LP step spans two event points
    events = sorted({x for x, _ in list(dl) + list(sl) if 0.0 < x < X})
    ev = np.array(events)
    per_step = np.searchsorted(ev, xs[1:], side="left") - np.searchsorted(ev, xs[:-1], side="right")
    assert np.all(per_step <= 1), "an LP step spans two event points; refine N"
    print(f"solver {p.duration_s:.4f} s, LP(N={N}) {T_lp:.4f} s, LP - solver = {T_lp - p.duration_s:+.4f} s")
    return p.duration_s, T_lp


CASES = {
    # adhesion 2.7 km/h/s, comfort 3.6 km/h/s, falling 15 ‰ then rising 8 ‰ towards the stop
    "adhesion_and_gradients": (22.0, 550.0, 0.6, [(0.0, 0.75), (150.0, 0.603), (330.0, 0.8284)], [(0.0, 22.0)]),
    # less deceleration available over the last 200 m (falling gradient at the platform)
    "weaker_near_the_stop": (20.0, 500.0, 0.6, [(0.0, 1.0), (300.0, 0.6)], [(0.0, 20.0)]),
    # an 11 m/s restriction 50 m before the stop, met while braking, and gradients
    "restriction_met_braking": (20.0, 450.0, 0.5, [(0.0, 0.8), (200.0, 0.702), (380.0, 0.849)],
                                [(0.0, 20.0), (400.0, 11.0)]),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_matches_an_independent_lp(name):
    v0, X, J, dl, sl = CASES[name]
    T, T_lp = check_against_lp(v0, X, J, dl, sl)
    # one-sided and rigorous: no LP-feasible (hence admissible) trajectory is faster
    assert T <= T_lp + 1e-9
    # and the LP comes down onto it within its discretisation error
    assert T_lp - T <= lp_tolerance(T_lp, N_STEPS)


def test_lp_gap_shrinks_with_the_grid():
    v0, X, J, dl, sl = CASES["weaker_near_the_stop"]
    T, T1 = check_against_lp(v0, X, J, dl, sl, N=70)
    _, T2 = check_against_lp(v0, X, J, dl, sl, N=140)
    assert T <= T2 <= T1 + BISECT_TOL_S
    assert T2 - T < 0.6 * (T1 - T) + BISECT_TOL_S


STEP_DOWN = {
    # a 9 m/s restriction 90 m before the stop, cruised through: the optimum enters it still braking
    "restriction_then_cruise": (15.0, 220.0, 0.7, [(0.0, 0.9)], [(0.0, 15.0), (130.0, 9.0)]),
}
N_FINE = 200
"""The LP grid of the step-down check: fine enough that the LP optimum is within 0.01 s of the minimum."""


@pytest.mark.parametrize("name", sorted(STEP_DOWN))
def test_speed_step_down_is_entered_in_minimum_time(name):
    """Issue 14, defect 2: at a speed step-down followed by a cruise the paper's rule (lower speed
    reached with a = 0 at the restriction start) is not the minimum. The independent LP (whose
    trajectories all meet every limit) beats the paper's rule by several hundredths of a second;
    the solver must be no slower than the LP and within 0.01 s of it."""
    v0, X, J, dl, sl = STEP_DOWN[name]
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    paper = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, rule="paper")
    assert p.feasible and paper.feasible
    T_lp, _ = lp_min_time(N_FINE, v0, X, J, dl, sl, p.duration_s, tol=5e-4, bracket=(0.999, 1.001))
    print(f"solver {p.duration_s:.4f} s, paper's rule {paper.duration_s:.4f} s, LP(N={N_FINE}) {T_lp:.4f} s")
    assert p.duration_s <= T_lp + 1e-9  # no admissible (LP) trajectory is faster
    assert T_lp - p.duration_s <= 0.01
    assert paper.duration_s - T_lp >= 0.05  # the paper's rule is not the minimum


# --------------------------------------------------------------------------------------
# the same bound with the crossing steps fixed: a pure LP, no binaries
# --------------------------------------------------------------------------------------


def _regions(v0, X, decel_limits, speed_limits):
    """Event points in (0, X) and the limits between them: deceleration, speed cap (running minimum)."""
    events = sorted({x for x, _ in list(decel_limits) + list(speed_limits) if 0.0 < x < X})
    A_reg, V_reg = [], []
    cap = v0
    for xb in [0.0] + events:
        A_reg.append([v for x, v in decel_limits if x <= xb][-1])
        cap = min(cap, [v for x, v in speed_limits if x <= xb][-1])
        V_reg.append(cap)
    return events, A_reg, V_reg


def pinned_lp_feasible(T, N, v0, X, J, decel_limits, speed_limits, pins, unit_steps=None):
    """Is there a trajectory of duration T, jerk constant on each of N equal steps, that crosses
    event point k inside step ``pins[k]`` (strictly increasing) and meets every limit?

    With the crossing steps fixed there is nothing left to decide by binaries: every limit is a
    bound on one variable. A step lies in one region, or (the crossing step) takes the stricter
    limits of both sides. The acceleration is linear in a step, so ``a >= -A`` at both ends holds
    throughout; ``a <= 0`` makes the speed fall, so ``v <= C`` at the step's start holds throughout,
    and ``v >= 0`` at its end keeps x monotone (``x_k <= e <= x_{k+1}`` places the crossing). So
    every feasible point is an admissible trajectory and the LP's minimum time is a rigorous upper
    bound on the true minimum. A pure LP (HiGHS, fast at thousands of steps), unlike
    :func:`lp_feasible`, whose binaries time out near the bound on fine grids. ``unit_steps``: the
    N steps as fractions of T (default equal), to refine the grid where it matters.
    """
    events, A_reg, V_reg = _regions(v0, X, decel_limits, speed_limits)
    hs = np.full(N, T / N) if unit_steps is None else T * np.asarray(unit_steps)
    pins = np.asarray(pins, dtype=int)
    region = np.searchsorted(pins, np.arange(N), side="left")  # region of each step (the crossing: before)
    A_step = np.asarray(A_reg)[region]
    C_step = np.asarray(V_reg)[region]
    A_step[pins] = np.minimum(A_step[pins], np.asarray(A_reg)[1:])  # the crossing step: both sides
    C_step[pins] = np.asarray(V_reg)[1:]  # the running minimum: the far side's is the lower
    # event point k crossed inside step pins[k]: at or after its start node, at or before its end node
    x_at = [(i, -np.inf, e) for e, i in zip(events, pins)] + [(i + 1, e, np.inf) for e, i in zip(events, pins)]
    return step_lp_feasible(hs, v0, X, J, A_step, C_step, x_at)


def refined_steps(N, crossing_guess, fine):
    """N equal steps (as fractions of the duration), each of the two around every guessed crossing
    cut into ``fine``: the steps and, per event, the index of the first fine step."""
    cut = set()
    for f in crossing_guess:
        c = min(int(f * N), N - 1)
        cut.update({max(c - 1, 0), c, min(c + 1, N - 1)})
    steps, first = [], {}
    for i in range(N):
        if i in cut:
            first.setdefault(i, len(steps))
            steps += [1.0 / (N * fine)] * fine
        else:
            steps.append(1.0 / N)
    starts = np.concatenate([[0.0], np.cumsum(steps)])
    return np.asarray(steps), [int(np.searchsorted(starts, f, side="right") - 1) for f in crossing_guess]


def min_feasible_time(feasible, lo, hi, tol, give_up=None):
    """The least T (to ``tol``, the feasible end) with ``feasible(T)``: [lo, hi] widened by its own width
    until ``lo`` is infeasible and ``hi`` feasible, then bisected. None when ``hi`` passes ``give_up``."""
    while feasible(lo):
        lo -= hi - lo
    while not feasible(hi):
        hi += hi - lo
        if give_up is not None and hi > give_up:
            return None
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return hi


def pinned_lp_min_time(N, v0, X, J, decel_limits, speed_limits, T_guess, crossing_guess, *, window=3,
                       tol=1e-4, bracket=(0.995, 1.005), fine=1):
    """The LP's minimum time by bisection on T; at every T the crossing steps are searched in a window
    of ``window`` steps around ``crossing_guess`` (each event's crossing as a fraction of the
    duration: where to look, which does not touch the bound's rigour, only how tight it is)."""
    from itertools import product

    events, _, _ = _regions(v0, X, decel_limits, speed_limits)
    assert len(crossing_guess) == len(events)

    unit, centre = refined_steps(N, crossing_guess, fine)
    M = unit.size

    def feasible(T):
        for pins in product(*[range(max(1, c - window), min(M - 1, c + window) + 1) for c in centre]):
            if all(p < q for p, q in zip(pins, pins[1:])) and pinned_lp_feasible(
                    T, M, v0, X, J, decel_limits, speed_limits, pins, unit):
                return True
        return False

    return min_feasible_time(feasible, bracket[0] * T_guess, bracket[1] * T_guess, tol)


def crossing_fractions(p, events):
    """When the pattern ``p`` passes each event point, as fractions of its duration."""
    s = p.sample(p.duration_s / 20000.0)
    return [float(np.interp(e, s.x_m, s.t_s)) / p.duration_s for e in events]


# --------------------------------------------------------------------------------------
# random position-dependent approaches: nothing admissible is faster than the solver
# --------------------------------------------------------------------------------------

N_RANDOM = 120
"""The MILP grid of the random cases (each check one MILP of ~500 binaries at most)."""


@st.composite
def spaced_approaches(draw):
    """Approaches with speed steps down and up and deceleration steps (gradients) at event points at
    least 20 m apart (so that an LP step of a faster trajectory spans at most one of them)."""
    X = draw(st.floats(120.0, 450.0))
    v0 = draw(st.floats(6.0, 22.0))
    J = draw(st.floats(0.35, 1.0))
    n_ev = draw(st.integers(1, 3))
    grid = sorted(draw(st.sets(st.integers(1, int((X - 20.0) // 20.0)), min_size=n_ev, max_size=n_ev)))
    dl, sl = [(0.0, draw(st.floats(0.45, 1.1)))], [(0.0, v0 * draw(st.floats(1.0, 1.15)))]
    for g in grid:
        x = 20.0 * g + draw(st.floats(0.0, 5.0))
        if draw(st.booleans()):
            dl.append((x, draw(st.floats(0.45, 1.1))))
        else:
            sl.append((x, v0 * draw(st.floats(0.3, 1.05))))
    return v0, X, J, dl, sl


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(spaced_approaches())
def test_no_admissible_trajectory_is_faster_than_the_solver(case):
    """Issue 37: the solver against an independent bound, not against itself. For random approaches
    with speed steps down and up and deceleration steps, the MILP (every feasible point of which is
    an admissible trajectory, checked: no step spans two event points) must prove that no trajectory
    on its grid stops in less than the solver's duration. It finds the defects issue 37 fixed (a
    step-down met while still braking, 0.05-0.1 s) when they are larger than its grid's loss."""
    v0, X, J, dl, sl = case
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    assume(p.feasible)
    T = p.duration_s * (1.0 - 1e-9) - 1e-6
    faster, xs = lp_feasible(T, N_RANDOM, v0, X, J, dl, sl, time_limit=30.0, proved=True)
    if faster:
        ev = np.array(sorted({x for x, _ in dl + sl if 0.0 < x < X}))
        per_step = np.searchsorted(ev, xs[1:], side="left") - np.searchsorted(ev, xs[:-1], side="right")
        assert np.any(per_step > 1), f"an admissible trajectory stops faster than {p.duration_s:.4f} s"


def test_case_study_step_down_met_while_still_braking():
    """Issue 37: the seed paper's case study (350 m from 70 km/h, 40 km/h from 250 m, -20 ‰ before
    150 m, jerk 0.6 m/s³, comfort 3.3 km/h/s) at adhesion 2.5 km/h/s. The step-down cannot be met at
    a = 0 with a cruise after it; the optimum passes 250 m at 40 km/h still braking (about
    -2.2 km/h/s). The construction that forced a = 0 there took 33.2526 s: the independent LP finds an
    admissible trajectory faster than that, and none faster than the solver."""
    from planner.stopping.pattern import decel_limit_profile

    kmh = 1.0 / 3.6
    v0, X, J = 70.0 * kmh, 350.0, 0.6
    dl = decel_limit_profile(3.3 * kmh, 2.5 * kmh, [(0.0, -20.0), (150.0, 0.0)])
    sl = [(0.0, v0), (250.0, 40.0 * kmh)]
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    s = p.sample(1e-3)
    i = int(np.searchsorted(s.x_m, 250.0))
    assert s.v_ms[i] == pytest.approx(40.0 * kmh, abs=1e-3) and s.a_ms2[i] < -2.0 * kmh
    events, _, _ = _regions(v0, X, dl, sl)
    T_lp = pinned_lp_min_time(200, v0, X, J, dl, sl, p.duration_s, crossing_fractions(p, events), window=1,
                              tol=5e-4)
    print(f"solver {p.duration_s:.4f} s, LP(N=200) {T_lp:.4f} s")
    assert p.duration_s <= T_lp + 1e-9
    assert T_lp < 33.2526 - 0.04  # the a = 0 entry was not the minimum, by the LP alone
    assert T_lp - p.duration_s <= 0.01


# --------------------------------------------------------------------------------------
# the bound with each event point at a grid node: no crossing step, converges onto the minimum
# --------------------------------------------------------------------------------------


def node_grid(N, fractions):
    """N equal steps (as fractions of the duration) with the nearest inner node moved onto each of
    ``fractions``: the steps and the node index of each fraction."""
    t = np.linspace(0.0, 1.0, N + 1)
    nodes = []
    for f in fractions:
        k = int(np.argmin(np.abs(t[1:-1] - f))) + 1
        t[k] = f
        nodes.append(k)
    assert np.all(np.diff(t) > 0.0), "two event points at one node: refine N"
    return np.diff(t), nodes


def node_lp_feasible(T, unit_steps, nodes, v0, X, J, decel_limits, speed_limits, time_limit=None):
    """Is there a trajectory of duration T, jerk constant on each step (``unit_steps`` fractions of T),
    that is at event point k exactly at node ``nodes[k]`` and meets every limit?

    No step spans an event point, so each step takes its own region's limits and nothing else: the
    acceleration is linear in a step (``a >= -A`` at both ends holds throughout), the speed falls
    (``v <= C`` at its start holds throughout). Every feasible point is an admissible trajectory: the
    minimum T is a rigorous upper bound on the true minimum, without the crossing step's conservative
    loss of :func:`pinned_lp_feasible` (a step crossed while braking at b loses about b·h of speed),
    so it comes down onto the minimum as the grid is refined (jerk switches off the grid only).
    """
    events, A_reg, V_reg = _regions(v0, X, decel_limits, speed_limits)
    hs = T * np.asarray(unit_steps)
    N = hs.size
    region = np.searchsorted(np.asarray(nodes), np.arange(N), side="right")
    A_step, C_step = np.asarray(A_reg)[region], np.asarray(V_reg)[region]
    return step_lp_feasible(hs, v0, X, J, A_step, C_step, [(k, e, e) for e, k in zip(events, nodes)], time_limit)


def step_lp_feasible(hs, v0, X, J, A_step, C_step, x_at, time_limit=None):
    """The LP both grids share: jerk constant on each step ``hs`` [s], from (0, v0, 0) to (X, 0, 0), position,
    speed and acceleration at the nodes linked exactly by each step's cubic; each step braking at most
    ``A_step`` and starting at most ``C_step``; ``x_at``: (node, lower, upper) bounds on the position at a node.
    Feasible or not; RuntimeError when HiGHS does neither (it can stall on a rare LP until ``time_limit``)."""
    N = hs.size
    n = N + 1
    ix, iv, ia, ij = 0, n, 2 * n, 3 * n
    nvar = 3 * n + N
    lb, ub = np.full(nvar, -np.inf), np.full(nvar, np.inf)
    lb[ix:ix + n], ub[ix:ix + n] = 0.0, X
    lb[iv:iv + n], ub[iv:iv + n] = 0.0, v0
    ub[ia:ia + n] = 0.0
    lb[ij:ij + N], ub[ij:ij + N] = -J, J
    lb[ia:ia + N] = -A_step
    lb[ia + 1:ia + n] = np.maximum(lb[ia + 1:ia + n], -A_step)
    ub[iv:iv + N] = np.minimum(ub[iv:iv + N], C_step)
    for k, lo, hi in x_at:
        lb[ix + k], ub[ix + k] = max(lb[ix + k], lo), min(ub[ix + k], hi)
    for k, val in ((ix, 0.0), (iv, v0), (ia, 0.0), (ix + N, X), (iv + N, 0.0), (ia + N, 0.0)):
        lb[k] = ub[k] = val
    rows, cols, vals = [], [], []
    for i, h in enumerate(hs):
        r = 3 * i
        for c, val in ((ix + i + 1, 1.0), (ix + i, -1.0), (iv + i, -h), (ia + i, -h * h / 2), (ij + i, -h ** 3 / 6)):
            rows.append(r), cols.append(c), vals.append(val)
        for c, val in ((iv + i + 1, 1.0), (iv + i, -1.0), (ia + i, -h), (ij + i, -h * h / 2)):
            rows.append(r + 1), cols.append(c), vals.append(val)
        for c, val in ((ia + i + 1, 1.0), (ia + i, -1.0), (ij + i, -h)):
            rows.append(r + 2), cols.append(c), vals.append(val)
    M = coo_matrix((vals, (rows, cols)), shape=(3 * N, nvar)).tocsr()
    options = {} if time_limit is None else {"time_limit": time_limit}
    res = linprog(np.zeros(nvar), A_eq=M, b_eq=np.zeros(3 * N), bounds=np.column_stack([lb, ub]), method="highs",
                  options=options)
    if res.status not in (0, 2):
        raise RuntimeError(f"LP neither solved nor proved infeasible: {res.message}")
    return res.status == 0


def node_lp_min_time(N, v0, X, J, decel_limits, speed_limits, T_guess, fractions, tol=2e-5):
    """The minimum T of :func:`node_lp_feasible` by bisection, the event points at the nodes nearest
    ``fractions`` of T (where the solver's pattern passes them: where to look, not the bound's rigour).
    Pinning at fractions of T suits events crossed while braking; a cruise through two events at the
    top speed has one T only (then the bound is NaN: use :func:`pinned_lp_min_time`)."""
    unit, nodes = node_grid(N, fractions)

    def feasible(T):
        return node_lp_feasible(T, unit, nodes, v0, X, J, decel_limits, speed_limits)

    T = min_feasible_time(feasible, T_guess * (1.0 - 1e-3), T_guess * (1.0 + 1e-3), tol, give_up=1.05 * T_guess)
    return math.nan if T is None else T


def test_case_study_bound_comes_down_onto_the_solver():
    """Issue 37: the case study at 2.5 km/h/s against the bound with its two event points at grid
    nodes. The bound is an admissible trajectory, so never faster than the solver; refined, it comes
    down onto it (measured: +1.3e-3 s at N=400, +2.2e-4 s at 800, +8.1e-5 s at 1600, +2.4e-5 s at
    3200): the solver is the minimum to the bound's resolution. The earlier construction that forced
    a = 0 at the step-down (33.2526 s) is 0.05 s above this bound."""
    from planner.stopping.pattern import decel_limit_profile

    kmh = 1.0 / 3.6
    v0, X, J = 70.0 * kmh, 350.0, 0.6
    dl = decel_limit_profile(3.3 * kmh, 2.5 * kmh, [(0.0, -20.0), (150.0, 0.0)])
    sl = [(0.0, v0), (250.0, 40.0 * kmh)]
    p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
    events, _, _ = _regions(v0, X, dl, sl)
    T_lp = node_lp_min_time(800, v0, X, J, dl, sl, p.duration_s, crossing_fractions(p, events), tol=5e-5)
    print(f"solver {p.duration_s:.6f} s, node-pinned LP(N=800) {T_lp:.6f} s")
    assert p.duration_s <= T_lp + 1e-9
    assert T_lp - p.duration_s <= 5e-4
