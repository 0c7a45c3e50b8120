"""Benchmark: the margin-time report of the sample line (``planner margins``), printing figures.

    python benchmarks/bench_margins.py                      # tables and closed loop computed here
    python benchmarks/bench_margins.py --tables T --closed-loop C   # reuse `planner tables` / `simulate` output

Prints wall and CPU time of the computation and of the HTML page, and the
report's headline figures. Figures only: nothing is asserted.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _cpu() -> float:
    """CPU seconds of this process and its finished children (joblib workers count once reaped)."""
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--line", default=str(ROOT / "lines" / "sample"))
    ap.add_argument("--tables", default=None)
    ap.add_argument("--closed-loop", default=None)
    ap.add_argument("--jobs", type=int, default=-1)
    a = ap.parse_args()

    from planner import load_line
    from planner.report.margins import compute_margins
    from planner.pages.margin_report import render_html, stop_markers

    line = load_line(a.line)
    t0, c0 = time.perf_counter(), _cpu()
    rep = compute_margins(line, tables_dir=a.tables, closed_loop_dir=a.closed_loop, n_jobs=a.jobs)
    t1, c1 = time.perf_counter(), _cpu()
    page = render_html(rep, stop_markers(line))
    t2, c2 = time.perf_counter(), _cpu()
    rows = rep.rows[rep.rows.scheduled_running_time_s.notna()]
    print(f"line {line.line_id}: {len(rep.rows)} legs x train type, {len(rows)} timetabled, "
          f"tables {rep.sources['tables_dataset']} read / {rep.sources['tables_computed']} computed, "
          f"closed loop from dataset: {rep.sources['closed_loop_dataset']}")
    print(f"  compute: {t1 - t0:6.1f} s wall, {c1 - c0:6.1f} s CPU (this process; {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f})")
    print(f"  HTML:    {t2 - t1:6.1f} s wall, {c2 - c1:6.1f} s CPU, {len(page) / 1e3:.0f} kB")
    print(f"  flags: {int(rows.infeasible.sum())} infeasible, {int(rows.tight.sum())} tight, "
          f"{int(rows.unreachable.sum())} unreachable, {int((~rows.supplement_met).sum())} below the rule")


if __name__ == "__main__":
    main()
