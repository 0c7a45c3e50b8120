"""Stopping patterns for every station approach: set-up from the line, the adhesion sweep, datasets, CLI.

The small in-memory lines use the default test train of ``planner.line.testing``:
300 kN constant effort on 300 t, no resistance, no rotating mass, so it
accelerates at exactly 1 m/s² (the 100 km/h/s cap never binds) and the run's
speed at running distance s is ``sqrt(2 s)`` until the 100 km/h line maximum;
comfort deceleration 3.6 km/h/s = 1 m/s², jerk 3.6 km/h/s² = 1 m/s³, length
100 m, no speed margin.
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pyarrow.dataset as pads
import pytest
from typer.testing import CliRunner

from planner.line import testing
from planner.errors import InputError, UnknownNameError
from planner.line.model import Beacon
from planner.stopping.sweep import (
    DEFAULT_ADHESION_KMH_S,
    InfeasibleStopWarning,
    adhesion_levels,
    approach_patterns,
    stop_sweep,
)
from planner.datasets.stops import STOP_SAMPLES_SCHEMA, STOP_SUMMARY_SCHEMA, datasets, write_stops
from planner.line.units import KMH, KMH_S

from linedb import write_line_db

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "lines" / "sample"

# Tolerances. The run's speed is exact for constant acceleration (Heun in v² is exact for a
# linear w(s)), so only round-off remains; patterns are exact cubics, so the dense-sample limit
# checks allow round-off only (as in tests/test_stopping_props.py).
V_RUN_TOL = 1e-9  # m/s
TOL_V = 1e-7  # m/s
TOL_A = 1e-7  # m/s²
TOL_J = 1e-12  # m/s³
END_X = 1e-3  # m: the "within 1 mm"
LEVELS_MS2 = [a * KMH_S for a in DEFAULT_ADHESION_KMH_S]


def line_a(**kw):
    """Stations at 0, 900, 2900 m; the S1 down approach (550 m) starts at s = 350 m, still accelerating."""
    return testing.line(length_m=3000.0, stations=[0.0, 900.0, 2900.0], **kw)


def line_b():
    """As line_a with a 60 km/h restriction 700-760 m and gradients inside the S1 approaches."""
    return line_a(limits=[(700.0, 760.0, 60.0)], gradients=[(600.0, 750.0, -15.0), (800.0, 1200.0, 5.0)])


def step_value(steps, x):
    xs = np.array([s[0] for s in steps])
    vals = np.array([s[1] for s in steps])
    return vals[np.searchsorted(xs, x, side="right") - 1]


def assert_meets_limits(r, k):
    """Pattern k of approach r against the limits it was solved for, on dense samples."""
    p, dl, sl, J = r.patterns[k], r.decel_limits[k], r.speed_limits, r.jerk_max_ms3
    s = p.sample(min(0.02, p.duration_s / 4000.0))
    x, v, a, j = s.x_m, s.v_ms, s.a_ms2, s.j_ms3
    assert np.all(v <= step_value(sl, x) + TOL_V), f"{r.station_id} {r.direction}: speed over the limit"
    assert np.all(-a <= step_value(dl, x) + TOL_A), f"{r.station_id} {r.direction}: deceleration over the limit"
    assert np.all(np.abs(j) <= J + TOL_J)
    assert np.all(a <= TOL_A), "re-acceleration"
    assert np.all(np.diff(x) >= -1e-9)
    assert abs(x[-1] - r.approach_length_m) <= END_X and abs(v[-1]) <= 1e-9 and abs(a[-1]) <= 1e-9
    assert v[0] == pytest.approx(r.v_start_ms) and a[0] == 0.0


# --------------------------------------------------------------------------------------
# the adhesion sweep specification
# --------------------------------------------------------------------------------------


def test_adhesion_levels():
    assert DEFAULT_ADHESION_KMH_S == (2.5, 2.6, 2.7, 2.8, 2.9, 3.0, 3.1, 3.2, 3.3, 3.4, 3.5)
    assert adhesion_levels("2.5:3.5:0.5") == (2.5, 3.0, 3.5)
    assert adhesion_levels("3.0, 2.5") == (2.5, 3.0)
    assert adhesion_levels([3.0]) == (3.0,)
    assert adhesion_levels("2.5:2.5:0.1") == (2.5,)


@pytest.mark.parametrize("spec", ["3.5:2.5:0.1", "2.5:3.5:0", "2.5:3.5", "a:b:c", "", "-1", "0.0,2.5",
                                  "1:1000:0.5"])
def test_bad_adhesion_spec_names_the_flag(spec):
    with pytest.raises(InputError, match="--adhesion"):
        adhesion_levels(spec)


# --------------------------------------------------------------------------------------
# one approach, set up from the line
# --------------------------------------------------------------------------------------


def test_fixed_approach_start_and_speed_of_the_minimum_time_run():
    r = approach_patterns(line_a(), "T", "S0", "S1", LEVELS_MS2, approach_m=550.0)
    assert (r.station_id, r.origin, r.direction, r.tasc_beacon_id) == ("S1", "S0", "down", "")
    assert r.approach_start_m == 350.0 and r.stop_m == 900.0 and r.approach_length_m == 550.0
    # 1 m/s² from standstill over 350 m: v² = 2 a s
    assert r.v_start_ms == pytest.approx(math.sqrt(700.0), abs=V_RUN_TOL)
    assert r.run_phase == "power"
    assert r.speed_limits == ((0.0, 100.0 * KMH),)
    assert r.gradients_permil == ((0.0, 0.0),)
    assert r.adhesion_ms2 == pytest.approx([a * KMH_S for a in DEFAULT_ADHESION_KMH_S], abs=1e-12)
    assert all(p.feasible for p in r.patterns) and r.warnings == ()


def test_approach_starts_at_the_last_tasc_beacon_before_the_marker():
    beacons = (
        Beacon("T1", 300.0, "down", "tasc", "TASC:S1:0600", False),
        Beacon("T2", 380.0, "down", "tasc", "TASC:S1:0520", False),   # the last one before the marker
        Beacon("SG", 500.0, "down", "signal", "SIG", True),            # not a TASC beacon
        Beacon("TU", 600.0, "up", "tasc", "TASC:S0:0600", False),      # read by up trains only
        Beacon("T3", 950.0, "down", "tasc", "TASC:S2:1950", False),    # past the marker: next interstation
    )
    line = dataclasses.replace(line_a(), beacons=beacons)
    fit = LEVELS_MS2[2:]  # from T2 (520 m) the two lowest levels cannot stop: 556.8 m needed at 2.5 km/h/s
    r = approach_patterns(line, "T", "S0", "S1", fit, approach_m=123.0)
    assert r.tasc_beacon_id == "T2"
    assert r.approach_start_m == 380.0 and r.approach_length_m == 520.0
    assert r.v_start_ms == pytest.approx(math.sqrt(760.0), abs=V_RUN_TOL)  # still below 100 km/h


def test_a_tasc_beacon_too_close_for_the_train_moves_its_approach_back_and_says_so():
    """The same beacon with every level of the sweep: from 520 m no stop fits at 2.5 km/h/s (556.8 m needed),
    so the approach starts earlier (where the physics says, or 10 % beyond what the solver needed), every
    level is feasible, and a note names the beacon: the sweep agrees with the margin report."""
    line = dataclasses.replace(line_a(), beacons=(Beacon("T2", 380.0, "down", "tasc", "TASC:S1:0520", False),))
    r = approach_patterns(line, "T", "S0", "S1", LEVELS_MS2, approach_m=123.0)
    assert r.tasc_beacon_id == "" and r.approach_length_m > 1.09 * 556.8  # what was needed, plus the margin
    assert r.n_feasible == len(r.patterns) == len(LEVELS_MS2)
    assert [w for w in r.warnings if "TASC beacon T2 lies 520 m before the marker, too close" in w]


def test_speed_limits_and_gradients_over_the_approach_both_directions():
    line = line_b()
    down = approach_patterns(line, "T", "S0", "S1", LEVELS_MS2, approach_m=550.0)
    # the 60 km/h restriction holds the front from 700 m until the tail clears 760 m (front at 860 m):
    # 350 and 510 m from the approach start at 350 m
    assert down.speed_limits == ((0.0, 100 * KMH), (350.0, 60 * KMH), (510.0, 100 * KMH))
    # gradient averaged over the 100 m train (by hand: the share of the body on each slope), kinks
    # where the front or the tail passes a gradient change: front at 600 (x = 250: 0 ‰), tail at 600
    # (x = 350: -15), front at 750 (x = 400: -15), front at 800 (x = 450: half on -15 = -7.5), tail
    # at 750 (x = 500: half on +5 = +2.5), marker (x = 550: +5). Each linear piece at its smaller end
    # value: 0 | -15 over 250-450 | -7.5 | +2.5
    from planner.stopping.approach import gradient_steps

    assert gradient_steps(line, 100.0, "down", 350.0, 550.0, slice_m=math.inf) == [
        (0.0, 0.0), (250.0, -15.0), (450.0, -7.5), (500.0, 2.5)]
    # the sweep slices the sloping pieces to 25 m (each slice at its smaller end value)
    assert down.gradients_permil == ((0.0, 0.0), (250.0, -3.75), (275.0, -7.5), (300.0, -11.25), (325.0, -15.0),
                                     (425.0, -11.25), (450.0, -7.5), (475.0, -2.5), (500.0, 2.5), (525.0, 3.75))
    # up from S2 (2900) to S1 (900): start at 1450 m chainage, running towards lower chainage; the
    # +5 ‰ (rising towards higher chainage) is a fall of 5 ‰ for up trains from chainage 1200 on:
    # ḡ falls from 0 (front at 1200, x = 250) to -5 ‰ (tail at 1200, x = 350) and stays there;
    # the restriction lies beyond the marker for up trains
    up = approach_patterns(line, "T", "S2", "S1", LEVELS_MS2, approach_m=550.0)
    assert up.direction == "up" and up.approach_start_m == 1450.0 and up.stop_m == 900.0
    assert up.speed_limits == ((0.0, 100 * KMH),)
    assert up.gradients_permil == ((0.0, 0.0), (250.0, -1.25), (275.0, -2.5), (300.0, -3.75), (325.0, -5.0))
    assert up.v_start_ms == pytest.approx(100 * KMH, abs=V_RUN_TOL)  # holding the line maximum
    assert up.run_phase == "hold"
    # the deceleration limit follows min(comfort, adhesion) + g s / 1000 / (1 + ρ), ρ = 0 here
    for a_ms2, dl in zip(LEVELS_MS2, up.decel_limits):
        assert [x for x, _ in dl] == [0.0, 250.0, 275.0, 300.0, 325.0]
        assert dl[0][1] == pytest.approx(min(1.0, a_ms2))
        assert dl[-1][1] == pytest.approx(min(1.0, a_ms2) - G_STD * 0.005)
    assert down.n_feasible >= len(LEVELS_MS2) - 1  # the -15 ‰ under the whole train: 2.5 needs 559.5 m
    assert 0 < up.n_feasible < len(LEVELS_MS2)  # 100 km/h onto a fall: the lowest levels need > 550 m
    for r in (down, up):
        for k, p in enumerate(r.patterns):
            if p.feasible:
                assert_meets_limits(r, k)


def test_lower_adhesion_brakes_earlier_and_takes_longer():
    for origin in ("S0", "S2"):
        r = approach_patterns(line_b(), "T", origin, "S1", LEVELS_MS2)
        feas = [p.feasible for p in r.patterns]
        assert feas == sorted(feas) and feas[-1]  # infeasible only at the lowest levels
        pats = [p for p in r.patterns if p.feasible]
        dur = np.array([p.duration_s for p in pats])  # adhesion ascending
        brake_x = np.array([p.brake_start_m for p in pats])  # from the approach start
        assert np.all(np.diff(dur) < 0.0), "more adhesion must be strictly faster"
        assert np.all(np.diff(brake_x) > 0.0), "more adhesion must brake strictly later"
        lost = np.array([t for t, p in zip(r.time_lost_s, r.patterns) if p.feasible])
        assert lost[-1] == 0.0 and np.all(lost[:-1] > 0.0)
        assert lost == pytest.approx(dur - dur[-1], abs=1e-12)


def test_too_short_approach_is_an_infeasible_row_with_a_warning():
    # 40 m before the marker the minimum-time run is on its stopping-brake curve (1 m/s²):
    # v = sqrt(2 * 40) m/s. Even at 3.5 km/h/s the jerk-limited stop from a = 0 needs
    # v (v/A + A/J)/2 = 45.5 m (closed form, trapezoidal deceleration), so no level fits.
    r = approach_patterns(line_a(), "T", "S0", "S1", LEVELS_MS2, approach_m=40.0)
    v = math.sqrt(80.0)
    assert r.v_start_ms == pytest.approx(v, abs=1e-6) and r.run_phase == "stop"
    A = 3.5 * KMH_S
    assert v * (v / A + A / 1.0) / 2.0 > 40.0
    assert r.n_feasible == 0 and math.isnan(r.best_duration_s)
    assert len(r.warnings) == len(LEVELS_MS2)
    for a, p, msg in zip(r.adhesion_ms2, r.patterns, r.warnings):
        a = round(a / KMH_S, 9)  # the messages speak km/h/s, as the job file
        assert not p.feasible and "needs" in p.reason and "only 40.0 m" in p.reason
        for part in ("S1", "down", "train type T", f"adhesion {a:g} km/h/s", p.reason):
            assert part in msg
    t = datasets([r])["stop_summary"].to_pylist()
    assert [row["feasible"] for row in t] == [False] * len(LEVELS_MS2)
    assert all(row["reason"] and row["duration_s"] is None and row["brake_start_m"] is None for row in t)
    assert all(row["brake_start_distance_m"] > 40.0 for row in t)  # what the limits would need
    assert datasets([r])["stop_samples"].num_rows == 0
    # the line-level sweep issues the warnings (named station, direction, type, adhesion)
    with pytest.warns(InfeasibleStopWarning) as rec:
        stop_sweep(line_a(), adhesion_kmh_s="2.5", approach_m=40.0, directions=["down"], n_jobs=1)
    assert [str(w.message).split(":")[0] for w in rec] == [
        "no stopping pattern at S1 (down, train type T, from S0) at adhesion 2.5 km/h/s",
        "no stopping pattern at S2 (down, train type T, from S1) at adhesion 2.5 km/h/s"]


def test_approach_longer_than_the_interstation():
    r = approach_patterns(line_a(), "T", "S0", "S1", LEVELS_MS2[:2], approach_m=1000.0)
    assert r.n_feasible == 0
    assert "not shorter than the interstation (900.0 m)" in r.patterns[0].reason
    assert len(r.warnings) == 2


def test_bad_inputs():
    with pytest.raises(InputError, match="approach_m"):
        approach_patterns(line_a(), "T", "S0", "S1", LEVELS_MS2, approach_m=-5.0)
    with pytest.raises(InputError, match="adhesion"):
        approach_patterns(line_a(), "T", "S0", "S1", [0.0])
    with pytest.raises(UnknownNameError, match="known"):
        stop_sweep(line_a(), train_types=["X"], n_jobs=1)
    with pytest.raises(UnknownNameError, match="direction"):
        stop_sweep(line_a(), directions=["sideways"], n_jobs=1)


# --------------------------------------------------------------------------------------
# the line-level sweep and its datasets
# --------------------------------------------------------------------------------------


@pytest.mark.filterwarnings("ignore::planner.stopping.sweep.InfeasibleStopWarning")
def test_sweep_order_is_deterministic_and_independent_of_n_jobs():
    line = line_b()
    one = stop_sweep(line, adhesion_kmh_s="2.5:3.5:0.5", n_jobs=1)
    two = stop_sweep(line, adhesion_kmh_s="2.5:3.5:0.5", n_jobs=2)
    keys = [(r.train_type, r.direction, r.origin, r.station_id) for r in one]
    assert keys == [("T", "down", "S0", "S1"), ("T", "down", "S1", "S2"), ("T", "up", "S2", "S1"),
                    ("T", "up", "S1", "S0")]
    assert keys == [(r.train_type, r.direction, r.origin, r.station_id) for r in two]
    np.testing.assert_array_equal([p.duration_s for r in one for p in r.patterns],
                                  [p.duration_s for r in two for p in r.patterns])  # NaN where infeasible


@pytest.mark.filterwarnings("ignore::planner.stopping.sweep.InfeasibleStopWarning")
def test_datasets_read_back_with_hive_partitioning(tmp_path):
    results = stop_sweep(line_b(), adhesion_kmh_s="2.75:3.25:0.25", approach_m=550.0, n_jobs=1)
    files = write_stops(results, tmp_path)
    rel = sorted(f.relative_to(tmp_path).as_posix() for f in files)
    assert rel == [f"{d}/line=test/direction={di}/train_type=T/part-0.parquet"
                   for d in ("stop_samples", "stop_summary") for di in ("down", "up")]
    summ = pads.dataset(tmp_path / "stop_summary", format="parquet", partitioning="hive").to_table()
    assert summ.num_rows == 4 * 3
    assert set(STOP_SUMMARY_SCHEMA.names) <= set(summ.column_names)
    assert set(summ.column("direction").to_pylist()) == {"down", "up"}
    f = pads.dataset(next(p for p in files if "stop_summary" in p.parts), format="parquet").schema
    assert f.field("duration_s").metadata[b"description"]
    rows = [r for r in summ.to_pylist() if r["station_id"] == "S1" and r["direction"] == "down"]
    assert [r["adhesion_ms2"] for r in rows] == pytest.approx([2.75 * KMH_S, 3.0 * KMH_S, 3.25 * KMH_S], abs=1e-12)
    ref = next(r for r in results if r.station_id == "S1" and r.direction == "down")
    for row, p, lost in zip(rows, ref.patterns, ref.time_lost_s):
        assert row["feasible"] and row["reason"] == ""
        assert row["duration_s"] == p.duration_s and row["time_lost_s"] == lost
        assert row["v_start_kmh"] == pytest.approx(math.sqrt(700.0) * 3.6, abs=1e-6)
        # chainage of the brake start, and its distance before the marker
        assert row["brake_start_m"] == pytest.approx(350.0 + p.brake_start_m)
        assert row["brake_start_m"] + row["brake_start_distance_m"] == pytest.approx(900.0)
    samp = pads.dataset(tmp_path / "stop_samples", format="parquet", partitioning="hive").to_table()
    assert set(STOP_SAMPLES_SCHEMA.names) <= set(samp.column_names)
    df = samp.to_pandas()
    for (st, di, a), g in df.groupby(["station_id", "direction", "adhesion_ms2"]):
        g = g.sort_values("t_s")
        assert g.t_s.iloc[0] == 0.0 and np.all(np.diff(g.t_s) > 0) and np.diff(g.t_s).max() <= 0.1 + 1e-9
        assert g.distance_to_stop_m.iloc[-1] == pytest.approx(0.0, abs=END_X)
        assert abs(g.speed_kmh.iloc[-1]) < 1e-6
        stop = 900.0 if st == "S1" else (2900.0 if di == "down" else 0.0)
        assert np.allclose(np.abs(g.position_m - stop), g.distance_to_stop_m)
    # deterministic bytes
    again = write_stops(results, tmp_path / "again")
    for a, b in zip(sorted(files), sorted(again)):
        assert a.read_bytes() == b.read_bytes()


def test_adhesion_in_km_h_s_is_the_jobs_own_value(tmp_path):
    """stop_summary and stop_samples carry the level as the job writes it: 1.9 km/h/s does not come back
    from m/s² by arithmetic (1.9 / 3.6 * 3.6 = 1.9000000000000001), the column filters on it exactly
    (levels below the train's 3.6 km/h/s cap)."""
    assert 1.9 / 3.6 * 3.6 != 1.9  # why the column is worth having
    results = stop_sweep(line_b(), adhesion_kmh_s="1.9,2.5,3.0", approach_m=550.0, directions=["down"],
                         n_jobs=1)
    write_stops(results, tmp_path)
    for name in ("stop_summary", "stop_samples"):
        t = pads.dataset(tmp_path / name, format="parquet", partitioning="hive").to_table().to_pandas()
        levels = set(t.adhesion_kmh_s)  # samples: feasible levels only
        assert levels == {1.9, 2.5, 3.0} if name == "stop_summary" else levels <= {1.9, 2.5, 3.0}, name
        assert np.allclose(t.adhesion_kmh_s * KMH_S, t.adhesion_ms2, rtol=1e-12, atol=0)
        assert len(t[t.adhesion_kmh_s == 2.5]) == len(t[np.isclose(t.adhesion_ms2, 2.5 * KMH_S)]) > 0


# --------------------------------------------------------------------------------------
# the sample line
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sample_sweep():
    from planner import load_line

    line = load_line(SAMPLE)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InfeasibleStopWarning)
        results = stop_sweep(line, n_jobs=1)
    return line, results, [str(w.message) for w in caught if w.category is InfeasibleStopWarning]


def test_sample_line_sweep_meets_every_limit(sample_sweep):
    line, results, caught = sample_sweep
    n_arrivals = sum(len(line.interstations(d)) for d in ("down", "up"))
    assert len(results) == len(line.train_types) * n_arrivals
    n_checked = 0
    for r in results:
        assert r.tasc_beacon_id.startswith(("D-TASC", "U-TASC"))  # every arrival has its TASC beacon
        beacon = next(b for b in line.beacons if b.beacon_id == r.tasc_beacon_id)
        assert r.approach_length_m == pytest.approx(float(beacon.telegram.rsplit(":", 1)[1]))  # the TASC distance
        for k, p in enumerate(r.patterns):
            if p.feasible:
                assert_meets_limits(r, k)
                n_checked += 1
        lost = [t for t in r.time_lost_s if not math.isnan(t)]
        assert all(t >= 0.0 for t in lost) and (not lost or min(lost) == 0.0)
        # less adhesion never helps: feasible levels form an upper range, times fall with adhesion
        feas = [p.feasible for p in r.patterns]
        assert feas == sorted(feas)
        d = [p.duration_s for p in r.patterns if p.feasible]
        assert all(b <= a + 1e-9 for a, b in zip(d, d[1:]))
    assert n_checked >= 0.8 * sum(len(r.patterns) for r in results)
    # every infeasible level produced exactly one warning, naming it
    assert len(caught) == sum(len(r.warnings) for r in results)
    assert sorted(caught) == sorted(m for r in results for m in r.warnings)


def test_sample_line_takadai_down(sample_sweep, tmp_path):
    """TKD down (README, 'the hard approach'): the TASC beacon 550 m out lies inside the 70 km/h
    curve restriction (held until the tail clears, front at S − 150 m), so v_start is the on-board
    maximum 70 − 3 = 67 km/h for E10/E8 (constant-speed hold); the sawtooth E6 coasts in its
    5 km/h band below 70 − 5 = 65 km/h. The pattern must be at 40 − margin km/h 100 m out."""
    results = sample_sweep[1]
    tkd = {r.train_type: r for r in results if r.station_id == "TKD" and r.direction == "down"}
    assert tkd["E10"].tasc_beacon_id == "D-TASC-005" and tkd["E10"].approach_start_m == 10750.0
    for t in ("E10", "E8"):
        assert tkd[t].v_start_ms * 3.6 == pytest.approx(67.0, abs=1e-9)
    assert 60.0 - 1e-6 <= tkd["E6"].v_start_ms * 3.6 <= 65.0 + 1e-6
    # the gradient steps bound the train-averaged gradient from below, and touch it on every piece
    from planner.physics import dynamics

    line = sample_sweep[0]
    r = tkd["E10"]
    x = np.linspace(0.0, r.approach_length_m, 5501)
    gbar = 1000.0 * dynamics.running_gradient(line.gradients, r.chainage_m(x), line.train_type("E10").length_m, 1)
    steps = step_value(r.gradients_permil, x)
    assert np.all(steps <= gbar + 1e-9)
    assert steps.min() == pytest.approx(gbar.min(), abs=1e-9) and gbar.min() < -10.0
    assert tkd["E10"].speed_limits[-1] == (450.0, pytest.approx(37.0 * KMH))
    r = tkd["E10"]
    assert r.n_feasible == len(r.patterns)
    for p in r.patterns:
        s = p.sample(0.01)
        assert np.max(s.v_ms[s.x_m >= 450.0]) <= 37.0 * KMH + TOL_V
    from planner.report.plots import approach_chart

    png = approach_chart(r, tmp_path / "tkd.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------


def test_cli_writes_datasets_summary_and_plot(tmp_path):
    from planner.cli import app

    db = write_line_db(tmp_path / "tiny")
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["stops", str(db), "--out", str(out), "--adhesion", "2.5:3.5:0.5",
                                 "--train-type", "EMU10", "--direction", "down", "--plot", "B", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert "tiny: 2 station approaches x up to 3 adhesion levels (2.5 … 3.5 km/h/s) = 6 patterns" in r.stdout
    assert "feasible" in r.stdout and "time lost against the best adhesion" in r.stdout
    png = out / "plots" / "stop_B_down_EMU10.png"
    assert png.is_file() and png.read_bytes()[:4] == b"\x89PNG"
    assert (out / "stop_summary" / "line=tiny" / "direction=down" / "train_type=EMU10" / "part-0.parquet").is_file()


@pytest.mark.parametrize("args, match", [
    (["--adhesion", "3.5:2.5:0.1"], "--adhesion"),
    (["--plot", "A", "--direction", "down"], "--plot A"),
    (["--plot", "Z"], "unknown station"),
    (["--direction", "left"], "--direction"),
])
def test_cli_bad_options_are_one_line_errors(tmp_path, args, match):
    from planner.cli import app

    db = write_line_db(tmp_path / "tiny")
    r = CliRunner().invoke(app, ["stops", str(db), "--out", str(tmp_path / "out"), "--jobs", "1", *args])
    assert r.exit_code == 1
    assert match in r.output and "Traceback" not in r.output
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------------------
# issue 14: one gradient model (the train-averaged one of the run curves), one approach start
# --------------------------------------------------------------------------------------

G_STD = 9.80665  # m/s², standard gravity (the run curves' g)


def test_pattern_never_asks_the_brake_for_more_than_adhesion_under_the_whole_train():
    """Issue 14, defect 1: a 200 m train, level track with +25 ‰ over the last 150 m before the
    marker, adhesion 2.5 km/h/s. The rising gradient helps only as much of the train as stands on
    it: with the front 60 m onto the slope, ḡ = 25 ‰ × 60/200. Re-simulated with that gradient
    (by hand here: the overlap of the train body with the slope), the brake may give at most the
    adhesion limit anywhere; the front-only pattern asked for 3.35 km/h/s."""
    tt = testing.train_type(length_m=200.0)  # no rotating mass: gravity gives g ḡ
    line = line_a(gradients=[(750.0, 900.0, 25.0)], train_types=[tt])
    adh = 2.5 * KMH_S
    r = approach_patterns(line, "T", "S0", "S1", [adh])
    p = r.patterns[0]
    assert p.feasible
    s = p.sample(0.002)
    front = r.approach_start_m + s.x_m  # down: chainage grows with x
    on_slope = np.clip(np.minimum(front, 900.0) - np.maximum(front - 200.0, 750.0), 0.0, None)
    gbar = 0.025 * on_slope / 200.0
    brake = -s.a_ms2 - G_STD * gbar
    assert brake.max() <= adh + 1e-6, f"asks the brake for {brake.max() / KMH_S:.3f} km/h/s"
    # and the bound is not wasted: on the level the pattern brakes at the adhesion limit itself
    assert brake.max() >= adh - 1e-9


def test_one_approach_start_for_stops_and_margins():
    """Issue 14, defect 6: the stopping sweep and the margin report start the approach at the
    same place, also where the fixed approach reaches back beyond the middle of the leg
    (900 m leg, 550 m approach: 350 m after the departure marker)."""
    from planner.report.leg_margin import leg_result

    line = line_a()
    r = approach_patterns(line, "T", "S0", "S1", LEVELS_MS2[:1], approach_m=550.0)
    m = leg_result(line, "T", "S0", "S1", [], ratios=[1.0, 0.6], adhesion_kmh_s="3.5", approach_m=550.0)
    assert r.approach_start_m == 350.0
    assert m.pattern_start_m == r.approach_start_m
    # and the start from the physics (no TASC beacon, no approach_m) is one too, for the same sweep
    r = approach_patterns(line, "T", "S0", "S1", [3.5 * KMH_S])
    m = leg_result(line, "T", "S0", "S1", [], ratios=[1.0, 0.6], adhesion_kmh_s="3.5")
    assert r.approach_start_m == m.pattern_start_m and m.pattern_source == "physics"


@pytest.fixture(scope="module")
def sample_brake_demand(sample_sweep):
    """Per feasible pattern of the sample-line sweep: the largest brake demand over the limit [m/s²],
    re-simulated with the run-curve force model (gradient averaged over the train, g/(1 + ρ))."""
    from planner.physics import dynamics
    from planner.line.model import sign

    line, results, _ = sample_sweep
    over = []
    for r in results:
        tt = line.train_type(r.train_type)
        sg = sign(r.direction)
        for a, p in zip(r.adhesion_ms2, r.patterns):
            if not p.feasible:
                continue
            s = p.sample(min(0.01, p.duration_s / 4000.0))
            gbar = dynamics.running_gradient(line.gradients, r.chainage_m(s.x_m), tt.length_m, sg)
            brake = -s.a_ms2 + dynamics.track_accel_ms2(gbar, 0.0, tt.rotating_mass_factor)
            over.append(float(brake.max()) - min(r.comfort_ms2, a))
    return np.array(over)


def test_sample_line_patterns_never_ask_the_brake_for_more_than_comfort_and_adhesion(sample_brake_demand):
    over = sample_brake_demand
    assert over.size >= 500
    assert np.all(over <= 1e-6), f"{np.sum(over > 1e-6)} of {over.size} patterns, worst +{over.max():.4f} m/s²"
