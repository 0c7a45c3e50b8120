"""Margin report on a line whose running times are known in closed form.

The line (``planner.line.testing``): level, straight, no running resistance, a
constant 300 kN on 300 t empty (no rotating mass), so the train accelerates at
a = 1 m/s² up to the on-board maximum V = 100 km/h, holds it, and stops with the
stopping brake b = 1 m/s². Stations at 0, 1500 and 3000 m.

Closed forms used below (derived by hand, independent of the code):

* run of length L at ratio r (target c = r V, L ≥ c²):
  ``T(L, r) = c/a + c/b + (L − c²/2a − c²/2b)/c = L/c + c`` (a = b = 1);
  traction energy ``E(r) = M c²/2`` (work only while accelerating; no resistance);
* degraded (load 1.0: 400 t; traction × 0.9: 270 kN → a_d = 0.675 m/s²) to the
  pattern start s_p, cruising at V by then: ``t = V/a_d + (s_p − V²/2a_d)/V``;
* stopping pattern from V at deceleration limit A (adhesion below comfort), jerk
  J: the classic symmetric jerk-limited profile takes ``T_b = V/A + A/J`` over
  ``D_b = V T_b / 2`` (speed is point-symmetric about the half-way time), plus
  the cruise ``(X − D_b)/V`` from the pattern start at X before the marker;
  hence ``degraded(L) = V/(2 a_d) + (L − D_b)/V + T_b``.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, strategies as st

from planner.line import testing
from planner.io.parquet import read_dataset
from planner.errors import InputError
from planner.report.margin_datasets import MARGIN_TOTALS_SCHEMA, MARGINS_SCHEMA, write_margins
from planner.report.margin_rule import MarginRule, margin_columns, round_up_s
from planner.report.margins import compute_margins, timetable_legs
from planner.line.model import Call, Train

V = 100 / 3.6          # on-board maximum [m/s]
A_NOM = 1.0            # 300 kN / 300 t
B = 1.0                # stop and service brake 3.6 km/h/s
A_DEG = 0.9 * 300e3 / 400e3
J = 1.0                # jerk limit 3.6 km/h/s²
ADH = 3.0 / 3.6        # lowest adhesion of the sweep "3.0:3.5:0.5" [m/s²] (below comfort 1.0)
APPROACH = 700.0       # pattern start before the marker (no TASC beacons on this line)
M_EMPTY = 300e3
SMALL_GRID = [1.0, 0.6, 0.2]  # tests that check neither the ratio choice nor the slowest time
GRID = [1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2]  # default grid, 100 km/h line

TOL_S = 0.05
"""Integrator accuracy on closed-form cases (docs/design.md §2: within 0.05 s at the default 1 m step)."""
TOL_KWH = 1e-3 * 32.0
"""Energy: 0.1 % of the full-ratio energy (Heun's step is exact for constant force; round-off only)."""


def t_run(L, r):
    c = r * V
    return L / c + c


def energy_kwh(r):
    return M_EMPTY * (r * V) ** 2 / 2 / 3.6e6


def t_degraded(L, adh=ADH):
    tb = V / adh + adh / J
    db = V * tb / 2
    return V / (2 * A_DEG) + (L - db) / V + tb


def required(L, t_min):
    return 0.03 * t_min + 1.0 * 60 * L / 100_000


def _train(tid, direction, calls):
    return Train(tid, "T", direction, tuple(Call(i, s, a, d, stops) for i, (s, a, d, stops) in enumerate(calls)))


NAN = float("nan")
TRAINS = (
    # local down: 100 s (ok), 95 s (tight: 3.3 s left on a bad day)
    _train("L1", "down", [("S0", NAN, 0.0, True), ("S1", 100.0, 130.0, True), ("S2", 225.0, NAN, True)]),
    # rapid down passing S1: 140 s (infeasible: below the degraded 145.7 s, and short of the supplement)
    _train("R1", "down", [("S0", NAN, 600.0, True), ("S1", 670.0, 670.0, False), ("S2", 740.0, NAN, True)]),
    # two locals up with the same running times: 82 s (infeasible), 290 s (unreachable: slowest is 275.6 s)
    _train("L2", "up", [("S2", NAN, 1000.0, True), ("S1", 1082.0, 1112.0, True), ("S0", 1402.0, NAN, True)]),
    _train("L3", "up", [("S2", NAN, 2000.0, True), ("S1", 2082.0, 2112.0, True), ("S0", 2402.0, NAN, True)]),
)


def closed_form_line(trains=TRAINS):
    line = testing.line(stations=[0.0, 1500.0, 3000.0])
    return dataclasses.replace(line, trains=trains)


@pytest.fixture(scope="module")
def report():
    return compute_margins(closed_form_line(), adhesion_kmh_s="3.0:3.5:0.5", approach_m=APPROACH,
                           conflicts=False)


def row(rep, direction, o, d):
    r = rep.rows[(rep.rows.direction == direction) & (rep.rows.origin == o) & (rep.rows.destination == d)]
    assert len(r) == 1, r
    return r.iloc[0]


EXPECTED = {  # (direction, origin, destination): (length, scheduled, flags)
    ("down", "S0", "S1"): (1500.0, 100.0, set()),
    ("down", "S1", "S2"): (1500.0, 95.0, {"tight"}),
    ("down", "S0", "S2"): (3000.0, 140.0, {"infeasible"}),
    ("up", "S2", "S1"): (1500.0, 82.0, {"infeasible"}),
    ("up", "S1", "S0"): (1500.0, 290.0, {"unreachable"}),
}


def test_rows_are_legs_between_stops(report):
    keys = {(r.direction, r.origin, r.destination) for r in report.rows.itertuples()}
    assert keys == set(EXPECTED)
    assert list(row(report, "down", "S0", "S2").passes) == ["S1"]  # a pass is not a stop
    assert list(row(report, "down", "S0", "S1").passes) == []
    up = row(report, "up", "S2", "S1")
    assert up.n_trains == 2 and list(up.train_ids) == ["L2", "L3"]


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_minimum_margin_rounding_supplement(report, key):
    L, sched, _ = EXPECTED[key]
    r = row(report, *key)
    tmin = t_run(L, 1.0)
    assert r.length_m == pytest.approx(L, abs=1e-9)
    assert r.scheduled_running_time_s == sched
    assert r.min_running_time_s == pytest.approx(tmin, abs=TOL_S)
    assert r.min_running_time_rounded_s == math.ceil(tmin / 10) * 10  # 81.8 -> 90, 135.8 -> 140
    assert r.margin_s == pytest.approx(sched - tmin, abs=TOL_S)
    assert r.margin_percent == pytest.approx(100 * (sched - tmin) / tmin, abs=0.1)
    assert r.supplement_required_s == pytest.approx(required(L, tmin), abs=TOL_S)
    assert bool(r.supplement_met) == (sched - tmin >= required(L, tmin))
    assert r.slowest_running_time_s == pytest.approx(t_run(L, GRID[-1]), abs=TOL_S)


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_degraded_minimum_and_flags(report, key):
    L, sched, flags = EXPECTED[key]
    r = row(report, *key)
    assert r.pattern_start_source == "approach"
    assert r.degraded_min_running_time_s == pytest.approx(t_degraded(L), abs=TOL_S)
    assert r.remaining_margin_s == pytest.approx(sched - t_degraded(L), abs=TOL_S)
    # the two parts of the bad-day loss, each in closed form
    s_p = L - APPROACH
    t_nom_sp = V / A_NOM + (s_p - V * V / (2 * A_NOM)) / V
    t_deg_sp = V / A_DEG + (s_p - V * V / (2 * A_DEG)) / V
    tb = V / ADH + ADH / J
    assert r.degraded_loss_running_s == pytest.approx(t_deg_sp - t_nom_sp, abs=TOL_S)
    # one stop model (issue 14, defect 5): the nominal stop is the jerk-limited pattern too, at the
    # best adhesion of the sweep (3.5 km/h/s, below comfort) from the nominal run's speed V there
    a_hi = 3.5 / 3.6
    tb_hi = V / a_hi + a_hi / J
    stop_nom = (APPROACH - V * tb_hi / 2) / V + tb_hi
    assert r.stop_time_nominal_s == pytest.approx(stop_nom, abs=1e-6)
    assert r.stop_time_degraded_s == pytest.approx((APPROACH - V * tb / 2) / V + tb, abs=1e-6)  # exact pattern
    # both at speed V over the same approach: only the adhesion effect is left, (T_b(lo) - T_b(hi)) / 2
    assert r.degraded_loss_stop_s == pytest.approx((tb - tb_hi) / 2, abs=1e-6)
    assert r.degraded_loss_stop_s == pytest.approx(r.adhesion_loss_s, abs=1e-6)
    got = {f for f in ("infeasible", "tight", "unreachable") if bool(getattr(r, f))}
    assert got == flags


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_ratio_energy_closed_loop(report, key):
    L, sched, _ = EXPECTED[key]
    r = row(report, *key)
    times = np.array([t_run(L, x) for x in GRID])
    r_exp = GRID[int(np.argmin(np.abs(times - sched)))]
    assert r.ratio_on_time == r_exp
    assert r.energy_at_full_ratio_kwh == pytest.approx(energy_kwh(1.0), abs=TOL_KWH)
    assert r.energy_at_ratio_kwh == pytest.approx(energy_kwh(r_exp), abs=TOL_KWH)
    assert r.energy_saved_percent == pytest.approx(100 * (1 - r_exp ** 2), abs=0.1)
    err = closed_loop_error(L, sched)
    assert r.arrival_error_s == pytest.approx(err, abs=TOL_S)


def closed_loop_error(L, sched, x_eval=200.0):
    """The on-board nearest rule in closed form: decide at departure and at 200 m (the only points)."""
    grid = np.array(GRID)

    def from_state(s0, v0, r):  # time from (s0, v0) to the stop at ratio r (service brake 1 m/s² if above)
        c = r * V
        t1, d1 = (abs(c - v0) / 1.0, abs(c * c - v0 * v0) / 2.0)
        rest = L - s0 - d1 - c * c / (2 * B)
        assert rest >= 0
        return t1 + rest / c + c / B

    def at_x(r):  # state at 200 m when running at r from the start
        c = r * V
        if c * c / (2 * A_NOM) <= x_eval:
            return c, c / A_NOM + (x_eval - c * c / (2 * A_NOM)) / c
        v = math.sqrt(2 * A_NOM * x_eval)
        return v, v / A_NOM

    r0 = grid[int(np.argmin(np.abs([t_run(L, x) - sched for x in grid])))]
    v_x, t_x = at_x(r0)
    row_b = np.array([from_state(x_eval, v_x, x) for x in grid])
    r1 = grid[int(np.argmin(np.abs(row_b - (sched - t_x))))]
    return t_x + from_state(x_eval, v_x, r1) - sched


def test_totals_per_train_and_line(report):
    t = report.totals
    tr = t[t.level == "train"].set_index("train_id")
    assert sorted(tr.index) == ["L1", "L2", "L3", "R1"]
    m15, m30 = t_run(1500, 1), t_run(3000, 1)
    d15, d30 = t_degraded(1500), t_degraded(3000)
    exp = {  # train: (legs, sum min, sum rounded, sum scheduled, sum degraded, infeasible, tight, unreachable)
        "L1": (2, 2 * m15, 180.0, 195.0, 2 * d15, 0, 1, 0),
        "R1": (1, m30, 140.0, 140.0, d30, 1, 0, 0),
        "L2": (2, 2 * m15, 180.0, 372.0, 2 * d15, 1, 0, 1),
        "L3": (2, 2 * m15, 180.0, 372.0, 2 * d15, 1, 0, 1),
    }
    for tid, (n, smin, srnd, ssch, sdeg, ninf, ntight, nunr) in exp.items():
        r = tr.loc[tid]
        assert r.n_legs == n and r.n_trains == 1
        assert r.min_running_time_s == pytest.approx(smin, abs=2 * TOL_S)
        assert r.min_running_time_rounded_s == srnd
        assert r.scheduled_running_time_s == ssch
        assert r.margin_s == pytest.approx(ssch - smin, abs=2 * TOL_S)
        assert r.degraded_min_running_time_s == pytest.approx(sdeg, abs=2 * TOL_S)
        assert r.remaining_margin_s == pytest.approx(ssch - sdeg, abs=2 * TOL_S)
        assert (r.n_infeasible, r.n_tight, r.n_unreachable) == (ninf, ntight, nunr)
    assert tr.loc["L1"].origin == "S0" and tr.loc["L1"].destination == "S2"
    assert tr.loc["L2"].min_remaining_margin_s == pytest.approx(82.0 - d15, abs=TOL_S)
    # what each train lacks on a bad day, leg by leg (the unreachable leg lacks nothing)
    assert tr.loc["L1"].bad_day_shortfall_s == 0.0
    assert tr.loc["R1"].bad_day_shortfall_s == pytest.approx(d30 - 140.0, abs=TOL_S)
    assert tr.loc["L2"].bad_day_shortfall_s == pytest.approx(d15 - 82.0, abs=TOL_S)
    for d, tids in (("down", ["L1", "R1"]), ("up", ["L2", "L3"])):
        for level in ("type", "line"):
            r = t[(t.level == level) & (t.direction == d)]
            assert len(r) == 1
            r = r.iloc[0]
            assert r.train_type == ("T" if level == "type" else "all")
            assert r.n_trains == len(tids)
            assert r.n_legs == sum(exp[x][0] for x in tids)
            assert r.scheduled_running_time_s == sum(exp[x][3] for x in tids)
            assert r.min_running_time_s == pytest.approx(sum(exp[x][1] for x in tids), abs=4 * TOL_S)
            assert r.n_infeasible == sum(exp[x][5] for x in tids)
            assert r.margin_percent == pytest.approx(100 * r.margin_s / r.min_running_time_s)


def test_timetable_edited_to_be_infeasible():
    # L1's second leg: 95 s -> 88 s, above the nominal minimum (81.8 s) but below the bad-day one (91.7 s)
    l1 = TRAINS[0]
    calls = list(l1.calls)
    calls[2] = dataclasses.replace(calls[2], arrival_s=130.0 + 88.0)
    edited = (dataclasses.replace(l1, calls=tuple(calls)),) + TRAINS[1:]
    rep = compute_margins(closed_form_line(edited), train_types=["T"], adhesion_kmh_s="3.0:3.5:0.5",
                          approach_m=APPROACH, conflicts=False, ratios=SMALL_GRID)
    r = row(rep, "down", "S1", "S2")
    assert r.scheduled_running_time_s == 88.0
    assert r.margin_s > 0  # the nominal run makes it ...
    assert bool(r.infeasible) and not bool(r.tight)  # ... a bad day does not
    assert r.remaining_margin_s == pytest.approx(88.0 - t_degraded(1500), abs=TOL_S)
    tot = rep.totals.set_index(["level", "train_id"])
    assert tot.loc[("train", "L1")].n_infeasible == 1 and tot.loc[("train", "L1")].n_tight == 0
    # the other rows are unchanged
    assert not bool(row(rep, "down", "S0", "S1").infeasible)


def test_pattern_start_moves_back_when_the_lowest_adhesion_needs_more_room():
    # 2.5 km/h/s from 100 km/h needs D_b = V (V/A + A/J)/2 = 565.2 m: more than the 550 m approach,
    # so the pattern starts at the first 25 m step back that suffices, 575 m before the marker
    adh = 2.5 / 3.6
    rep = compute_margins(closed_form_line(TRAINS[:1]), adhesion_kmh_s="2.5:3.5:0.5", approach_m=550.0,
                          conflicts=False, ratios=SMALL_GRID)
    r = row(rep, "down", "S0", "S1")
    tb = V / adh + adh / J
    assert V * tb / 2 > 550.0
    assert r.pattern_start_source == "approach+moved"
    assert "575 m" in r.note
    assert r.pattern_start_m == pytest.approx(1500.0 - 575.0)
    assert r.degraded_min_running_time_s == pytest.approx(t_degraded(1500, adh), abs=TOL_S)


def test_sweep_matches_the_stopping_pattern_step():
    from planner.stopping.sweep import approach_patterns

    line = closed_form_line(TRAINS[:1])
    rep = compute_margins(line, adhesion_kmh_s="3.0:3.5:0.1", approach_m=APPROACH, conflicts=False,
                          ratios=SMALL_GRID)
    sw = rep.sweep[(rep.sweep.direction == "down") & (rep.sweep.origin == "S0")].sort_values("adhesion_kmh_s")
    ap = approach_patterns(line, "T", "S0", "S1", [a / 3.6 for a in sw.adhesion_kmh_s], APPROACH)
    np.testing.assert_allclose(sw.stop_time_s, [p.duration_s for p in ap.patterns], atol=1e-6)
    # growth of the stopping time from the best to the worst adhesion, in closed form
    r = row(rep, "down", "S0", "S1")
    tb = [V / a + a / J for a in (3.0 / 3.6, 3.5 / 3.6)]
    exp = [(APPROACH - V * x / 2) / V + x for x in tb]
    assert r.adhesion_loss_s == pytest.approx(exp[0] - exp[1], abs=1e-6)


# --- the pure part ---------------------------------------------------------------------

@pytest.mark.parametrize("t,exp", [(0.0, 0.0), (0.5, 10.0), (130.0, 130.0), (130.0 + 1e-9, 130.0),
                                   (130.01, 140.0), (135.78, 140.0), (139.999, 140.0)])
def test_round_up(t, exp):
    assert round_up_s(t) == exp


@given(st.floats(0.0, 1e5))
def test_round_up_properties(t):
    r = round_up_s(t)
    assert r % 10 == 0
    assert t - 1e-6 <= r < t + 10


def test_margin_columns_no_schedule_and_boundaries():
    rule = MarginRule(tight_threshold_s=5.0)
    c = margin_columns([100.0, 100.0, 100.0, 100.0], [np.nan, 110.0, 115.0, 110.0],
                       [108.0, 110.0, 110.0, 120.0], [200.0, 200.0, 112.0, 200.0], [1000.0] * 4, rule)
    assert not c["infeasible"][0] and not c["tight"][0] and not c["supplement_met"][0]
    assert np.isnan(c["margin_s"][0]) and np.isnan(c["supplement_shortfall_s"][0])
    # scheduled exactly the degraded minimum: not infeasible, but nothing left -> tight
    assert not c["infeasible"][1] and c["tight"][1]
    # 5 s left is not below the 5 s threshold; 115 > slowest 112 -> unreachable
    assert not c["tight"][2] and c["unreachable"][2]
    assert c["infeasible"][3] and not c["tight"][3]
    # 3 % of 100 s + 1 min/100 km over 1 km = 3.6 s
    np.testing.assert_allclose(c["supplement_required_s"], 3.6)
    assert c["supplement_met"][1] and c["supplement_shortfall_s"][1] == 0.0


@given(tmin=st.floats(30, 1000), extra=st.floats(-50, 100), loss=st.floats(0, 60), thr=st.floats(0, 20))
def test_flag_properties(tmin, extra, loss, thr):
    sched, deg = tmin + extra, tmin + loss
    c = margin_columns([tmin], [sched], [deg], [tmin * 3], [2000.0], MarginRule(tight_threshold_s=thr))
    rem = sched - deg
    assert c["remaining_margin_s"][0] == pytest.approx(rem)
    assert not (c["infeasible"][0] and c["tight"][0])
    if rem < -1e-5:
        assert c["infeasible"][0]
    if rem > 1e-5:
        assert not c["infeasible"][0]
    if 1e-5 < rem < thr - 1e-5:
        assert c["tight"][0]
    if rem > thr + 1e-5:
        assert not c["tight"][0]


def test_rule_checks_and_job_section():
    from planner.job.config import MarginsSection

    r = MarginRule.from_section(MarginsSection(supplement_percent=5.0, tight_threshold_s=8.0))
    assert (r.supplement_percent, r.tight_threshold_s, r.degraded_traction) == (5.0, 8.0, 0.9)
    with pytest.raises(InputError, match="degraded_traction"):
        MarginRule(degraded_traction=0.0)
    with pytest.raises(InputError, match="supplement_percent"):
        MarginRule(supplement_percent=-1.0)


def test_timetable_leg_without_arrival_is_an_input_error():
    bad = _train("X", "down", [("S0", NAN, 0.0, True), ("S2", NAN, NAN, True)])
    with pytest.raises(InputError, match="train X .*S0->S2"):
        timetable_legs(closed_form_line((bad,)))


def test_timetable_legs_are_made_once_per_line_object_and_cannot_be_changed_by_a_caller():
    # the nightly job asks for the same line's legs in several steps: they are kept per line object (shared by every
    # caller, so a tuple), and an edited line (another object) gets its own
    line = closed_form_line()
    first = timetable_legs(line)
    assert [lg.train_id for lg in first] == [t.train_id for t in TRAINS for _ in range(len(t.stop_calls()) - 1)]
    assert isinstance(first, tuple) and timetable_legs(line) is first
    assert timetable_legs(closed_form_line()) == first and timetable_legs(closed_form_line()) is not first
    fewer = dataclasses.replace(line, trains=TRAINS[:1])
    assert {lg.train_id for lg in timetable_legs(fewer)} == {TRAINS[0].train_id}
    assert len(timetable_legs(line)) == len(first) > len(timetable_legs(fewer))


# --- datasets ---------------------------------------------------------------------------

def test_datasets_schema_partitions_and_determinism(report, tmp_path):
    files = write_margins(report, tmp_path / "a")
    write_margins(report, tmp_path / "b")
    rel = sorted(str(f.relative_to(tmp_path / "a")) for f in files)
    assert "margins/line=test/direction=down/train_type=T/part-0.parquet" in rel
    assert "margin_totals/line=test/direction=up/train_type=all/part-0.parquet" in rel
    for f in rel:
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
    sch = pq.read_schema(tmp_path / "a" / "margins/line=test/direction=down/train_type=T/part-0.parquet")
    assert sch.names == MARGINS_SCHEMA.names
    for f in sch:
        assert f.metadata and f.metadata[b"description"]
    got = read_dataset(tmp_path / "a", "margins").to_pandas()
    assert len(got) == len(report.rows)
    got = got.sort_values(["direction", "origin", "destination"]).reset_index(drop=True)
    exp = report.rows.sort_values(["direction", "origin", "destination"]).reset_index(drop=True)
    np.testing.assert_allclose(got.remaining_margin_s, exp.remaining_margin_s)
    tot = read_dataset(tmp_path / "a", "margin_totals").to_pandas()
    assert set(tot.columns) >= set(MARGIN_TOTALS_SCHEMA.names)
    assert sorted(tot.level.unique()) == ["line", "train", "type"]
    # the clock column says the same time as the seconds after midnight, as HH:MM:SS
    for t_s, text in zip(tot.first_departure_s, tot.first_departure_clock):
        h, m, sec = (int(x) for x in text.split(":"))
        assert len(text) == 8 and h * 3600 + m * 60 + sec == round(t_s), (t_s, text)


def test_totals_per_train_same_bits_as_each_train_alone():
    """The trains' totals, computed a leg count at a time, are each train's own numpy sums over its legs in leg
    order, bit for bit (what a train's total was when it was summed alone): trains of 1 to 40 legs (past
    numpy's 8-wide pairwise blocks), values over nine decades, NaN (unassessed) and -0.0 among them."""
    import pandas as pd

    from planner.report.margin_rule import COUNTED, TOTAL_SUM_COLS, UNKNOWN_WHEN_UNASSESSED, margin_totals

    rng = np.random.default_rng(7)
    legs, rows = [], []
    for i in range(300):
        n = int(rng.integers(1, 41))
        for s in range(n):
            legs.append({"train_id": f"T{i:03d}", "direction": "down" if i % 3 else "up", "train_type": "E",
                         "origin": f"S{s}", "destination": f"S{s + 1}", "scheduled_running_time_s": float(len(rows)),
                         "departure_s": float(rng.uniform(0, 86400)), "leg_seq": s})
            x = rng.standard_normal(len(TOTAL_SUM_COLS)) * 10.0 ** rng.uniform(-3, 6, len(TOTAL_SUM_COLS))
            r = dict(zip(TOTAL_SUM_COLS, x))
            r["min_running_time_s"] = abs(r["min_running_time_s"]) + 1.0
            if rng.random() < 0.03:
                r["degraded_min_running_time_s"] = r["remaining_margin_s"] = np.nan
            if rng.random() < 0.03:
                r["energy_saved_kwh"] = -0.0
            rows.append({**r, **{k: legs[-1][k] for k in ("direction", "train_type", "origin", "destination",
                                                       "scheduled_running_time_s")},
                         "supplement_met": bool(rng.random() < 0.5), **{f: bool(rng.random() < 0.2) for f in COUNTED}})
    legs, rows = pd.DataFrame(legs), pd.DataFrame(rows)
    got = margin_totals(rows, legs).query("level == 'train'").set_index("train_id")
    assert len(got) == 300
    merged = legs.merge(rows, on=["direction", "train_type", "origin", "destination", "scheduled_running_time_s"])
    for tid, g in merged.sort_values(["train_id", "leg_seq"]).groupby("train_id"):
        r = got.loc[tid]
        for c in TOTAL_SUM_COLS:
            x = g[c].to_numpy(float)
            want = x.sum() if c in UNKNOWN_WHEN_UNASSESSED else np.where(np.isnan(x), 0.0, x).sum()
            assert np.float64(r[c]).tobytes() == np.float64(want).tobytes(), (tid, c)
        rm = g["remaining_margin_s"].to_numpy(float)
        assert np.float64(r.min_remaining_margin_s).tobytes() == np.float64(rm.min()).tobytes()
        assert np.float64(r.bad_day_shortfall_s).tobytes() == np.maximum(-rm, 0.0).sum().tobytes()
        assert r.first_departure_s == g["departure_s"].min() and r.n_legs == len(g)
        assert (r.origin, r.destination) == (g["origin"].iloc[0], g["destination"].iloc[-1])
        assert r.n_supplement_short == int((~g["supplement_met"]).sum())
        assert [r[f"n_{f}"] for f in COUNTED] == [int(g[f].sum()) for f in COUNTED]
