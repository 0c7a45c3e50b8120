"""planner import csv / railjson / railml: fidelity against hand-written lines, and refusals.

Sources are the small files of tests/importsrc.py, written for these tests; the
expected tables there are written by hand from the geometry in its docstring, not
from the importer's output.
"""
from __future__ import annotations

import filecmp
import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

import importsrc as src
from linedb import write_line_db
from planner import load_line, running_time
from planner.cli import app
from planner.errors import SourceError
from planner.line.importers.common import DEFAULTS, to_arrow
from planner.line.importers.csv import export_csv, import_csv, write_templates
from planner.line.importers.railjson import import_railjson
from planner.line.importers.railml import import_railml
from planner.line.schema import TABLES

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "lines" / "sample"
RUNTIME_TOL_S = 1e-9


def _norm(t: pa.Table) -> pa.Table:
    """Columns, types and values only (no field metadata or nullability flags)."""
    return pa.Table.from_arrays(t.columns, names=t.column_names)


def _read(folder: Path, name: str) -> pa.Table:
    return _norm(pq.read_table(folder / TABLES[name].file))


# --------------------------------------------------------------------------- CSV
def test_sample_line_round_trips_through_csv_identically(tmp_path):
    export_csv(SAMPLE, tmp_path / "csv")
    summary = import_csv(tmp_path / "csv", tmp_path / "back")
    assert summary.line_id == "sample" and not summary.defaults
    for name, spec in TABLES.items():
        if (SAMPLE / spec.file).exists():
            assert _read(tmp_path / "back", name).equals(_read(SAMPLE, name)), name
    # and the CSV written from the imported line is byte-identical to the first export
    export_csv(tmp_path / "back", tmp_path / "csv2")
    files = sorted(p.name for p in (tmp_path / "csv").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "csv2").iterdir())
    assert filecmp.cmpfiles(tmp_path / "csv", tmp_path / "csv2", files, shallow=False)[0] == files


def test_sample_line_round_trips_through_csv_byte_for_byte(tmp_path):
    """export csv -> import csv gives the sample's Parquet files back in the same bytes (same schema
    metadata, column order, types and writer options), so the same source digest: a run after the
    round trip finds every cached result."""
    from planner.line.loader import source_digest

    export_csv(SAMPLE, tmp_path / "csv")
    import_csv(tmp_path / "csv", tmp_path / "back")
    files = sorted(p.name for p in SAMPLE.glob("*.parquet"))
    assert files == sorted(p.name for p in (tmp_path / "back").glob("*.parquet"))
    for f in files:
        assert (tmp_path / "back" / f).read_bytes() == (SAMPLE / f).read_bytes(), f
    assert source_digest(tmp_path / "back") == source_digest(SAMPLE)


def test_csv_keeps_every_float_bit_and_nulls(tmp_path):
    write_line_db(tmp_path / "a", gradients=pd.DataFrame(
        [(0.0, 1000.0 / 3.0, 0.1 + 0.2), (1000.0 / 3.0, 2000.0, -1e-300)],
        columns=["start_m", "end_m", "gradient_permil"]))
    export_csv(tmp_path / "a", tmp_path / "csv")
    import_csv(tmp_path / "csv", tmp_path / "b")
    got = pq.read_table(tmp_path / "b" / "gradients.parquet").column("gradient_permil").to_pylist()
    assert got == [0.1 + 0.2, -1e-300]
    tt = pq.read_table(tmp_path / "b" / "timetable.parquet")
    assert tt.column("arrival_s").to_pylist()[0] is None  # null at the origin survives
    sl = pq.read_table(tmp_path / "b" / "speed_limits.parquet")
    assert sl.column("train_type").to_pylist() == [None, "EMU6", None]


def test_templates_are_commented_and_complete(tmp_path):
    paths = write_templates(tmp_path / "t")
    assert sorted(p.stem for p in paths) == sorted(TABLES)
    for name, spec in TABLES.items():
        text = (tmp_path / "t" / f"{name}.csv").read_text()
        header = [ln for ln in text.splitlines() if not ln.startswith("#")]
        assert header == [",".join(f.name for f in spec.schema)], name
        assert "docs/line-database.md" in text
    with pytest.raises(Exception, match="already exists"):
        write_templates(tmp_path / "t")


# --------------------------------------------------------------------------- railjson / railML fidelity
@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    root = tmp_path_factory.mktemp("imp")
    i, r, x = src.write_railjson(root / "rj")
    rj = import_railjson(i, ["W", "M", "E"], [r], root / "lines" / "from_railjson", extra=x, line_id="rj")
    f, r2, x2 = src.write_railml(root / "rm")
    rm = import_railml(f, "L1", [r2], root / "lines" / "from_railml", extra=x2)
    hand = root / "lines" / "by_hand"
    write_line_db(hand, nodes=None, edges=None, **src.expected_tables("hand"))
    return {"railjson": (rj, root / "lines" / "from_railjson"), "railml": (rm, root / "lines" / "from_railml"),
            "hand": hand}


@pytest.mark.parametrize("name", ["line", "stations", "gradients", "curves", "speed_limits", "beacons", "signals",
                                  "rolling_stock", "traction", "timetable"])
def test_railjson_gives_the_expected_rows(imported, name):
    want = src.expected_tables("rj")[name]
    assert _read(imported["railjson"][1], name).equals(_norm(to_arrow(name, want))), name


@pytest.mark.parametrize("name", ["stations", "gradients", "curves", "beacons", "signals", "rolling_stock",
                                  "traction", "timetable"])
def test_railml_gives_the_expected_rows(imported, name):
    want = src.expected_tables("L1")[name]
    assert _read(imported["railml"][1], name).equals(_norm(to_arrow(name, want))), name


def test_railml_speed_limits_give_the_expected_limit_everywhere(imported):
    """railML speed changes are per direction: the rows differ, the limit met at every metre does not."""
    got, want = load_line(imported["railml"][1]), load_line(imported["hand"])

    def limit_at(line, direction: str, x: float) -> float:
        return min([s.limit_ms for s in line.limits_for(direction, "EMU") if s.start_m <= x < s.end_m]
                   + [line.max_speed_ms])
    for d in ("down", "up"):
        for x in range(0, 6500, 10):
            assert limit_at(got, d, x) == limit_at(want, d, x), (d, x)


@pytest.fixture(scope="module")
def loaded(imported):
    return {k: load_line(imported[k][1] if k != "hand" else imported[k]) for k in ("hand", "railjson", "railml")}


@pytest.mark.parametrize("origin,destination,ratio", [("W", "M", 1.0), ("M", "E", 1.0), ("E", "W", 0.8)])
def test_imported_lines_run_like_the_hand_written_one(loaded, origin, destination, ratio):
    want = running_time(loaded["hand"], "EMU", origin, destination, ratio=ratio).time_s
    assert want > 0
    for source in ("railjson", "railml"):
        got = running_time(loaded[source], "EMU", origin, destination, ratio=ratio).time_s
        assert abs(got - want) <= RUNTIME_TOL_S, (source, got, want)


def test_summary_lists_every_default_used(imported):
    rj, _ = imported["railjson"]
    text = "\n".join(rj.lines())
    for key in ("platform_length_m", "stop_markers", "speed_limit_kind", "has_beacon", "line_max_speed",
                "max_accel_kmh_s", "brake_comfort_kmh_s", "service_brake_kmh_s", "stop_brake_kmh_s",
                "atsp_pattern_kmh_s", "speed_margin_kmh", "cruise", "coast_band_kmh"):
        assert f"- {key} = " in text, key
    # given by the TOML, so not defaults: the jerk limit, the full-load mass, the name, E's platform
    for key in ("jerk_limit_kmh_s2", "full_load_mass_t", "line_name"):
        assert f"- {key} = " not in text, key
    assert "platform_length_m = 200.0 (default: platform length where the source gives none [m]) for W, M" in text
    assert all(k in DEFAULTS for k in (label.split(" = ")[0] for label in rj.defaults))


def test_a_copy_of_a_line_under_another_id_is_not_a_cache_hit(imported):
    """Found running the hand-written line and its railjson twin in one job: the stops cache (keyed by
    interstation inputs) handed line 'rj' rows to line 'hand', and margins found no rows for 'hand'."""
    from planner.job.pipeline import digest
    from planner.job.units import interstation_inputs

    a = interstation_inputs(load_line(imported["hand"]), "EMU", "W", "M")
    b = interstation_inputs(load_line(imported["railjson"][1]), "EMU", "W", "M")
    assert digest(a) != digest(b)
    a.pop("line_id"), b.pop("line_id")
    assert digest(a) == digest(b)  # the twins differ in nothing else


def test_force_replaces_only_with_a_valid_line(tmp_path):
    i, r, x = src.write_railjson(tmp_path / "s")
    out = tmp_path / "lines" / "coast"
    import_railjson(i, ["W", "M", "E"], [r], out, extra=x, line_id="coast")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(SourceError, match="no connected route"):
        import_railjson(i, ["M", "B"], [r], out, force=True)  # B is on the branch: only by reversing
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # the old line is untouched
    import_railjson(i, ["W", "M"], [r], out, line_id="coast2", force=True)
    assert load_line(out).line_id == "coast2" and len(load_line(out).stations) == 2
    assert sorted(p.name for p in out.parent.iterdir()) == ["coast"]  # no temp or old folder left


def test_toml_defaults_replace_documented_and_derived_values(tmp_path):
    i, r, x = src.write_railjson(tmp_path)
    x.write_text("[defaults]\nplatform_length_m = 150.0\nstop_brake_kmh_s = 3.0\n"
                 "[rolling_stock.EMU]\ntrain_type = \"E6\"\n")
    s = import_railjson(i, ["W", "M", "E"], [r], tmp_path / "out", extra=x)
    st = pq.read_table(tmp_path / "out" / "stations.parquet").column("platform_length_m").to_pylist()
    rs = pq.read_table(tmp_path / "out" / "rolling_stock.parquet")
    assert st == [150.0] * 3 and rs.column("stop_brake_kmh_s").to_pylist() == [3.0]
    assert load_line(tmp_path / "out").train_type("E6").traction_effort_N[0] == 200_000.0  # renamed with its curve
    assert rs.column("service_brake_kmh_s").to_pylist() == [3.6]  # still derived from const_gamma
    assert any(k.startswith("stop_brake_kmh_s = 3.0 (TOML [defaults]") for k in s.defaults)


def test_cli_import_and_any_folder_name(tmp_path):
    i, r, x = src.write_railjson(tmp_path / "s")
    out = tmp_path / "Some Folder"
    res = CliRunner().invoke(app, ["import", "railjson", str(i), "--path", "W,M,E", "--rolling-stock", str(r),
                                   "--extra", str(x), "--line-id", "coast", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "defaults used: " in res.output and load_line(out).line_id == "coast"
    res = CliRunner().invoke(app, ["import", "railjson", str(i), "--path", "W,M,E", "--rolling-stock", str(r),
                                   "--out", str(out)])
    assert res.exit_code != 0 and "already exists" in res.output + res.stderr + str(res.exception or "")


# --------------------------------------------------------------------------- refusals
def _rj(edit=None, rs_edit=None, path=("W", "M", "E"), extra=None):
    def run(tmp: Path):
        infra = src.edited(src.railjson_infra, edit) if edit else None
        rs = src.edited(src.rolling_stock, rs_edit) if rs_edit else None
        i, r, x = src.write_railjson(tmp, infra, rs)
        if extra is not None:
            x.write_text(extra)
        import_railjson(i, list(path), [r], tmp / "out" / "line", extra=x)
    return run


def _rml(text=None, line="L1", **parts):
    def run(tmp: Path):
        f, r, x = src.write_railml(tmp, text if text is not None else src.railml_text(**parts) if parts else None)
        import_railml(f, line, [r], tmp / "out" / "line", extra=x)
    return run


def _rml_sub(old: str, new: str):
    text = src.railml_text()
    assert old in text, old
    return _rml(text.replace(old, new, 1))


def _csv(edit):
    def run(tmp: Path):
        write_line_db(tmp / "db")
        export_csv(tmp / "db", tmp / "csv")
        edit(tmp / "csv")
        import_csv(tmp / "csv", tmp / "out" / "line")
    return run


def _replace_in(name: str, old: str, new: str):
    def edit(folder: Path):
        p = folder / name
        text = p.read_text()
        assert old in text, (name, old)
        p.write_text(text.replace(old, new, 1))
    return edit


def _set(path, value):
    def edit(d):
        target = d
        for k in path[:-1]:
            target = target[k]
        if value is _DELETE:
            del target[path[-1]]
        else:
            target[path[-1]] = value
    return edit


_DELETE = object()

MALFORMED = [
    # --- railjson: missing elements, broken references, units, topology
    ("rj_no_track_sections", _rj(_set(["track_sections"], _DELETE)), ["infra.json", "track_sections", "missing"]),
    ("rj_track_length_missing", _rj(_set(["track_sections", 1, "length"], _DELETE)),
     ["infra.json", "track_sections[1] (id T2)", "length", "missing"]),
    ("rj_unknown_op", _rj(path=("W", "X", "E")), ["infra.json", "--path", "'X'"]),
    ("rj_switch_to_unknown_track", _rj(_set(["switches", 1, "ports", "B", "track"], "T9")),
     ["switches[1] (id L1)", "ports.B.track", "'T9'"]),
    ("rj_path_not_connected", _rj(_set(["switches"], [])), ["--path", "no connected route", "'W'", "'M'"]),
    ("rj_path_needs_reversal", _rj(path=("M", "W", "E")), ["no connected route from operational point 'W' to 'E'"]),
    ("rj_slopes_overlap", _rj(_set(["track_sections", 0, "slopes", 1, "begin"], 900.0)),
     ["track_sections[0] (id T1)", "slopes[1]", "overlaps slopes[0]"]),
    ("rj_slope_beyond_track", _rj(_set(["track_sections", 2, "slopes", 0, "end"], 1700.0)),
     ["track_sections[2] (id T3)", "slopes[0]", "length 1500.0"]),
    ("rj_gradient_in_wrong_unit", _rj(_set(["track_sections", 0, "slopes", 0, "gradient"], 50.0)),
     ["track_sections[0] (id T1)", "slopes[0].gradient", "m/km"]),
    ("rj_speed_in_kmh", _rj(_set(["speed_sections", 1, "speed_limit"], 180.0)),
     ["speed_sections[1] (id V80)", "speed_limit", "km/h"]),
    ("rj_signal_off_track", _rj(_set(["signals", 0, "position"], 3500.0)),
     ["signals[0] (id SIG1)", "position", "outside track section 'T1'"]),
    ("rj_signal_bad_direction", _rj(_set(["signals", 0, "direction"], "UP")), ["signals[0] (id SIG1)", "direction"]),
    ("rj_op_part_unknown_track", _rj(_set(["operational_points", 1, "parts", 0, "track"], "NOPE")),
     ["operational_points[1].parts[0]", "track", "'NOPE'"]),
    ("rj_not_json", lambda tmp: (src.write_railjson(tmp), (tmp / "infra.json").write_text("{\"track_sections\": [}"),
                                 import_railjson(tmp / "infra.json", ["W", "E"], [tmp / "emu.json"],
                                                 tmp / "out" / "line")),
     ["infra.json line 1", "not valid JSON"]),
    # --- OSRD rolling stock
    ("rs_mass_in_tonnes", _rj(rs_edit=_set(["mass"], 250.0)), ["emu.json", "mass", "kg"]),
    ("rs_curve_not_increasing", _rj(rs_edit=_set(["effort_curves", "modes", "1500V", "default_curve", "speeds"],
                                                 [0.0, 20.0, 10.0])),
     ["emu.json", "default_curve.speeds", "increase strictly"]),
    ("rs_no_braking", _rj(rs_edit=_set(["const_gamma"], _DELETE)), ["emu.json", "const_gamma", "missing"]),
    ("rs_inertia_as_factor", _rj(rs_edit=_set(["inertia_coefficient"], 0.08)), ["emu.json", "inertia_coefficient"]),
    # --- --extra TOML
    ("toml_unknown_key", _rj(extra="[line]\nmax_speed_ms = 30.0\n"), ["extra.toml", "[line].max_speed_ms",
                                                                       "unknown key"]),
    ("toml_beacon_at_unknown", _rj(extra='[[beacons]]\nbeacon_id = "B"\nat = "NOPE"\ndirection = "up"\n'),
     ["extra.toml", "[[beacons]] #1.at", "'NOPE'"]),
    ("toml_unknown_station", _rj(extra="[stations.Q]\nplatform_length_m = 100.0\n"),
     ["extra.toml", "[stations.Q]", "no station 'Q'"]),
    ("toml_timetable_unknown_station",
     _rj(extra='[[timetable]]\ntrain_id="1"\ntrain_type="EMU"\ndirection="down"\nseq=0\nstation_id="Z"\n'
               'departure_s=1.0\nstops=true\n[[timetable]]\ntrain_id="1"\ntrain_type="EMU"\ndirection="down"\n'
               'seq=1\nstation_id="E"\narrival_s=2.0\nstops=true\n'),
     ["imported line would be invalid", "timetable.parquet row 0", "station_id", "'Z'"]),
    # --- railML
    ("rml_not_xml", _rml("<railml><infrastructure>"), ["line.railml line", "not well-formed XML"]),
    ("rml_unknown_line", _rml(line="L9"), ["line.railml", "--line", "'L9'", "L1"]),
    ("rml_track_ref_broken", _rml_sub('<trackRef ref="tr2"', '<trackRef ref="trX"'), ["trackRef ref='trX'"]),
    ("rml_tracks_not_connected", _rml_sub('<connection id="c21" ref="c12"/>', '<openEnd id="oe2"/>'),
     ["<trackEnd id='te1'>", "'tr1' is not connected", "'tr2'"]),
    ("rml_gradient_gap", _rml_sub('<gradientChange id="g5" pos="0.0" slope="0"/>', ""),
     ["<gradientChange id='g6'> @pos", "trackBegin", "gap"]),
    ("rml_gradient_overlap", _rml_sub('<gradientChange id="g2" pos="1000.0" slope="0.0"/>',
                                      '<gradientChange id="g2" pos="0.0" slope="2.0"/>'),
     ["<gradientChange id='g2'> @pos", "overlap"]),
    ("rml_gradient_percent", _rml_sub('slope="-8.0"', 'slope="-80"'), ["<gradientChange id='g3'> @slope", "‰"]),
    ("rml_pos_with_unit", _rml_sub('<signal id="SIG1" pos="2800.0"', '<signal id="SIG1" pos="2.8km"'),
     ["<signal id='SIG1'> @pos", "not a number"]),
    ("rml_pos_outside_track", _rml_sub('<balise id="BC1" pos="1000.0"', '<balise id="BC1" pos="1600.0"'),
     ["<balise id='BC1'> @pos", "outside track 'tr3'"]),
    ("rml_speed_no_dir", _rml_sub('<speedChange id="v6" pos="500.0" dir="down"', '<speedChange id="v6" pos="500.0"'),
     ["<speedChange id='v6'> @dir", "missing"]),
    ("rml_ocp_ref_broken", _rml_sub('ocpRef="M"/>', 'ocpRef="MX"/>'), ["<crossSection id='cs2'> @ocpRef", "'MX'"]),
    ("rml_missing_vmax", _rml_sub(' vMax="60"', ""), ["<speedChange id='v6'> @vMax", "missing"]),
    ("rml_version_3", _rml('<?xml version="1.0"?><railml xmlns="https://www.railml.org/schemas/3.2" version="3.2">'
                           '<infrastructure/></railml>'), ["railML 3.x is not supported"]),
    # --- CSV
    ("csv_missing_table", _csv(lambda d: (d / "stations.csv").unlink()), ["stations.csv is missing"]),
    ("csv_wrong_unit_column", _csv(_replace_in("gradients.csv", "gradient_permil", "gradient_percent")),
     ["gradients.csv line 1", "gradient_permil is missing", "'gradient_percent'"]),
    ("csv_unit_in_cell", _csv(_replace_in("curves.csv", "1600.0,600.0", "1600.0,600 m")),
     ["curves.csv line 2 column radius_m", "'600 m' is not a number"]),
    ("csv_overlapping_gradients", _csv(_replace_in("gradients.csv", "2500.0,3500.0", "1500.0,3500.0")),
     ["gradients.csv line 4 column start_m", "overlaps"]),
    ("csv_broken_reference", _csv(_replace_in("timetable.csv", "202,EMU6,up,0,C", "202,EMU6,up,0,Q")),
     ["timetable.csv line 5 column station_id", "unknown station 'Q'"]),
    ("csv_bad_boolean", _csv(_replace_in("beacons.csv", "true", "maybe")), ["beacons.csv line 2 column "
                                                                          "evaluation_point", "true or false"]),
    ("csv_semicolons", _csv(lambda d: (d / "curves.csv").write_text("start_m;end_m;radius_m\n1;2;3\n")),
     ["curves.csv line 1", "semicolons"]),
    ("rj_slope_not_object", _rj(_set(["track_sections", 0, "slopes", 0], 5.0)),
     ["track_sections[0] (id T1)", "slopes[0]", "must be an object"]),
    ("csv_unknown_table", _csv(lambda d: (d / "gradient.csv").write_text("start_m\n")),
     ["gradient.csv", "unknown table"]),
]


@pytest.mark.parametrize("case,run,fragments", MALFORMED, ids=[c[0] for c in MALFORMED])
def test_malformed_sources_are_refused_with_one_line_and_leave_nothing(tmp_path, case, run, fragments):
    with pytest.raises(SourceError) as e:
        run(tmp_path)
    msg = str(e.value)
    assert "\n" not in msg, msg
    msg = " | ".join([msg, *getattr(e.value, "problems", [])])  # several problems: each its own line too
    for f in fragments:
        assert f in msg, (f, msg)
    assert not (tmp_path / "out").exists()  # not even the parent folder the import would have made


def test_there_are_at_least_twenty_malformed_cases():
    assert len(MALFORMED) >= 20


def test_cli_refusal_is_one_line_without_traceback(tmp_path, monkeypatch, capsys):
    import sys

    from planner.cli import main

    i, r, _ = src.write_railjson(tmp_path)
    bad = json.loads(i.read_text())
    bad["switches"] = []
    i.write_text(json.dumps(bad))
    monkeypatch.setattr(sys, "argv", ["planner", "import", "railjson", str(i), "--path", "W,M,E",
                                      "--rolling-stock", str(r), "--out", str(tmp_path / "x")])
    with pytest.raises(SystemExit) as e:
        main()
    err = capsys.readouterr().err
    assert e.value.code == 1 and "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith("error: infra.json: --path: no connected route")
    assert not (tmp_path / "x").exists()


def test_a_terminus_at_the_lines_end_gets_a_stop_marker_where_the_longest_train_stands(tmp_path):
    """A station at the line's start (position 0) and a 400 m train: the default down marker, the platform's far
    end at 100 m, put the departing train's tail at -300 m and validation refused the line. The importer moves it
    to 400 m (the tail at the line's start) and says so; the other markers keep their defaults."""
    import json

    from importsrc import rolling_stock, write_railjson
    from planner.line.importers.railjson import import_railjson

    rs = rolling_stock()
    rs["length"] = 400.0
    i, r, x = write_railjson(tmp_path / "src", rs=rs)
    x.write_text(x.read_text().replace('[stations.E]', '[stations.T0]\nposition_m = 0.0\n\n[stations.E]', 1))
    s = import_railjson(i, ["W", "M", "E"], [r], tmp_path / "coast", extra=x, line_id="coast")
    line = load_line(tmp_path / "coast")  # valid: refused before
    t0, w = line.station("T0"), line.station("W")
    assert t0.stop_down_m == pytest.approx(400.0) and t0.stop_up_m == 0.0
    assert (w.stop_down_m, w.stop_up_m) == (600.0, 400.0)  # W at 500 m: the platform's ends, as before
    assert any("station T0: stop marker down at 400 m, not 100 m, so that a 400 m train" in n for n in s.notes)


def test_a_railml_line_that_lists_a_station_areas_tracks_as_a_group_takes_its_through_route(tmp_path):
    """CAD exports list the tracks of a station area under one <line>, in no running order, sidings among them:
    "track … is not connected to the next track of line …". The through route (each track's end connected to
    the next one's begin, the longest) is the line, with a note; the same line as the chained listing."""
    from importsrc import railml_text, write_railml
    from planner.line.importers.railml import import_railml

    siding = """
    <track id="trS" name="Siding">
      <trackTopology>
        <trackBegin id="tbS" pos="0.0"><openEnd id="oeS1"/></trackBegin>
        <trackEnd id="teS" pos="400.0"><openEnd id="oeS2"/></trackEnd>
      </trackTopology>
    </track>"""
    chained = railml_text()
    tracks = chained.split("<tracks>", 1)[1].split("</tracks>", 1)[0] + siding
    grouped = railml_text(tracks=tracks, lines="""
    <line id="L1" name="Station area as a group">
      <trackRef ref="tr2"/><trackRef ref="trS"/><trackRef ref="tr3"/><trackRef ref="tr1"/>
    </line>""")
    f, r, x = write_railml(tmp_path / "g", grouped)
    s = import_railml(f, "L1", [r], tmp_path / "grouped", extra=x)
    assert any("its through route tr1 → tr2 → tr3 is the line, the other tracks (trS)" in n for n in s.notes)
    f2, r2, x2 = write_railml(tmp_path / "c", chained)
    import_railml(f2, "L1", [r2], tmp_path / "chained", extra=x2)
    a, b = load_line(tmp_path / "grouped"), load_line(tmp_path / "chained")
    assert (a.start_m, a.end_m) == (b.start_m, b.end_m) == (0.0, 6500.0)
    assert [st.position_m for st in a.stations] == [st.position_m for st in b.stations]


def test_an_import_says_the_lines_warnings_grouped(tmp_path):
    """A train longer than the platforms is legitimate on some railways (a warning, not a refusal): the import says
    so as `planner validate` would, one line per rule and the first rows, instead of the night finding it."""
    export_csv(Path(__file__).resolve().parents[1] / "lines" / "sample", tmp_path / "csv")
    rs = tmp_path / "csv" / "rolling_stock.csv"
    rs.write_text(rs.read_text().replace("\nE10,200.0,", "\nE10,260.0,", 1))
    r = CliRunner().invoke(app, ["import", "csv", str(tmp_path / "csv"), "--out", str(tmp_path / "line")])
    assert r.exit_code == 0, r.output
    assert "warnings (they do not refuse the line" in r.output
    shown = r.output[r.output.index("warnings (they do not refuse"):]
    assert "train_fits_platform: 1992 rows" in shown and "(260.0 m long)" in shown
    assert len(shown.splitlines()) <= 6  # grouped: a head per rule and the first few rows, not one line per call
