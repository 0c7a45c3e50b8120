"""The bad day by effect (issue 17): load, traction and adhesion each on/off and valued, each with its share.

Closed form on the test line of test_margins.py (constant force 300 kN, 300 t empty, 400 t full, brakes
3.6 km/h/s, no resistance): accelerating to V at a takes V/(2a) longer than running at V, so the
load alone costs V/(2·0.75) − V/2 and the weak traction on top of it V/(2·0.675) − V/(2·0.75).
"""
from __future__ import annotations

import pytest

from planner.errors import InputError
from planner.report.leg_margin import leg_result
from planner.report.margin_rule import MarginRule
from test_margins import A_DEG, APPROACH, SMALL_GRID, TOL_S, V, closed_form_line, t_degraded

A_LOAD = 300e3 / 400e3  # full load, nominal traction
L = 1500.0


def _leg(**rule):
    return leg_result(closed_form_line(), "T", "S0", "S1", [100.0], rule=MarginRule(**rule),
                      adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH, ratios=SMALL_GRID)


@pytest.fixture(scope="module")
def full():
    return _leg()


def test_each_effect_has_its_share_and_they_add_up(full):
    assert full.degraded_loss_load_s == pytest.approx(V / (2 * A_LOAD) - V / 2, abs=TOL_S)
    assert full.degraded_loss_traction_s == pytest.approx(V / (2 * A_DEG) - V / (2 * A_LOAD), abs=TOL_S)
    total = full.degraded_loss_load_s + full.degraded_loss_traction_s + full.degraded_loss_stop_s
    # they add up to degraded − the nominal run with the same stop model (issue 14: the jerk-limited
    # pattern in both): the table minimum with its constant 1 m/s² stop over the approach (cruise at V,
    # then V/1 s of braking over V²/2 m) swapped for the nominal pattern's duration
    nominal_same_model = full.min_time_s - ((APPROACH - V * V / 2) / V + V) + full.stop_time_nominal_s
    assert total == pytest.approx(full.degraded_min_s - nominal_same_model, abs=TOL_S)
    assert full.degraded_min_s == pytest.approx(t_degraded(L), abs=TOL_S)
    # the fourth share is that swap of stop model: the nominal pattern against cruising at V to the brake
    # point and braking at 1 m/s² (the table minimum's last APPROACH metres)
    assert full.degraded_loss_stop_model_s == pytest.approx(
        full.stop_time_nominal_s - ((APPROACH - V * V / 2) / V + V), abs=TOL_S)
    assert full.degraded_loss_stop_model_s > 0.5  # the jerk-limited pattern is slower: the old three did not add up


@pytest.mark.parametrize("rule", [{}, {"bad_day_adhesion": False}, {"bad_day_load": False},
                                  {"degraded_adhesion_kmh_s": 2.5}])
def test_four_shares_add_up_to_the_bad_day_cost(rule):
    r = _leg(**rule)
    shares = (r.degraded_loss_load_s + r.degraded_loss_traction_s + r.degraded_loss_stop_s
              + r.degraded_loss_stop_model_s)
    assert shares == pytest.approx(r.degraded_min_s - r.min_time_s, abs=1e-9)


def test_effects_switch_off():
    # adhesion off: the degraded run stops with the tables' stopping brake (1 m/s²)
    r = _leg(bad_day_adhesion=False)
    assert r.degraded_min_s == pytest.approx(V / (2 * A_DEG) + L / V + V / 2, abs=TOL_S)
    assert r.degraded_loss_stop_s == pytest.approx(0.0, abs=TOL_S)
    # load and traction off: only the low-adhesion stop remains
    r = _leg(bad_day_load=False, bad_day_traction=False)
    assert r.degraded_loss_load_s == pytest.approx(0.0, abs=1e-9)
    assert r.degraded_loss_traction_s == pytest.approx(0.0, abs=1e-9)
    assert r.degraded_min_s == pytest.approx(V / 2 + t_degraded(L) - V / (2 * A_DEG), abs=TOL_S)


def test_values_are_used():
    # a lighter bad day (half the passengers: 350 t) and a chosen adhesion (2.5 km/h/s instead of the sweep's 3.0)
    r = _leg(degraded_load=0.5, bad_day_traction=False, degraded_adhesion_kmh_s=2.5)
    assert r.degraded_loss_load_s == pytest.approx(V / (2 * 300 / 350) - V / 2, abs=TOL_S)
    assert r.adhesion_min_kmh_s == 2.5
    assert r.stop_time_degraded_s > _leg(degraded_load=0.5, bad_day_traction=False).stop_time_degraded_s


def test_rule_describes_and_checks_itself():
    assert MarginRule().describe([2.5, 3.5]) == "load 100%, traction ×0.9, adhesion 2.5 km/h/s"
    assert MarginRule(bad_day_load=False, bad_day_adhesion=False).describe([2.5]) == (
        "load off (empty), traction ×0.9, adhesion off (stopping brake)")
    with pytest.raises(InputError, match="degraded_load"):
        MarginRule(degraded_load=1.5)


def test_a_train_types_bad_day_does_not_depend_on_the_other_types_on_the_line(tmp_path):
    """The stops step sweeps each train type's adhesion levels, capped by its brake; the margin report took the
    lowest level of the whole line for every type's bad day, so one weak freight brake (0.82 km/h/s) made the
    passenger legs short on a bad day. EMU10's rows are the same with EMU6 on the line with a weak stopping
    brake (its levels capped at 1.0 km/h/s) and without."""
    import warnings

    import pandas as pd

    from linedb import default_tables, write_line_db
    from planner.datasets.stops import write_stops
    from planner.line.loader import load_line
    from planner.report.margins import compute_margins
    from planner.stopping.sweep import stop_sweep

    t = default_tables()
    rs = t["rolling_stock"]
    rs.loc[rs.train_type == "EMU6", ["stop_brake_kmh_s", "brake_comfort_kmh_s"]] = 1.0
    line = load_line(write_line_db(tmp_path / "tiny", nodes=None, edges=None, rolling_stock=rs))
    rows = {}
    for name, types in (("alone", ["EMU10"]), ("shared", ["EMU10", "EMU6"])):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = stop_sweep(line, train_types=types, adhesion_kmh_s="2.5:3.5:0.5", n_jobs=1)
        write_stops(res, tmp_path / name)
        rep = compute_margins(line, train_types=["EMU10"], stops_dir=tmp_path / name, n_jobs=1)
        rows[name] = rep.rows
    assert rows["shared"]["adhesion_min_kmh_s"].eq(2.5).all()  # EMU10's own lowest level, not EMU6's 1.0
    pd.testing.assert_frame_equal(rows["alone"], rows["shared"])
