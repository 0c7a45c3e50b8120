"""Benchmark: closed-loop arrival error on a long line without beacons, before and after the fill interval.

A 106 km line of its own (made in memory with :mod:`planner.line.testing`): stations at 0.5, 60.5
and 105.5 km (legs of 60 and 45 km), gradients of −3 and +4 ‰ alternating every 10 km, three
speed restrictions (90, 80, 95 km/h) with curves, line maximum 130 km/h, **no beacons**. Two train
types: ``EMU`` (constant-speed cruise, 130 km/h, 300 kN) and ``SAW`` (sawtooth, 120 km/h, 10 km/h
coasting band, 200 kN). For every leg and type: the tables (default ratio grid) with evaluation
points as before issue 33 (``dep`` and ``dep+200`` only) and with the fill interval of
``[tables] eval_auto_s`` seconds (default 30 s: the distance run in 30 s at the leg's maximum), then
the closed loop (designated times minimum … minimum + 60 s, modes nearest and adaptive, scenarios
nominal and perturbed = load 1.0, traction × 0.9). Prints the max |arrival error| over feasible
runs per leg, scenario and mode, the number of evaluation points and the table build's CPU time.

Run: ``.venv/bin/python benchmarks/bench_eval_auto.py [--auto 30,15] [--types EMU]``
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner.line import testing  # noqa: E402
from planner.tables.build import interstation_tables  # noqa: E402
from planner.tables.closed_loop import closed_loop_batch  # noqa: E402
from planner.tables.eval_points import DEFAULT_AUTO_S  # noqa: E402
from planner.tables.ratios import ratio_grid  # noqa: E402

LEGS = (("S0", "S1"), ("S1", "S2"), ("S2", "S1"))


def long_line():
    """The 106 km beacon-less line of the module doc."""
    emu = testing.train_type(
        "EMU", length_m=200, empty_mass_t=320, full_load_mass_t=150, rotating_mass_factor=0.08, max_speed_kmh=130,
        max_accel_kmh_s=3.0, davis_a_kN=5, davis_b_kN_per_kmh=0.036, davis_c_kN_per_kmh2=0.0036,
        service_brake_kmh_s=3.6, stop_brake_kmh_s=3.9, jerk_limit_kmh_s2=7.2,
        traction=((0, 300), (40, 300), (130, 90)))
    saw = testing.train_type(
        "SAW", length_m=120, empty_mass_t=200, full_load_mass_t=90, rotating_mass_factor=0.1, max_speed_kmh=120,
        max_accel_kmh_s=2.5, davis_a_kN=3, davis_b_kN_per_kmh=0.02, davis_c_kN_per_kmh2=0.002,
        service_brake_kmh_s=3.5, stop_brake_kmh_s=3.5, cruise="sawtooth", coast_band_kmh=10,
        traction=((0, 200), (35, 200), (120, 60)))
    grads = [(5000 + 10000 * i, 9000 + 10000 * i, 4.0 if i % 2 else -3.0) for i in range(10)]
    return testing.line(length_m=106000, stations=[500, 60500, 105500], max_speed_kmh=130, gradients=grads,
                        limits=[(20000, 21500, 90), (47000, 48000, 80), (80000, 82000, 95)],
                        curves=[(20000, 21500, 600), (47000, 48000, 500)], train_types=[emu, saw], line_id="long")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--auto", default=f"0,{DEFAULT_AUTO_S:g}", help="eval_auto_s values; 0 = before (no fill)")
    ap.add_argument("--types", default="EMU,SAW")
    a = ap.parse_args()
    line = long_line()
    grid = ratio_grid("1.0:0.7:0.1,0.7:floor:0.05", line_max_speed_ms=line.max_speed_ms)
    worst: dict[tuple[float, str, str], float] = {}
    print("eval_auto_s type leg        points  nominal nearest / adaptive  perturbed nearest / adaptive  "
          "max |error| [s]  tables CPU [s]")
    for auto in (float(x) for x in a.auto.split(",")):
        for tt in a.types.split(","):
            for o, d in LEGS:
                t0 = time.process_time()
                tab = interstation_tables(line, tt, o, d, grid, eval_auto_s=auto or None)
                cpu = time.process_time() - t0
                res = closed_loop_batch(line, tt, tab.onboard(), scenarios=["nominal", "perturbed"],
                                        modes=["nearest", "adaptive"])
                e = {(r.scenario, r.mode): float(np.max(np.abs(r.error_s[r.feasible]))) for r in res}
                for (sc, m), v in e.items():
                    worst[(auto, sc, m)] = max(worst.get((auto, sc, m), 0.0), v)
                print(f"{auto:>11g} {tt:<4} {o}->{d}  {len(tab.points):>6}  "
                      f"{e['nominal', 'nearest']:>15.2f} / {e['nominal', 'adaptive']:<8.2f} "
                      f"{e['perturbed', 'nearest']:>17.2f} / {e['perturbed', 'adaptive']:<8.2f}  {cpu:>26.1f}",
                      flush=True)
    print("\nworst over legs and types, max |arrival error| [s]:")
    for (auto, sc, m), v in sorted(worst.items()):
        print(f"  eval_auto_s {auto:>4g}  {sc:<9} {m:<8} {v:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
