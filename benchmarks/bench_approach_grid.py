"""Benchmark: what table (d)'s speed grid costs and what a coarser one would lose (issue 48).

Table (d) (``planner.tables.build.approach_table``) is the largest part of the 100x line's cold night: about
216 of its ~886 s of CPU. Its runs start from every speed on a 2 km/h grid (``APPROACH_SPEED_STEP_MS``), and the
vehicle interpolates linearly between them. This script builds the sample line's tables step (the nightly job's
[tables] settings, every leg, direction and train type, in this one process) on the 2 km/h grid and on a
coarser one (``--coarse``, 4 km/h by default: a multiple of it), in alternating pairs, and prints:

- the step's CPU time on each grid (``time.process_time``, median of the pairs);
- the coarse grid's error: its tables interpolated linearly at the fine grid's speeds in between, against the
  fine grid's own times there (table train and reference train, both phases, every ratio), as the vehicle
  would read them. Where both grids have a speed, the times must be the same bits (the runs are the same runs);
  otherwise the benchmark fails.

Run: ``.venv/bin/python benchmarks/bench_approach_grid.py [--pairs N] [--coarse KMH]``
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import planner  # noqa: E402
import planner.tables.build as build  # noqa: E402
from bench_reuse import tables_step  # noqa: E402
from planner.job.config import load_job  # noqa: E402
from planner.line.units import KMH  # noqa: E402

TOLERANCES_S = (0.05, 0.1, 0.5, 1.0)


def _run(line, job, step_kmh: float):
    build.APPROACH_SPEED_STEP_MS = step_kmh * KMH
    t0 = time.process_time()
    res = tables_step(line, job)
    return time.process_time() - t0, [r.approach for r in res]


def compare(fine: list, coarse: list) -> tuple[np.ndarray, np.ndarray]:
    """The coarse tables' interpolation errors [s] at the fine grid's in-between speeds, and those speeds [m/s]."""
    errs, speeds = [], []
    for a, c in zip(fine, coarse):
        if a is None or c is None:
            if (a is None) != (c is None):
                raise SystemExit("bench_approach_grid: a leg has table (d) on one grid only")
            continue
        vf, vc = a.speeds_ms, c.speeds_ms
        ratio = int(round((vc[1] - vc[0]) / (vf[1] - vf[0])))
        between = (np.arange(vf.size) % ratio != 0) & (vf <= vc[-1])  # every ratio-th fine speed is a coarse one
        for tf, tc in ((a.time_s, c.time_s), (a.ref_time_s, c.ref_time_s)):
            k = min(tc.shape[1], tf[:, ::ratio].shape[1])
            if not np.array_equal(tf[:, ::ratio][:, :k], tc[:, :k]):
                raise SystemExit("bench_approach_grid: the two grids' runs from the same speed differ")
            for p in range(tf.shape[0]):
                for j in range(tf.shape[2]):
                    f = np.interp(vf[between], vc, tc[p, :, j])
                    errs.append(np.abs(f - tf[p, between, j]))
                    speeds.append(vf[between])
    return np.concatenate(errs), np.concatenate(speeds)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=2)
    ap.add_argument("--coarse", type=float, default=4.0, help="the coarser grid's step [km/h] (default 4)")
    a = ap.parse_args(argv)
    fine_kmh = build.APPROACH_SPEED_STEP_MS / KMH
    if a.coarse <= fine_kmh or abs(a.coarse / fine_kmh - round(a.coarse / fine_kmh)) > 1e-9:
        ap.error(f"--coarse must be a multiple of the grid's {fine_kmh:g} km/h above it (4, 6, 8 ...)")
    job = load_job(ROOT / "jobs" / "nightly.toml")
    line = planner.load_line(ROOT / "lines" / "sample")
    tables_step(line, job)  # warm: imports, compiled kernels
    cpu: dict[float, list[float]] = {fine_kmh: [], a.coarse: []}
    got: dict[float, list] = {}
    for _ in range(a.pairs):
        for kmh in (fine_kmh, a.coarse):
            s, got[kmh] = _run(line, job, kmh)
            cpu[kmh].append(s)
    build.APPROACH_SPEED_STEP_MS = fine_kmh * KMH
    err, v = compare(got[fine_kmh], got[a.coarse])
    f, c = statistics.median(cpu[fine_kmh]), statistics.median(cpu[a.coarse])
    print(f"bench_approach_grid: the sample's tables step, CPU (median of {a.pairs}): {f:.2f} s on the {fine_kmh:g} "
          f"km/h grid, {c:.2f} s on {a.coarse:g} km/h ({(f - c) / f:.0%} less)")
    print(f"bench_approach_grid: {a.coarse:g} km/h interpolated at the {fine_kmh:g} km/h speeds between its own "
          f"({err.size} table times): median error {np.median(err):.3f} s, 99th percentile "
          f"{np.percentile(err, 99):.3f} s, largest {err.max():.2f} s at {v[err.argmax()] / KMH:.0f} km/h")
    print("bench_approach_grid: share of those times off by more than "
          + ", ".join(f"{t:g} s: {np.mean(err > t):.1%}" for t in TOLERANCES_S))
    return 0


if __name__ == "__main__":
    sys.exit(main())
