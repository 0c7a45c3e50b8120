"""Route conflicts on the sample line's whole-day timetable: what the check finds and how long it takes.

Run ``python benchmarks/bench_network.py [LINE_DIR] [--n-jobs N]``. Prints the time to load the line, to
simulate the run curves (one lock-step batch of target-speed ratios per interstation), to check the timetable
(routes, arrival prediction, windows, conflicts; target ≤ 10 s), to write the datasets, and the summary of
what was found, for run curves at the ratio that meets the schedule and, for comparison, ratio 1.0 stretched.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner import load_line  # noqa: E402
from planner.datasets.conflicts import check_conflicts, write_conflicts  # noqa: E402
from planner.network.arrivals import SimulatorCurves, interstation_keys  # noqa: E402
from planner.network.windows import BlockingParams  # noqa: E402

TARGET_S = 10.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("line", nargs="?", default=str(ROOT / "lines" / "sample"))
    ap.add_argument("--n-jobs", type=int, default=2, help="processes for the run-curve simulations")
    args = ap.parse_args()
    if not (Path(args.line) / "nodes.parquet").exists():
        print(f"{args.line}: no track network (nodes.parquet); nothing to benchmark")
        return 0

    t0 = time.perf_counter()
    line = load_line(args.line)
    t_load = time.perf_counter() - t0
    params = BlockingParams()
    keys = sorted(set(interstation_keys(line.trains)))
    curves = SimulatorCurves(line, n_jobs=args.n_jobs)
    t0 = time.perf_counter()
    curves.prepare(keys)
    t_curves = time.perf_counter() - t0

    t0 = time.perf_counter()
    rep = check_conflicts(line, params, curves=curves)
    t_check = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        files = write_conflicts(rep, d)
        t_write = time.perf_counter() - t0

    stretch = SimulatorCurves(line, mode="stretch")
    stretch._tables = curves._tables  # the ratio-1.0 row is in the same batches
    rep_s = check_conflicts(line, params, curves=stretch)

    n_calls = sum(len(t.calls) for t in line.trains)
    print(f"line {line.line_id}: {len(line.trains)} trains, {n_calls} calls, "
          f"{len(line.network.nodes)} nodes, {len(line.network.edges)} edges, {len(line.signals)} signals")
    print(f"blocking parameters: setting {params.setting_s:g} s, approach {params.approach_s:g} s, "
          f"release {params.release_s:g} s")
    print(f"load line            {t_load:7.2f} s")
    print(f"run curves           {t_curves:7.2f} s  ({len(keys)} interstations × {len(curves.ratios)} ratios, "
          f"ds {curves.ds_m:g} m, {args.n_jobs} process(es))")
    print(f"check timetable      {t_check:7.2f} s  (target ≤ {TARGET_S:g} s: {'met' if t_check <= TARGET_S else 'MISSED'})")
    print(f"write datasets       {t_write:7.2f} s  ({len(files)} files)")
    print(f"total                {t_load + t_curves + t_check + t_write:7.2f} s")
    print()
    print("run curves at the ratio that meets the schedule:")
    for msg in rep.summary_lines():
        print("  " + msg)
    c = rep.conflicts
    if len(c):
        by_res = c.groupby("resource_id")["conflict_id"].nunique().sort_values(ascending=False)
        print("  conflicts per resource: " + ", ".join(f"{k} {v}" for k, v in by_res.head(8).items()))
    print()
    s = rep_s.summary
    print(f"ratio 1.0 stretched uniformly (first approximation): {s['conflicts']} conflicts, "
          f"{s['deadlocks']} deadlocks, delay total {s['delay_total_s']:.1f} s, largest {s['delay_max_s']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
