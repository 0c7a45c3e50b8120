"""Train types from public parameters, typed in by hand (railway units), and a long steep line of our own.

Figures as published (rounded where noted); what the sources do not give is marked ``assumed``:

- ``OSRD_FAST``: OSRD's fast test rolling stock (tests/data/rolling_stocks/fast_rolling_stock.json):
  400 m, 900 t, 80 m/s (288 km/h), inertia coefficient 1.05, comfort acceleration 0.25 m/s²
  (traction comfort: the acceleration cap), const_gamma 0.5 m/s² (its brake), Davis A 5400 N,
  B 200 N/(m/s), C 12 N/(m/s)²; its effort curve at 0, 5, 10, 15, 20, 22, 27, 32, 37, 42, 47, 52,
  57, 62, 67, 72, 77 m/s (kN, rounded to 0.1), held flat to 300 km/h. No braking comfort in OSRD:
  the importer's 3.3 km/h/s.
- ``OSRD_FAST_095``: the same with a 0.95 m/s² brake (the variant the issue ran).
- ``OSRD_SLOW`` and ``OSRD_SHORT``: OSRD's slow test rolling stocks (slow_rolling_stock.json,
  short_slow_rolling_stock.json): the fast stock's mass, inertia, Davis coefficients, comfort
  acceleration, const_gamma 0.5 m/s² and effort curve, but a maximum of 10 m/s (36 km/h), 400 m
  and 15 m long.
- ``TR_DMU``: TrainRuns.jl's regional train (Siemens Desiro Classic, test/data/trains/local.yaml):
  41.7 m, 68 t + 20 t load limit, 120 km/h, rotation mass 1.08, a_braking 0.4253 m/s²; effort
  curve sampled at the published points where it bends (kN). Resistance as Davis ``assumed``:
  A = (3.0 + 1.4) ‰ of the weight, C 0.0004 kN/(km/h)².
- ``TR_IC``: TrainRuns.jl's Intercity 2 (test/data/trains/longdistance.yaml): Traxx P160 85 t +
  4 × 50 t + 58 t = 343 t, 18.9 + 4 × 26.8 + 27.27 = 153.37 m, 160 km/h, 300 kN to 66 km/h then
  the published curve (kN at 80, 100, 120, 140, 160 km/h). Brake 0.5 m/s² ``assumed`` (not in the file).
- ``TR_FREIGHT``: TrainRuns.jl's freight (test/data/trains/freight.yaml): DB V90 80 t + 10 loaded
  Facs 124 (25 t + 59 t) = 920 t, 14.32 + 10 × 19.04 = 204.72 m, 80 km/h; the V90's effort every
  10 km/h (kN). Base resistance 2.2 ‰ (loco) and 1.4 ‰ (wagons) as Davis A; brake 0.225 m/s²
  (what the issue's freight braked at). The whole consist is its mass (no passenger load).
"""
from __future__ import annotations

from pathlib import Path

from planner.line import testing

G = 9.80665


def _ms(v_ms: list[float]) -> list[float]:
    return [v * 3.6 for v in v_ms]


_FAST_V = _ms([0, 5, 10, 15, 20, 22, 27, 32, 37, 42, 47, 52, 57, 62, 67, 72, 77]) + [300.0]
_FAST_F = [441.7, 439.5, 435.7, 427.8, 400.0, 351.0, 347.2, 346.9, 344.4, 334.3, 313.6, 283.6, 250.6, 222.7,
           204.7, 196.0, 192.9, 192.9]


def osrd_fast(name: str = "OSRD_FAST", brake_ms2: float = 0.5):
    return testing.train_type(
        name, length_m=400.0, empty_mass_t=900.0, full_load_mass_t=0.0, rotating_mass_factor=0.05,
        max_speed_kmh=288.0, max_accel_kmh_s=0.25 * 3.6, davis_a_kN=5.4, davis_b_kN_per_kmh=0.2 / 3.6,
        davis_c_kN_per_kmh2=0.012 / 3.6**2, service_brake_kmh_s=brake_ms2 * 3.6, stop_brake_kmh_s=brake_ms2 * 3.6,
        atsp_pattern_kmh_s=brake_ms2 * 3.6, brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8,
        traction=tuple(zip(_FAST_V, _FAST_F)))


def osrd_slow(name: str = "OSRD_SLOW", length_m: float = 400.0):
    return testing.train_type(
        name, length_m=length_m, empty_mass_t=900.0, full_load_mass_t=0.0, rotating_mass_factor=0.05,
        max_speed_kmh=36.0, max_accel_kmh_s=0.25 * 3.6, davis_a_kN=5.4, davis_b_kN_per_kmh=0.2 / 3.6,
        davis_c_kN_per_kmh2=0.012 / 3.6**2, service_brake_kmh_s=1.8, stop_brake_kmh_s=1.8, atsp_pattern_kmh_s=1.8,
        brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8, traction=tuple(zip(_FAST_V, _FAST_F)))


def tr_dmu():
    return testing.train_type(
        "TR_DMU", length_m=41.7, empty_mass_t=68.0, full_load_mass_t=20.0, rotating_mass_factor=0.08,
        max_speed_kmh=120.0, max_accel_kmh_s=100.0, davis_a_kN=68.0 * G * 4.4e-3, davis_c_kN_per_kmh2=0.0004,
        service_brake_kmh_s=0.4253 * 3.6, stop_brake_kmh_s=0.4253 * 3.6, atsp_pattern_kmh_s=0.4253 * 3.6,
        brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8,
        traction=((0, 94.4), (10, 80.0), (20, 61.33), (30, 42.63), (37, 35.6), (51, 31.59), (52, 26.3), (70, 22.99),
                  (71, 19.4), (88, 18.25), (89, 15.36), (110, 14.31), (120, 13.38), (130, 13.38)))


def tr_ic():
    return testing.train_type(
        "TR_IC", length_m=153.37, empty_mass_t=343.0, full_load_mass_t=0.0, rotating_mass_factor=0.06,
        max_speed_kmh=160.0, max_accel_kmh_s=100.0, davis_a_kN=343.0 * G * 2.0e-3, davis_c_kN_per_kmh2=0.0012,
        service_brake_kmh_s=1.8, stop_brake_kmh_s=1.8, atsp_pattern_kmh_s=1.8, brake_comfort_kmh_s=3.3,
        jerk_limit_kmh_s2=1.8,
        traction=((0, 300.0), (66, 300.0), (80, 249.38), (100, 199.5), (120, 166.25), (140, 142.5),
                  (160, 124.69), (170, 124.69)))


def tr_freight():
    return testing.train_type(
        "TR_FREIGHT", length_m=204.72, empty_mass_t=920.0, full_load_mass_t=0.0, rotating_mass_factor=0.04,
        max_speed_kmh=80.0, max_accel_kmh_s=100.0, davis_a_kN=(80.0 * 2.2 + 840.0 * 1.4) * G / 1000.0,
        davis_c_kN_per_kmh2=0.0005, service_brake_kmh_s=0.81, stop_brake_kmh_s=0.81, atsp_pattern_kmh_s=0.81,
        brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8,
        traction=((0, 186.94), (10, 144.12), (20, 101.53), (30, 73.58), (40, 55.83), (50, 44.73), (60, 37.37),
                  (70, 31.45), (80, 26.98), (90, 26.98)))


def public_trains():
    return [osrd_fast(), osrd_fast("OSRD_FAST_095", 0.95), tr_dmu(), tr_ic(), tr_freight()]


def all_public_trains():
    """The five above and OSRD's slow and short slow stocks: seven train types."""
    return public_trains() + [osrd_slow(), osrd_slow("OSRD_SHORT", 15.0)]


def steep_line(train_types=None):
    """21 km, no beacons, no line maximum; a 12 ‰ climb, a 10 ‰ fall, stops A (0), B (9 km), C (20.5 km)."""
    return testing.line(
        length_m=21_000.0, stations=[0.0, 9000.0, 20_500.0], max_speed_kmh=None,
        gradients=[(2000.0, 7000.0, 12.0), (9500.0, 15_000.0, -10.0), (15_000.0, 19_000.0, 8.0),
                   (19_000.0, 21_000.0, -5.0)],
        limits=[(9500.0, 11_000.0, 120.0)], train_types=train_types or public_trains())


def long_steep_line(train_types=None):
    """62 km, no beacons, no line maximum: stops A (0), B (30 km), C (61.5 km); a 15 ‰ climb of 6 km
    towards B, a 15 ‰ fall of 5 km after it and a 10 ‰ climb of 8 km towards C; one 120 km/h restriction.

    15 ‰ is what the 920 t freight still climbs (at about 9 km/h: 135 kN of gradient and 13 kN of
    resistance against the V90's 187 kN at standstill, 144 kN at 10 km/h), and on the bad day
    (traction x 0.9) at about 5 km/h; steeper, it would stall empty, which is bad input.
    """
    return testing.line(
        length_m=62_000.0, stations=[0.0, 30_000.0, 61_500.0], max_speed_kmh=None,
        gradients=[(3000.0, 20_000.0, 4.0), (22_000.0, 28_000.0, 15.0), (31_000.0, 36_000.0, -15.0),
                   (36_000.0, 50_000.0, 2.0), (51_000.0, 59_000.0, 10.0)],
        limits=[(40_000.0, 44_000.0, 120.0)], train_types=train_types or all_public_trains())


# --- the issue-33 matrix: every public train type on the sample line and the long steep line ----------------

SAMPLE_LEGS = (("TKD", "OHS"), ("OHS", "TKD"), ("SKM", "KWB"), ("KWB", "SKM"))
"""Legs of the sample line in the matrix: its longest (7 km, both ways) and a short one with a climb."""
LONG_LEGS = (("S0", "S1"), ("S1", "S2"), ("S2", "S1"), ("S1", "S0"))


def sample_line_with(train_types=None):
    """The sample line (lines/sample) with the public train types instead of its own, and no timetable."""
    import dataclasses

    from planner.line.loader import load_line

    line = load_line(Path(__file__).resolve().parents[1] / "lines" / "sample")
    return dataclasses.replace(line, train_types=tuple(train_types or all_public_trains()), trains=())


def matrix_lines():
    """``{name: (line, legs)}`` of the matrix."""
    return {"sample": (sample_line_with(), SAMPLE_LEGS), "long_steep": (long_steep_line(), LONG_LEGS)}


def leg_rows(line, r, scheduled_s):
    """The ``margins`` columns of one leg (a :class:`planner.report.leg_margin.LegResult`) at the given
    scheduled times, flags and their words included, as the margin report makes them."""
    import math

    import pandas as pd

    from planner.report.leg_flags import flag_reasons
    from planner.report.margin_rule import MarginRule, margin_columns
    from planner.report.margins import _leg_columns

    rule = MarginRule()
    n = len(scheduled_s)
    base = _leg_columns(line, r)
    rows = pd.DataFrame([base] * n)
    rows["scheduled_running_time_s"] = list(scheduled_s)
    rows["closed_loop_max_error_s"] = math.nan
    cols = margin_columns([r.min_time_s] * n, list(scheduled_s), [r.degraded_min_s] * n, [r.slowest_time_s] * n,
                          [r.length_m] * n, rule)
    for k, v in cols.items():
        rows[k] = v
    rows["unassessed_reason"] = ["" if not u else (r.note or "degraded minimum unknown") for u in cols["unassessed"]]
    rows["flag_reason"], rows["bad_day_cause"] = flag_reasons(rows, rule.tight_threshold_s,
                                                              rule.arrival_error_threshold_s)
    return rows


def matrix(levels_kmh_s: str = "2.5:3.5:0.1"):
    """One record per line, train type and leg: the leg's margin result, its stopping patterns, the
    minimum of an independent run (``planner.api.running_time`` at ratio 1, ``api_min_s``) and the leg's
    rows scheduled at that minimum + 8 % (``plus8``), at the leg's own minimum (``plus0``) and at the
    independent minimum - 1 % (``minus1``)."""
    from planner.api import running_time
    from planner.line.units import KMH_S
    from planner.report.leg_margin import leg_result
    from planner.stopping.sweep import adhesion_levels, approach_patterns

    levels = [a * KMH_S for a in adhesion_levels(levels_kmh_s)]
    out = []
    for name, (line, legs) in matrix_lines().items():
        for tt in (t.train_type for t in line.train_types):
            for o, d in legs:
                r = leg_result(line, tt, o, d, [], adhesion_kmh_s=adhesion_levels(levels_kmh_s))
                ap = approach_patterns(line, tt, o, d, levels)
                tmin = float(running_time(line, tt, o, d, ratio=1.0).time_s)
                rows = leg_rows(line, r, [1.08 * tmin, r.min_time_s, 0.99 * tmin])
                out.append({"line": name, "train_type": tt, "origin": o, "destination": d, "result": r,
                            "patterns": ap, "api_min_s": tmin, "plus8": rows.iloc[0], "plus0": rows.iloc[1],
                            "minus1": rows.iloc[2]})
    return out


def matrix_table(records) -> str:
    """The matrix as a Markdown table: per line and train type, the legs' minimum, the verdict at + 8 %
    and the flags with their causes at + 0 %."""
    from collections import Counter

    lines = ["| line | train type | legs: minimum [s] | + 8 %: impossible / short / patterns infeasible "
             "| + 0 %: flags (cause) | largest short on a bad day at + 0 % |", "|---|---|---|---|---|---|"]
    groups: dict = {}
    for x in records:
        groups.setdefault((x["line"], x["train_type"]), []).append(x)
    for (ln, tt), xs in groups.items():
        mins = ", ".join(f"{x['origin']}-{x['destination']} {x['result'].min_time_s:.0f}" for x in xs)
        imp = sum(bool(x["plus8"].impossible) for x in xs)
        short = sum(bool(x["plus8"].short_bad_day) for x in xs)
        bad_pat = sum(x["patterns"].n_feasible < len(x["patterns"].patterns) for x in xs)
        f0 = Counter((x["plus0"].bad_day_cause or "-") for x in xs if bool(x["plus0"].short_bad_day))
        worst = max(xs, key=lambda x: -x["plus0"].remaining_margin_s)
        lines.append(f"| {ln} | {tt} | {mins} | {imp} / {short} / {bad_pat} | "
                     f"{sum(bool(x['plus0'].short_bad_day) for x in xs)} short ("
                     + ", ".join(f"{k} {v}" for k, v in sorted(f0.items())) + ") | "
                     f"{worst['origin']}-{worst['destination']} {-worst['plus0'].remaining_margin_s:.1f} s |")
    return "\n".join(lines)


if __name__ == "__main__":  # PYTHONPATH=. python tests/public_trains.py: the matrix as a table
    print(matrix_table(matrix()))
