"""Loader: SI conversions against hand-computed values, model contents, digest, no DataFrames past the loader."""
from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest

import planner
from planner.line import testing
from planner.errors import InputError
from planner.line.loader import load_line, source_digest
from planner.line.model import Line, Network, Segments, TrainType
from planner.line.schema import SCHEMA_VERSION, TABLES

from linedb import default_tables, write_line_db

# Conversions are a single multiply/divide of float64 values: a few ulps at most.
REL = 1e-12


@pytest.fixture()
def line_dir(tmp_path):
    return write_line_db(tmp_path / "tiny")


@pytest.fixture()
def line(line_dir) -> Line:
    return load_line(line_dir)


def approx(x):
    return pytest.approx(x, rel=REL, abs=1e-12)


# --------------------------------------------------------------------------- unit conversions
def test_speed_36_kmh_is_10_ms(tmp_path):
    t = default_tables()
    t["speed_limits"].loc[0, "limit_kmh"] = 36.0
    line = load_line(write_line_db(tmp_path / "tiny", speed_limits=t["speed_limits"]))
    assert line.speed_limits[0].limit_ms == approx(10.0)
    assert line.speed_limits[1].limit_ms == approx(60 / 3.6)


def test_line_max_speed(line):
    assert line.max_speed_ms == approx(100 / 3.6)  # 27.77… m/s


def test_decelerations_kmh_s_to_ms2(tmp_path):
    t = default_tables()
    t["rolling_stock"].loc[0, "service_brake_kmh_s"] = 3.6   # 3.6 km/h/s = 1 m/s²
    t["rolling_stock"].loc[0, "stop_brake_kmh_s"] = 7.2      # = 2 m/s²
    t["rolling_stock"].loc[0, "max_accel_kmh_s"] = 1.8       # = 0.5 m/s²
    line = load_line(write_line_db(tmp_path / "tiny", rolling_stock=t["rolling_stock"]))
    tt = line.train_type("EMU10")
    assert tt.service_brake_ms2 == approx(1.0)
    assert tt.stop_brake_ms2 == approx(2.0)
    assert tt.max_accel_ms2 == approx(0.5)
    assert tt.atsp_pattern_ms2 == approx(2.9 / 3.6)
    assert tt.brake_comfort_ms2 == approx(3.2 / 3.6)


def test_rolling_stock_si(line):
    tt = line.train_type("EMU10")
    assert tt.length_m == 200.0
    assert tt.empty_mass_kg == approx(320_000.0)          # 320 t
    assert tt.full_load_mass_kg == approx(150_000.0)      # 150 t
    assert tt.mass_kg(1.0) == approx(470_000.0)
    assert tt.rotating_mass_factor == 0.08
    assert tt.max_speed_ms == approx(110 / 3.6)
    assert tt.jerk_limit_ms3 == approx(2.0)               # 7.2 km/h/s² = 2 m/s³
    assert tt.speed_margin_ms == approx(3.0 / 3.6)
    assert tt.coast_band_ms == 0.0
    assert tt.cruise == "constant"
    assert line.train_type("EMU6").cruise == "sawtooth"
    assert line.train_type("EMU6").coast_band_ms == approx(10 / 3.6)


def test_davis_coefficients(line):
    tt = line.train_type("EMU10")
    assert tt.davis_a_N == approx(5000.0)                 # 5 kN
    assert tt.davis_b_N_per_ms == approx(129.6)           # 0.036 kN/(km/h) = 36 N × 3.6 per m/s
    assert tt.davis_c_N_per_ms2 == approx(46.656)         # 0.0036 kN/(km/h)² = 3.6 N × 3.6² per (m/s)²


def test_davis_resistance_is_unit_invariant(line):
    """R at 72 km/h = 20 m/s, both ways: 5 + 0.036·72 + 0.0036·72² = 26.2544 kN."""
    tt = line.train_type("EMU10")
    r_si = tt.davis_a_N + tt.davis_b_N_per_ms * 20.0 + tt.davis_c_N_per_ms2 * 20.0**2
    assert r_si == approx(26_254.4)


def test_traction_curve_si_with_interleaved_types(tmp_path):
    t = default_tables()
    shuffled = t["traction"].iloc[[3, 0, 4, 1, 5, 2]]  # types interleaved, each in order.reset_index(drop=True)
    line = load_line(write_line_db(tmp_path / "tiny", traction=shuffled))
    tt = line.train_type("EMU10")
    np.testing.assert_allclose(tt.traction_speed_ms, [0.0, 40 / 3.6, 120 / 3.6], rtol=REL)
    np.testing.assert_allclose(tt.traction_effort_N, [300_000.0, 300_000.0, 100_000.0], rtol=REL)
    assert tt.traction_speed_ms.dtype == np.float64


def test_gradients_permil_to_rise_per_metre(line):
    g = line.gradients
    assert isinstance(g, Segments)
    np.testing.assert_array_equal(g.start_m, [0.0, 1000.0, 2500.0])
    np.testing.assert_array_equal(g.end_m, [1000.0, 2000.0, 3500.0])
    np.testing.assert_allclose(g.value, [0.0, 0.005, -0.010], rtol=REL)


def test_curves_radius_in_metres(line):
    np.testing.assert_array_equal(line.curves.value, [600.0, 800.0])


def test_matches_in_memory_testing_helper(line):
    """The loader and planner.line.testing convert the same railway units to the same SI values."""
    rs = default_tables()["rolling_stock"].iloc[0].to_dict()
    rs.pop("train_type")
    ref = testing.train_type("EMU10", traction=((0.0, 300.0), (40.0, 300.0), (120.0, 100.0)), **rs)
    got = line.train_type("EMU10")
    for f in dataclasses.fields(TrainType):
        a, b = getattr(got, f.name), getattr(ref, f.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_allclose(a, b, rtol=REL)
        elif isinstance(a, float):
            assert a == approx(b), f.name
        else:
            assert a == b, f.name


# --------------------------------------------------------------------------- model contents
def test_line_fields(line, line_dir):
    assert line.line_id == "tiny"
    assert line.name == "Tiny test line"
    assert (line.start_m, line.end_m) == (0.0, 5000.0)
    assert line.schema_version == SCHEMA_VERSION == 2
    assert line.source_path == str(line_dir)


def test_stations(line):
    assert [s.station_id for s in line.stations] == ["A", "B", "C"]
    b = line.station("B")
    assert (b.name, b.position_m, b.stop_m("down"), b.stop_m("up"), b.platform_length_m) == (
        "Bashi", 2500.0, 2560.0, 2440.0, 200.0)
    assert [(a.station_id, z.station_id) for a, z in line.interstations("up")] == [("C", "B"), ("B", "A")]


def test_speed_limits(line):
    sl = line.speed_limits
    assert [s.row for s in sl] == [0, 1, 2]
    assert sl[0].train_type is None and sl[1].train_type == "EMU6"
    assert (sl[1].direction, sl[1].kind, sl[1].has_beacon) == ("down", "turnout", False)
    assert [s.row for s in line.limits_for("down", "EMU10")] == [0]
    assert [s.row for s in line.limits_for("down", "EMU6")] == [0, 1]


def test_beacons_and_signals(line):
    assert [b.beacon_id for b in line.beacons_for("down")] == ["B1", "B2"]
    assert [b.beacon_id for b in line.beacons_for("up")] == ["B3", "B4"]
    b2 = line.beacons[1]
    assert (b2.position_m, b2.kind, b2.telegram, b2.evaluation_point) == (1000.0, "pattern_update",
                                                                          "P80@1200", True)
    assert [(s.signal_id, s.direction) for s in line.signals] == [("SG1", "down"), ("SG2", "up")]


def test_beacons_within_a_stretch_are_those_of_the_pass_over_all(sample_line):
    """``beacons_for(d, within=(lo, hi))`` (a search in the line's index) against the filter over every beacon,
    in running order, on the sample with every third beacon given again at the same chainage."""
    rng = np.random.default_rng(7)
    extra = tuple(dataclasses.replace(b, beacon_id=b.beacon_id + "x") for b in sample_line.beacons[::3])
    line = dataclasses.replace(sample_line, beacons=sample_line.beacons + extra)
    pos = sorted({b.position_m for b in line.beacons})
    ends = [(rng.uniform(-100.0, 21_000.0), rng.uniform(-100.0, 21_000.0)) for _ in range(200)]
    ends += [(a, b) for a, b in zip(pos, pos[3:])]  # ends on beacons: both ends count
    for d in ("down", "up"):
        for a, b in ends:
            lo, hi = min(a, b), max(a, b)
            sg = 1.0 if d == "down" else -1.0
            want = [x.beacon_id for x in sorted(line.beacons, key=lambda x: sg * x.position_m)
                    if x.direction == d and lo <= x.position_m <= hi]
            assert [x.beacon_id for x in line.beacons_for(d, within=(lo, hi))] == want
            assert [x.beacon_id for x in line.beacons_for(d, within=(hi, lo))] == want


def test_trains_calls_in_seq_order_with_nan_for_missing_times(tmp_path):
    tt = default_tables()["timetable"].iloc[[5, 3, 1, 4, 0, 2]].reset_index(drop=True)
    line = load_line(write_line_db(tmp_path / "tiny", timetable=tt))
    assert [t.train_id for t in line.trains] == ["202", "101"]  # order of first appearance
    up = line.trains[0]
    assert (up.train_type, up.direction) == ("EMU6", "up")
    assert [c.station_id for c in up.calls] == ["C", "B", "A"]
    assert [c.seq for c in up.calls] == [0, 1, 2]
    assert math.isnan(up.calls[0].arrival_s) and math.isnan(up.calls[2].departure_s)
    assert (up.calls[1].arrival_s, up.calls[1].departure_s, up.calls[1].stops) == (22200.0, 22200.0, False)


def test_network(line):
    assert isinstance(line.network, Network)
    n2 = line.network.nodes[1]
    assert (n2.node_id, n2.kind, n2.position_m, n2.interlocking, n2.station_id, n2.track) == (
        "N2", "stop", 260.0, "IXL1", "A", "1")
    assert line.network.nodes[0].station_id is None
    assert [(e.from_node, e.to_node, e.length_m) for e in line.network.edges] == [
        ("N1", "N2", 260.0), ("N2", "N3", 740.0), ("N3", "N4", 4000.0)]


def test_optional_tables_absent(tmp_path):
    line = load_line(write_line_db(tmp_path / "tiny", signals=None, nodes=None, edges=None))
    assert line.signals == ()
    assert line.network is None


def test_empty_tables_give_empty_model_parts(tmp_path):
    t = default_tables()
    line = load_line(write_line_db(tmp_path / "tiny", **{n: t[n].iloc[0:0] for n in
                                                        ("gradients", "curves", "speed_limits", "beacons")}))
    assert len(line.gradients) == 0 and len(line.curves) == 0
    assert line.gradients.start_m.dtype == np.float64
    assert line.speed_limits == () and line.beacons == ()


def _walk(obj, seen=None):
    """Every value reachable from a model object (dataclass fields, tuples)."""
    yield obj
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _walk(getattr(obj, f.name))
    elif isinstance(obj, tuple):
        for x in obj:
            yield from _walk(x)


def test_no_dataframes_or_arrow_past_the_loader(line):
    kinds = {type(x) for x in _walk(line)}
    assert not any(issubclass(k, (pd.DataFrame, pd.Series, pa.Table, pa.Array, pa.ChunkedArray)) for k in kinds)
    assert all(x.dtype == np.float64 for x in _walk(line) if isinstance(x, np.ndarray))
    # strings are plain str, not numpy scalars
    assert all(type(s.station_id) is str for s in line.stations)


def test_model_is_frozen(line):
    with pytest.raises(dataclasses.FrozenInstanceError):
        line.line_id = "x"  # type: ignore[misc]


def test_package_entry_point_delegates(line_dir):
    assert planner.load_line(line_dir).line_id == "tiny"


def test_any_folder_name_works_the_line_id_comes_from_the_data(tmp_path):
    """The folder is named by the job file; the line is named by line.parquet (issue 16)."""
    folder = write_line_db(tmp_path / "My Line (copy) 2026", line=default_tables("tiny")["line"])
    line = load_line(folder)
    assert line.line_id == "tiny" and folder.name != line.line_id


def test_missing_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_line(tmp_path / "nowhere")


def test_file_instead_of_folder(tmp_path):
    f = tmp_path / "line.parquet"
    f.write_bytes(b"x")
    with pytest.raises(InputError, match="is not a folder"):
        load_line(f)


# --------------------------------------------------------------------------- digest
def test_source_digest_framing(line, line_dir):
    """SHA-256 over (name, NUL, 8-byte big-endian length, bytes) of each *.parquet in name order."""
    h = hashlib.sha256()
    names = sorted(p.name for p in line_dir.glob("*.parquet"))
    assert names == sorted(spec.file for spec in TABLES.values())
    for name in names:
        data = (line_dir / name).read_bytes()
        h.update(name.encode() + b"\0" + len(data).to_bytes(8, "big") + data)
    assert line.source_digest == h.hexdigest()
    assert len(line.source_digest) == 64


def test_source_digest_is_deterministic_and_ignores_other_files(tmp_path, line):
    again = write_line_db(tmp_path / "copy" / "tiny")
    (again / "README.md").write_text("notes do not change what is loaded\n")
    assert load_line(again).source_digest == line.source_digest


def test_source_digest_changes_with_content_and_extra_tables(tmp_path, line):
    t = default_tables()
    t["curves"].loc[0, "radius_m"] = 601.0
    changed = load_line(write_line_db(tmp_path / "a" / "tiny", curves=t["curves"]))
    assert changed.source_digest != line.source_digest
    extra = load_line(write_line_db(tmp_path / "b" / "tiny", depots=pd.DataFrame({"depot_id": ["D"]})))
    assert extra.source_digest != line.source_digest
    assert source_digest(tmp_path / "b" / "tiny") == extra.source_digest


# --------------------------------------------------------------------------- declared schema
# The public contract, typed from docs/line-database.md: (table, columns). Renaming or dropping any is a breaking change.
CONTRACT = {
    "line": "line_id name start_m end_m max_speed_kmh schema_version",
    "stations": "station_id name position_m stop_down_m stop_up_m platform_length_m",
    "gradients": "start_m end_m gradient_permil",
    "curves": "start_m end_m radius_m",
    "speed_limits": "start_m end_m limit_kmh direction train_type kind has_beacon",
    "beacons": "beacon_id position_m direction kind telegram evaluation_point",
    "signals": "signal_id position_m direction",
    "rolling_stock": "train_type length_m empty_mass_t full_load_mass_t rotating_mass_factor max_speed_kmh "
                     "max_accel_kmh_s davis_a_kN davis_b_kN_per_kmh davis_c_kN_per_kmh2 service_brake_kmh_s "
                     "stop_brake_kmh_s atsp_pattern_kmh_s brake_comfort_kmh_s jerk_limit_kmh_s2 "
                     "speed_margin_kmh cruise coast_band_kmh",
    "traction": "train_type speed_kmh effort_kN",
    "timetable": "train_id train_type direction seq station_id arrival_s departure_s stops",
    "nodes": "node_id kind position_m interlocking",
    "edges": "edge_id from_node to_node length_m track",
}


def test_schema_declares_the_public_contract():
    assert SCHEMA_VERSION == 2
    assert list(TABLES) == list(CONTRACT)
    for name, cols in CONTRACT.items():
        spec = TABLES[name]
        required = [f.name for f in spec.schema if f.name not in spec.optional_columns]
        assert required == cols.split(), name
        assert spec.schema.metadata[b"schema_version"] == b"2"
        for f in spec.schema:
            assert f.metadata[b"description"].strip(), (name, f.name)
    assert TABLES["nodes"].optional_columns == {"station_id", "track"}
    assert {n for n, s in TABLES.items() if not s.required} == {"signals", "nodes", "edges"}
    assert {n: s.min_rows for n, s in TABLES.items() if s.min_rows} == {
        "line": 1, "stations": 2, "rolling_stock": 1, "traction": 1}
    nullable = {(n, f.name) for n, s in TABLES.items() for f in s.schema if f.nullable}
    assert nullable == {("line", "approach_m"), ("line", "max_speed_kmh"), ("speed_limits", "train_type"), ("timetable", "arrival_s"),
                        ("timetable", "departure_s"), ("nodes", "station_id"), ("nodes", "track"),
                        ("line", "running_side"), ("edges", "direction")}
    assert TABLES["timetable"].schema.field("seq").type == pa.int32()
    assert TABLES["line"].schema.field("schema_version").type == pa.int32()
