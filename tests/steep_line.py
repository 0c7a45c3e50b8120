"""A small line with a steep climb and a heavy freight that stalls on it only on the bad day.

``write_steep_line(path, freight=True)`` writes a valid line database (tests/linedb.py
helpers): chainage 0 … 12,000 m, stations A (500 m), B (6,000 m), C (11,500 m), a 20 ‰ climb
from 1,500 to 5,000 m (rising towards B in the down direction), line maximum 100 km/h, no
track network. Train types: ``EMU10`` of the tiny line (a normal passenger EMU) and, with
``freight=True``, ``FRT``: 760 t empty + 160 t payload (920 t loaded), tractive effort 190 kN
to 30 km/h then constant power (190 kN × 30/v).

Why FRT stalls loaded and weak but climbs empty and nominal (gradient force M g ḡ, Davis
A = 8 kN at low speed): empty 760 t on 20 ‰ needs 149 + 8 = 157 kN < 190 kN (or 171 kN
with traction × 0.9), it climbs; loaded 920 t needs 180.5 + 8 = 188.5 kN > 0.9 × 190 =
171 kN, it loses speed all the way up the 3.5 km climb and stops: below 30 km/h it has
0.5 · 975 t · (8.3 m/s)² ≈ 34 MJ of kinetic energy against a deficit of at least 17.5 kN,
spent in under 2 km (above 30 km/h the power curve's deficit is larger still).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from planner.line.schema import SCHEMA_VERSION

from linedb import default_tables, write_line_db

N = None

FREIGHT = dict(train_type="FRT", length_m=200.0, empty_mass_t=760.0, full_load_mass_t=160.0,
               rotating_mass_factor=0.06, max_speed_kmh=80.0, max_accel_kmh_s=1.0, davis_a_kN=8.0,
               davis_b_kN_per_kmh=0.1, davis_c_kN_per_kmh2=0.002, service_brake_kmh_s=2.5,
               stop_brake_kmh_s=2.5, atsp_pattern_kmh_s=2.0, brake_comfort_kmh_s=2.5,
               jerk_limit_kmh_s2=3.0, speed_margin_kmh=3.0, cruise="constant", coast_band_kmh=0.0)
"""The freight train type (rolling_stock.parquet columns, railway units)."""


def steep_tables(line_id: str = "steep", freight: bool = True) -> dict[str, pd.DataFrame]:
    """The steep line's tables (railway units, as on disk); ``freight=False`` leaves FRT out."""
    t = default_tables(line_id)
    t["line"] = pd.DataFrame([dict(line_id=line_id, name="Steep test line", start_m=0.0, end_m=12000.0,
                                   max_speed_kmh=100.0, schema_version=SCHEMA_VERSION)])
    t["stations"] = pd.DataFrame(
        [("A", "Aoba", 500.0, 560.0, 440.0, 200.0),
         ("B", "Bashi", 6000.0, 6060.0, 5940.0, 200.0),
         ("C", "Chuo", 11500.0, 11560.0, 11440.0, 200.0)],
        columns=["station_id", "name", "position_m", "stop_down_m", "stop_up_m", "platform_length_m"])
    t["gradients"] = pd.DataFrame([(1500.0, 5000.0, 20.0)], columns=["start_m", "end_m", "gradient_permil"])
    t["curves"] = pd.DataFrame([(8000.0, 8400.0, 800.0)], columns=["start_m", "end_m", "radius_m"])
    t["speed_limits"] = pd.DataFrame(
        [(8000.0, 8400.0, 85.0, "both", N, "curve", True)],
        columns=["start_m", "end_m", "limit_kmh", "direction", "train_type", "kind", "has_beacon"])
    t["beacons"] = pd.DataFrame(
        [("B1", 3000.0, "down", "signal", "S1:G", True), ("B2", 9000.0, "down", "signal", "S2:G", True),
         ("B3", 9000.0, "up", "signal", "S3:G", True), ("B4", 3000.0, "up", "signal", "S4:G", True)],
        columns=["beacon_id", "position_m", "direction", "kind", "telegram", "evaluation_point"])
    t["signals"] = pd.DataFrame([("SG1", 3000.0, "down"), ("SG2", 9000.0, "up")],
                                columns=["signal_id", "position_m", "direction"])
    rs = t["rolling_stock"][t["rolling_stock"].train_type == "EMU10"]
    tr = t["traction"][t["traction"].train_type == "EMU10"]
    tt = [("101", "EMU10", "down", 0, "A", N, 21600.0, True),
          ("101", "EMU10", "down", 1, "B", 21900.0, 21930.0, True),
          ("101", "EMU10", "down", 2, "C", 22250.0, N, True),
          ("102", "EMU10", "up", 0, "C", N, 23000.0, True),
          ("102", "EMU10", "up", 1, "B", 23300.0, 23330.0, True),
          ("102", "EMU10", "up", 2, "A", 23650.0, N, True)]
    if freight:
        rs = pd.concat([rs, pd.DataFrame([FREIGHT])], ignore_index=True)
        v = [0.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0]
        tr = pd.concat([tr, pd.DataFrame([("FRT", x, 190.0 * 30.0 / max(x, 30.0)) for x in v],
                                         columns=tr.columns)], ignore_index=True)
        tt += [("901", "FRT", "down", 0, "A", N, 25000.0, True),
               ("901", "FRT", "down", 1, "B", 25700.0, 25760.0, True),
               ("901", "FRT", "down", 2, "C", 26300.0, N, True),
               ("902", "FRT", "up", 0, "C", N, 27000.0, True),
               ("902", "FRT", "up", 1, "B", 27600.0, 27660.0, True),
               ("902", "FRT", "up", 2, "A", 28200.0, N, True)]
    t["rolling_stock"] = rs.reset_index(drop=True)
    t["traction"] = tr.reset_index(drop=True)
    t["timetable"] = pd.DataFrame(tt, columns=t["timetable"].columns)
    t["nodes"] = None
    t["edges"] = None
    return t


def write_steep_line(path: str | Path, freight: bool = True, line_id: str = "steep") -> Path:
    """Write the steep line to folder ``path`` (module doc)."""
    return write_line_db(path, **steep_tables(line_id, freight))
