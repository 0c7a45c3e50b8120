"""Benchmark: solve time of one minimum-time stopping pattern (DESIGN §5, issue 5).

Prints the median (and 90th percentile) wall time per ``solve_stop`` call over a few
thousand seeded random station approaches with up to six event points (positions
where a deceleration or speed limit changes), split by the number of event points,
against the 0.5 ms target. Run: ``.venv/bin/python benchmarks/bench_stopping.py``.
"""
from __future__ import annotations

import random
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.stopping.pattern import decel_limit_profile, solve_stop  # noqa: E402

TARGET_MS = 0.5
N_CASES = 4000


def random_approach(rng: random.Random):
    """A station approach: 300-900 m from the TASC beacon, 40-110 km/h, gradients and restrictions."""
    X = rng.uniform(300.0, 900.0)
    v0 = rng.uniform(40.0, 110.0) / 3.6
    J = rng.uniform(0.4, 1.0)
    n_grad = rng.randint(0, 3)
    n_speed = rng.randint(0, 6 - n_grad)
    grads = [(0.0, rng.uniform(-10.0, 10.0))] + sorted(
        (rng.uniform(10.0, X - 10.0), rng.uniform(-15.0, 15.0)) for _ in range(n_grad)
    )
    adhesion = rng.uniform(2.5, 3.5) / 3.6
    dl = decel_limit_profile(3.6 / 3.6, adhesion, grads)
    sl = [(0.0, v0 * rng.uniform(1.0, 1.2))] + sorted(
        (rng.uniform(10.0, X - 10.0), rng.uniform(25.0, 100.0) / 3.6) for _ in range(n_speed)
    )
    return v0, X, J, dl, sl


def safe_side_cost(step_m: float = 0.25) -> dict:
    """Time the per-piece safe-side bound of the deceleration limit costs on the sample line.

    The train-averaged gradient is piecewise linear in the front's position;
    the patterns bound each linear piece by its least favourable value
    (:func:`planner.stopping.approach.gradient_steps`). The exact bound is approached
    from the safe side by cutting every piece into ``step_m`` slices, each at
    its own least favourable value (the duration converges to the exact
    bound's from above as the slices shrink); the optimistic slices (each at
    its most favourable value) bound it from below. Over every feasible
    pattern of the nightly sweep (2.5 … 3.5 km/h/s) prints the extra time of
    the per-piece bound against the fine one: sum, median, max.
    """
    import warnings

    import numpy as np

    from planner.stopping import approach
    from planner.physics import dynamics
    from planner.line.loader import load_line
    from planner.line.model import sign
    from planner.stopping.sweep import InfeasibleStopWarning, stop_sweep

    line = load_line(Path(__file__).resolve().parents[1] / "lines" / "sample")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InfeasibleStopWarning)
        results = stop_sweep(line, n_jobs=1)
    extra, bracket = [], []
    for r in results:
        tt = line.train_type(r.train_type)
        sg = sign(r.direction)
        X = r.approach_length_m
        knots, _ = approach._mean_gradient_knots(line, tt.length_m, r.direction, r.approach_start_m, X)
        xs = np.unique(np.concatenate([knots, np.arange(0.0, X, step_m)]))
        g = dynamics.running_gradient(line.gradients, r.approach_start_m + sg * xs, tt.length_m, sg) * 1000.0
        lo = [(float(x), float(v)) for x, v in zip(xs[:-1], np.minimum(g[:-1], g[1:]))]
        hi = [(float(x), float(v)) for x, v in zip(xs[:-1], np.maximum(g[:-1], g[1:]))]
        for a, p in zip(r.adhesion_ms2, r.patterns):
            if not p.feasible:
                continue
            fine = [approach.decel_limits(line, tt, r.direction, r.approach_start_m, X, a, gs)
                    for gs in (lo, hi)]
            q_lo, q_hi = (solve_stop(r.v_start_ms, X, jerk_max=r.jerk_max_ms3, decel_limits=dl,
                                     speed_limits=r.speed_limits) for dl in fine)
            if q_lo.feasible:
                extra.append(p.duration_s - q_lo.duration_s)
                bracket.append(q_lo.duration_s - q_hi.duration_s)
    ex = np.array(extra)
    print(f"  safe-side bound per piece vs {step_m:g} m slices (exact bound), {ex.size} patterns of the "
          f"sample sweep: extra time sum {ex.sum():.2f} s, median {np.median(ex):.4f} s, max {ex.max():.3f} s "
          f"(slices vs optimistic slices: max {max(bracket):.4f} s)")
    return {"n": int(ex.size), "sum_s": float(ex.sum()), "median_s": float(np.median(ex)), "max_s": float(ex.max())}


def main() -> None:
    rng = random.Random(12345)
    cases = [random_approach(rng) for _ in range(N_CASES)]
    by_events: dict[int, list[float]] = {}
    all_t: list[float] = []
    n_feasible = 0
    # warm-up (imports, caches)
    for c in cases[:50]:
        solve_stop(c[0], c[1], jerk_max=c[2], decel_limits=c[3], speed_limits=c[4])
    for v0, X, J, dl, sl in cases:
        t0 = time.perf_counter()
        p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
        dt = time.perf_counter() - t0
        n_ev = len({x for x, _ in dl[1:] + sl[1:] if x < X})
        by_events.setdefault(n_ev, []).append(dt)
        all_t.append(dt)
        n_feasible += p.feasible
    paper_t: list[float] = []
    gain: list[float] = []
    for v0, X, J, dl, sl in cases:
        t0 = time.perf_counter()
        q = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, rule="paper")
        paper_t.append(time.perf_counter() - t0)
        if q.feasible:
            p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
            gain.append(q.duration_s - p.duration_s)
    med = statistics.median(all_t) * 1e3
    p90 = statistics.quantiles(all_t, n=10)[-1] * 1e3
    print(f"bench_stopping: {N_CASES} random approaches ({n_feasible} feasible), up to 6 event points")
    print(f"  solve_stop median {med:.3f} ms, p90 {p90:.3f} ms per pattern (target <= {TARGET_MS} ms); "
          f"rule='paper' median {statistics.median(paper_t) * 1e3:.3f} ms")
    g = sorted(gain)
    print(f"  true minimum vs the paper's rule: faster on {sum(x > 1e-9 for x in g)} of {len(g)} patterns, "
          f"by up to {g[-1]:.3f} s (never slower: min {g[0]:+.2e} s)")
    for k in sorted(by_events):
        ts = by_events[k]
        print(f"    {k} event points: n={len(ts):4d}  median {statistics.median(ts) * 1e3:.3f} ms")
    safe_side_cost()


if __name__ == "__main__":
    main()
