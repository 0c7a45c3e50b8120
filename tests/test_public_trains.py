"""Five train types from public parameters (tests/public_trains.py) on a long, steep, beacon-less line of ours.

What the braking defaults of a commuter EMU used to decide, the train's own physics decides now: every
stopping pattern is feasible from the start the physics gives, the bad day is never faster than nominal,
and a timetable at the minimum + 8 % is flagged only where the bad day's load and traction cost more
than 8 % on the climbs (a physical verdict), never because of a stop.

The matrix below (issue 33) puts seven train types (tests/public_trains.py) on two lines, the sample
line and a 62 km line with 15 ‰ grades, through the margin report's leg functions: at the minimum
+ 8 % no leg is impossible and a leg is short on a bad day only because of its load or weak traction;
at the minimum every leg is short on a bad day by what the bad day costs, and says why; 1 % below it
every leg is impossible. ``PYTHONPATH=. python tests/public_trains.py`` prints the matrix as a table.
"""
from __future__ import annotations

import re

import pytest

from public_trains import public_trains, steep_line
from planner.line.units import KMH_S
from planner.report.leg_margin import leg_result
from planner.stopping.sweep import adhesion_levels, approach_patterns

LEVELS_MS2 = [a * KMH_S for a in adhesion_levels("2.5:3.5:0.1")]
LEGS = [("S0", "S1"), ("S1", "S2"), ("S2", "S1"), ("S1", "S0")]
NO_LOAD_CHANGE = {"OSRD_FAST", "OSRD_FAST_095", "TR_IC"}  # no passenger load: the bad day is traction × 0.9 only


@pytest.fixture(scope="module")
def line():
    return steep_line()


@pytest.mark.parametrize("tt", [t.train_type for t in public_trains()])
def test_every_stop_is_feasible_and_the_bad_day_never_faster(line, tt):
    for o, d in LEGS:
        ap = approach_patterns(line, tt, o, d, LEVELS_MS2)
        assert ap.tasc_beacon_id == "" and ap.n_feasible == len(ap.patterns), (o, d, ap.warnings)
        r = leg_result(line, tt, o, d, [])
        assert r.pattern_source == "physics" and r.note == "", (o, d, r.note)  # the start was never moved back
        assert r.pattern_start_m == pytest.approx(ap.approach_start_m)
        assert r.degraded_min_s >= r.min_time_s, (o, d)
        assert r.degraded_loss_stop_s >= 0.0 and r.degraded_loss_stop_model_s >= 0.0, (o, d)
        # min + 8 %: a stop never eats the 8 %; trains without a load change keep it on every leg
        assert r.degraded_loss_stop_s + r.degraded_loss_stop_model_s < 0.08 * r.min_time_s, (o, d)
        if tt in NO_LOAD_CHANGE:
            assert 1.08 * r.min_time_s >= r.degraded_min_s, (o, d)


# --- the matrix: seven public train types on the sample line and a 62 km line with 15 ‰ grades ----------------

from public_trains import matrix  # noqa: E402

TOL_S = 0.05
"""The integrator's accuracy on a run (1 m steps): two computations of one run agree to this [s]."""
TASC_TOO_CLOSE = {"OSRD_FAST", "TR_DMU", "TR_IC"}
"""Train types whose minimum-time run is already braking at its stopping brake (0.43-0.5 m/s² from
100 km/h: 770-910 m) when it passes the sample line's TASC beacons, 650 m before the stop: no
jerk-limited pattern at most that brake stops from there (662.7 m needed at TKD->OHS), so their
approach starts where the physics says (a note names the beacon), in the sweep as in the margin report."""
COST_RE = re.compile(r"the bad day costs (-?[\d.]+) s \(load (-?[\d.]+), traction (-?[\d.]+), "
                     r"adhesion (-?[\d.]+), stop model (-?[\d.]+) s\)")


@pytest.fixture(scope="module")
def records():
    return matrix()


def _types(records, line=None):
    return sorted({x["train_type"] for x in records if line in (None, x["line"])})


def test_the_matrix_is_seven_types_on_two_lines(records):
    assert {x["line"] for x in records} == {"sample", "long_steep"}
    assert len(_types(records, "sample")) == len(_types(records, "long_steep")) == 7


def test_the_minimum_is_the_independent_run_at_ratio_one(records):
    for x in records:  # table (a) at ratio 1 against planner.api.running_time: two paths, one run
        assert x["result"].min_time_s == pytest.approx(x["api_min_s"], abs=TOL_S), x["train_type"]


def test_the_bad_day_is_never_faster_than_nominal(records):
    for x in records:
        r = x["result"]
        key = (x["line"], x["train_type"], x["origin"], x["destination"])
        assert r.degraded_min_s >= r.min_time_s - TOL_S, key
        for share in (r.degraded_loss_load_s, r.degraded_loss_traction_s, r.degraded_loss_stop_s):
            assert not share < -TOL_S, key  # NaN (the stop part unknown) is no speed-up either


@pytest.mark.parametrize("line,tt", [pytest.param(ln, tt)
                                     for ln in ("sample", "long_steep") for tt in
                                     ("OSRD_FAST", "OSRD_FAST_095", "TR_DMU", "TR_IC", "TR_FREIGHT", "OSRD_SLOW",
                                      "OSRD_SHORT")])
def test_every_stopping_pattern_is_feasible(records, line, tt):
    for x in records:
        if (x["line"], x["train_type"]) == (line, tt):
            ap = x["patterns"]
            assert ap.n_feasible == len(ap.patterns), (x["origin"], x["destination"], ap.warnings)
    if line == "sample" and tt in TASC_TOO_CLOSE:  # their starts moved back from the beacons, and said so
        assert any("too close for this train" in w for x in records if (x["line"], x["train_type"]) == (line, tt)
                   for w in x["patterns"].warnings)


def test_min_plus_8_percent_is_never_impossible_and_never_short_because_of_a_stop(records):
    for x in records:
        row, r = x["plus8"], x["result"]
        key = (x["line"], x["train_type"], x["origin"], x["destination"])
        assert not row.impossible and not row.unassessed, key
        assert bool(row.short_bad_day) == (r.degraded_min_s > 1.08 * x["api_min_s"]), key
        if row.short_bad_day:  # the load or the weak traction on a climb costs more than the 8 %: a physical verdict
            assert row.bad_day_cause in ("load", "traction"), (key, row.flag_reason)


def test_at_the_minimum_the_flags_say_how_short_and_why(records):
    for x in records:
        row, r = x["plus0"], x["result"]
        key = (x["line"], x["train_type"], x["origin"], x["destination"])
        assert not row.impossible, key
        cost = r.degraded_min_s - r.min_time_s
        assert bool(row.short_bad_day) == (cost > 1e-6), key
        assert row.flag_reason.startswith(f"short on a bad day by {cost:.1f} s: margin "), (key, row.flag_reason)
        m = COST_RE.search(row.flag_reason)
        if m is None:  # a share unknown (no nominal pattern from the beacon): the total alone, no parts
            assert f"the bad day costs {cost:.1f} s," in row.flag_reason, (key, row.flag_reason)
            continue
        total, *parts = (float(v) for v in m.groups())
        assert total == pytest.approx(cost, abs=0.05) and sum(parts) == pytest.approx(total, abs=1e-9), key
    by = {(x["line"], x["train_type"], x["origin"], x["destination"]): x["plus0"].bad_day_cause for x in records}
    # no payload, no load share: those types never blame the load
    assert not [k for k, c in by.items() if c == "load" and k[1] != "TR_DMU"]
    # a 920 t freight crawling up 15 ‰ at 9 km/h, 5 km/h with traction x 0.9: the traction
    assert by[("long_steep", "TR_FREIGHT", "S0", "S1")] == "traction"
    # the DMU, 68 t + 20 t of passengers, the one type with a payload: the load costs time on every leg
    assert all(x["result"].degraded_loss_load_s > 0.5 for x in records if x["train_type"] == "TR_DMU")
    assert "load" in {c for k, c in by.items() if k[1] == "TR_DMU"}
    # at 36 km/h a 900 t train never runs out of effort: its bad day is the stop model alone
    assert {c for k, c in by.items() if k[1] in ("OSRD_SLOW", "OSRD_SHORT")} == {"stop_model"}


def test_below_the_minimum_is_impossible_and_says_by_how_much(records):
    for x in records:
        row = x["minus1"]
        assert row.impossible and not row.short_bad_day and row.infeasible, x["train_type"]
        below = x["result"].min_time_s - 0.99 * x["api_min_s"]
        assert row.flag_reason.startswith(f"impossible: scheduled {0.99 * x['api_min_s']:.1f} s, {below:.1f} s "
                                          "below the minimum running time"), row.flag_reason
