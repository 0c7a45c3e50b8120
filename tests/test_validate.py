"""One test per validation rule: break a copy of the tiny line DB, expect a message naming file, row, column."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from planner.errors import LineValidationError, Violation
from planner.line.loader import check_line, load_line
from planner.line.validate import format_violations

from linedb import default_tables, to_arrow, write_line_db

N = None


# ---- mutators: each takes fresh default tables and returns overrides for write_line_db
def cell(table, row, column, value):
    def m(t):
        df = t[table]
        if value is None or isinstance(value, str):
            df[column] = df[column].astype(object)
        df.loc[row, column] = value
        return {table: df}
    return m


def cells(table, changes):
    """Several (row, column, value) edits in one table."""
    def m(t):
        df = t[table]
        for row, column, value in changes:
            if value is None or isinstance(value, str):
                df[column] = df[column].astype(object)
            df.loc[row, column] = value
        return {table: df}
    return m


def rows(table, keep=None, add=None, order=None):
    def m(t):
        df = t[table]
        if keep is not None:
            df = df.iloc[keep].reset_index(drop=True)
        if order is not None:
            df = df.iloc[order].reset_index(drop=True)
        if add is not None:
            df = pd.concat([df, pd.DataFrame(add, columns=df.columns)], ignore_index=True)
        return {table: df}
    return m


def arrow(table, column, values):
    """Replace one column by a raw pyarrow array (wrong types, NaN, inf)."""
    def m(t):
        tab = to_arrow(table, t[table])
        i = tab.column_names.index(column)
        return {table: tab.set_column(i, column, pa.array(values))}
    return m


def drop_column(table, column):
    return lambda t: {table: t[table].drop(columns=[column])}


def omit(*tables):
    return lambda t: {name: None for name in tables}


def empty(table):
    return lambda t: {table: t[table].iloc[0:0]}


# (id, mutator, file, row, column, text expected in the message)
CASES = [
    # --- structure: files, columns, types, cells
    ("missing_file", omit("gradients"), "gradients.parquet", N, N, "file is missing"),
    ("missing_rolling_stock", omit("rolling_stock"), "rolling_stock.parquet", N, N, "file is missing"),
    ("edges_without_nodes", omit("nodes"), "nodes.parquet", N, N, "edges.parquet exists"),
    ("nodes_without_edges", omit("edges"), "edges.parquet", N, N, "nodes.parquet exists"),
    ("missing_column", drop_column("curves", "radius_m"), "curves.parquet", N, "radius_m",
     "required column is missing"),
    ("wrong_type_string_for_double", arrow("stations", "position_m", ["200", "2500", "4800"]),
     "stations.parquet", N, "position_m", "expected double, found string"),
    ("wrong_type_double_for_int32", arrow("timetable", "seq", [0.0, 1.0, 2.0, 0.0, 1.0, 2.0]),
     "timetable.parquet", N, "seq", "expected int32, found double"),
    ("wrong_type_string_for_bool", arrow("speed_limits", "has_beacon", ["yes", "no", "yes"]),
     "speed_limits.parquet", N, "has_beacon", "expected bool, found string"),
    ("int32_overflow", arrow("timetable", "seq", [0, 1, 2**40, 0, 1, 2]),
     "timetable.parquet", N, "seq", "do not convert"),
    ("nan", arrow("gradients", "gradient_permil", [0.0, math.nan, -10.0]),
     "gradients.parquet", 1, "gradient_permil", "NaN"),
    ("nan_in_nullable", arrow("timetable", "arrival_s", [None, math.nan, 22100.0, None, 22200.0, 22500.0]),
     "timetable.parquet", 1, "arrival_s", "NaN"),
    ("inf", arrow("curves", "radius_m", [600.0, math.inf]), "curves.parquet", 1, "radius_m", "inf"),
    ("minus_inf", arrow("beacons", "position_m", [900.0, -math.inf, 4310.0, 2000.0]),
     "beacons.parquet", 1, "position_m", "-inf"),
    ("null_double", cell("stations", 1, "platform_length_m", None), "stations.parquet", 1,
     "platform_length_m", "null value"),
    ("null_string", cell("timetable", 0, "station_id", None), "timetable.parquet", 0, "station_id",
     "null value"),
    ("empty_line", empty("line"), "line.parquet", N, N, "exactly 1 row"),
    ("empty_stations", empty("stations"), "stations.parquet", N, N, "at least 2 rows"),
    ("one_station", rows("stations", keep=[0]), "stations.parquet", N, N, "at least 2 rows"),
    ("empty_rolling_stock", empty("rolling_stock"), "rolling_stock.parquet", N, N, "at least 1 row"),
    ("empty_traction", empty("traction"), "traction.parquet", N, N, "at least 1 row"),
    # --- line.parquet
    ("line_two_rows", rows("line", keep=[0, 0]), "line.parquet", N, N, "has 2 rows"),
    ("schema_version", cell("line", 0, "schema_version", 3), "line.parquet", 0, "schema_version",
     "schema versions 1 to 2: a newer one needs a newer planner"),
    ("line_start_after_end", cell("line", 0, "end_m", 0.0), "line.parquet", 0, "end_m",
     "must be greater than start_m"),
    ("line_max_speed", cell("line", 0, "max_speed_kmh", 0.0), "line.parquet", 0, "max_speed_kmh", "> 0"),
    # --- stations.parquet
    ("station_duplicate_id", cell("stations", 2, "station_id", "A"), "stations.parquet", 2, "station_id",
     "duplicate station_id 'A'; also in row 0"),
    ("station_empty_id", cell("stations", 1, "station_id", ""), "stations.parquet", 1, "station_id", "empty"),
    ("stations_unsorted", cell("stations", 1, "position_m", 100.0), "stations.parquet", 1, "position_m",
     "sorted by position_m"),
    ("stop_marker_outside", cell("stations", 2, "stop_down_m", 5100.0), "stations.parquet", 2,
     "stop_down_m", "outside the line's chainage range [0.0, 5000.0]"),
    ("stop_up_marker_outside", cell("stations", 0, "stop_up_m", -10.0), "stations.parquet", 0,
     "stop_up_m", "outside"),
    ("platform_length", cell("stations", 0, "platform_length_m", 0.0), "stations.parquet", 0,
     "platform_length_m", "> 0"),
    # --- gradients.parquet
    ("gradient_start_after_end", cell("gradients", 1, "end_m", 900.0), "gradients.parquet", 1, "end_m",
     "must be greater than start_m"),
    ("gradient_overlap", cell("gradients", 2, "start_m", 1900.0), "gradients.parquet", 2, "start_m",
     "overlaps row 1, which ends at 2000.0"),
    ("gradient_unsorted", rows("gradients", order=[0, 2, 1]), "gradients.parquet", 2, "start_m",
     "not sorted"),
    ("gradient_too_steep", cell("gradients", 1, "gradient_permil", 40.5), "gradients.parquet", 1,
     "gradient_permil", "must be <= 40, found 40.5"),
    ("gradient_too_steep_down", cell("gradients", 2, "gradient_permil", -41.0), "gradients.parquet", 2,
     "gradient_permil", "must be >= -40, found -41.0"),
    ("gradient_outside_line", cell("gradients", 2, "end_m", 5500.0), "gradients.parquet", 2, "end_m",
     "outside"),
    # --- curves.parquet
    ("curve_start_after_end", cell("curves", 0, "end_m", 1200.0), "curves.parquet", 0, "end_m",
     "must be greater"),
    ("curve_overlap", cell("curves", 1, "start_m", 1500.0), "curves.parquet", 1, "start_m",
     "overlaps row 0, which ends at 1600.0"),
    ("curve_radius_zero", cell("curves", 0, "radius_m", 0.0), "curves.parquet", 0, "radius_m", "must be >= 10, found 0.0"),
    ("curve_radius_negative", cell("curves", 1, "radius_m", -300.0), "curves.parquet", 1, "radius_m", "must be >= 10"),
    ("curve_outside_line", cell("curves", 0, "start_m", -50.0), "curves.parquet", 0, "start_m", "outside"),
    # --- speed_limits.parquet
    ("limit_start_after_end", cell("speed_limits", 1, "end_m", 2300.0), "speed_limits.parquet", 1, "end_m",
     "must be greater"),
    ("limit_zero", cell("speed_limits", 0, "limit_kmh", 0.0), "speed_limits.parquet", 0, "limit_kmh", "must be >= 1"),
    ("limit_direction", cell("speed_limits", 2, "direction", "sideways"), "speed_limits.parquet", 2,
     "direction", "not one of both, down, up"),
    ("limit_unknown_train_type", cell("speed_limits", 1, "train_type", "EMU99"), "speed_limits.parquet", 1,
     "train_type", "unknown train type 'EMU99'"),
    # --- beacons.parquet
    ("beacon_duplicate_id", cell("beacons", 3, "beacon_id", "B1"), "beacons.parquet", 3, "beacon_id",
     "duplicate beacon_id 'B1'"),
    ("beacon_direction_both", cell("beacons", 0, "direction", "both"), "beacons.parquet", 0, "direction",
     "not one of down, up"),
    ("beacon_kind", cell("beacons", 1, "kind", "balise"), "beacons.parquet", 1, "kind",
     "not one of signal, pattern_update, tasc, other"),
    ("beacon_outside_line", cell("beacons", 2, "position_m", 6000.0), "beacons.parquet", 2, "position_m",
     "outside"),
    # --- signals.parquet
    ("signal_duplicate_id", cell("signals", 1, "signal_id", "SG1"), "signals.parquet", 1, "signal_id",
     "duplicate"),
    ("signal_direction", cell("signals", 0, "direction", "north"), "signals.parquet", 0, "direction",
     "not one of down, up"),
    ("signal_outside_line", cell("signals", 1, "position_m", -1.0), "signals.parquet", 1, "position_m",
     "outside"),
    # --- rolling_stock.parquet
    ("stock_duplicate_type", cell("rolling_stock", 1, "train_type", "EMU10"), "rolling_stock.parquet", 1,
     "train_type", "duplicate train_type 'EMU10'"),
    ("stock_length", cell("rolling_stock", 0, "length_m", 0.0), "rolling_stock.parquet", 0, "length_m",
     "must be >= 1"),
    ("stock_mass", cell("rolling_stock", 1, "empty_mass_t", -5.0), "rolling_stock.parquet", 1,
     "empty_mass_t", "must be >= 1"),
    ("stock_passenger_mass", cell("rolling_stock", 1, "full_load_mass_t", -5.0), "rolling_stock.parquet", 1,
     "full_load_mass_t", ">= 0"),
    ("stock_max_speed", cell("rolling_stock", 0, "max_speed_kmh", 0.0), "rolling_stock.parquet", 0,
     "max_speed_kmh", "> 0"),
    ("stock_stop_brake", cell("rolling_stock", 0, "stop_brake_kmh_s", 0.0), "rolling_stock.parquet", 0,
     "stop_brake_kmh_s", "must be >= 0.05"),
    ("stock_service_brake", cell("rolling_stock", 1, "service_brake_kmh_s", -3.5), "rolling_stock.parquet", 1,
     "service_brake_kmh_s", "must be >= 0.05"),
    ("stock_jerk", cell("rolling_stock", 1, "jerk_limit_kmh_s2", 0.0), "rolling_stock.parquet", 1,
     "jerk_limit_kmh_s2", "> 0"),
    ("stock_rotating_factor", cell("rolling_stock", 0, "rotating_mass_factor", -0.01),
     "rolling_stock.parquet", 0, "rotating_mass_factor", ">= 0"),
    ("stock_davis", cell("rolling_stock", 0, "davis_b_kN_per_kmh", -0.01), "rolling_stock.parquet", 0,
     "davis_b_kN_per_kmh", ">= 0"),
    ("stock_cruise", cell("rolling_stock", 0, "cruise", "eco"), "rolling_stock.parquet", 0, "cruise",
     "not one of constant, sawtooth"),
    ("stock_sawtooth_band", cell("rolling_stock", 1, "coast_band_kmh", 0.0), "rolling_stock.parquet", 1,
     "coast_band_kmh", "sawtooth"),
    # --- traction.parquet
    ("traction_not_from_zero", cell("traction", 3, "speed_kmh", 5.0), "traction.parquet", 3, "speed_kmh",
     "must start at 0 km/h"),
    ("traction_not_increasing", cell("traction", 1, "speed_kmh", 0.0), "traction.parquet", 1, "speed_kmh",
     "strictly increasing"),
    ("traction_below_max_speed", cell("traction", 2, "speed_kmh", 100.0), "traction.parquet", 2,
     "speed_kmh", "below its max_speed_kmh 110.0"),
    ("traction_negative_effort", cell("traction", 4, "effort_kN", -1.0), "traction.parquet", 4, "effort_kN",
     ">= 0"),
    ("traction_unknown_type", rows("traction", add=[("EMU99", 0.0, 100.0), ("EMU99", 120.0, 50.0)]),
     "traction.parquet", 6, "train_type", "unknown train type 'EMU99'"),
    ("stock_without_traction", rows("traction", keep=[0, 1, 2]), "rolling_stock.parquet", 1, "train_type",
     "no traction curve"),
    # --- timetable.parquet
    ("tt_unknown_train_type", cells("timetable", [(r, "train_type", "EMU99") for r in (0, 1, 2)]),
     "timetable.parquet", 0, "train_type", "unknown train type 'EMU99'"),
    ("tt_unknown_station", cell("timetable", 1, "station_id", "Z"), "timetable.parquet", 1, "station_id",
     "unknown station 'Z'"),
    ("tt_direction", cells("timetable", [(r, "direction", "left") for r in (3, 4, 5)]), "timetable.parquet",
     3, "direction", "not one of down, up"),
    ("tt_seq_gap", cell("timetable", 2, "seq", 3), "timetable.parquet", 2, "seq",
     "must run 0..2 without gaps; found 0, 1, 3"),
    ("tt_seq_not_from_zero", cells("timetable", [(3, "seq", 1), (4, "seq", 2), (5, "seq", 3)]),
     "timetable.parquet", 3, "seq", "without gaps"),
    ("tt_seq_duplicate", cell("timetable", 2, "seq", 1), "timetable.parquet", 2, "seq",
     "duplicate seq 1 for train '101'; also in row 1"),
    ("tt_two_directions", cell("timetable", 1, "direction", "up"), "timetable.parquet", 1, "direction",
     "one train has one direction"),
    ("tt_two_train_types", cell("timetable", 4, "train_type", "EMU10"), "timetable.parquet", 4, "train_type",
     "one train has one train_type"),
    ("tt_departure_before_arrival", cell("timetable", 1, "arrival_s", 21840.0), "timetable.parquet", 1,
     "departure_s", "earlier than arrival_s 21840.0"),
    ("tt_arrival_before_previous_departure", cell("timetable", 1, "departure_s", 22200.0), "timetable.parquet",
     2, "arrival_s", "earlier than departure_s 22200.0 in row 1 (seq 1)"),
    ("tt_null_arrival_en_route", cell("timetable", 4, "arrival_s", None), "timetable.parquet", 4,
     "arrival_s", "only at the origin"),
    ("tt_null_departure_at_origin", cell("timetable", 0, "departure_s", None), "timetable.parquet", 0,
     "departure_s", "only at the terminus (seq 2)"),
    ("tt_wrong_way_down", cells("timetable", [(1, "station_id", "C"), (2, "station_id", "B")]),
     "timetable.parquet", 2, "station_id", "a down train's calls must follow its direction"),
    ("tt_wrong_way_up", cells("timetable", [(3, "station_id", "A"), (5, "station_id", "C")]),
     "timetable.parquet", 4, "station_id", "an up train's calls must follow its direction"),
    ("tt_same_station_twice", cell("timetable", 2, "station_id", "B"), "timetable.parquet", 2, "station_id",
     "must follow its direction"),
    ("tt_single_call", rows("timetable", add=[("303", "EMU6", "down", 0, "A", N, 30000.0, True)]),
     "timetable.parquet", 6, "train_id", "at least two"),
    # --- nodes.parquet, edges.parquet
    ("node_duplicate_id", cell("nodes", 3, "node_id", "N1"), "nodes.parquet", 3, "node_id", "duplicate"),
    ("node_kind", cell("nodes", 2, "kind", "bridge"), "nodes.parquet", 2, "kind",
     "not one of switch, stop, boundary, end"),
    ("node_unknown_station", cell("nodes", 1, "station_id", "Z"), "nodes.parquet", 1, "station_id",
     "unknown station 'Z'"),
    ("edge_duplicate_id", cell("edges", 2, "edge_id", "E1"), "edges.parquet", 2, "edge_id", "duplicate"),
    ("edge_unknown_from", cell("edges", 0, "from_node", "N9"), "edges.parquet", 0, "from_node",
     "unknown node 'N9'"),
    ("edge_unknown_to", cell("edges", 2, "to_node", "N9"), "edges.parquet", 2, "to_node", "unknown node"),
    ("edge_length", cell("edges", 1, "length_m", 0.0), "edges.parquet", 1, "length_m", "> 0"),
]


def _violations(tmp_path, overrides) -> list[Violation]:
    path = write_line_db(tmp_path / "tiny", **overrides)
    with pytest.raises(LineValidationError) as ei:
        load_line(path)
    assert ei.value.violations == check_line(path)
    return ei.value.violations


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_rule(tmp_path, case):
    _, mutate, file, row, column, text = case
    found = _violations(tmp_path, mutate(default_tables()))
    hits = [v for v in found if (v.file, v.row, v.column) == (file, row, column) and text in v.message]
    assert hits, "expected {} row {} column {} ~ {!r}; got:\n{}".format(
        file, row, column, text, "\n".join(map(str, found)))
    line = str(hits[0])
    assert line.startswith(file)
    assert "\n" not in line
    if row is not None:
        assert f"{file} row {row}" in line
    if column is not None:
        assert f"column {column}:" in line


def test_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


def test_message_format_matches_schema_example(tmp_path):
    found = _violations(tmp_path, cells("gradients", [(1, "end_m", 4350.0), (2, "start_m", 4200.0),
                                                      (2, "end_m", 4500.0)])(default_tables()))
    assert ("gradients.parquet row 2 (start_m=4200.0) column start_m: overlaps row 1, which ends at 4350.0"
            in [str(v) for v in found])


def test_row_id_names_timetable_train_and_seq(tmp_path):
    found = _violations(tmp_path, cell("timetable", 1, "station_id", "Z")(default_tables()))
    assert [str(v) for v in found] == [
        "timetable.parquet row 1 (train_id=101 seq=1) column station_id: unknown station 'Z' "
        "(not in stations.parquet)"
    ]


def test_valid_db_has_no_violations(tmp_path):
    assert check_line(write_line_db(tmp_path / "tiny")) == []


@pytest.mark.parametrize("table", ["gradients", "curves", "speed_limits", "beacons"])
def test_empty_optional_content_tables_are_valid(tmp_path, table):
    path = write_line_db(tmp_path / "tiny", **{table: default_tables()[table].iloc[0:0]})
    assert check_line(path) == []


def test_empty_tables_written_by_pandas_with_null_types_are_valid(tmp_path):
    """pandas writes empty object columns as pyarrow `null` type; that must not count as a wrong type."""
    t = default_tables()
    over = {name: pa.Table.from_pandas(t[name].iloc[0:0].astype(object), preserve_index=False)
            for name in ("gradients", "curves", "speed_limits", "beacons")}
    assert all(pa.types.is_null(f.type) for f in over["beacons"].schema)
    assert check_line(write_line_db(tmp_path / "tiny", **over)) == []


@pytest.mark.parametrize("tables", [("signals",), ("nodes", "edges"), ("signals", "nodes", "edges")])
def test_optional_tables_may_be_absent(tmp_path, tables):
    assert check_line(write_line_db(tmp_path / "tiny", **{n: None for n in tables})) == []


def test_integer_columns_are_accepted_where_double_is_declared(tmp_path):
    t = default_tables()
    g = to_arrow("gradients", t["gradients"])
    g = g.set_column(0, "start_m", pa.array([0, 1000, 2500], pa.int64()))
    seq = to_arrow("timetable", t["timetable"])
    seq = seq.set_column(3, "seq", pa.array(seq.column("seq").to_pylist(), pa.int64()))
    path = write_line_db(tmp_path / "tiny", gradients=g, timetable=seq)
    assert check_line(path) == []
    line = load_line(path)
    assert line.gradients.start_m.dtype == np.float64
    assert line.trains[0].calls[2].seq == 2


def test_string_variants_are_accepted(tmp_path):
    st = to_arrow("stations", default_tables()["stations"])
    st = st.set_column(0, "station_id", st.column("station_id").cast(pa.large_string()))
    st = st.set_column(1, "name", st.column("name").dictionary_encode())
    assert check_line(write_line_db(tmp_path / "tiny", stations=st)) == []


def test_extra_columns_and_tables_are_allowed(tmp_path):
    t = default_tables()
    t["stations"]["operator_note"] = ["x", "y", "z"]
    path = write_line_db(tmp_path / "tiny", stations=t["stations"],
                         depots=pd.DataFrame({"depot_id": ["D1"]}))
    assert check_line(path) == []


def test_nodes_optional_columns_may_be_absent(tmp_path):
    nodes = default_tables()["nodes"].drop(columns=["station_id", "track"])
    line = load_line(write_line_db(tmp_path / "tiny", nodes=nodes))
    assert all(n.station_id is None and n.track is None for n in line.network.nodes)


def test_not_parquet(tmp_path):
    path = write_line_db(tmp_path / "tiny")
    (path / "beacons.parquet").write_text("beacon_id,position_m\nB1,900\n")
    found = check_line(path)
    assert len(found) == 1
    assert str(found[0]).startswith("beacons.parquet: is not a readable Parquet file")


def test_table_path_that_is_a_folder(tmp_path):
    path = write_line_db(tmp_path / "tiny", curves=None)
    (path / "curves.parquet").mkdir()
    assert [str(v) for v in check_line(path)] == ["curves.parquet: is not a file; expected one Parquet file"]


def test_all_violations_are_collected(tmp_path):
    t = default_tables()
    over = {}
    over.update(cell("gradients", 1, "gradient_permil", 45.0)(t))
    over.update(cell("curves", 0, "radius_m", -1.0)(t))
    over.update(cell("timetable", 1, "station_id", "Z")(t))
    over.update(cell("stations", 2, "stop_down_m", 9999.0)(t))
    over["beacons"] = None
    found = _violations(tmp_path, over)
    assert [(v.file, v.row, v.column) for v in found] == [
        ("stations.parquet", 2, "stop_down_m"),
        ("gradients.parquet", 1, "gradient_permil"),
        ("curves.parquet", 0, "radius_m"),
        ("beacons.parquet", None, None),
        ("timetable.parquet", 1, "station_id"),
    ]


@pytest.mark.parametrize("mutate, where", [
    (cell("stations", 1, "position_m", None), ("stations.parquet", 1, "position_m")),
    (cell("timetable", 0, "station_id", None), ("timetable.parquet", 0, "station_id")),
    (arrow("timetable", "arrival_s", [None, math.nan, 22100.0, None, 22200.0, 22500.0]),
     ("timetable.parquet", 1, "arrival_s")),
])
def test_bad_cell_does_not_cascade(tmp_path, mutate, where):
    """A bad cell is reported once, not again as "unsorted", "outside the line" or "seq has a gap"."""
    found = _violations(tmp_path, mutate(default_tables()))
    assert [(v.file, v.row, v.column) for v in found] == [where]


def test_many_violations_are_capped_when_formatted(tmp_path):
    g = pd.DataFrame({"start_m": np.arange(60) * 10.0, "end_m": np.arange(60) * 10.0 + 5.0,
                      "gradient_permil": np.full(60, 50.0)})
    found = _violations(tmp_path, {"gradients": g})
    assert len(found) == 60
    lines = format_violations(found)
    assert len(lines) == 51
    assert lines[-1] == "… and 10 more"
    assert lines[0].startswith("gradients.parquet row 0 (start_m=0.0) column gradient_permil:")


def test_error_message_is_one_line(tmp_path):
    path = write_line_db(tmp_path / "tiny", curves=None)
    with pytest.raises(LineValidationError) as ei:
        load_line(path)
    assert "\n" not in str(ei.value)
    assert "curves.parquet" in str(ei.value)
    assert ei.value.total == 1


# --------------------------------------------------------------------------- broken copies of the sample line
SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"
needs_sample = pytest.mark.skipif(not (SAMPLE / "line.parquet").exists(),
                                  reason="lines/sample/*.parquet not built yet (run `make sample`)")


def _sample_copy(tmp_path) -> tuple[Path, dict[str, pd.DataFrame]]:
    dst = tmp_path / "sample"
    dst.mkdir()
    tables = {}
    for f in sorted(SAMPLE.glob("*.parquet")):
        shutil.copyfile(f, dst / f.name)
        tables[f.stem] = pq.read_table(f).to_pandas()
    return dst, tables


def _break_gradient_overlap(t):
    g = t["gradients"]
    g.loc[1, "start_m"] = g.loc[0, "end_m"] - 1.0
    return "gradients", 1, "start_m", f"overlaps row 0, which ends at {float(g.loc[0, 'end_m'])!r}"


def _break_timetable_station(t):
    tt = t["timetable"]
    tt["station_id"] = tt["station_id"].astype(object)
    tt.loc[5, "station_id"] = "NOWHERE"
    return "timetable", 5, "station_id", "unknown station 'NOWHERE'"


def _break_stop_marker(t):
    st, end = t["stations"], float(t["line"].loc[0, "end_m"])
    last = len(st) - 1
    st.loc[last, "stop_down_m"] = end + 100.0
    return "stations", last, "stop_down_m", "outside the line's chainage range"


def _break_traction_reach(t):
    rs, tr = t["rolling_stock"], t["traction"]
    name = rs.loc[0, "train_type"]
    rs.loc[0, "max_speed_kmh"] = 500.0
    rows = tr.index[tr["train_type"] == name]
    last = int(tr.loc[rows, "speed_kmh"].idxmax())
    return "traction", last, "speed_kmh", "below its max_speed_kmh 500.0"


def _break_schema_version(t):
    t["line"].loc[0, "schema_version"] = 3
    return "line", 0, "schema_version", "schema versions 1 to 2"


@needs_sample
@pytest.mark.parametrize("breaker", [_break_gradient_overlap, _break_timetable_station, _break_stop_marker,
                                     _break_traction_reach, _break_schema_version],
                         ids=lambda f: f.__name__[7:])
def test_broken_sample_copy(tmp_path, breaker):
    path, tables = _sample_copy(tmp_path)
    assert check_line(path) == []
    table, row, column, text = breaker(tables)
    for name, df in tables.items():  # rewrite every table: a breaker may touch several
        pq.write_table(to_arrow(name, df), path / f"{name}.parquet")
    found = check_line(path)
    hits = [v for v in found if (v.file, v.row, v.column) == (f"{table}.parquet", row, column)
            and text in v.message]
    assert hits, "\n".join(map(str, found))
    assert f"{table}.parquet row {row}" in str(hits[0]) and f"column {column}:" in str(hits[0])
