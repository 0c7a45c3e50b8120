"""Benchmark: the stopping solver against the admissible-trajectory LP bound on random approaches (issue 37).

The same 40 seeded approaches as ``tests/test_stopping_bound.py`` (speed steps down and up, deceleration
steps), the bound's minimum time by bisection (to 2e-5 s) on two grids of 400 coarse steps, the steps
around the pattern's jerk switches cut 8x:

* *holding the pattern* (a node also at each of its jerk switches): the worst excess of the solver over
  this bound (positive would mean an admissible trajectory is faster than the solver);
* *independent* (no node at the solver's switches) at 200, 400 and 800 steps: how far above the solver
  the bound still is, and how many patterns it cannot follow (a segment braked at its limit from its
  start has one duration, which an event node at the pattern's crossing time does not leave room for).

Figures only, CPU time (process), nothing asserted. ``python benchmarks/bench_stop_bound.py``.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.stop_bound import segment_lp_min_time  # noqa: E402
from tests.test_stopping_bound import CASES, REFINE  # noqa: E402


def bound(p, case, N, **kw):
    """The bound's minimum time, stretching the braking segments, else the last only; NaN if neither."""
    for stretch in ("braking", "last"):
        try:
            return segment_lp_min_time(p, N, *case, refine=REFINE, stretch=stretch, **kw)
        except RuntimeError:
            continue
    return math.nan


def main() -> None:
    t0 = time.process_time()
    excess, gaps = [], {200: [], 400: [], 800: []}
    for i, (p, case) in enumerate(CASES):
        T = p.duration_s
        held = bound(p, case, 400, with_switches=True)
        excess.append(T - held)
        row = [bound(p, case, N) - T for N in gaps]
        for N, g in zip(gaps, row):
            gaps[N].append(g)
        print(f"case {i:2d}: {T:8.3f} s, {len(case[3]) + len(case[4]) - 2} events; solver - bound(holding) "
              f"{T - held:+.6f} s; independent bound - solver " + " ".join(f"{g:+.5f}" for g in row), flush=True)
    print(f"\n{len(CASES)} cases; worst excess of the solver over the bound holding the pattern: {max(excess):+.6f} s")
    for N, g in gaps.items():
        ok = [x for x in g if not math.isnan(x)]
        print(f"independent grid, {N} steps: followed {len(ok)}/{len(g)}, bound - solver min {min(ok):+.6f} "
              f"median {sorted(ok)[len(ok) // 2]:+.6f} max {max(ok):+.6f} s")
    print(f"CPU {time.process_time() - t0:.0f} s")


if __name__ == "__main__":
    main()
