"""An admissible-trajectory bound on the minimum stopping time, built on segments between event points.

The linear programme is :func:`tests.test_stopping_lp.node_lp_feasible` (jerk constant per step,
integrated exactly, each event point passed exactly at a grid node, every limit a bound on one
variable): every solution is an admissible trajectory, so its minimum time is an upper bound on the
true minimum, and the solver (if minimal) is never below it. What this module adds is the grid:

* the time between two event points is a *segment*; each gets its share of the N steps. When the
  horizon T is searched, only the segments where the solver's pattern brakes are stretched; a
  segment the pattern cruises through at a speed limit keeps its duration (its length over that
  speed is fixed: stretching it with T, as fractions of T do, leaves no T feasible when the train
  cruises through two event points);
* ``refine``: the coarse steps around each of the pattern's jerk switches cut into ``refine`` fine
  steps (aligned to the coarse grid, not to the switch: the switch lies anywhere in a fine step),
  so a long approach converges without a fine grid everywhere.

Where the segments start (the pattern's crossing times) and where to refine is taken from the
solver: that only decides how tight the bound is, never whether it is an admissible trajectory.
"""
from __future__ import annotations

import math

import numpy as np

from tests.test_stopping_lp import _regions, min_feasible_time, node_lp_feasible


def crossing_times(p, events):
    """When the pattern ``p`` passes each event point [s], to 1e-12 s (bisection on its cubic piece)."""
    t, x, v, a, j = (np.asarray(q) for q in (p.t_s, p.x_m, p.v_ms, p.a_ms2, p.j_ms3))
    out = []
    for e in events:
        i = min(int(np.searchsorted(x, e, side="right")) - 1, j.size - 1)
        lo, hi = 0.0, t[i + 1] - t[i]
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if x[i] + mid * (v[i] + mid * (a[i] / 2.0 + j[i] * mid / 6.0)) < e:
                lo = mid
            else:
                hi = mid
        out.append(t[i] + 0.5 * (lo + hi))
    return out


def segment_grid(p, events, caps, N, refine=1, with_switches=False):
    """The grid of the bound for pattern ``p``: unit steps per segment and which segments stretch.

    ``caps``: the speed cap of each segment. Returns (per segment: its duration in the pattern [s],
    its steps as fractions of it, whether it stretches with T: all but a cruise at the cap).
    ``with_switches``: a node also at each of the pattern's jerk switches (then the pattern itself is
    a point of the LP at its own duration).
    """
    T = p.duration_s
    edges = [0.0] + crossing_times(p, events) + [T]
    t_b = np.asarray(p.t_s)
    a_b = np.asarray(p.a_ms2)
    switches = t_b[1:-1]
    segments = []
    v_b = np.asarray(p.v_ms)
    for t0, t1, cap in zip(edges[:-1], edges[1:], caps):
        d = t1 - t0
        n = max(2, math.ceil(N * d / T))
        inside = (t_b[:-1] < t1) & (t_b[1:] > t0)  # pieces overlapping the segment
        a_in = np.concatenate([a_b[:-1][inside], a_b[1:][inside]])
        v_in = np.concatenate([v_b[:-1][inside], v_b[1:][inside]])
        stretch = bool(np.any(np.abs(a_in) > 1e-9) or np.any(v_in < cap - 1e-9))
        cut = set()
        if refine > 1:
            for s in switches[(switches > t0) & (switches < t1)]:
                c = min(int((s - t0) / d * n), n - 1)
                cut.update({max(c - 1, 0), c, min(c + 1, n - 1)})
        steps = []
        for i in range(n):
            steps += [1.0 / (n * refine)] * refine if i in cut else [1.0 / n]
        if with_switches:
            u = np.concatenate([[0.0], np.cumsum(steps)[:-1], (switches[(switches > t0) & (switches < t1)] - t0) / d, [1.0]])
            u = np.unique(u)
            steps = np.diff(u)[np.diff(u) > 1e-12]
        segments.append((d, np.asarray(steps) / np.sum(steps), stretch))
    if not any(s for _, _, s in segments):
        segments[-1] = segments[-1][:2] + (True,)
    return segments


def segment_lp(p, N, v0, X, J, decel_limits, speed_limits, *, refine=1, with_switches=False, stretch="braking"):
    """``feasible(T)``: is there an admissible trajectory of duration T on :func:`segment_grid`'s grid
    for pattern ``p`` (N coarse steps), its segments stretched or shrunk from the pattern's?

    ``stretch``: which segments take the difference T - (the pattern's): ``"braking"`` all but a
    cruise at the cap, in proportion; ``"last"`` the one ending at the stop only (a segment the
    pattern brakes through at its limit from its start has a fixed duration, longest and shortest).
    ``feasible`` raises RuntimeError when HiGHS neither solves nor refutes an LP in 20 s (it can stall
    on a rare one): the caller decides (the property test fails, the bisection calls it infeasible).
    """
    events, _, caps = _regions(v0, X, decel_limits, speed_limits)
    segments = segment_grid(p, events, caps, N, refine, with_switches)
    T_s = p.duration_s
    d = np.array([s[0] for s in segments])
    w = np.array([s[0] if s[2] else 0.0 for s in segments])
    if stretch == "last":
        w = np.zeros_like(d)
        w[-1] = 1.0
    w = w / w.sum()
    nodes = list(np.cumsum([s[1].size for s in segments])[:-1])

    def feasible(T):
        dur = d + (T - T_s) * w
        if np.any(dur <= 0.0):
            return False
        hs = np.concatenate([dj * s[1] for dj, s in zip(dur, segments)])
        return node_lp_feasible(T, hs / T, nodes, v0, X, J, decel_limits, speed_limits, time_limit=20.0)

    return feasible


def segment_lp_min_time(p, N, v0, X, J, decel_limits, speed_limits, *, refine=1, tol=2e-5, stretch="braking",
                        with_switches=False):
    """The bound's minimum time [s] (feasible; the infeasible end of the bisection within ``tol``).

    Raises RuntimeError when no T up to 5 % above the pattern's is feasible (the grid cannot follow).
    """
    proved = segment_lp(p, N, v0, X, J, decel_limits, speed_limits, refine=refine, stretch=stretch,
                        with_switches=with_switches)

    def feasible(T):  # an LP HiGHS stalls on counts as infeasible: the bound is a feasible T all the same
        try:
            return proved(T)
        except RuntimeError:
            return False

    T_s = p.duration_s
    T = min_feasible_time(feasible, T_s * (1.0 - 1e-4), T_s * (1.0 + 1e-3), tol, give_up=1.05 * T_s)
    if T is None:
        raise RuntimeError(f"no admissible trajectory on the grid up to 5 % above the pattern's {T_s:.3f} s")
    return T


def random_approach(rng):
    """One random approach, the same family as the MILP property test's: speed steps down and up and
    deceleration steps at event points at least 20 m apart. (v0, X, J, decel_limits, speed_limits)."""
    X = rng.uniform(120.0, 450.0)
    v0 = rng.uniform(6.0, 22.0)
    J = rng.uniform(0.35, 1.0)
    n_ev = int(rng.integers(1, 4))
    slots = np.arange(1, int((X - 20.0) // 20.0) + 1)
    grid = sorted(rng.choice(slots, size=min(n_ev, slots.size), replace=False))
    dl, sl = [(0.0, rng.uniform(0.45, 1.1))], [(0.0, v0 * rng.uniform(1.0, 1.15))]
    for g in grid:
        x = 20.0 * float(g) + rng.uniform(0.0, 5.0)
        if rng.random() < 0.5:
            dl.append((x, rng.uniform(0.45, 1.1)))
        else:
            sl.append((x, v0 * rng.uniform(0.3, 1.05)))
    return v0, X, J, dl, sl
