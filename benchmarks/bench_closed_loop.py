"""Benchmark: closed-loop arrival errors of the on-board modes on the whole sample line (issue 4).

Builds the running-time tables (load 0, nominal traction, default ratio grid) for
every interstation, direction and train type, then runs the closed loop for the
designated times minimum … minimum + 60 s in 1 s steps, for each mode
(``nearest``, ``interpolate``, ``adaptive``) and scenario (``nominal``,
``perturbed``: load 1.0, traction × 0.9, the tables unchanged). Prints the
median / 95th percentile / maximum |arrival error| over feasible runs per
mode × scenario, then per train type, the worst interstations, and the issue's
targets (nearest: max ≤ 2 s nominal, ≤ 3 s perturbed; better mode: median ≤ 0.3 s,
max ≤ 1 s in both).

Slow-ish (a few minutes on 2 cores): it is the whole proof, 66 interstation
tasks × 61 designated times × modes × scenarios.

Run: ``.venv/bin/python benchmarks/bench_closed_loop.py [--modes nearest,adaptive]
[--scenarios nominal] [--jobs N] [--tables DIR] [--worst 5]``
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
from planner.tables.eval_points import evaluation_points, interstation_length_m  # noqa: E402
from planner.line.model import DIRECTIONS  # noqa: E402
from planner.tables.build import build_tables
from planner.datasets.tables import write_tables  # noqa: E402

TARGETS = {  # (mode, scenario) -> (median bound, max bound) [s], issue 4
    ("nearest", "nominal"): (None, 2.0),
    ("nearest", "perturbed"): (None, 3.0),
    ("interpolate", "nominal"): (0.3, 1.0),
    ("interpolate", "perturbed"): (0.3, 1.0),
    ("adaptive", "nominal"): (0.3, 1.0),
    ("adaptive", "perturbed"): (0.3, 1.0),
}


def _fmt(st: dict) -> str:
    return (f"{st['median_abs_error_s']:7.3f} {st['p95_abs_error_s']:7.3f} {st['max_abs_error_s']:7.3f}"
            f"   {st['n_feasible']:5d}/{st['n_runs']:<5d}")


def last_point_distances(line) -> list[float]:
    """Distance from the last evaluation point to the arrival stop marker, every interstation [m]."""
    out = []
    for d in DIRECTIONS:
        for a, b in line.interstations(d):
            pts = evaluation_points(line, a.station_id, b.station_id)
            out.append(interstation_length_m(line, a.station_id, b.station_id) - pts[-1].s_m)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--modes", default="nearest,interpolate,adaptive")
    ap.add_argument("--scenarios", default="nominal,perturbed")
    ap.add_argument("--jobs", type=int, default=-1)
    ap.add_argument("--tables", type=Path, default=None,
                    help="reuse tables already built with `planner tables` into this folder")
    ap.add_argument("--worst", type=int, default=5, help="list this many worst interstations per case")
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    modes = [m for m in args.modes.split(",") if m]
    scenarios = [s for s in args.scenarios.split(",") if s]
    dist = last_point_distances(line)
    print(f"bench_closed_loop: sample line, last evaluation point {min(dist):.0f}-{max(dist):.0f} m "
          f"before the arrival stop marker (median {np.median(dist):.0f} m)")
    with tempfile.TemporaryDirectory() as tmp:
        tables_dir = args.tables
        if tables_dir is None:
            tables_dir = Path(tmp)
            t0 = time.perf_counter()
            write_tables(build_tables(line, n_jobs=args.jobs), tables_dir)
            print(f"  tables built in {time.perf_counter() - t0:.1f} s")
        results = {}
        for mode in modes:
            for sc in scenarios:
                t0 = time.perf_counter()
                results[(mode, sc)] = run_closed_loop(line, tables_dir, scenario=sc, mode=mode, n_jobs=args.jobs)
                print(f"  closed loop {mode:11s} {sc:9s} {time.perf_counter() - t0:6.1f} s", flush=True)

    header = f"  {'mode':11s} {'scenario':9s} {'type':4s}  median     p95     max  feasible/runs"
    print("\n|arrival error| over feasible runs [s]")
    print(header)
    for (mode, sc), res in results.items():
        print(f"  {mode:11s} {sc:9s} {'all':4s} " + _fmt(overall(res)))
    print("\nper train type")
    print(header)
    for (mode, sc), res in results.items():
        for tt in sorted({r.train_type for r in res}):
            print(f"  {mode:11s} {sc:9s} {tt:4s} " + _fmt(overall([r for r in res if r.train_type == tt])))
    if args.worst > 0:
        print(f"\nworst {args.worst} interstations per case (max |error| [s], median, infeasible runs)")
        for (mode, sc), res in results.items():
            rows = sorted(((summary_row(r), r) for r in res), key=lambda x: -x[0]["max_abs_error_s"])
            cells = [f"{r.train_type} {r.origin}->{r.destination} {s['max_abs_error_s']:.2f}"
                     f" (med {s['median_abs_error_s']:.2f}, inf {s['n_runs'] - s['n_feasible']})"
                     for s, r in rows[: args.worst]]
            print(f"  {mode:11s} {sc:9s} " + "; ".join(cells))
    print("\ntargets (issue 4)")
    for (mode, sc), res in results.items():
        med_b, max_b = TARGETS.get((mode, sc), (None, None))
        st = overall(res)
        ok_med = med_b is None or st["median_abs_error_s"] <= med_b
        ok_max = max_b is None or st["max_abs_error_s"] <= max_b
        want = " and ".join(x for x in (f"median <= {med_b} s" if med_b else "",
                                         f"max <= {max_b} s" if max_b else "") if x)
        print(f"  {mode:11s} {sc:9s} {want or 'no target':28s} -> {'met' if ok_med and ok_max else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
