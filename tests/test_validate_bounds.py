"""Declared value ranges (issue 32): at each bound of each bounded column, the value on the bound
(or the nearest float inside an open bound) keeps the tiny line valid, and the nearest float
outside gives exactly one one-line error naming file, row and column.

Each case edits one cell of the tiny line (tests/linedb.py). Where the value at a bound would
break another rule of the tiny line (a station at -10,000 km is outside its 5 km), the case
widens the line to the full chainage range first ("wide"), or lengthens the traction curve
("fast") so that a 600 km/h train is possible; sides that no valid line can reach are not
tested inside (a line cannot start at +10,000 km and end after it).
"""
from __future__ import annotations

import math

import pytest

from planner.errors import Violation
from planner.line.loader import check_line
from planner.line.schema import MAX_CHAINAGE_M, TABLES, column_range

from linedb import default_tables, write_line_db

C = MAX_CHAINAGE_M


def _wide(t):
    t["line"].loc[0, ["start_m", "end_m"]] = [-C, C]


def _fast(t):
    t["traction"].loc[len(t["traction"])] = ["EMU10", 1000.0, 50.0]


def _no_margin(t):
    """On-board margins 0: a speed just above 0 still leaves an on-board speed."""
    t["rolling_stock"]["speed_margin_kmh"] = 0.0


def _free(t):
    """Level track and no standstill resistance: any brake rate holds the train (the brake rule asks for > 0)."""
    t["gradients"]["gradient_permil"] = 0.0
    t["rolling_stock"]["davis_a_kN"] = 0.0


def _heavy(t):
    """A 100,000 t train on level track: 10,000 kN of Davis A is 0.1 m/s², less than its brakes."""
    t["gradients"]["gradient_permil"] = 0.0
    t["rolling_stock"]["empty_mass_t"] = 100_000.0


# (table, column, row, side, base): side "lo" or "hi" of the declared range; base edits the tiny line
CASES = [
    ("line", "start_m", 0, "lo", _wide), ("line", "end_m", 0, "hi", _wide),
    ("line", "max_speed_kmh", 0, "lo", _no_margin), ("line", "max_speed_kmh", 0, "hi", None),
    ("line", "approach_m", 0, "lo", None), ("line", "approach_m", 0, "hi", _wide),  # an optional column
    ("stations", "position_m", 0, "lo", _wide), ("stations", "position_m", 2, "hi", _wide),
    ("stations", "stop_down_m", 2, "hi", _wide), ("stations", "stop_up_m", 0, "lo", _wide),
    ("stations", "platform_length_m", 0, "lo", None), ("stations", "platform_length_m", 0, "hi", None),
    ("gradients", "start_m", 0, "lo", _wide), ("gradients", "end_m", 2, "hi", _wide),
    ("gradients", "gradient_permil", 1, "lo", None), ("gradients", "gradient_permil", 1, "hi", None),
    ("curves", "start_m", 0, "lo", _wide), ("curves", "end_m", 1, "hi", _wide),
    ("curves", "radius_m", 0, "lo", None), ("curves", "radius_m", 0, "hi", None),
    ("speed_limits", "start_m", 0, "lo", _wide), ("speed_limits", "end_m", 2, "hi", _wide),
    ("speed_limits", "limit_kmh", 0, "lo", _no_margin), ("speed_limits", "limit_kmh", 0, "hi", None),
    ("beacons", "position_m", 0, "lo", _wide), ("beacons", "position_m", 1, "hi", _wide),
    ("signals", "position_m", 0, "lo", _wide), ("signals", "position_m", 1, "hi", _wide),
    ("rolling_stock", "length_m", 0, "lo", None), ("rolling_stock", "length_m", 0, "hi", _wide),
    ("rolling_stock", "empty_mass_t", 0, "lo", _free), ("rolling_stock", "empty_mass_t", 0, "hi", None),
    ("rolling_stock", "full_load_mass_t", 0, "lo", None), ("rolling_stock", "full_load_mass_t", 0, "hi", None),
    ("rolling_stock", "rotating_mass_factor", 0, "lo", None),
    ("rolling_stock", "rotating_mass_factor", 0, "hi", None),
    ("rolling_stock", "max_speed_kmh", 0, "lo", _no_margin), ("rolling_stock", "max_speed_kmh", 0, "hi", _fast),
    *[("rolling_stock", c, 0, side, _heavy if (c, side) == ("davis_a_kN", "hi") else
       _free if c.endswith("_kmh_s") else None)
      for c in ("max_accel_kmh_s", "service_brake_kmh_s", "stop_brake_kmh_s", "atsp_pattern_kmh_s",
                "brake_comfort_kmh_s", "davis_a_kN", "davis_b_kN_per_kmh", "davis_c_kN_per_kmh2",
                "speed_margin_kmh", "coast_band_kmh")
      for side in ("lo", "hi")],
    ("rolling_stock", "jerk_limit_kmh_s2", 0, "hi", None),
    ("traction", "speed_kmh", 0, "lo", None), ("traction", "speed_kmh", 2, "hi", None),
    ("traction", "effort_kN", 0, "lo", None), ("traction", "effort_kN", 0, "hi", None),
    ("timetable", "departure_s", 0, "lo", None), ("timetable", "arrival_s", 2, "hi", None),
    ("nodes", "position_m", 0, "lo", None), ("nodes", "position_m", 3, "hi", None),
    ("edges", "length_m", 0, "lo", None), ("edges", "length_m", 0, "hi", None),
]
IDS = [f"{t}.{c}[{r}].{side}" for t, c, r, side, _ in CASES]


def _values(table: str, column: str, side: str) -> tuple[float, float]:
    """(just inside, just outside) the declared range at ``side``: adjacent floats, independent of the messages."""
    rng = column_range(TABLES[table].schema.field(column))
    if side == "hi":
        return rng.hi, math.nextafter(rng.hi, math.inf)
    if rng.lo_open:
        return math.nextafter(rng.lo, math.inf), rng.lo
    return rng.lo, math.nextafter(rng.lo, -math.inf)


def _check(tmp_path, name, table, column, row, value, base) -> list[Violation]:
    t = default_tables()
    if base is not None:
        base(t)
    t[table].loc[row, column] = value
    return check_line(write_line_db(tmp_path / name, **t))


@pytest.mark.parametrize("table, column, row, side, base", CASES, ids=IDS)
def test_bound(tmp_path, table, column, row, side, base):
    inside, outside = _values(table, column, side)
    assert _check(tmp_path, "inside", table, column, row, inside, base) == []
    found = _check(tmp_path, "outside", table, column, row, outside, base)
    assert [(v.file, v.row, v.column) for v in found] == [(f"{table}.parquet", row, column)], found
    line = str(found[0])
    assert line.startswith(f"{table}.parquet row {row} ") and f" column {column}: must be " in line
    assert "\n" not in line and "accepted" in line


def test_every_bounded_column_has_a_case():
    """A new bound without a test case fails here (columns of the line database with a declared range)."""
    bounded = {(name, f.name) for name, spec in TABLES.items() for f in spec.schema if column_range(f)}
    assert bounded == {(t, c) for t, c, *_ in CASES}


def test_every_number_column_is_bounded():
    """Each double column of the line database declares a range: nothing numeric is unbounded."""
    doubles = {(name, f.name) for name, spec in TABLES.items() for f in spec.schema if str(f.type) == "double"}
    assert doubles == {(name, f.name) for name, spec in TABLES.items() for f in spec.schema if column_range(f)}


@pytest.mark.parametrize("table, column, row", [
    ("line", "max_speed_kmh", 0), ("rolling_stock", "empty_mass_t", 0), ("rolling_stock", "davis_c_kN_per_kmh2", 1),
    ("gradients", "end_m", 0), ("timetable", "arrival_s", 1), ("traction", "effort_kN", 4),
])
def test_1e308_is_refused_up_front(tmp_path, table, column, row):
    """The issue's examples: 1e308 is one error on its own cell, not a late failure elsewhere."""
    found = _check(tmp_path, "big", table, column, row, 1e308, None)
    assert [(v.file, v.row, v.column) for v in found] == [(f"{table}.parquet", row, column)]
    assert "found 1e+308" in str(found[0])


def test_jerk_at_its_open_lower_bound_is_refused_once(tmp_path):
    """0 is outside (0, 100]; just above 0 no valid line exists (the jerk rule's own message)."""
    found = _check(tmp_path, "zero", "rolling_stock", "jerk_limit_kmh_s2", 0, 0.0, None)
    assert [(v.file, v.row, v.column) for v in found] == [("rolling_stock.parquet", 0, "jerk_limit_kmh_s2")]


@pytest.mark.parametrize("table", ["gradients", "curves"])
def test_segment_table_denser_than_a_row_per_metre_is_refused(tmp_path, table):
    """The tiny line is 5000 m long: 5000 segments of 1 m pass, 5001 of 5000/5001 m are refused as a whole file."""
    import numpy as np
    import pandas as pd

    value = {"gradients": ("gradient_permil", 1.0), "curves": ("radius_m", 500.0)}[table]
    for n, ok in ((5000, True), (5001, False)):
        edges = np.linspace(0.0, 5000.0, n + 1)
        df = pd.DataFrame({"start_m": edges[:-1], "end_m": edges[1:], value[0]: value[1]})
        found = check_line(write_line_db(tmp_path / f"{table}{n}", **{table: df}))
        if ok:
            assert found == []
        else:
            assert [(v.file, v.row, v.column) for v in found] == [(f"{table}.parquet", None, None)]
            assert "has 5001 rows for a line of 5000.0 m; at most 5000" in str(found[0])
