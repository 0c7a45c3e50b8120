"""Rules across tables (planner/line/plausibility.py), with closed-form numbers on the tiny line.

Impossible geometry (issue 33): a standing train's tail off the line is refused; a train longer
than its platform is a warning. A's down stop marker is at 260 m, C's up stop marker at 4740 m,
the line runs 0 … 5000 m, platforms are 200 m; train 101 (EMU10, down) calls A, B, C stopping at
each; train 202 (EMU6, up) calls C, passes B, ends at A.

Values that pass their own range but fail with another table (issue 32): an on-board margin that
leaves no speed under a restriction, a brake weaker than the steepest climb's pull.
"""
from __future__ import annotations

import pytest

from typer.testing import CliRunner

from planner.cli import app
from planner.line.loader import check_line, load_line

from linedb import default_tables, write_line_db


def _line(tmp_path, name, emu10_m=200.0, emu6_m=120.0):
    t = default_tables()
    t["rolling_stock"].loc[0, "length_m"] = emu10_m
    t["rolling_stock"].loc[1, "length_m"] = emu6_m
    return write_line_db(tmp_path / name, rolling_stock=t["rolling_stock"])


def test_down_train_whose_tail_is_before_the_line_start_is_refused(tmp_path):
    found = check_line(_line(tmp_path, "long", emu10_m=300.0))  # tail at 260 - 300 = -40 m
    assert [(v.file, v.row, v.column) for v in found] == [("timetable.parquet", 0, "station_id")]
    msg = str(found[0])
    assert "train '101'" in msg and "tail is at -40.0 m" in msg and "start_m 0.0" in msg and "\n" not in msg


def test_down_train_whose_tail_is_on_the_line_start_is_valid(tmp_path):
    assert check_line(_line(tmp_path, "exact", emu10_m=260.0)) == []  # tail at exactly 0 m


def test_up_train_whose_tail_is_beyond_the_line_end_is_refused(tmp_path):
    found = check_line(_line(tmp_path, "long", emu6_m=261.0))  # tail at 4740 + 261 = 5001 m
    assert [(v.file, v.row, v.column) for v in found] == [("timetable.parquet", 3, "station_id")]
    assert "tail is at 5001.0 m" in str(found[0]) and "end_m 5000.0" in str(found[0])
    assert check_line(_line(tmp_path, "exact", emu6_m=260.0)) == []  # tail at exactly 5000 m


def test_train_longer_than_its_platform_is_a_warning_where_it_stands(tmp_path):
    w: list = []
    load_line(_line(tmp_path, "fits", emu10_m=200.0, emu6_m=200.0), w)  # as long as the 200 m platforms
    assert w == []
    w = []
    line = load_line(_line(tmp_path, "over", emu10_m=201.0, emu6_m=201.0), w)  # loads: never refused
    assert line.train_type("EMU10").length_m == 201.0
    # 101 stands at A, B, C (rows 0-2); 202 stands at C and A (rows 3, 5) but passes B (row 4)
    assert [(v.file, v.row, v.column) for v in w] == [("timetable.parquet", r, "stops") for r in (0, 1, 2, 3, 5)]
    assert "201.0 m long" in str(w[0]) and "platform is 200.0 m" in str(w[0])


def test_validate_prints_the_warnings_grouped_by_rule_and_succeeds(tmp_path):
    """One line per rule with its count, then the first three rows: one freight type at 200 m platforms
    printed 792 lines (34 per train)."""
    r = CliRunner().invoke(app, ["validate", str(_line(tmp_path, "over", emu10_m=201.0))])
    assert r.exit_code == 0
    err = r.stderr.splitlines()
    assert err[0] == "warning: train_fits_platform: 3 rows (a train stands at a platform shorter than itself):"
    assert err[1].startswith("  timetable.parquet row 0 (train_id=101 seq=0) column stops: train '101'")
    assert len(err) == 4
    w = []
    load_line(_line(tmp_path, "both", emu10_m=201.0, emu6_m=201.0), w)
    from planner.line.validate import format_warnings

    lines = format_warnings(w)
    assert lines[0].startswith("warning") is False and lines[0].startswith("train_fits_platform: 5 rows")
    assert lines[0].endswith("; the first 3:") and len(lines) == 5 and lines[-1] == "  … and 2 more of this rule"


# --- values that pass their range but fail with another table (issue 32)
def _stock(tmp_path, name, row, **cells):
    t = default_tables()
    for c, v in cells.items():
        t["rolling_stock"].loc[row, c] = v
    t["speed_limits"].loc[1, "limit_kmh"] = 40.0  # the EMU6-only restriction
    return check_line(write_line_db(tmp_path / name, rolling_stock=t["rolling_stock"],
                                    speed_limits=t["speed_limits"]))


def test_margin_must_leave_an_on_board_speed_under_the_lowest_limit(tmp_path):
    found = _stock(tmp_path, "at", 1, speed_margin_kmh=40.0)  # EMU6 meets the 40 km/h restriction
    assert [(v.file, v.row, v.column) for v in found] == [("rolling_stock.parquet", 1, "speed_margin_kmh")]
    assert "under 40.0 km/h (speed_limits.parquet row 1)" in str(found[0])
    assert _stock(tmp_path, "below", 1, speed_margin_kmh=39.9) == []
    assert _stock(tmp_path, "other", 0, speed_margin_kmh=45.0) == []  # EMU10 does not meet it (70 km/h is its lowest)


def test_any_positive_brake_is_accepted_whatever_the_gradients(tmp_path):
    """A freight with a real 0.81 km/h/s brake on a 20 ‰ line was refused ("use a higher rate"): advice to make
    braking distances optimistic. Validation accepts any positive rate: a brake weaker than a gradient's pull is
    a verdict of physics on the legs where it matters (test_a_weak_brake_climbs_and_is_flagged_on_the_descent)."""
    assert _stock(tmp_path, "weak", 0, stop_brake_kmh_s=0.05, service_brake_kmh_s=0.05, atsp_pattern_kmh_s=0.05) == []


def test_a_weak_brake_climbs_and_is_flagged_on_the_descent(tmp_path):
    """The steep line's freight with a 0.6 km/h/s brake, weaker than the 0.67 km/h/s a 20 ‰ gradient pulls
    (g · 0.02 / (1 + ρ), ρ = 0.06): up the climb it runs and stops at its marker (a run below its braking curve
    powers: it brakes less than the curve asks); down the 20 ‰ fall towards A no stopping pattern stops it, a
    flag on that approach (the run's no_stop), not a failure."""
    import warnings

    from linedb import write_line_db
    from steep_line import steep_tables
    from planner import running_time
    from planner.line.loader import load_line
    from planner.stopping.sweep import stop_sweep

    pull = 9.80665 * 0.020 / 1.06 * 3.6
    assert 0.66 < pull < 0.67
    t = steep_tables()
    rs = t["rolling_stock"]
    for c in ("service_brake_kmh_s", "stop_brake_kmh_s", "brake_comfort_kmh_s", "atsp_pattern_kmh_s"):
        rs.loc[rs.train_type == "FRT", c] = 0.6
    line = load_line(write_line_db(tmp_path / "steep", **{**t, "rolling_stock": rs}))
    up_the_climb = running_time(line, "FRT", "A", "B", ratio=1.0)
    assert 300.0 < up_the_climb.time_s < 1000.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = stop_sweep(line, train_types=["FRT"], adhesion_kmh_s="2.5", n_jobs=1)
    stuck = {(r.direction, r.origin, r.station_id) for r in res if r.n_feasible < len(r.patterns)}
    assert ("up", "B", "A") in stuck and ("down", "A", "B") not in stuck
    desc = next(r for r in res if (r.direction, r.origin, r.station_id) == ("up", "B", "A"))
    assert "falling gradient" in desc.patterns[0].reason


def test_a_real_freight_brake_on_the_20_permil_line_stops_both_ways_within_its_energy(tmp_path):
    """The freight brake the issue had refused, 0.81 km/h/s (0.225 m/s²), on the same 20 ‰ line: it imports,
    climbs, and stops at A coming down the fall, where the gradient takes 0.185 m/s² (g · 0.02 / 1.06) of its
    brake. Closed form, independent of the solver: a stop from v0 over d_fall metres of the fall and d_flat
    metres of level track needs v0² ≤ 2 (b − pull) d_fall + 2 b d_flat (jerk limits only lengthen it), and
    the pattern never asks for more than the brake."""
    import warnings

    from linedb import write_line_db
    from steep_line import steep_tables
    from planner import running_time
    from planner.line.loader import load_line
    from planner.stopping.sweep import stop_sweep

    b = 0.81 / 3.6
    pull = 9.80665 * 0.020 / 1.06
    t = steep_tables()
    rs = t["rolling_stock"]
    for c in ("service_brake_kmh_s", "stop_brake_kmh_s", "brake_comfort_kmh_s", "atsp_pattern_kmh_s"):
        rs.loc[rs.train_type == "FRT", c] = 0.81
    line = load_line(write_line_db(tmp_path / "steep", **{**t, "rolling_stock": rs}))  # valid: no refusal
    for o, d in (("A", "B"), ("B", "A")):
        run = running_time(line, "FRT", o, d, ratio=1.0)
        assert 300.0 < run.time_s < 1500.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = stop_sweep(line, train_types=["FRT"], adhesion_kmh_s="2.5", n_jobs=1)
    desc = next(r for r in res if (r.direction, r.origin, r.station_id) == ("up", "B", "A"))
    assert desc.n_feasible == len(desc.patterns) == 1
    p = desc.patterns[0]
    assert p.feasible
    # where the approach starts: the fall runs from 5,000 m down to 1,500 m, then level track to the marker (440 m)
    x0, stop = desc.approach_start_m, desc.stop_m
    assert stop == 440.0 and x0 > 1500.0
    d_fall, d_flat = min(x0, 5000.0) - 1500.0, 1500.0 - stop
    v0 = desc.v_start_ms
    assert v0 > 5.0
    assert v0 ** 2 <= 2 * (b - pull) * d_fall + 2 * b * d_flat + 1e-6
    assert float(p.sample(0.05).a_ms2.min()) >= -b - 1e-9
    # it holds v0 down the fall and brakes on the level: the jerk-limited stop from cruise, v²/2b + v·b/2J
    J = 3.0 / 3.6  # the freight's jerk limit, 3 km/h/s²
    assert p.braking_distance_m < d_flat
    assert p.braking_distance_m == pytest.approx(v0 ** 2 / (2 * b) + v0 * b / (2 * J), abs=1e-3)
