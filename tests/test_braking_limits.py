"""Three braking limits kept apart: the traction comfort limit (acceleration), the ride-comfort limit on
stop braking, and the train's own stopping brake; what an importer maps onto each and what a stop asks.

Closed forms: g = 9.80665 m/s², a gradient of s ‰ adds g s / 1000 / (1 + ρ) to the deceleration achieved.
"""
from __future__ import annotations

import math
from dataclasses import replace

import pandas as pd
import pytest

import importsrc as src
from linedb import default_tables, write_line_db
from planner import load_line, running_time
from planner.errors import LineValidationError, SourceError
from planner.line import testing
from planner.line.importers.csv import export_csv, import_csv
from planner.line.importers.railjson import import_railjson
from planner.line.units import KMH, KMH_S
from planner.tables.ratios import leg_max_speed_ms
from planner.report.leg_margin import leg_result
from planner.stopping.approach import train_adhesion_ms2
from planner.stopping.pattern import decel_limit_profile, solve_stop
from planner.stopping.sweep import adhesion_levels, approach_patterns

G = 9.80665


def _old_folder(tmp_path):
    """A line database of schema version 1: rolling_stock's brake_comfort_kmh_s under its old name."""
    t = default_tables("old")
    t["rolling_stock"] = t["rolling_stock"].rename(columns={"brake_comfort_kmh_s": "comfort_accel_kmh_s"})
    t["line"]["schema_version"] = 1
    return write_line_db(tmp_path / "old", **t)


def test_a_folder_of_schema_1_is_read_as_2_with_one_note_and_upgraded_on_request(tmp_path):
    """Old names are never a hard wall: a folder of schema 1 was refused ("rename the column"). It is read as
    schema 2 with one note per change, `planner line upgrade DIR` rewrites it (then no note), and reads the
    same line as a folder written in schema 2 from the start."""
    from typer.testing import CliRunner

    from planner.cli import app

    old = _old_folder(tmp_path)
    line = load_line(old)
    assert line.schema_version == 2 and line.train_type("EMU10").brake_comfort_ms2 > 0
    assert len(line.upgrade_notes) == 2 and line.upgrade_notes[0] == "schema 1 read as 2"
    assert line.upgrade_notes[1].startswith("rolling_stock.parquet: column comfort_accel_kmh_s read as "
                                            "brake_comfort_kmh_s, the ride-comfort limit on stop braking")
    r = CliRunner().invoke(app, ["validate", str(old)])
    assert r.exit_code == 0 and f"`planner line upgrade {old}` rewrites the folder" in r.stderr
    r = CliRunner().invoke(app, ["line", "upgrade", str(old)])
    assert r.exit_code == 0 and r.stdout.count("\n") == 3 and "upgraded to schema version 2" in r.stdout
    again = load_line(old)
    assert again.upgrade_notes == () and again.schema_version == 2
    assert [t.brake_comfort_ms2 for t in again.train_types] == [t.brake_comfort_ms2 for t in line.train_types]
    assert [t.train_id for t in again.trains] == [t.train_id for t in line.trains]  # (NaN times: no ==)
    import pyarrow.parquet as pq

    assert "brake_comfort_kmh_s" in pq.read_table(old / "rolling_stock.parquet").column_names
    assert pq.read_table(old / "line.parquet").column("schema_version").to_pylist() == [2]
    assert "nothing to upgrade" in CliRunner().invoke(app, ["line", "upgrade", str(old)]).stdout


def test_a_csv_of_schema_1_imports_as_schema_2_with_a_note(tmp_path):
    """The CSV import said "brake_comfort_kmh_s is missing … rename"; it reads the old header as the new one."""
    import pyarrow.parquet as pq

    write_line_db(tmp_path / "a")
    export_csv(tmp_path / "a", tmp_path / "csv")
    p = tmp_path / "csv" / "rolling_stock.csv"
    p.write_text(p.read_text().replace("brake_comfort_kmh_s", "comfort_accel_kmh_s"))
    s = import_csv(tmp_path / "csv", tmp_path / "b")
    assert any(n.startswith("rolling_stock.csv: column comfort_accel_kmh_s read as brake_comfort_kmh_s")
               for n in s.notes)
    assert "brake_comfort_kmh_s" in pq.read_table(tmp_path / "b" / "rolling_stock.parquet").column_names
    assert load_line(tmp_path / "b").upgrade_notes == ()


def test_a_folder_of_a_newer_schema_is_refused_in_one_line(tmp_path):
    t = default_tables("new")
    t["line"]["schema_version"] = 3
    with pytest.raises(LineValidationError, match="schema versions 1 to 2: a newer one needs a newer planner"):
        load_line(write_line_db(tmp_path / "new", **t))


def test_the_stop_is_capped_by_the_train_brake_in_effort_and_in_what_it_achieves():
    # comfort 1.0, adhesion 0.8, brake 0.5 m/s² (rho 0): flat 0.5; -10 ‰ leaves 0.5 - g/100;
    # +30 ‰ would give 0.5 + 0.03 g = 0.794 but the brake caps the deceleration achieved at 0.5
    got = decel_limit_profile(1.0, 0.8, [(0.0, 0.0), (100.0, -10.0), (250.0, 30.0)], brake_ms2=0.5)
    assert got == [(0.0, 0.5), (100.0, pytest.approx(0.5 - G / 100)), (250.0, 0.5)]
    # without the train's brake the old rule: min(comfort, adhesion) + gravity
    old = decel_limit_profile(1.0, 0.8, [(0.0, 30.0)])
    assert old == [(0.0, pytest.approx(0.8 + 0.03 * G))]


def test_a_stop_on_a_climb_never_stops_harder_than_the_train_brake():
    brake = 2.0  # km/h/s; comfort 3.6, adhesion 3.5: the brake binds, on the climb in what is achieved
    tt = testing.train_type(stop_brake_kmh_s=brake, brake_comfort_kmh_s=3.6, max_speed_kmh=80.0)
    line = testing.line(length_m=4000.0, stations=[0.0, 3900.0], gradients=[(0.0, 4000.0, 20.0)],
                        max_speed_kmh=80.0, train_types=[tt])
    r = approach_patterns(line, "T", "S0", "S1", [3.5 * KMH_S], approach_m=900.0)
    p = r.patterns[0]
    assert p.feasible
    assert max(a for _, a in r.decel_limits[0]) == pytest.approx(brake * KMH_S)
    smp = p.sample(0.01)
    assert float(smp.a_ms2.min()) >= -brake * KMH_S - 1e-9
    # and it is no faster than braking at the brake's deceleration from the same speed (v / b + jerk)
    assert p.duration_s >= r.v_start_ms / (brake * KMH_S)


def test_an_osrd_fast_train_brakes_with_its_brake_not_its_comfort_acceleration(tmp_path):
    # OSRD's fast test stock: comfort_acceleration 0.25 m/s² (traction), const_gamma 0.5 m/s² (brake)
    rs = src.edited(src.rolling_stock, lambda d: d.update(comfort_acceleration=0.25, const_gamma=0.5))
    i, r, x = src.write_railjson(tmp_path / "rj", rs=rs)
    s = import_railjson(i, ["W", "M", "E"], [r], tmp_path / "line", extra=x)
    row = pd.read_parquet(tmp_path / "line" / "rolling_stock.parquet").iloc[0]
    assert row.max_accel_kmh_s == pytest.approx(0.25 * 3.6)      # traction comfort: caps acceleration
    assert row.stop_brake_kmh_s == pytest.approx(0.5 * 3.6)      # the train's own stopping brake
    assert row.service_brake_kmh_s == pytest.approx(0.5 * 3.6)
    assert row.brake_comfort_kmh_s == 3.3                        # OSRD has none: the stated default
    text = "\n".join(s.lines())
    assert "brake_comfort_kmh_s = 3.3 (default:" in text
    assert "comfort_acceleration 0.25 m/s² -> max_accel_kmh_s" in text
    assert "a stopping pattern asks for at most 1.8 km/h/s" in text
    line = load_line(tmp_path / "line")
    res = approach_patterns(line, "EMU", "W", "M", [3.5 * KMH_S], approach_m=1500.0)
    assert res.patterns[0].feasible, res.patterns[0].reason
    flat = [a for a in (d for _, d in res.decel_limits[0])]
    assert max(flat) == pytest.approx(0.5)  # the brake, not 0.25 (nor comfort 3.3 km/h/s = 0.917)


def test_the_min_time_pattern_at_the_brake_alone_is_the_closed_form():
    # position-independent check of the cap: v = 20 m/s, brake 0.5, jerk J = 1: T = v/b + b/J
    b, J, v = 0.5, 1.0, 20.0
    dl = decel_limit_profile(0.917, 0.97, brake_ms2=b)
    p = solve_stop(v, 1000.0, jerk_max=J, decel_limits=dl, speed_limits=[(0.0, v)])
    braking = v / b + b / J
    dist_braking = v * v / (2 * b) + v * b / (2 * J)
    assert p.feasible
    assert p.duration_s == pytest.approx((1000.0 - dist_braking) / v + braking, abs=1e-6)
    assert math.isclose(p.braking_distance_m, dist_braking, abs_tol=1e-6)


# --------------------------------------------------------------------------- adhesion levels relative to the train
def _freight(**kw):
    """A 920 t freight braking at 0.225 m/s² (0.81 km/h/s) with its own brake, 80 km/h."""
    return testing.train_type("FRT", empty_mass_t=920.0, full_load_mass_t=0.0, max_speed_kmh=80.0,
                              max_accel_kmh_s=1.0, service_brake_kmh_s=0.81, stop_brake_kmh_s=0.81,
                              brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=1.8, davis_a_kN=10.0,
                              traction=((0.0, 300.0), (200.0, 300.0)), **kw)


def test_levels_above_the_train_brake_become_the_brake_once():
    lv = [a * KMH_S for a in adhesion_levels("2.5:3.5:0.1")]
    assert train_adhesion_ms2(_freight(), lv) == (0.81 * KMH_S,)
    e10 = testing.train_type(stop_brake_kmh_s=3.2, brake_comfort_kmh_s=3.5)
    got = [round(a / KMH_S, 9) for a in train_adhesion_ms2(e10, lv)]
    assert got == [2.5, 2.6, 2.7, 2.8, 2.9, 3.0, 3.1, 3.2]
    e6 = testing.train_type(stop_brake_kmh_s=3.0, brake_comfort_kmh_s=2.8)  # comfort binds below the brake
    assert max(train_adhesion_ms2(e6, lv)) == 2.8 * KMH_S


def test_a_slow_braking_freight_sweeps_one_level_and_stops_at_its_brake():
    line = testing.line(length_m=8000.0, stations=[0.0, 7500.0], max_speed_kmh=80.0, train_types=[_freight()])
    r = approach_patterns(line, "FRT", "S0", "S1", [a * KMH_S for a in adhesion_levels("2.5:3.5:0.1")],
                          approach_m=2000.0)
    assert r.adhesion_ms2 == (0.81 * KMH_S,) and r.patterns[0].feasible
    assert float(r.patterns[0].sample(0.05).a_ms2.min()) >= -0.81 * KMH_S - 1e-9


@pytest.mark.parametrize("grad", [0.0, 10.0, -10.0])
def test_the_bad_day_of_a_slow_braking_freight_is_never_faster_than_nominal(grad):
    # before: the sweep 2.5 … 3.5 km/h/s stopped it at 0.69 … 0.97 m/s², three to four times its brake,
    # and the bad day came out faster than the minimum (a negative stop-model term)
    line = testing.line(length_m=8000.0, stations=[0.0, 7500.0], max_speed_kmh=80.0,
                        gradients=[(5000.0, 8000.0, grad)], train_types=[_freight()])
    r = leg_result(line, "FRT", "S0", "S1", [], approach_m=2000.0)
    assert r.sweep_adhesion_kmh_s.tolist() == [0.81]
    assert r.adhesion_min_kmh_s == 0.81
    assert r.degraded_min_s >= r.min_time_s
    assert r.degraded_loss_stop_model_s >= 0.0  # the jerk-limited stop at most at the brake: never faster
    assert r.degraded_loss_stop_s == 0.0        # one level: low rail adhesion does not limit this train
    if grad < 0:  # a falling approach takes g/100 from the brake: the stop is slower than the run curves'
        assert r.degraded_loss_stop_model_s > 10.0


# --------------------------------------------------------------------------- the line maximum
def test_where_no_restriction_applies_the_train_runs_at_its_own_maximum():
    tt = testing.train_type(max_speed_kmh=120.0)
    line = testing.line(length_m=10_000.0, stations=[0.0, 9000.0], max_speed_kmh=None, train_types=[tt],
                        limits=[(0.0, 1000.0, 60.0)])
    assert leg_max_speed_ms(line, "T", "S0", "S1") == pytest.approx(120.0 * KMH)
    same = running_time(replace(line, max_speed_ms=120.0 * KMH), "T", "S0", "S1").time_s
    assert running_time(line, "T", "S0", "S1").time_s == same
    # the old importer default (the highest limit on the path, 60 km/h) held the train at 60 everywhere
    assert running_time(replace(line, max_speed_ms=60.0 * KMH), "T", "S0", "S1").time_s > same + 100.0


def test_an_import_sets_no_line_maximum_unless_the_toml_does(tmp_path):
    def edit(d):  # the 100 km/h section now covers T1 only: T2 and T3 have no section but V60
        d["speed_sections"][0]["track_ranges"] = d["speed_sections"][0]["track_ranges"][:1]

    i, r, x = src.write_railjson(tmp_path / "rj", infra=src.edited(src.railjson_infra, edit))
    s = import_railjson(i, ["W", "M", "E"], [r], tmp_path / "line", extra=x)
    assert pd.read_parquet(tmp_path / "line" / "line.parquet").max_speed_kmh.isna().all()
    assert "line_max_speed = 'none'" in "\n".join(s.lines())
    line = load_line(tmp_path / "line")
    assert line.max_speed_ms == math.inf
    assert leg_max_speed_ms(line, "EMU", "M", "E") == pytest.approx(110.0 * KMH)  # the train's own, not 100
