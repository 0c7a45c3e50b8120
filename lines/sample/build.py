"""Build the sample line database ``lines/sample/`` (line_id ``sample``).

Run ``python lines/sample/build.py [--out DIR]``; without ``--out`` the Parquet
files are written next to this script. The build is deterministic: no random
numbers, no clocks, rows sorted, every table written with an explicit pyarrow
schema, so a re-run reproduces the committed files' contents exactly.

Everything the line is made of is a documented parameter in the first part of
this file; ``README.md`` beside it explains the assumptions behind each number.
The rest of the file derives the tables from them: rolling-stock data from
car masses and standard Japanese formulas, signals/beacons from the block
layout, the track network from the station layouts, and the timetable from a
self-contained minimum-running-time *estimate* plus margins.

Conventions (docs/line-database.md): chainage [m] grows from the origin terminus Minato;
``down`` runs towards increasing chainage, ``up`` towards decreasing chainage;
gradients in ‰, positive when rising towards increasing chainage.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa

# =====================================================================================
# Parameters
# =====================================================================================

LINE_ID = "sample"
LINE_NAME = "Minato Line (sample)"
SCHEMA_VERSION = 2       # line-database schema version (planner.line.schema.SCHEMA_VERSION)
START_M = 0.0            # line start: buffer stops of the origin terminus Minato [m]
END_M = 27_900.0         # line end: buffer stops of the terminus Senzan [m]
MAX_SPEED_KMH = 100.0    # line maximum speed

# Platforms take a 10-car train (10 x 20 m) plus 10 m of slack. The stop markers
# (train front) are 100 m either side of the platform centre, so a 10-car train
# standing at the down marker occupies exactly [centre - 100, centre + 100].
PLATFORM_LENGTH_M = 210.0
STOP_OFFSET_M = 100.0

# station_id, name, platform centre [m], rapid stop, passing loop, dwell of a
# stopping train [s] (busier stations longer; none at the termini)
STATIONS = [
    ("MNT", "Minato", 200.0, True, False, 0),
    ("SKM", "Sakuramachi", 2_000.0, False, False, 25),
    ("KWB", "Kawabata", 4_200.0, False, True, 25),
    ("HGO", "Higashi-Oka", 7_200.0, True, False, 35),
    ("MDR", "Midorigaoka", 8_800.0, False, False, 25),
    ("TKD", "Takadai", 11_200.0, True, False, 30),
    ("OHS", "Ohashi", 18_200.0, True, True, 40),
    ("NKN", "Nakanoshima", 20_100.0, False, False, 25),
    ("YMT", "Yamate", 22_200.0, True, False, 35),
    ("KTA", "Kitayama", 23_900.0, False, True, 25),
    ("AOB", "Aoba", 26_200.0, False, False, 25),
    ("SNZ", "Senzan", 27_700.0, True, False, 0),
]

# Gradients (start_m, end_m, permil); gaps are level. Platforms (centre +- 105 m)
# are level. Takadai (TKD) down approach: the hard case, see SPECIAL_* below.
GRADIENTS = [
    (400.0, 1_000.0, 5.0),
    (1_000.0, 1_700.0, 8.0),
    (2_300.0, 2_900.0, 3.0),
    (2_900.0, 3_800.0, -6.0),
    (4_500.0, 5_300.0, 10.0),
    (5_300.0, 6_200.0, 4.0),
    (6_200.0, 6_900.0, -7.0),
    (7_500.0, 8_400.0, 6.0),
    (9_000.0, 9_700.0, -5.0),
    (9_700.0, 10_400.0, 9.0),
    (10_400.0, 10_950.0, -4.0),
    (10_950.0, 11_100.0, -20.0),   # TKD down approach: 150 m at -20 permil, then level
    (11_500.0, 12_600.0, -10.0),   # down into the Ogawa river valley
    (12_600.0, 13_400.0, -6.0),
    (14_800.0, 15_900.0, 7.0),
    (15_900.0, 17_000.0, 10.0),
    (17_000.0, 17_900.0, 4.0),
    (18_500.0, 19_200.0, -8.0),
    (19_200.0, 19_800.0, -3.0),
    (20_400.0, 21_200.0, 6.0),
    (21_200.0, 21_900.0, 2.0),
    (22_500.0, 23_500.0, -9.0),
    (24_200.0, 25_000.0, 5.0),
    (25_000.0, 25_900.0, -4.0),
    (26_500.0, 27_400.0, -6.0),
]

# The hard station approach: Takadai (TKD), down direction. Stop marker
# S = 11 300 m. Over the last 350 m: [S-350, S-200] falls at -20 permil, [S-200, S]
# is level; a 70 km/h curve restriction ends at S-350 and a 40 km/h curved-
# platform restriction covers [S-100, S].
SPECIAL_STATION = "TKD"
SPECIAL_DIRECTION = "down"

# Curves (start_m, end_m, radius_m, limit_kmh or None, has_beacon). A curve with a
# limit gets a `curve` restriction over the same stretch, both directions.
# Limits follow the usual cant/cant-deficiency rule of thumb for 1067 mm gauge
# commuter lines: R 300 -> 70, R 400 -> 75, R 500 -> 80, R 600 -> 85, R 700 -> 90;
# R >= 800 m needs no restriction at 100 km/h.
CURVES = [
    (1_100.0, 1_450.0, 500.0, 80.0, True),
    (2_700.0, 3_000.0, 700.0, 90.0, True),
    (5_150.0, 5_600.0, 400.0, 75.0, False),    # no ATS-P beacon; 150 m after the next one
    (7_700.0, 8_100.0, 1_000.0, None, True),
    (10_450.0, 10_950.0, 300.0, 70.0, True),   # TKD approach, ends where the last 350 m begin
    (11_200.0, 11_300.0, 160.0, 40.0, True),   # TKD curved platform, last 100 m before S
    (12_000.0, 12_500.0, 700.0, 90.0, True),
    (16_200.0, 16_700.0, 500.0, 80.0, True),
    (18_700.0, 19_100.0, 500.0, 80.0, True),
    (21_000.0, 21_400.0, 600.0, 85.0, False),  # no ATS-P beacon
    (22_600.0, 23_000.0, 400.0, 75.0, True),
    (24_700.0, 25_200.0, 800.0, None, True),
    (26_600.0, 26_900.0, 400.0, 75.0, True),
]

# Other restrictions: (start_m, end_m, limit_kmh, direction, train_type, kind, has_beacon).
CIVIL_LIMITS = [
    # Kawabata-Higashi-Oka: old plate-girder bridge, 85 km/h, no ATS-P beacon; the
    # 75 km/h curve behind it starts 150 m later (two DB-fed patterns close together).
    (5_000.0, 5_150.0, 85.0, "both", None, "civil", False),
    # Old embankment near Aoba: 90 km/h, no ATS-P beacon.
    (25_400.0, 25_700.0, 90.0, "both", None, "civil", False),
]

# Turnout restrictions: only at the terminus throats, where every train runs
# through the scissors crossover (arrivals and departures alternate between the
# two stub platform tracks). 45 km/h over the crossover plus a little. The
# arriving direction has an ATS-P beacon, the departing one does not (a train
# starting 20 m before it cannot exceed it by much, and no beacon exists there).
TURNOUT_LIMIT_KMH = 45.0
TURNOUT_EXTRA_M = 10.0             # restriction reaches this far beyond the crossover switches

# Signals, per direction (Japanese practice: station signals at every station, automatic
# block signals between stations):
# * home signal (場内信号機) at the entrance of every station a train of this direction
#   arrives at: HOME_BEFORE_PLATFORM_M before the end of the platform the train enters, or
#   HOME_BEFORE_SWITCH_M before the first switch on its main track in the station throat
#   (loop switches, terminus scissors, the Ohashi crossover), whichever the train meets first;
# * starting signal (出発信号機) STARTING_SIGNAL_OFFSET_M beyond the stop marker of every
#   station a train departs from (short of the exit switches);
# * automatic block signals (閉塞信号機) between the starting signal of one station and the
#   home signal of the next, splitting that stretch into equal blocks of at most
#   BLOCK_MAX_M; the build asserts every such block is BLOCK_RANGE_M long.
STARTING_SIGNAL_OFFSET_M = 30.0
HOME_BEFORE_PLATFORM_M = 100.0
HOME_BEFORE_SWITCH_M = 50.0
HOME_SWITCH_SEARCH_M = 600.0       # throat switches: on the main within this far before the marker
BLOCK_MAX_M = 950.0
BLOCK_RANGE_M = (550.0, 1_000.0)   # automatic block lengths (starting/block -> block/home)
SIGNAL_BEACON_OFFSET_M = 20.0      # ATS-P signal beacon this far before its signal
PU_DISTANCE_M = 450.0              # pattern-update beacon before a restriction
PU_DISTANCE_RANGE_M = (300.0, 600.0)
PU_AFTER_STOP_M = 15.0             # ... or this far past a stop marker in between
TASC_DISTANCE_M = 550.0            # TASC beacon before every stop marker: at least this far out ...
TASC_ADHESION_KMH_S = 2.5          # ... and far enough that a train at line speed stops from it at the weakest
                                   # adhesion of the nightly stop sweep (jobs/nightly.toml [stops]), see tasc_distance_m
TASC_JERK_KMH_S2 = 2.0             # the fleet's lowest jerk limit (the brake builds up no faster)
TASC_MARGIN = 1.10                 # 10 % on the braking distance
TASC_ROUND_M = 50.0                # beacon distances in whole 50 m
BEACON_MIN_GAP_M = 30.0            # two beacons of one direction at least this far apart
# Automatic block signals on the Ogawa river bridge section were resignalled with
# ground coils that send a generic telegram (no signal number): consecutive
# beacons there send identical telegrams.
GENERIC_TELEGRAM_SECTION_M = (12_800.0, 15_000.0)

# Track network.
LOOP_SWITCH_OFFSET_M = 165.0       # loop switches this far either side of the platform centre
CROSSOVER_LENGTH_M = 60.0          # chainage span of a crossover
TERMINUS_CROSSOVER_M = {"MNT": 340.0, "SNZ": 27_500.0}   # lower-chainage switch of the scissors
INTERMEDIATE_CROSSOVER_M = {"OHS": 18_420.0}            # lower-chainage switch
# Interlocking areas: IXL-A from the line start, then a new area at each boundary.
IXL_NAMES = ["IXL-A", "IXL-B", "IXL-C", "IXL-D"]
IXL_BOUNDARIES_M = [5_700.0, 14_700.0, 23_050.0]

# Rolling stock. Masses from car masses; passenger mass at "full load" (load 1.0)
# = 180 % of the nominal capacity of 150 passengers per car, 55 kg each
# (14.85 t per car), a Tokyo-area peak-hour load.
PASSENGER_KG = 55.0
CAPACITY_PER_CAR = 150
FULL_LOAD_RATE = 1.80
DESIGN_LOAD = 0.5       # load at which traction is sized and the timetable estimated
G = 9.80665

# train_type: cars, motor cars, motor-car mass [t], trailer mass [t], rotating-mass
# factor, max speed [km/h], starting acceleration [km/h/s], base speed [km/h]
# (end of constant effort), characteristic speed [km/h] (start of the 1/v^2 region),
# service brake/own stopping brake/ATS-P pattern/ride-comfort limit on stop braking [km/h/s], jerk [km/h/s^2],
# speed margin [km/h], cruise, coast band [km/h].
TRAIN_TYPES = {
    "E10": dict(cars=10, motors=6, m_t=31.5, t_t=25.0, rot=0.08, vmax=110.0, acc=3.0,
                v_base=35.0, v_char=75.0, service=3.8, stop=3.2, atsp=3.0, comfort=3.5,
                jerk=2.5, margin=3.0, cruise="constant", band=5.0),
    "E8": dict(cars=8, motors=4, m_t=31.0, t_t=24.5, rot=0.08, vmax=120.0, acc=3.3,
               v_base=40.0, v_char=80.0, service=4.0, stop=3.4, atsp=3.0, comfort=3.5,
               jerk=2.5, margin=3.0, cruise="constant", band=5.0),
    "E6": dict(cars=6, motors=3, m_t=35.0, t_t=27.0, rot=0.10, vmax=100.0, acc=2.5,
               v_base=35.0, v_char=60.0, service=3.5, stop=3.0, atsp=2.8, comfort=3.0,
               jerk=2.0, margin=5.0, cruise="sawtooth", band=5.0),
}
CAR_LENGTH_M = 20.0
TRACTION_STEP_KMH = 5.0
TRACTION_EXTRA_KMH = 15.0          # traction curve runs to max speed + this

# Timetable. Periods: (first cycle start, end (exclusive), cycle [s], local departures
# in the cycle [s], rapid departure in the cycle [s] as (down, up) or None, local
# train types in rotation); up departures are shifted by UP_SHIFT_S. A rapid leaves
# 5.5 min after a local in the peak (7 min off-peak) and overtakes it where it catches up:
# peak down at Kawabata, peak up at Ohashi (cross-platform, both stop); off-peak down at
# Kitayama, off-peak up at Kawabata. In the peak the
# locals are spaced 8/6/6/4 min so that the rapid has room behind it (average 6 min).
HOUR = 3600
PERIODS = [
    (5 * HOUR, 6 * HOUR + 1800, 900, (0,), None, ("E6",)),
    (6 * HOUR + 1800, 9 * HOUR + 1800, 1440, (0, 480, 840, 1200), (330, 330), ("E10",)),
    (9 * HOUR + 1800, 16 * HOUR + 1800, 1200, (0, 600), (420, 420), ("E8", "E6")),
    (16 * HOUR + 1800, 19 * HOUR + 1800, 1440, (0, 480, 840, 1200), (330, 330), ("E10",)),
    (19 * HOUR + 1800, 22 * HOUR + 1800, 1200, (0, 600), (420, 420), ("E8", "E6")),
    (22 * HOUR + 1800, 23 * HOUR + 3000, 900, (0,), None, ("E6",)),
]
UP_SHIFT_S = 300                   # up trains leave Senzan 5 min after the down pattern
RAPID_TYPE = "E10"
MIN_HEADWAY_S = 120                # between consecutive trains on the same track
MIN_PLATFORM_REOCCUPY_S = 60       # follower arrives this long after the leader left
LOOP_CLEAR_S = 30                  # loop train must be in the loop this long before a pass
TIME_ROUND_S = 5
# Running times, the way a timetable planner builds them: the *standard running time* (the
# estimate below at ratio 1.0 and the design load) plus supplements, rounded UP to TIME_ROUND_S:
#   scheduled = ceil_5s( standard × (1 + percent / 100) + per_leg_s )
# * percent: the running-time supplement (load above the design load, weak catenary voltage,
#   driver variation), a share of the run;
# * per_leg_s: a fixed supplement per stop-to-stop leg, for the start and the stop (a heavy
#   train starting, braking on a poor rail), which do not grow with the leg's length.
# Sized so that the timetable survives a bad day (full load, traction x 0.9, adhesion
# 2.5 km/h/s) on almost every leg. Two deliberate exceptions (one direction each) show what the
# margin report must single out; see README.md.
SUPPLEMENT_PERCENT = 8.0
SUPPLEMENT_PER_LEG_S = 10.0
SUPPLEMENT_EXCEPTIONS = {  # (from, to) in running direction: (percent, per-leg s)
    # down: the climb out of Kawabata (+10 permil at 4.5-5.3 km, then +4) through the two
    # restrictions without an ATS-P beacon (85 then 75 km/h at 5.0-5.6 km), timetabled with the
    # bare running supplement and no start/stop allowance -> infeasible on a bad day
    ("KWB", "HGO"): (1.5, 0.0),
    # up: the 7 km Ogawa valley run ending in the climb to Takadai (+6 then +10 permil over the
    # last 1.9 km for up trains), timetabled with the start/stop allowance only, no running
    # supplement, to keep the peak cycle -> tight on a bad day
    ("OHS", "TKD"): (0.0, 10.0),
}


# =====================================================================================
# Stations and civil layout
# =====================================================================================


def stations() -> list[dict]:
    """Stations with stop markers, sorted by chainage."""
    out = []
    for sid, name, pos, rapid, loop, dwell in STATIONS:
        out.append(dict(station_id=sid, name=name, position_m=pos,
                        stop_down_m=pos + STOP_OFFSET_M, stop_up_m=pos - STOP_OFFSET_M,
                        platform_length_m=PLATFORM_LENGTH_M, rapid=rapid, loop=loop,
                        dwell_s=dwell))
    return sorted(out, key=lambda s: s["position_m"])


def interlocking_at(x_m: float) -> str:
    """Interlocking area that controls chainage ``x_m`` (a boundary belongs to the area it ends)."""
    return IXL_NAMES[int(np.searchsorted(IXL_BOUNDARIES_M, x_m, side="left"))]


def speed_limits() -> list[dict]:
    """Every restriction: curve limits, civil limits and terminus turnouts."""
    rows = []
    for a, b, _r, lim, beacon in CURVES:
        if lim is not None:
            rows.append(dict(start_m=a, end_m=b, limit_kmh=lim, direction="both",
                             train_type=None, kind="curve", has_beacon=beacon))
    for a, b, lim, d, tt, kind, beacon in CIVIL_LIMITS:
        rows.append(dict(start_m=a, end_m=b, limit_kmh=lim, direction=d, train_type=tt,
                         kind=kind, has_beacon=beacon))
    first, last = stations()[0]["station_id"], stations()[-1]["station_id"]
    for sid, a in TERMINUS_CROSSOVER_M.items():
        lo, hi = a - TURNOUT_EXTRA_M, a + CROSSOVER_LENGTH_M + TURNOUT_EXTRA_M
        # arriving direction: beacon; departing direction: none (see README)
        arriving = "up" if sid == first else "down"
        assert sid in (first, last)
        for d in ("down", "up"):
            rows.append(dict(start_m=lo, end_m=hi, limit_kmh=TURNOUT_LIMIT_KMH, direction=d,
                             train_type=None, kind="turnout", has_beacon=(d == arriving)))
    rows.sort(key=lambda r: (r["start_m"], r["end_m"], r["direction"], r["kind"]))
    return rows


# =====================================================================================
# Rolling stock
# =====================================================================================


def _sig(x: float, digits: int = 4) -> float:
    """Round to ``digits`` significant digits (stored values are what everyone uses)."""
    return float(f"{x:.{digits}g}")


def rolling_stock() -> tuple[list[dict], list[dict]]:
    """Rolling-stock rows and traction-curve rows.

    Running resistance: the JNR/JR formula for EMUs in kgf (W in t, V in km/h),
    R = (1.32 + 0.0164 V) W + (0.028 + 0.0078 (n - 1)) V², taken at the design load
    and converted to kN (x g / 1000). Traction: constant effort F0 up to the base
    speed, constant power F0 v_b / v up to the characteristic speed v_c, then
    F0 (v_b / v_c) (v_c / v)² ("motor characteristic" region). F0 gives the
    nominal starting acceleration at the design load: F0 = M_e a + R(0).
    """
    stock, traction = [], []
    for name, p in TRAIN_TYPES.items():
        empty_t = p["motors"] * p["m_t"] + (p["cars"] - p["motors"]) * p["t_t"]
        full_t = p["cars"] * CAPACITY_PER_CAR * FULL_LOAD_RATE * PASSENGER_KG / 1000.0
        w_t = empty_t + DESIGN_LOAD * full_t
        kgf = G / 1000.0                              # 1 kgf in kN
        a_kn = _sig(1.32 * w_t * kgf)
        b_kn = _sig(0.0164 * w_t * kgf)
        c_kn = _sig((0.028 + 0.0078 * (p["cars"] - 1)) * kgf)
        me_kg = w_t * 1000.0 * (1.0 + p["rot"])
        f0_kn = 5.0 * round((me_kg * p["acc"] / 3.6 / 1000.0 + a_kn) / 5.0)
        stock.append(dict(
            train_type=name, length_m=p["cars"] * CAR_LENGTH_M, empty_mass_t=empty_t,
            full_load_mass_t=round(full_t, 2), rotating_mass_factor=p["rot"],
            max_speed_kmh=p["vmax"], max_accel_kmh_s=p["acc"],
            davis_a_kN=a_kn, davis_b_kN_per_kmh=b_kn, davis_c_kN_per_kmh2=c_kn,
            service_brake_kmh_s=p["service"], stop_brake_kmh_s=p["stop"],
            atsp_pattern_kmh_s=p["atsp"], brake_comfort_kmh_s=p["comfort"],
            jerk_limit_kmh_s2=p["jerk"], speed_margin_kmh=p["margin"], cruise=p["cruise"],
            coast_band_kmh=p["band"]))
        vb, vc = p["v_base"], p["v_char"]
        n = int(math.ceil((p["vmax"] + TRACTION_EXTRA_KMH) / TRACTION_STEP_KMH))
        for k in range(n + 1):
            v = k * TRACTION_STEP_KMH
            if v <= vb:
                f = f0_kn
            elif v <= vc:
                f = f0_kn * vb / v
            else:
                f = f0_kn * vb / vc * (vc / v) ** 2
            traction.append(dict(train_type=name, speed_kmh=v, effort_kN=round(f, 2)))
    return stock, traction


def check_rolling_stock(stock: list[dict], traction: list[dict]) -> dict[str, dict]:
    """Performance checks every train type must pass; returns key figures for the README."""
    figures = {}
    for rs in stock:
        tt = rs["train_type"]
        tr = [r for r in traction if r["train_type"] == tt]
        v = np.array([r["speed_kmh"] for r in tr])
        f = np.array([r["effort_kN"] for r in tr])

        def resist(vk, load, grade_permil=0.0):
            m_t = rs["empty_mass_t"] + load * rs["full_load_mass_t"]
            return (rs["davis_a_kN"] + rs["davis_b_kN_per_kmh"] * vk
                    + rs["davis_c_kN_per_kmh2"] * vk ** 2 + m_t * G * grade_permil / 1000.0)

        def balance(load, grade):
            vv = np.arange(0.0, v[-1] + 1e-9, 0.1)
            ok = np.interp(vv, v, f) >= resist(vv, load, grade)
            return float(vv[ok][-1]) if ok.any() else 0.0

        target = min(MAX_SPEED_KMH, rs["max_speed_kmh"]) - rs["speed_margin_kmh"]
        b_level0 = balance(0.0, 0.0)
        b_rise = balance(DESIGN_LOAD, 10.0)
        assert b_level0 > MAX_SPEED_KMH, (tt, b_level0)
        assert b_rise >= target, (tt, "cannot hold the line maximum on +10 permil", b_rise)
        m_e = lambda load: (rs["empty_mass_t"] + load * rs["full_load_mass_t"]) * (
            1 + rs["rotating_mass_factor"])
        a0 = {ld: (f[0] - rs["davis_a_kN"]) / m_e(ld) * 3.6 for ld in (0.0, DESIGN_LOAD, 1.0)}
        assert abs(a0[DESIGN_LOAD] - rs["max_accel_kmh_s"]) < 0.1, (tt, a0)
        figures[tt] = dict(f0_kN=f[0], a0_kmh_s=a0, balance_level_empty_kmh=b_level0,
                           balance_rise10_design_kmh=b_rise,
                           balance_rise10_full_kmh=balance(1.0, 10.0),
                           resistance_100_kN=resist(100.0, DESIGN_LOAD))
    return figures


# =====================================================================================
# Minimum running-time estimate (self-contained; not planner's simulator)
# =====================================================================================


class RunEstimator:
    """Minimum running times of one train type in one direction, on a 1 m grid.

    A deliberately simple, self-contained kinematic estimate that follows the
    running model of docs/design.md §2 at ratio 1.0: full notch below the on-board
    maximum speed (restriction held until the tail clears, minus the speed
    margin), constant-speed hold or a coast band (sawtooth), service-brake
    curves to each lower limit, stop-brake curve to the stop marker; gradient
    and curve resistance (800/R N/kN) averaged over the train length. Speeds
    advance in v² with Heun's method on a 1 m step; time with dt = 2 ds / (v0 + v1),
    exact for constant acceleration. Distances ``u`` are metres from the line
    end where running starts (chainage - START_M down, END_M - chainage up).
    """

    def __init__(self, rs: dict, traction: list[dict], direction: str, limits: list[dict]):
        self.rs, self.direction = rs, direction
        n = int(round(END_M - START_M))
        grade = np.zeros(n)
        curve = np.zeros(n)
        for a, b, g in GRADIENTS:
            grade[int(a - START_M):int(b - START_M)] = g
        for a, b, r, _lim, _bc in CURVES:
            curve[int(a - START_M):int(b - START_M)] = 800.0 / r
        if direction == "up":
            grade, curve = -grade[::-1], curve[::-1]
        length = int(rs["length_m"])
        cum = np.concatenate([[0.0], np.cumsum(grade + curve)])
        u = np.arange(n + 1)
        # mean of (gradient + curve resistance) [permil] over the train behind the front
        self.resist_permil = (cum - cum[np.maximum(u - length, 0)]) / length
        vmax = np.full(n + 1, min(MAX_SPEED_KMH, rs["max_speed_kmh"]))
        for lim in limits:
            if lim["direction"] not in ("both", direction):
                continue
            if lim["train_type"] not in (None, rs["train_type"]):
                continue
            if direction == "down":
                ua, ub = lim["start_m"] - START_M, lim["end_m"] - START_M
            else:
                ua, ub = END_M - lim["end_m"], END_M - lim["start_m"]
            lo, hi = int(round(ua)), min(int(round(ub)) + length, n)
            vmax[lo:hi + 1] = np.minimum(vmax[lo:hi + 1], lim["limit_kmh"])
        self.vmax_ms = (vmax - rs["speed_margin_kmh"]) / 3.6
        # service-brake envelope to every lower limit ahead
        b = rs["service_brake_kmh_s"] / 3.6
        env = self.vmax_ms.copy()
        for i in range(n - 1, -1, -1):
            env[i] = min(env[i], math.sqrt(env[i + 1] ** 2 + 2.0 * b))
        self.env_ms = env
        self.tr_v = np.array([r["speed_kmh"] for r in traction if r["train_type"] == rs["train_type"]]) / 3.6
        self.tr_f = np.array([r["effort_kN"] for r in traction if r["train_type"] == rs["train_type"]]) * 1e3

    def u_of(self, chainage_m: float) -> int:
        x = chainage_m - START_M if self.direction == "down" else END_M - chainage_m
        return int(round(x))

    def run(self, u0: int, u1: int, load: float = DESIGN_LOAD) -> np.ndarray:
        """Times [s] at every grid node u0..u1 of a start-to-stop run."""
        rs = self.rs
        m = (rs["empty_mass_t"] + load * rs["full_load_mass_t"]) * 1e3
        me = m * (1.0 + rs["rotating_mass_factor"])
        a_max = rs["max_accel_kmh_s"] / 3.6
        A, B, C = rs["davis_a_kN"] * 1e3, rs["davis_b_kN_per_kmh"] * 1e3 * 3.6, rs["davis_c_kN_per_kmh2"] * 1e3 * 3.6 ** 2
        b_stop = rs["stop_brake_kmh_s"] / 3.6
        band = rs["coast_band_kmh"] / 3.6
        sawtooth = rs["cruise"] == "sawtooth"
        tv, tf = self.tr_v, self.tr_f
        dv = tv[1] - tv[0]
        nmax = len(tv) - 2

        def effort(v):
            k = min(int(v / dv), nmax)
            return tf[k] + (tf[k + 1] - tf[k]) * (v - tv[k]) / dv

        t = np.zeros(u1 - u0 + 1)
        v = 0.0
        coasting = False
        for i in range(u0, u1):
            gres = m * G * self.resist_permil[i] / 1000.0

            def acc(vv):
                r = A + B * vv + C * vv * vv + gres
                if coasting:
                    return -r / me
                return min((effort(vv) - r) / me, a_max)

            k1 = 2.0 * acc(v)
            vp = math.sqrt(max(v * v + k1, 0.0))
            k2 = 2.0 * acc(vp)
            v1 = math.sqrt(max(v * v + 0.5 * (k1 + k2), 0.0))
            cap = min(self.env_ms[i + 1], math.sqrt(2.0 * b_stop * (u1 - i - 1)))
            if v1 >= cap:
                if sawtooth and cap >= self.vmax_ms[i + 1] - 1e-9:
                    coasting = True
                v1 = cap
            if coasting and v1 <= self.vmax_ms[i + 1] - band:
                coasting = False
            if v1 <= 0.0 and i + 1 < u1:
                raise RuntimeError(f"{rs['train_type']} stalls at u={i} ({self.direction})")
            t[i + 1 - u0] = t[i - u0] + 2.0 / (v + v1)
            v = v1
        return t


# =====================================================================================
# Timetable
# =====================================================================================


def _round_t(t: float) -> float:
    return float(TIME_ROUND_S * round(t / TIME_ROUND_S))


def scheduled_running_time(standard_s: float, percent: float, per_leg_s: float) -> float:
    """Scheduled running time [s]: standard × (1 + percent/100) + per_leg_s, rounded up to TIME_ROUND_S.

    A value within 1e-6 s above a multiple stays on it.
    """
    t = standard_s * (1.0 + percent / 100.0) + per_leg_s
    return float(TIME_ROUND_S * math.ceil((t - 1e-6) / TIME_ROUND_S))


def supplement(a: str, b: str) -> tuple[float, float]:
    """(percent, per-leg s) of the interstation a -> b in running direction."""
    return SUPPLEMENT_EXCEPTIONS.get((a, b), (SUPPLEMENT_PERCENT, SUPPLEMENT_PER_LEG_S))


class RunTimes:
    """Scheduled running times per (train type, direction, stopping pattern), cached."""

    def __init__(self, stock: list[dict], traction: list[dict], limits: list[dict]):
        self.st = stations()
        self.stock = {r["train_type"]: r for r in stock}
        self.traction, self.limits = traction, limits
        self._est: dict = {}
        self._legs: dict = {}
        self.runs: dict = {}   # (tt, direction, from, to) -> (minimum, scheduled) running time [s]

    def order(self, direction: str) -> list[dict]:
        return self.st if direction == "down" else self.st[::-1]

    def estimator(self, tt: str, direction: str) -> RunEstimator:
        key = (tt, direction)
        if key not in self._est:
            self._est[key] = RunEstimator(self.stock[tt], self.traction, direction, self.limits)
        return self._est[key]

    def legs(self, tt: str, direction: str, rapid: bool) -> list[tuple]:
        """[(i_from, i_to, scheduled run [s], {i_pass: scheduled offset [s]})] in running order."""
        key = (tt, direction, rapid)
        if key in self._legs:
            return self._legs[key]
        est = self.estimator(tt, direction)
        order = self.order(direction)
        col = "stop_down_m" if direction == "down" else "stop_up_m"
        stops = [i for i, s in enumerate(order) if (s["rapid"] or not rapid) or i in (0, len(order) - 1)]
        out = []
        for i0, i1 in zip(stops[:-1], stops[1:]):
            u = [est.u_of(order[i][col]) for i in range(i0, i1 + 1)]
            t = est.run(u[0], u[-1])
            t_min = float(t[-1])
            # supplements of a multi-interstation leg: length-weighted mean of its interstations'
            w = np.diff(u).astype(float)
            sup = np.array([supplement(order[i]["station_id"], order[i + 1]["station_id"])
                            for i in range(i0, i1)])
            sched = scheduled_running_time(t_min, float((w * sup[:, 0]).sum() / w.sum()),
                                           float((w * sup[:, 1]).sum() / w.sum()))
            self.runs[(tt, direction, order[i0]["station_id"], order[i1]["station_id"])] = (t_min, sched)
            passes = {i: _round_t(float(t[u[i - i0] - u[0]]) * sched / t_min) for i in range(i0 + 1, i1)}
            out.append((i0, i1, sched, passes))
        self._legs[key] = out
        return out

    def free_run(self, train_id: str, tt: str, direction: str, rapid: bool, t0: float) -> dict:
        """A train's calls when nothing is in its way."""
        order = self.order(direction)
        main = "D1" if direction == "down" else "U1"
        calls = [None] * len(order)
        calls[0] = dict(arr=None, dep=t0, stops=True, track=main)
        dep = t0
        for i0, i1, run, passes in self.legs(tt, direction, rapid):
            for i, off in passes.items():
                calls[i] = dict(arr=dep + off, dep=dep + off, stops=False, track=main)
            arr = dep + run
            last = i1 == len(order) - 1
            dep = None if last else arr + order[i1]["dwell_s"]
            calls[i1] = dict(arr=arr, dep=dep, stops=True, track=main)
        return dict(train_id=train_id, train_type=tt, direction=direction,
                    service="rapid" if rapid else "local", calls=calls)


def _departures(direction: str) -> list[tuple[float, bool, str]]:
    """(origin departure [s], rapid, train type) of the day's pattern, in time order."""
    out = []
    k_dir = 0 if direction == "down" else 1
    for start, end, cycle, local_offsets, rapid_offset, types in PERIODS:
        j = 0
        for t in range(start, end, cycle):
            for off in local_offsets:
                if t + off < end:
                    out.append((float(t + off), False, types[j % len(types)]))
                    j += 1
            if rapid_offset is not None and t + rapid_offset[k_dir] < end:
                out.append((float(t + rapid_offset[k_dir]), True, RAPID_TYPE))
    return sorted(out)


def _time_at(call: dict, which: str) -> float:
    return call["arr"] if which == "arr" and call["arr"] is not None else call["dep"]


def _conflict(lead: dict, foll: dict, i: int) -> bool:
    """True if ``foll`` comes too close behind ``lead`` at station index i on the same track."""
    a, b = lead["calls"][i], foll["calls"][i]
    if a["track"] != b["track"]:
        return False
    la, ld = _time_at(a, "arr"), _time_at(a, "dep")
    fa, fd = _time_at(b, "arr"), _time_at(b, "dep")
    if ld is None or fd is None:           # at the terminus: arrivals only
        return fa < la + MIN_HEADWAY_S
    return fa < la + MIN_HEADWAY_S or fd < ld + MIN_HEADWAY_S or fa < ld + MIN_PLATFORM_REOCCUPY_S


def _shift(train: dict, i: int, new_dep: float) -> None:
    """Hold ``train`` at station index i until new_dep; later calls move by the same delay."""
    c = train["calls"]
    delta = new_dep - c[i]["dep"]
    c[i]["dep"] = new_dep
    for k in range(i + 1, len(c)):
        c[k]["arr"] += delta
        if c[k]["dep"] is not None:
            c[k]["dep"] += delta


def timetable(runtimes: RunTimes) -> list[dict]:
    """The whole day both ways, with rapids overtaking locals in passing loops."""
    trains = []
    for direction in ("down", "up"):
        order = runtimes.order(direction)
        loop_track = "D2" if direction == "down" else "U2"
        shift = 0 if direction == "down" else UP_SHIFT_S
        n_loc = n_rap = 0
        day = sorted((t + shift, rapid, tt) for t, rapid, tt in _departures(direction))
        mine = []
        for t, rapid, tt in day:
            if rapid:
                n_rap += 1
                tid = f"{2000 + 2 * n_rap - (1 if direction == 'down' else 0)}{'D' if direction == 'down' else 'U'}"
            else:
                n_loc += 1
                tid = f"{1000 + 2 * n_loc - (1 if direction == 'down' else 0)}{'D' if direction == 'down' else 'U'}"
            mine.append(runtimes.free_run(tid, tt, direction, rapid, float(t)))
        # overtaking: each rapid, from the nearest local ahead outwards
        rapids = [x for x in mine if x["service"] == "rapid"]
        locals_ = [x for x in mine if x["service"] == "local"]
        for r in rapids:
            t0 = r["calls"][0]["dep"]
            ahead = sorted((x for x in locals_ if x["calls"][0]["dep"] < t0),
                           key=lambda x: -x["calls"][0]["dep"])
            for loc in ahead[:3]:
                k = next((i for i in range(len(order)) if _conflict(loc, r, i)), None)
                if k is None:
                    continue
                loops = [i for i in range(1, k + 1) if order[i]["loop"]
                         and r["calls"][i]["arr"] >= loc["calls"][i]["arr"] + LOOP_CLEAR_S]
                if not loops:
                    raise RuntimeError(f"rapid {r['train_id']} catches local {loc['train_id']} at "
                                       f"{order[k]['station_id']} before any passing loop")
                j = loops[-1]
                loc["calls"][j]["track"] = loop_track
                _shift(loc, j, max(loc["calls"][j]["dep"], r["calls"][j]["dep"] + MIN_HEADWAY_S))
                # a local faster than the rapid on some later interstation waits a little longer
                while any(_conflict(r, loc, i) for i in range(j + 1, len(order))):
                    _shift(loc, j, loc["calls"][j]["dep"] + TIME_ROUND_S)
        trains.extend(mine)
    return trains


def check_timetable(runtimes: RunTimes, trains: list[dict]) -> list[str]:
    """Headway problems between consecutive trains on the same track at every station."""
    problems = []
    for direction in ("down", "up"):
        order = runtimes.order(direction)
        mine = [t for t in trains if t["direction"] == direction]
        for i, st in enumerate(order):
            for track in {t["calls"][i]["track"] for t in mine}:
                here = sorted((t for t in mine if t["calls"][i]["track"] == track),
                              key=lambda t: _time_at(t["calls"][i], "arr"))
                for a, b in zip(here[:-1], here[1:]):
                    if _conflict(a, b, i):
                        problems.append(f"{direction} {st['station_id']} {track}: {b['train_id']} "
                                        f"too close behind {a['train_id']}")
            # no overtaking on the plain line between i and i+1
            if i + 1 < len(order):
                seq_dep = sorted(mine, key=lambda t: _time_at(t["calls"][i], "dep"))
                arr = [_time_at(t["calls"][i + 1], "arr") for t in seq_dep]
                if any(x >= y for x, y in zip(arr[:-1], arr[1:])):
                    problems.append(f"{direction}: overtaking between {st['station_id']} and "
                                    f"{order[i + 1]['station_id']}")
    return problems


# =====================================================================================
# Signals and beacons
# =====================================================================================


def _ahead(direction: str, x: float, d: float) -> float:
    """Chainage ``d`` metres ahead of ``x`` in the running direction."""
    return x + d if direction == "down" else x - d


def home_signal_m(direction: str, station: dict, main_switches: list[float]) -> float:
    """Chainage of the home signal of ``station`` for trains arriving in ``direction``.

    HOME_BEFORE_PLATFORM_M before the platform end the train enters, or
    HOME_BEFORE_SWITCH_M before the first switch of the station throat on the
    direction's main track (within HOME_SWITCH_SEARCH_M before the stop marker),
    whichever comes first in the running direction.
    """
    sg = 1.0 if direction == "down" else -1.0
    stop = station["stop_down_m" if direction == "down" else "stop_up_m"]
    entry = station["position_m"] - sg * station["platform_length_m"] / 2.0
    cands = [_ahead(direction, entry, -HOME_BEFORE_PLATFORM_M)]
    cands += [_ahead(direction, x, -HOME_BEFORE_SWITCH_M) for x in main_switches
              if 0.0 < sg * (stop - x) <= HOME_SWITCH_SEARCH_M]
    return min(cands, key=lambda x: sg * x)


def signal_layout(direction: str) -> list[tuple[float, str]]:
    """Signals of one direction in running order: (chainage [m], kind).

    ``kind`` is ``starting`` (departure end of a station), ``block`` (automatic
    block signal) or ``home`` (station entrance). Between a starting signal and
    the next station's home signal, the automatic block signals split the
    stretch into the fewest equal blocks of at most BLOCK_MAX_M; every such
    block must be BLOCK_RANGE_M long (asserted).
    """
    st = stations()
    order = st if direction == "down" else st[::-1]
    col = "stop_down_m" if direction == "down" else "stop_up_m"
    main = "D1" if direction == "down" else "U1"
    switches = [n["position_m"] for n in network()[0] if n["kind"] == "switch" and n["track"] == main]
    out: list[tuple[float, str]] = []
    for k in range(len(order) - 1):
        a = _ahead(direction, order[k][col], STARTING_SIGNAL_OFFSET_M)
        b = home_signal_m(direction, order[k + 1], switches)
        n = int(math.ceil(abs(b - a) / BLOCK_MAX_M))
        pts = [a] + [float(round(a + (b - a) * i / n)) for i in range(1, n)] + [b]
        blocks = np.abs(np.diff(pts))
        lo, hi = BLOCK_RANGE_M
        assert blocks.min() >= lo and blocks.max() <= hi, (direction, order[k]["station_id"], blocks)
        out.append((a, "starting"))
        out += [(x, "block") for x in pts[1:-1]]
        out.append((b, "home"))
    return out


def tasc_distance_m(stop_m: float, direction: str, limits: list[dict]) -> float:
    """How far before the stop marker the TASC beacon of ``direction`` must stand [m].

    A real line puts the TASC beacon where a train at the highest speed allowed
    there can still follow a stopping pattern to the marker. Here: the braking
    curve back from the marker at the weakest adhesion the nightly sweep assumes
    (``TASC_ADHESION_KMH_S``), less a falling gradient's pull (``g·i/(1+ρ)``, the
    lowest rotating-mass factor) and capped by every restriction on the way, must
    reach the speed allowed at the beacon (line speed, or a restriction the beacon
    stands in) after the distance run while the brake builds up at the fleet's
    lowest jerk and 10 % margin. The nearest such point at least ``TASC_DISTANCE_M``
    out, in whole 50 m.
    """
    sg = 1.0 if direction == "down" else -1.0      # down runs towards rising chainage
    rho = min(p["rot"] for p in TRAIN_TYPES.values())
    a_adh = TASC_ADHESION_KMH_S / 3.6
    j_min = TASC_JERK_KMH_S2 / 3.6
    v_line = MAX_SPEED_KMH / 3.6
    caps = [(min(r["start_m"], r["end_m"]), max(r["start_m"], r["end_m"]), r["limit_kmh"] / 3.6)
            for r in limits if r["direction"] in ("both", direction)]

    def allowed(y: float) -> float:
        x = stop_m - sg * y                               # chainage, y metres before the marker
        return min([v_line] + [v for lo, hi, v in caps if lo <= x <= hi])

    ds, n = 1.0, 3000
    brake = np.zeros(n + 1)                               # v² of the braking curve, y = k·ds before the marker
    for k in range(n):
        x = stop_m - sg * (k + 0.5) * ds
        rise = sg * sum(g for a, b, g in GRADIENTS if a <= x < b) / 1000.0
        a = a_adh + G * rise / (1.0 + rho)               # a rising approach helps the brake
        brake[k + 1] = min(brake[k] + 2.0 * a * ds, allowed((k + 1) * ds) ** 2)
    y = TASC_DISTANCE_M
    while True:
        v = allowed(y)
        y_eff = (y - v * a_adh / (2.0 * j_min)) / TASC_MARGIN   # brake build-up, then 10 %
        if brake[min(int(y_eff / ds), n)] >= v * v - 1e-9:
            return y
        y += TASC_ROUND_M


def signals_and_beacons(limits: list[dict]) -> tuple[list[dict], list[dict]]:
    """Block signals and ATS-P / TASC beacons of both directions.

    Telegrams (what the on-board unit receives):
    ``SIG:<signal_id>:G`` signal beacon, signal number and aspect (G = proceed, the
    static content the DB holds); ``SIG:AUTO:G`` the generic telegram of the
    resignalled Ogawa bridge section; ``PU:<limit km/h, 3 digits>:<distance to
    the restriction, m, 4 digits>`` pattern update; ``TASC:<station_id>:<distance
    to the stop marker, m, 4 digits>`` TASC stopping-pattern start.
    """
    st = stations()
    sigs, beacons = [], []
    for direction in ("down", "up"):
        order = st if direction == "down" else st[::-1]
        col = "stop_down_m" if direction == "down" else "stop_up_m"
        sg = +1.0 if direction == "down" else -1.0
        tag = "D" if direction == "down" else "U"
        # --- station signals (home, starting) and automatic block signals between them
        layout = signal_layout(direction)
        mine_sig = []
        for i, (x, kind) in enumerate(layout):
            sid = f"S{tag}{i + 1:02d}"
            mine_sig.append(dict(signal_id=sid, position_m=x, direction=direction, kind=kind))
            generic = kind == "block" and GENERIC_TELEGRAM_SECTION_M[0] <= x <= GENERIC_TELEGRAM_SECTION_M[1]
            beacons.append(dict(beacon_id=f"{tag}-SIG-{i + 1:03d}",
                                position_m=_ahead(direction, x, -SIGNAL_BEACON_OFFSET_M),
                                direction=direction, kind="signal",
                                telegram=f"SIG:{'AUTO' if generic else sid}:G", evaluation_point=True))
        sigs.extend(mine_sig)
        taken = [b["position_m"] for b in beacons if b["direction"] == direction]

        def free(x):
            return START_M <= x <= END_M and all(abs(x - y) >= BEACON_MIN_GAP_M for y in taken)

        # --- TASC: before every stop marker a train of this direction arrives at, far enough out
        # for the approach speed (tasc_distance_m), moved out by 10 m steps if a beacon stands there
        n_tasc = 0
        for s in order[1:]:
            need = tasc_distance_m(s[col], direction, limits)
            for d in (need + 10.0 * k for k in range(0, 12)):
                x = _ahead(direction, s[col], -d)
                if free(x):
                    break
            else:
                raise RuntimeError(f"no room for the TASC beacon of {s['station_id']} {direction}")
            n_tasc += 1
            beacons.append(dict(beacon_id=f"{tag}-TASC-{n_tasc:03d}", position_m=x,
                                direction=direction, kind="tasc",
                                telegram=f"TASC:{s['station_id']}:{int(round(abs(s[col] - x))):04d}",
                                evaluation_point=False))
            taken.append(x)
        # --- pattern-update beacons before each restriction that has one
        stops = sorted(s[col] for s in order)
        pu = []
        for lim in limits:
            if not lim["has_beacon"] or lim["direction"] not in ("both", direction):
                continue
            near = lim["start_m"] if direction == "down" else lim["end_m"]
            x0 = _ahead(direction, near, -PU_DISTANCE_M)
            lo, hi = PU_DISTANCE_RANGE_M
            prev = [m for m in stops if 0.0 < sg * (near - m) < hi]   # stop markers in the way
            after = max(prev, key=lambda m: sg * m) if prev else None
            cands = [_ahead(direction, x0, 10.0 * k * (-1) ** k) for k in range(0, 31)]
            cands = [c for c in cands if lo <= sg * (near - c) <= hi
                     and (after is None or sg * (c - after) >= PU_AFTER_STOP_M)]
            if not cands and after is not None:
                # restriction right after a station: just past its stop marker, where trains start
                cands = [_ahead(direction, after, PU_AFTER_STOP_M + 10.0 * k) for k in range(10)]
                cands = [c for c in cands if sg * (near - c) > 0]
            x = next((c for c in cands if free(c)), None)
            if x is None:
                raise RuntimeError(f"no room for the pattern-update beacon of {lim} {direction}")
            taken.append(x)
            pu.append((x, f"PU:{int(lim['limit_kmh']):03d}:{int(round(abs(near - x))):04d}"))
        for i, (x, tel) in enumerate(sorted(pu, key=lambda p: sg * p[0])):
            beacons.append(dict(beacon_id=f"{tag}-PU-{i + 1:03d}", position_m=x, direction=direction,
                                kind="pattern_update", telegram=tel, evaluation_point=True))
    sigs.sort(key=lambda r: (r["direction"], r["position_m"]))
    beacons.sort(key=lambda r: (r["direction"], r["position_m"]))
    return sigs, beacons


def identical_runs(beacons: list[dict]) -> list[list[str]]:
    """Runs of >= 2 consecutive beacons (running order, one direction) with equal telegrams."""
    runs = []
    for direction in ("down", "up"):
        b = sorted((x for x in beacons if x["direction"] == direction),
                   key=lambda x: x["position_m"] * (1 if direction == "down" else -1))
        cur = [b[0]]
        for x in b[1:] + [None]:
            if x is not None and x["telegram"] == cur[-1]["telegram"]:
                cur.append(x)
                continue
            if len(cur) >= 2:
                runs.append([y["beacon_id"] for y in cur])
            cur = [x]
    return runs


# =====================================================================================
# Track network
# =====================================================================================


def network() -> tuple[list[dict], list[dict]]:
    """Nodes and edges of the double-track line with loops and crossovers.

    Edges are undirected track pieces between consecutive nodes of a track;
    ``from_node`` is the node at lower chainage, ``length_m`` = |Δ chainage|.
    """
    st = stations()
    nodes: list[dict] = []

    def node(node_id, kind, x, track, station_id=None):
        nodes.append(dict(node_id=node_id, kind=kind, position_m=float(x),
                          interlocking=interlocking_at(x), station_id=station_id, track=track))
        return node_id

    edges: list[dict] = []

    def edge(edge_id, a, b, track):
        pa_, pb_ = (next(n["position_m"] for n in nodes if n["node_id"] == k) for k in (a, b))
        if pa_ > pb_:
            a, b, pa_, pb_ = b, a, pb_, pa_
        assert pb_ > pa_, (edge_id, a, b)
        edges.append(dict(edge_id=edge_id, from_node=a, to_node=b, length_m=pb_ - pa_, track=track))

    on_main = {"D1": [], "U1": []}
    for main in ("D1", "U1"):
        col = "stop_down_m" if main == "D1" else "stop_up_m"
        on_main[main].append(node(f"END-{st[0]['station_id']}-{main}", "end", START_M, main))
        on_main[main].append(node(f"END-{st[-1]['station_id']}-{main}", "end", END_M, main))
        for s in st:
            sid = s["station_id"]
            on_main[main].append(node(f"STOP-{sid}-{main}", "stop", s[col], main, sid))
            if s["loop"]:
                loop = main[0] + "2"
                lo = node(f"SW-{sid}-{main}-L1", "switch", s["position_m"] - LOOP_SWITCH_OFFSET_M, main)
                hi = node(f"SW-{sid}-{main}-L2", "switch", s["position_m"] + LOOP_SWITCH_OFFSET_M, main)
                on_main[main] += [lo, hi]
                stop = node(f"STOP-{sid}-{loop}", "stop", s[col], loop, sid)
                edge(f"{loop}-{sid}-1", lo, stop, loop)
                edge(f"{loop}-{sid}-2", stop, hi, loop)
        for k, (x, name) in enumerate(zip(IXL_BOUNDARIES_M, IXL_NAMES[1:])):
            on_main[main].append(node(f"BND-{IXL_NAMES[k][-1]}{name[-1]}-{main}", "boundary", x, main))
    # crossovers: a scissors (two crossovers) at each terminus, one crossover at OHS
    xo = []
    for sid, a in TERMINUS_CROSSOVER_M.items():
        b = a + CROSSOVER_LENGTH_M
        xo += [(sid, 1, ("D1", a), ("U1", b)), (sid, 2, ("U1", a), ("D1", b))]
    for sid, a in INTERMEDIATE_CROSSOVER_M.items():
        xo.append((sid, 1, ("D1", a), ("U1", a + CROSSOVER_LENGTH_M)))
    for sid, k, (t1, x1), (t2, x2) in xo:
        n1 = node(f"SW-{sid}-{t1}-X{k}", "switch", x1, t1)
        n2 = node(f"SW-{sid}-{t2}-X{k}", "switch", x2, t2)
        on_main[t1].append(n1)
        on_main[t2].append(n2)
        edge(f"X-{sid}-{k}", n1, n2, f"X-{sid}-{k}")
    pos = {n["node_id"]: n["position_m"] for n in nodes}
    for main, ids in on_main.items():
        ids = sorted(ids, key=lambda k: pos[k])
        for i, (a, b) in enumerate(zip(ids[:-1], ids[1:])):
            edge(f"{main}-{i + 1:03d}", a, b, main)
    nodes.sort(key=lambda n: (n["position_m"], n["node_id"]))
    edges.sort(key=lambda e: e["edge_id"])
    return nodes, edges


# =====================================================================================
# Tables and output
# =====================================================================================

_S, _D, _I, _B = pa.string(), pa.float64(), pa.int32(), pa.bool_()
SCHEMAS = {
    "line": pa.schema([("line_id", _S), ("name", _S), ("start_m", _D), ("end_m", _D),
                       ("max_speed_kmh", _D), ("schema_version", _I)]),
    "stations": pa.schema([("station_id", _S), ("name", _S), ("position_m", _D),
                           ("stop_down_m", _D), ("stop_up_m", _D), ("platform_length_m", _D)]),
    "gradients": pa.schema([("start_m", _D), ("end_m", _D), ("gradient_permil", _D)]),
    "curves": pa.schema([("start_m", _D), ("end_m", _D), ("radius_m", _D)]),
    "speed_limits": pa.schema([("start_m", _D), ("end_m", _D), ("limit_kmh", _D),
                               ("direction", _S), ("train_type", _S), ("kind", _S),
                               ("has_beacon", _B)]),
    "beacons": pa.schema([("beacon_id", _S), ("position_m", _D), ("direction", _S),
                          ("kind", _S), ("telegram", _S), ("evaluation_point", _B)]),
    # `kind` is an optional extra column: home, starting or (automatic) block signal
    "signals": pa.schema([("signal_id", _S), ("position_m", _D), ("direction", _S), ("kind", _S)]),
    "rolling_stock": pa.schema([
        ("train_type", _S), ("length_m", _D), ("empty_mass_t", _D), ("full_load_mass_t", _D),
        ("rotating_mass_factor", _D), ("max_speed_kmh", _D), ("max_accel_kmh_s", _D),
        ("davis_a_kN", _D), ("davis_b_kN_per_kmh", _D), ("davis_c_kN_per_kmh2", _D),
        ("service_brake_kmh_s", _D), ("stop_brake_kmh_s", _D), ("atsp_pattern_kmh_s", _D),
        ("brake_comfort_kmh_s", _D), ("jerk_limit_kmh_s2", _D), ("speed_margin_kmh", _D),
        ("cruise", _S), ("coast_band_kmh", _D)]),
    "traction": pa.schema([("train_type", _S), ("speed_kmh", _D), ("effort_kN", _D)]),
    # `track` is an optional extra column: the platform or through track used at the call
    "timetable": pa.schema([("train_id", _S), ("train_type", _S), ("direction", _S),
                            ("seq", _I), ("station_id", _S), ("arrival_s", _D),
                            ("departure_s", _D), ("stops", _B), ("track", _S)]),
    # `station_id` and `track` are optional extra columns (docs/line-database.md allows them)
    "nodes": pa.schema([("node_id", _S), ("kind", _S), ("position_m", _D),
                        ("interlocking", _S), ("station_id", _S), ("track", _S)]),
    "edges": pa.schema([("edge_id", _S), ("from_node", _S), ("to_node", _S),
                        ("length_m", _D), ("track", _S)]),
}


def _table(name: str, rows: list[dict]) -> pa.Table:
    schema = SCHEMAS[name]
    cols = {f.name: [r[f.name] for r in rows] for f in schema}
    return pa.Table.from_pydict(cols, schema=schema)


def timetable_rows(trains: list[dict]) -> list[dict]:
    order = {"down": stations(), "up": stations()[::-1]}
    rows = []
    for t in sorted(trains, key=lambda t: t["train_id"]):
        for seq, (s, c) in enumerate(zip(order[t["direction"]], t["calls"])):
            rows.append(dict(train_id=t["train_id"], train_type=t["train_type"],
                             direction=t["direction"], seq=seq, station_id=s["station_id"],
                             arrival_s=c["arr"], departure_s=c["dep"], stops=c["stops"],
                             track=c["track"]))
    return rows


def build_tables() -> tuple[dict[str, pa.Table], dict]:
    """Every table of the sample line, plus figures for the summary."""
    st = stations()
    limits = speed_limits()
    stock, traction = rolling_stock()
    figures = check_rolling_stock(stock, traction)
    sigs, beacons = signals_and_beacons(limits)
    runs = identical_runs(beacons)
    assert any(len(r) >= 3 for r in runs), runs
    nodes, edges = network()
    runtimes = RunTimes(stock, traction, limits)
    trains = timetable(runtimes)
    problems = check_timetable(runtimes, trains)
    if problems:
        raise RuntimeError("timetable conflicts:\n" + "\n".join(problems[:20]))
    check_special_approach(limits)
    line = [dict(line_id=LINE_ID, name=LINE_NAME, start_m=START_M, end_m=END_M,
                 max_speed_kmh=MAX_SPEED_KMH, schema_version=SCHEMA_VERSION)]
    tables = {
        "line": _table("line", line),
        "stations": _table("stations", st),
        "gradients": _table("gradients", [dict(start_m=a, end_m=b, gradient_permil=g)
                                          for a, b, g in sorted(GRADIENTS)]),
        "curves": _table("curves", [dict(start_m=a, end_m=b, radius_m=r)
                                    for a, b, r, _l, _b in sorted(CURVES)]),
        "speed_limits": _table("speed_limits", limits),
        "beacons": _table("beacons", beacons),
        "signals": _table("signals", sigs),
        "rolling_stock": _table("rolling_stock", sorted(stock, key=lambda r: r["train_type"])),
        "traction": _table("traction", sorted(traction, key=lambda r: (r["train_type"], r["speed_kmh"]))),
        "timetable": _table("timetable", timetable_rows(trains)),
        "nodes": _table("nodes", nodes),
        "edges": _table("edges", edges),
    }
    info = dict(figures=figures, runs=runs, trains=trains, runtimes=runtimes)
    return tables, info


def check_special_approach(limits: list[dict]) -> None:
    """The hard Takadai approach is exactly as specified (and nothing else overlaps it)."""
    s = next(x for x in stations() if x["station_id"] == SPECIAL_STATION)
    assert SPECIAL_DIRECTION == "down"
    stop = s["stop_down_m"]
    grads = [g for g in GRADIENTS if g[0] < stop and g[1] > stop - 350.0]
    assert grads == [(stop - 350.0, stop - 200.0, -20.0)], grads
    lim = {(x["start_m"], x["end_m"], x["limit_kmh"]) for x in limits}
    assert (stop - 100.0, stop, 40.0) in lim
    assert any(b == stop - 350.0 and v == 70.0 and b - a >= 300.0 for a, b, v in lim)
    others = [x for x in limits if x["start_m"] < stop and x["end_m"] > stop - 350.0
              and x["limit_kmh"] != 40.0]
    assert not others, others
    assert any(c[0] <= stop - 100.0 and c[1] >= stop for c in CURVES)


def write_tables(tables: dict[str, pa.Table], out: Path) -> None:
    """Write each table atomically in its declared form, with the writer every importer uses, so that
    `planner export csv` -> `planner import csv` gives these files back byte for byte."""
    from planner.line.schema import write_line_table

    out.mkdir(parents=True, exist_ok=True)
    for name, table in tables.items():
        write_line_table(name, table, out / f"{name}.parquet")


def _hms(t: float | None) -> str:
    if t is None:
        return "--"
    t = int(round(t))
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}:{t % 60:02d}"


def summary(tables: dict[str, pa.Table], info: dict) -> str:
    """Human-readable figures (what README.md quotes)."""
    st = stations()
    lines = [f"{LINE_NAME}: {START_M:.0f}-{END_M:.0f} m, {len(st)} stations"]
    for a, b in zip(st[:-1], st[1:]):
        lines.append(f"  {a['station_id']}->{b['station_id']}: {b['position_m'] - a['position_m']:.0f} m")
    for tt, f in info["figures"].items():
        lines.append(f"  {tt}: F0 {f['f0_kN']:.0f} kN, a0 "
                     + "/".join(f"{v:.2f}" for v in f["a0_kmh_s"].values())
                     + f" km/h/s (0/design/full load), balance level empty {f['balance_level_empty_kmh']:.0f}"
                     f", +10 permil design {f['balance_rise10_design_kmh']:.0f}"
                     f", full {f['balance_rise10_full_kmh']:.0f} km/h, R(100) {f['resistance_100_kN']:.1f} kN")
    trains = info["trains"]
    runtimes = info["runtimes"]
    for d in ("down", "up"):
        mine = [t for t in trains if t["direction"] == d]
        n_r = sum(t["service"] == "rapid" for t in mine)
        over = [(t["train_id"], s["station_id"], c["dep"] - c["arr"])
                for t in mine for s, c in zip(runtimes.order(d), t["calls"]) if c["track"][1] == "2"]
        where = {}
        for _tid, sid, _dw in over:
            where[sid] = where.get(sid, 0) + 1
        lines.append(f"  {d}: {len(mine)} trains ({len(mine) - n_r} locals, {n_r} rapids), "
                     f"first {_hms(min(t['calls'][0]['dep'] for t in mine))}, overtakes {where}, "
                     f"loop dwell {min(x[2] for x in over):.0f}-{max(x[2] for x in over):.0f} s")
    for (tt, d, a, b), (t_min, sched) in sorted(runtimes.runs.items()):
        lines.append(f"  run {tt} {d} {a}->{b}: min {t_min:.1f} s, scheduled {sched:.0f} s,"
                     f" margin {100 * (sched / t_min - 1):.1f} %")
    lines.append(f"  identical telegram runs: {info['runs']}")
    lines.append("  rows: " + ", ".join(f"{k} {v.num_rows}" for k, v in tables.items()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent,
                    help="output folder (default: next to this script)")
    ap.add_argument("--summary", action="store_true", help="print the figures README.md quotes")
    args = ap.parse_args(argv)
    tables, info = build_tables()
    write_tables(tables, args.out)
    print(f"wrote {len(tables)} tables to {args.out}")
    if args.summary:
        print(summary(tables, info))
    return 0


if __name__ == "__main__":
    sys.exit(main())
