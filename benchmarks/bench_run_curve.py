"""Run-curve simulator throughput (issue 3).

Prints:
1. simulated run-steps per second (runs × grid steps / wall s) for batches of 1, 100 and 2,000 runs
   on a 3 km interstation at the default 1 m step;
2. the per-run cost of that interstation at batch 2,000 (target ≤ 0.5 ms per run on one core);
3. the minimum running time (ratio 100 %, nominal) of every interstation of the sample line, both
   directions, every train type, with the total wall time.

Run: ``python benchmarks/bench_run_curve.py`` (from the repository root).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner.line import testing  # noqa: E402
from planner.physics.track import make_track
from planner.physics.run_curve import simulate  # noqa: E402

REPEATS = 3


def interstation_3km():
    """A 3 km interstation with everything the integrator handles."""
    tt = testing.train_type(
        "B", length_m=160, rotating_mass_factor=0.08, davis_a_kN=6, davis_b_kN_per_kmh=0.05,
        davis_c_kN_per_kmh2=0.0011, max_accel_kmh_s=3.0, service_brake_kmh_s=2.5, stop_brake_kmh_s=3.2,
        speed_margin_kmh=3, traction=((0, 330), (35, 330), (70, 200), (110, 120), (140, 90)))
    line = testing.line(
        length_m=3200, stations=[100, 3100], max_speed_kmh=110, train_types=[tt],
        gradients=[(400, 1300, 12), (1300, 2100, -9), (2300, 2900, 5)],
        curves=[(700, 1000, 450), (2400, 2600, 600)],
        limits=[(1100, 1450, 65), (2500, 2700, 80)],
    )
    return line, tt


def best_wall(fn) -> tuple[float, float]:
    """Best wall and CPU seconds of REPEATS calls (CPU time shows the cost on a shared machine)."""
    best, cpu = float("inf"), float("inf")
    for _ in range(REPEATS):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return best, cpu


def main() -> None:
    line, tt = interstation_3km()
    track = make_track(line, "B", "S0", "S1")
    steps = len(track.s_m) - 1
    grid = np.array([1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2])
    print(f"3 km interstation: {track.length_m:.0f} m, {steps} steps of ≤ {track.settings.ds_m:g} m; "
          f"best of {REPEATS}, wall clock, one process")
    print(f"{'batch':>6} {'wall s':>9} {'cpu s':>9} {'run-steps/s':>13} {'ms/run':>9}")
    per_run_2000 = None
    for n in (1, 100, 2000):
        rng = np.random.default_rng(n)
        ratio = np.resize(grid, n)
        load = rng.uniform(0.0, 1.0, n)
        tf = rng.uniform(0.9, 1.0, n)
        wall, cpu = best_wall(lambda: simulate(track, tt, ratio, load=load, traction_factor=tf))
        print(f"{n:>6} {wall:>9.3f} {cpu:>9.3f} {n * steps / wall:>13,.0f} {wall / n * 1e3:>9.3f}")
        if n == 2000:
            per_run_2000, cpu_2000 = wall / n * 1e3, cpu / n * 1e3
    verdict = "meets" if per_run_2000 <= 0.5 else "misses"
    print(f"per-run cost of a 3 km interstation at batch 2,000: {per_run_2000:.3f} ms wall, "
          f"{cpu_2000:.3f} ms CPU ({verdict} the 0.5 ms target on wall time)")

    sample = ROOT / "lines" / "sample"
    try:
        import planner

        sl = planner.load_line(sample)
    except (ImportError, FileNotFoundError, OSError) as e:
        print(f"\nsample line: skipped ({e})")
        return
    print(f"\nminimum running times, sample line {sl.line_id} (ratio 100 %, load 0, traction 1.0)")
    t0 = time.perf_counter()
    rows = []
    for t in sl.train_types:
        for direction in ("down", "up"):
            for a, b in sl.interstations(direction):
                tr = make_track(sl, t.train_type, a.station_id, b.station_id)
                res = simulate(tr, t, 1.0)
                rows.append((t.train_type, direction, a.station_id, b.station_id, tr.length_m,
                             float(res.time_s[0]), float(res.energy_kwh[0])))
    wall = time.perf_counter() - t0
    print(f"{'type':<6}{'dir':<5}{'from':<6}{'to':<6}{'dist m':>9}{'time s':>9}{'kWh':>8}")
    for r in rows:
        print(f"{r[0]:<6}{r[1]:<5}{r[2]:<6}{r[3]:<6}{r[4]:>9.0f}{r[5]:>9.1f}{r[6]:>8.1f}")
    print(f"{len(rows)} interstation runs (single-run batches) in {wall:.2f} s wall")


if __name__ == "__main__":
    main()
