"""Benchmark: the time-keeping mode (docs/design.md §4) in closed loop on the whole sample line (issue 14).

The on-board logic has the vehicle's nominal model (load 0, traction 1.0); the
plant is the real train of the scenario (``perturbed``: load 1.0, traction × 0.9).
For every interstation, direction and train type, designated running times from
the tables' minimum to the minimum + 60 s (``--step`` apart) are driven through
the one integrator. Prints |arrival error| median / p95 / p99 / max over the runs the
plant can make (designated ≥ the plant's own minimum) and the worst single run, |stop error| max (where
the plant came to a stand − the marker), CPU time, the worst interstations, and
the issue's targets (max arrival error ≤ 0.5 s, stop error ≤ 0.2 m). The default
sweep is issue 37's: 1 s steps (3,488 feasible runs perturbed), where one run (E8 down
MDR→TKD, 173 s) once arrived 1.12 s early: a trim shed that ran above a restriction's
braking curve (``tests/test_timekeeping_drive.py`` pins it). Every error above 0.04 s is E6's, the
sample's one sawtooth vehicle (measured before the fix below, 1 s steps: perturbed 3,488 feasible runs, max 0.389 s,
p99 0.235 s, E10 max 0.040 s, E8 0.000 s; nominal 4,026 runs, max 0.643 s, p99 0.236 s, E10 and
E8 0.000 s). The nominal outlier (E6 down MDR→TKD, designated 160 s, 0.643 s late) was its
coasting band: late from 1781 m (the target infeasible, so "flat out"), it was in its band at
17.2 m/s and coasted 300 m on −4 ‰ without reaching the band's lower edge (16.67 m/s), so it never
powered again (with the band narrowed to 0.3 m/s the runs at 158-162 s kept time within 0.011 s,
with constant-speed control exactly). Now a lifted cap (flat out) ends the coasting, so the train
powers from there, and the flat-out look-ahead powers from the measured state likewise
(``tests/test_sawtooth_catch_up.py``). Measured after, 1 s steps: nominal max 0.407 s, p99 0.234 s
(5 of E6's 1,342 runs changed: MDR→TKD 159-161 s, KTA→AOB 131 s, NKN→OHS 120 s; 160 s now
0.053 s early); perturbed max 0.389 s, p99 0.235 s, as before (E6 median 0.079 → 0.080 s).
The largest left (E6 down AOB→SNZ, 171 s) is unchanged by it. Ending the band on every raised cap instead changed
1,139 of E6's nominal runs (762 worse, median 0.071 → 0.090 s); on a cap raised to the line's
speed, 272 (185 worse): the cap aims the band's middle, so a finite raise keeps the band.

Run: ``.venv/bin/python benchmarks/bench_timekeeping.py [--scenarios perturbed,nominal]
[--step 1] [--jobs N]``
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.tables.closed_loop import overall, summary_row
from planner.datasets.closed_loop import run_closed_loop  # noqa: E402
from planner.tables.build import build_tables
from planner.datasets.tables import write_tables  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="perturbed,nominal")
    ap.add_argument("--step", type=float, default=1.0, help="designated-time step [s]")
    ap.add_argument("--jobs", type=int, default=-1)
    ap.add_argument("--worst", type=int, default=5)
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    with tempfile.TemporaryDirectory() as tmp:
        write_tables(build_tables(line, ratios=[1.0, 0.9], n_jobs=args.jobs), tmp)  # only the minimum is used
        for sc in [s for s in args.scenarios.split(",") if s]:
            t0 = time.perf_counter()
            res = run_closed_loop(line, tmp, scenario=sc, mode="timekeeping", step_s=args.step, n_jobs=args.jobs)
            wall = time.perf_counter() - t0
            st = overall(res)
            print(f"bench_timekeeping {sc}: {st['n_runs']} runs ({st['n_feasible']} feasible for the plant) over "
                  f"{len(res)} interstation x direction x type, {wall:.1f} s wall")
            print(f"  |arrival error| median {st['median_abs_error_s']:.3f} s, p95 {st['p95_abs_error_s']:.3f} s, "
                  f"max {st['max_abs_error_s']:.3f} s; |stop error| max {st['max_abs_stop_error_m']:.4f} m; "
                  f"infeasible runs: worst arrival after the plant's minimum {st['infeasible_excess_max_s']:.3f} s")
            err = np.concatenate([np.abs(r.error_s[r.feasible]) for r in res])
            worst = max(((float(np.abs(e)), r, float(d)) for r in res
                         for e, d, f in zip(r.error_s, r.designated_s, r.feasible) if f), key=lambda x: x[0])
            print(f"  |arrival error| over the {err.size} feasible runs ({args.step:g} s steps): "
                  f"p99 {np.percentile(err, 99):.3f} s, max {err.max():.3f} s (worst run: {worst[1].train_type} "
                  f"{worst[1].direction} {worst[1].origin}->{worst[1].destination}, designated {worst[2]:.0f} s)")
            for tt in sorted({r.train_type for r in res}):
                o = overall([r for r in res if r.train_type == tt])
                print(f"  {tt}: median {o['median_abs_error_s']:.3f} s, max {o['max_abs_error_s']:.3f} s")
            rows = sorted(((summary_row(r), r) for r in res), key=lambda x: -x[0]["max_abs_error_s"])
            print("  worst: " + "; ".join(f"{r.train_type} {r.origin}->{r.destination} {s['max_abs_error_s']:.3f} s"
                                          for s, r in rows[: args.worst]))
            ok = st["max_abs_error_s"] <= 0.5 and st["max_abs_stop_error_m"] <= 0.2
            print(f"  target (max arrival error <= 0.5 s, stop error <= 0.2 m): {'met' if ok else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
