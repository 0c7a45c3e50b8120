"""Benchmark: running-time tables (a) and (b) for the whole sample line.

Every interstation, both directions, every train type, default ratio grid,
joblib over all cores (target ≤ 30 s wall time on the 2-core machine).
Prints wall time, the parent's CPU time and the table sizes; pass ``--jobs N``
to change the process count, ``--serial-cpu`` to also time one process
(the CPU cost independent of other load on the machine).

Run: ``.venv/bin/python benchmarks/bench_tables.py``
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.tables.build import build_tables
from planner.datasets.tables import write_tables  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=-1)
    ap.add_argument("--serial-cpu", action="store_true")
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    t0 = time.perf_counter()
    results = build_tables(line, n_jobs=args.jobs)
    t_build = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as d:
        t1 = time.perf_counter()
        files = write_tables(results, d)
        t_write = time.perf_counter() - t1
    n_a = sum(len(r.ratios) for r in results)
    n_b = sum(r.remaining_s.size for r in results)
    n_x = sum(len(r.points) for r in results)
    print(f"bench_tables: sample line, {len(results)} interstation x direction x train type tasks, "
          f"{n_x} evaluation points, {len(results[0].ratios)} ratios")
    print(f"  table (a) rows: {n_a}, table (b) rows: {n_b}, files: {len(files)}")
    print(f"  wall time build: {t_build:.2f} s (n_jobs={args.jobs}, {os.cpu_count()} cores), write: {t_write:.2f} s")
    print(f"  target: <= 30 s wall on 2 cores -> {'OK' if t_build + t_write <= 30 else 'OVER'}")
    try:
        print(f"  load average during run: {os.getloadavg()[0]:.1f}")
    except OSError:
        pass
    if args.serial_cpu:
        c0 = time.process_time()
        build_tables(line, n_jobs=1)
        print(f"  CPU time, one process: {time.process_time() - c0:.2f} s")


if __name__ == "__main__":
    main()
