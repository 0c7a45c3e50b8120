"""Benchmark: the whole default station-approach sweep of the sample line (``make bench``).

Prints the sweep's wall time, how many patterns it solved (and how many are
infeasible), the median ``solve_stop`` time on the sample's own approaches and
the largest time lost against the best adhesion level. Figures only; nothing
is asserted.
"""
from __future__ import annotations

import math
import statistics
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.line.loader import load_line  # noqa: E402
from planner.stopping.pattern import solve_stop  # noqa: E402
from planner.stopping.sweep import InfeasibleStopWarning, stop_sweep  # noqa: E402


def sweep_sample_line(n_jobs: int = -1) -> dict:
    """Time the whole default sweep of the sample line and print the figures (used by ``make bench``).

    Returns
    -------
    dict
        ``approaches``, ``patterns``, ``infeasible``, ``wall_s``, ``solve_median_ms``.
    """
    root = Path(__file__).resolve().parents[1] / "lines" / "sample"
    line = load_line(root)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InfeasibleStopWarning)
        results = stop_sweep(line, n_jobs=n_jobs)
    wall = time.perf_counter() - t0
    # solve time alone, from the approaches as set up (the simulation of v_start dominates the sweep)
    solves = []
    for r in results:
        for a, dl in zip(r.adhesion_kmh_s, r.decel_limits):
            if not dl:
                continue
            t1 = time.perf_counter()
            solve_stop(r.v_start_ms, r.approach_length_m, jerk_max=r.jerk_max_ms3, decel_limits=dl,
                       speed_limits=r.speed_limits)
            solves.append(time.perf_counter() - t1)
    n_pat = sum(len(r.patterns) for r in results)
    n_inf = sum(len(r.patterns) - r.n_feasible for r in results)
    lost = [t for r in results for t in r.time_lost_s if not math.isnan(t)]
    med = statistics.median(solves) * 1e3 if solves else math.nan
    print(f"  sample line sweep: {len(results)} approaches x {len(results[0].adhesion_kmh_s) if results else 0} "
          f"adhesion levels = {n_pat} patterns ({n_inf} infeasible) in {wall:.2f} s wall "
          f"(n_jobs={n_jobs}); solve_stop median {med:.3f} ms on these approaches; "
          f"time lost vs best adhesion up to {max(lost) if lost else math.nan:.2f} s")
    return {"approaches": len(results), "patterns": n_pat, "infeasible": n_inf, "wall_s": wall,
            "solve_median_ms": med}


if __name__ == "__main__":
    sweep_sample_line(n_jobs=int(sys.argv[1]) if len(sys.argv) > 1 else -1)
