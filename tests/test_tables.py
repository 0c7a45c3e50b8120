"""Running-time tables (a) and (b): closed forms, consistency, monotonicity, determinism, datasets."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import planner
from planner.line import testing
from planner.io.parquet import read_dataset
from planner.line.model import Beacon
from planner.tables.ratios import ratio_grid
from planner.physics.track import make_track
from planner.physics.run_curve import simulate
from planner.tables.build import build_tables, interstation_tables
from planner.datasets.tables import TABLE_B_SCHEMA, write_tables

from linedb import write_line_db

CLOSED_FORM_TOL_S = 0.05
"""docs/design.md §2: running times within 0.05 s of closed-form answers at the default 1 m step."""
CONSISTENCY_TOL_S = 0.1
"""Issue 4: table (b) at (r, r) + time to reach X at r equals table (a) at r within 0.1 s."""
SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"


def flat_line():
    """Flat, no resistance, 300 kN on 300 t: 1 m/s² up, 1 m/s² service and stopping brake, 100 km/h."""
    ln = testing.line(length_m=3000.0)
    beacons = (
        Beacon("B1", 1000.0, "down", "signal", "a", True),
        Beacon("B2", 2200.0, "down", "signal", "b", True),
    )
    return dataclasses.replace(ln, beacons=beacons)


VMAX = 100 / 3.6
L = 3000.0


def t_a(v):
    """Accelerate at 1 m/s² to v, cruise, stop at 1 m/s²: T = v + L/v (v² ≤ L)."""
    return v + L / v


def t_b(x, vb, va):
    """Remaining time from X after running at target vb up to X, then target va (1 m/s² everywhere)."""
    vx = min(vb, math.sqrt(2 * x))  # still accelerating at X if vb was not reached
    d = L - x
    if va <= vx:  # service brake vx -> va, cruise, stop
        return (vx - va) + (d - vx**2 / 2) / va + va
    return (va - vx) + (d - va**2 + vx**2 / 2) / va + va  # accelerate, cruise, stop


@pytest.fixture(scope="module")
def flat():
    ln = flat_line()
    return ln, interstation_tables(ln, "T", "S0", "S1", ratio_grid(line_max_speed_ms=ln.max_speed_ms))


def test_table_a_closed_form(flat):
    _, t = flat
    expected = [t_a(r * VMAX) for r in t.ratios]
    np.testing.assert_allclose(t.time_a_s, expected, atol=CLOSED_FORM_TOL_S)


def test_table_b_closed_form(flat):
    _, t = flat
    assert [p.eval_point_id for p in t.points] == ["dep", "dep+200", "B1", "B2"]
    for k, p in enumerate(t.points):
        expected = np.array([[t_b(p.s_m, rb * VMAX, ra * VMAX) if p.s_m > 0 else t_a(ra * VMAX)
                              for ra in t.ratios] for rb in t.ratios])
        np.testing.assert_allclose(t.remaining_s[k], expected, atol=CLOSED_FORM_TOL_S, err_msg=p.eval_point_id)


def _hilly():
    tt = [
        testing.train_type("C", davis_a_kN=4, davis_b_kN_per_kmh=0.05, davis_c_kN_per_kmh2=0.0008,
                           traction=((0, 250), (40, 250), (100, 110), (130, 80)), rotating_mass_factor=0.08,
                           max_accel_kmh_s=3.0, service_brake_kmh_s=3.0, stop_brake_kmh_s=2.8),
        testing.train_type("S", cruise="sawtooth", coast_band_kmh=5.0, davis_a_kN=4, davis_c_kN_per_kmh2=0.001,
                           traction=((0, 220), (35, 220), (100, 90), (130, 60)), max_accel_kmh_s=2.5),
    ]
    ln = testing.line(length_m=4200.0, stations=[100.0, 2100.0, 4100.0], max_speed_kmh=110.0,
                      gradients=[(500, 1100, 8.0), (1100, 1900, -6.0), (2600, 3600, 10.0)],
                      curves=[(1500, 1700, 400.0)], limits=[(900, 1200, 60.0), (3000, 3300, 75.0)],
                      train_types=tt)
    # D1 sits where the 60 km/h restriction's tail clears (1200 + 100 m train): a ratio lowered
    # there must not let the train jump up to the new, higher ceiling
    b = [Beacon(f"D{i}", x, "down", "signal", "t", True) for i, x in enumerate([700, 1300, 1650, 2900, 3500])]
    b += [Beacon(f"U{i}", x, "up", "signal", "t", True) for i, x in enumerate([3700, 3150, 2500, 1500, 800])]
    return dataclasses.replace(ln, beacons=tuple(b))


@pytest.fixture(scope="module")
def hilly():
    ln = _hilly()
    return ln, build_tables(ln, n_jobs=1)


def test_consistency_prefix_plus_remaining_equals_table_a(hilly):
    """Table (b) at (r, r) + time to reach X at r = table (a) at r, the time to X read off an
    independent recorded run (not the table's own prefix snapshots)."""
    ln, results = hilly
    assert len(results) == 2 * 2 * 2
    for t in results:
        track = make_track(ln, t.train_type, t.origin, t.destination, nodes_m=[p.s_m for p in t.points])
        rec = simulate(track, ln.train_type(t.train_type), t.ratios, record=True)
        for k, p in enumerate(t.points):
            j = int(np.argmin(np.abs(rec.s_m - p.s_m)))
            assert abs(rec.s_m[j] - p.s_m) < 1e-6
            total = np.diagonal(t.remaining_s[k]) + rec.t_s[:, j]
            np.testing.assert_allclose(total, t.time_a_s, atol=CONSISTENCY_TOL_S,
                                       err_msg=f"{t.train_type} {t.origin}->{t.destination} {p.eval_point_id}")


def test_table_b_rows_are_the_runs_restarted_from_the_state_at_each_point(hilly):
    """Table (b) comes from one batch of runs that change their ratio at X (tables.build, step 2). The same
    rows by another road: a separate run for each point X and ratio after, started from the constant-ratio
    run's whole state at X (RunState: speed², phase, coasting flag), no ratio change and no run of another
    point beside it. Equal to the bit: a ratio change at X and a start from the state there step alike,
    and the runs that meet across points are stepped once without changing a bit."""
    ln, results = hilly
    for t in results:
        track = make_track(ln, t.train_type, t.origin, t.destination, nodes_m=[p.s_m for p in t.points])
        train = ln.train_type(t.train_type)
        s_pts = [p.s_m for p in t.points]
        full = simulate(track, train, t.ratios, snapshots_m=s_pts[1:])
        n_r = t.ratios.size
        for k in range(1, len(s_pts)):
            snap = full.snapshots[s_pts[k]]
            for i in range(n_r):
                fields = (getattr(snap, f.name) for f in dataclasses.fields(snap))
                start = type(snap)(*(None if x is None else np.repeat(x[i:i + 1], n_r) for x in fields))
                again = simulate(track, train, t.ratios, start=start)
                np.testing.assert_array_equal(
                    np.asarray(again.time_s) - snap.t_s[i], t.remaining_s[k, i],
                    err_msg=f"{t.train_type} {t.origin}->{t.destination} point {k} ratio before {t.ratios[i]}")


def test_running_time_grows_as_ratio_falls(hilly):
    _, results = hilly
    for t in results:
        assert np.all(np.diff(t.time_a_s) > 0), (t.train_type, t.origin, t.destination)
        for k in range(len(t.points)):
            # a lower ratio after X is never faster; equal where neither target is reached
            assert np.all(np.diff(t.remaining_s[k], axis=1) > -1e-9)


@pytest.mark.skipif(not (SAMPLE / "line.parquet").exists(), reason="sample line not built")
def test_exception_sawtooth_higher_ratio_can_be_slower():
    """The known exception to monotonicity: a sawtooth vehicle (E6) on the sample line, AOB->KTA.

    At r = 0.596 the train's coast crosses the band's lower edge just before a long -5 ‰ fall, so
    it powers back to its target and holds it down the hill; at r = 0.598 the same coast starts a
    moment later, the fall keeps the speed inside the band, and the train coasts the whole hill
    a few km/h below the target: the *higher* ratio is ~4 s slower. The driving rule is
    discontinuous there; the default grid happens not to straddle such a point (checked above
    for the tiny line and, in the report, for the sample), and the closed loop compensates at
    later evaluation points.
    """
    ln = planner.load_line(SAMPLE)
    track = make_track(ln, "E6", "AOB", "KTA")
    t = simulate(track, ln.train_type("E6"), np.array([0.596, 0.598])).time_s
    assert t[1] - t[0] > 2.0


def test_parallel_equals_serial_and_files_are_deterministic(hilly, tmp_path):
    ln, results = hilly
    serial = [r for r in results if r.train_type == "S"]
    par = build_tables(ln, train_types=["S"], n_jobs=2)
    assert len(par) == len(serial) == 4
    for a, b in zip(serial, par):
        assert (a.train_type, a.direction, a.origin) == (b.train_type, b.direction, b.origin)
        np.testing.assert_array_equal(a.remaining_s, b.remaining_s)
        np.testing.assert_array_equal(a.time_a_s, b.time_a_s)
    f1 = write_tables(serial, tmp_path / "one")
    f2 = write_tables(par, tmp_path / "two")
    assert [p.relative_to(tmp_path / "one") for p in f1] == [p.relative_to(tmp_path / "two") for p in f2]
    for a, b in zip(f1, f2):
        assert a.read_bytes() == b.read_bytes()


def test_datasets_layout_and_schema(hilly, tmp_path):
    _, results = hilly
    write_tables(results, tmp_path)
    f = tmp_path / "table_b" / "line=test" / "direction=down" / "train_type=C" / "part-0.parquet"
    schema = pq.read_schema(f)
    assert schema.names == TABLE_B_SCHEMA.names
    assert all(schema.field(n).metadata[b"description"] for n in schema.names)
    tb = read_dataset(tmp_path, "table_b", direction="up", train_type="S").to_pandas()
    t = next(r for r in results if r.direction == "up" and r.train_type == "S")
    n_r = len(t.ratios)
    first = tb[(tb.origin == t.origin) & (tb.destination == t.destination)]
    assert len(first) == len(t.points) * n_r * n_r
    ta = read_dataset(tmp_path, "table_a").to_pandas()
    assert set(ta.columns) >= {"line", "direction", "train_type", "origin", "destination", "ratio",
                               "running_time_s", "energy_kwh"}
    assert (ta.energy_kwh > 0).all()
    ep = read_dataset(tmp_path, "eval_points", direction="up", train_type="C").to_pandas()
    # up: chainage falls as running distance grows
    g = ep[ep.origin == "S2"]
    assert np.all(np.diff(g.eval_distance_m) > 0) and np.all(np.diff(g.eval_position_m) < 0)


def test_tiny_line_db_from_disk(tmp_path):
    """The loader's tiny database end to end (both cruise kinds), grid from a spec string."""
    ln = planner.load_line(write_line_db(tmp_path / "tiny"))
    res = build_tables(ln, ratios="1.0:0.6:0.2", n_jobs=1)
    assert {r.train_type for r in res} == {t.train_type for t in ln.train_types}
    for r in res:
        assert r.ratios.tolist() == [1.0, 0.8, 0.6]
        assert np.all(np.diff(r.time_a_s) > 0)


# --- table (d): the last evaluation point, by the train's own state --------------------------

def _last_states(ln, t):
    """Speed and powering flag of the table train at the last point at each grid ratio, from an
    independent recorded run (not the table build's snapshots)."""
    from planner.physics.run_curve import PHASE_POWER

    track = make_track(ln, t.train_type, t.origin, t.destination, nodes_m=[p.s_m for p in t.points])
    rec = simulate(track, ln.train_type(t.train_type), t.ratios, record=True)
    j = int(np.argmin(np.abs(rec.s_m - t.points[-1].s_m)))
    return rec.v_ms[:, j], rec.phase[:, j] == PHASE_POWER


def test_table_d_only_for_sawtooth_vehicles(hilly):
    _, results = hilly
    for t in results:
        assert (t.approach is not None) == (t.train_type == "S"), (t.train_type, t.origin)


def test_table_d_at_the_table_trains_own_state_reproduces_table_b(hilly):
    """Table (d) looked up at the state the table train really has at the last point (after
    running at grid ratio r_b) gives table (b)'s row for r_b: both are the remaining time from
    that same state. Only the 2 km/h speed interpolation separates them; a wiring error (phase
    slices swapped, km/h for m/s, ratios reversed) is off by seconds.

    Columns with a kink (the ratio's target, or the coasting band's lower edge) within one speed
    step of the state are left out: there the time jumps (power on at once, or coast on) and
    the interpolation, one-sided as it is, is off by up to ~0.8 s on this line (a known
    limitation of table (d), see ApproachTable). Elsewhere the two agree within 0.5 s: most
    columns within 0.01 s, up to ~0.3 s where a high state brakes down to a low ratio's target
    (braking time is far from linear in the start speed)."""
    ln, results = hilly
    compared, worst = 0, 0.0
    for t in (r for r in results if r.approach is not None):
        ap = t.approach
        cols = np.array([int(np.flatnonzero(np.isclose(ap.ratios, r))[0]) for r in t.ratios])
        v, powering = _last_states(ln, t)
        for i in range(len(t.ratios)):
            time_d, ref_d = ap.rows(v[i], powering[i])
            far = _off_kinks(ap, v[i], powering[i])[cols]
            err = np.abs(time_d[cols] - t.remaining_s[-1, i])[far]
            compared += int(far.sum())
            worst = max(worst, float(err.max(initial=0.0)))
            assert err.max(initial=0.0) < 0.5, (t.origin, t.destination, t.ratios[i], v[i] * 3.6, powering[i], err)
            assert np.all(ref_d[cols] > 0)
    assert compared > 0.8 * sum(len(r.ratios) ** 2 for r in results if r.approach is not None), compared
    assert worst > 0.0  # the check compared something


def _off_kinks(ap, v: float, powering: bool) -> np.ndarray:
    """Columns of table (d) with no kink within one speed step of ``v``: the ratio's target,
    and, not powering, the coasting band's lower edge (where the time jumps)."""
    from planner.physics.run_curve import SAWTOOTH_MIN_FRACTION
    from planner.tables.build import APPROACH_SPEED_STEP_MS

    target = ap.ratios * ap.vmax_ms
    far = np.abs(target - v) > 1.01 * APPROACH_SPEED_STEP_MS
    if not powering:
        bottom = np.maximum(target - ap.coast_band_ms, SAWTOOTH_MIN_FRACTION * target)
        far &= np.abs(bottom - v) > 1.01 * APPROACH_SPEED_STEP_MS
    return far


def test_table_d_speed_interpolation_converges(hilly):
    """Refinement: halving the speed step barely moves table (d) at speeds between the nodes."""
    from planner.tables import build as tables_mod

    ln, results = hilly
    t = next(r for r in results if r.approach is not None and r.direction == "down")
    track = make_track(ln, t.train_type, t.origin, t.destination, nodes_m=[p.s_m for p in t.points])
    train = ln.train_type(t.train_type)
    kw = dict(load=0.0, traction_factor=1.0, ref_load=1.0, ref_traction_factor=0.9)
    top = float(t.speed_ms[:, -1].max())
    step = tables_mod.APPROACH_SPEED_STEP_MS
    coarse = tables_mod.approach_table(track, train, t.points[-1].s_m, top, t.ratios, **kw)
    try:
        tables_mod.APPROACH_SPEED_STEP_MS = step / 2
        fine = tables_mod.approach_table(track, train, t.points[-1].s_m, top, t.ratios, **kw)
    finally:
        tables_mod.APPROACH_SPEED_STEP_MS = step
    assert len(fine.speeds_ms) > 1.9 * len(coarse.speeds_ms)
    mids = fine.speeds_ms[1:-1:2]  # the nodes the coarse grid lacks
    mids = mids[mids < coarse.speeds_ms[-1]]
    diffs = []
    for v in mids:
        for p in (True, False):
            far = _off_kinks(coarse, v, p)  # kinks: see the test above
            diffs.append(np.abs(coarse.rows(v, p)[0] - fine.rows(v, p)[0])[far])
    d = np.concatenate(diffs)
    assert d.size > 0.8 * len(mids) * 2 * len(coarse.ratios)
    assert np.median(d) < 0.01 and d.max() < 0.5, (np.median(d), d.max())


def test_table_d_round_trip_through_the_datasets(hilly, tmp_path):
    from planner.datasets.tables import load_tables

    ln, results = hilly
    write_tables(results, tmp_path)
    for t in (r for r in results if r.approach is not None):
        got = load_tables(tmp_path, ln.line_id, t.direction, t.train_type)[(t.origin, t.destination)].approach
        np.testing.assert_allclose(got.speeds_ms, t.approach.speeds_ms, rtol=1e-12)
        np.testing.assert_array_equal(got.ratios, t.approach.ratios)
        assert got.powering == t.approach.powering == (True, False)
        np.testing.assert_array_equal(got.time_s, t.approach.time_s)
        np.testing.assert_array_equal(got.ref_time_s, t.approach.ref_time_s)
    for t in (r for r in results if r.approach is None):
        assert load_tables(tmp_path, ln.line_id, t.direction, t.train_type)[(t.origin, t.destination)].approach is None


def _assert_same_tables(got, want):
    """Two RunningTimeTables hold the same numbers (speeds to round-off: they are stored in km/h)."""
    assert (got.origin, got.destination, got.eval_point_ids, got.flags) == \
        (want.origin, want.destination, want.eval_point_ids, want.flags)
    for f in ("ratios", "time_a_s", "eval_distance_m", "eval_position_m", "remaining_s", "ref_remaining_s"):
        w, g = getattr(want, f), getattr(got, f)
        assert (g is None) == (w is None), f
        if w is not None:
            assert g.dtype == w.dtype and g.shape == w.shape, f
            np.testing.assert_array_equal(g, w, err_msg=f)
    assert (got.speed_ms is None) == (want.speed_ms is None)
    if want.speed_ms is not None:
        np.testing.assert_allclose(got.speed_ms, want.speed_ms, rtol=1e-12)
    assert (got.approach is None) == (want.approach is None)
    if want.approach is not None:
        g, w = got.approach, want.approach
        assert g.powering == w.powering
        np.testing.assert_allclose(g.speeds_ms, w.speeds_ms, rtol=1e-12)
        np.testing.assert_allclose([g.vmax_ms, g.coast_band_ms], [w.vmax_ms, w.coast_band_ms], rtol=1e-12)
        for f in ("ratios", "time_s", "ref_time_s"):
            np.testing.assert_array_equal(getattr(g, f), getattr(w, f), err_msg=f)


def test_tables_read_back_as_built_whatever_the_row_order_of_the_files(hilly, tmp_path):
    """load_tables gives each interstation the tables the vehicle was built with (``onboard()``), in
    running order; and the same tables from files whose rows are in any order: the rows are split by
    interstation and placed by their point and ratios, not by where they are in the file."""
    import shutil

    from planner.datasets.tables import load_tables

    ln, results = hilly
    assert any(r.approach is not None for r in results) and any(r.ref_remaining_s is not None for r in results)
    write_tables(results, tmp_path / "written")
    shutil.copytree(tmp_path / "written", tmp_path / "shuffled")
    rng = np.random.default_rng(7)
    for f in sorted((tmp_path / "shuffled").rglob("*.parquet")):
        t = pq.read_table(f)
        pq.write_table(t.take(rng.permutation(t.num_rows)), f)
    for part in sorted({(r.direction, r.train_type) for r in results}):
        want = {(r.origin, r.destination): r.onboard() for r in results if (r.direction, r.train_type) == part}
        got = load_tables(tmp_path / "written", ln.line_id, *part)
        shuffled = load_tables(tmp_path / "shuffled", ln.line_id, *part)
        assert list(got) == list(want) and set(shuffled) == set(want)
        for k, w in want.items():
            _assert_same_tables(got[k], w)
            _assert_same_tables(shuffled[k], w)


def test_a_margin_leg_given_its_stored_tables_computes_what_the_datasets_give(hilly, tmp_path):
    """The nightly job gives each margin leg a reference to the tables step's stored result, read on the worker
    (report.margin_datasets.given_leg), instead of the tables read back from their datasets: the same tables and table (a)
    energy as the datasets hold, and so the same leg, to the bit."""
    from planner.datasets.tables import load_tables
    from planner.report.leg_margin import leg_result
    from planner.report.margin_datasets import read_energy
    from planner.report.margin_datasets import given_leg

    class Ref:  # what a stored result is to the margins: something with load()
        def __init__(self, built):
            self.built = built

        def load(self):
            return self.built

    ln, results = hilly
    write_tables(results, tmp_path)
    for r in results:
        tabs, energy = given_leg(Ref(r), None)
        _assert_same_tables(tabs, load_tables(tmp_path, ln.line_id, r.direction, r.train_type)[(r.origin, r.destination)])
        np.testing.assert_array_equal(energy, read_energy(tmp_path, ln.line_id, r.direction, r.train_type)[(r.origin, r.destination)])
    r = results[0]
    sched = [float(r.time_a_s.min()) * 1.08]
    want = leg_result(ln, r.train_type, r.origin, r.destination, sched,
                      tables=load_tables(tmp_path, ln.line_id, r.direction, r.train_type)[(r.origin, r.destination)],
                      energy_a_kwh=read_energy(tmp_path, ln.line_id, r.direction, r.train_type)[(r.origin, r.destination)])
    tabs, energy = given_leg(Ref(r), None)
    got = leg_result(ln, r.train_type, r.origin, r.destination, sched, tables=tabs, energy_a_kwh=energy)
    assert len(want.schedules) == 1 and math.isfinite(want.schedules[0]["arrival_error_s"])
    assert got.schedules == want.schedules
    for f in ("min_time_s", "energy_full_kwh", "degraded_min_s", "stop_time_degraded_s"):
        g, w = getattr(got, f), getattr(want, f)
        assert g == w or (math.isnan(g) and math.isnan(w)), f


@pytest.mark.parametrize("damage", ["foreign_ratio", "missing_row"])
def test_tables_that_do_not_fit_together_are_one_line_errors(flat, tmp_path, damage):
    """load_tables: a table_b row at a ratio table (a) does not have, or a row missing, names the
    dataset, the interstation and the fix (never an IndexError, never a silently wrong cell)."""
    import pyarrow as pa

    from planner.datasets.tables import load_tables
    from planner.errors import InputError

    ln, res = flat
    files = write_tables([res], tmp_path)
    f = next(p for p in map(Path, files) if "table_b" in p.parts)
    t = pq.read_table(f)
    if damage == "foreign_ratio":  # one row's ratio_before moved off the grid
        col = t.column("ratio_before").to_numpy().copy()
        col[0] = 0.123
        t = t.set_column(t.schema.get_field_index("ratio_before"), t.schema.field("ratio_before"),
                         pa.array(col))
        want = "table_b for S0->S1 has a ratio_before the other tables do not have; rebuild the tables"
    else:
        t = t.slice(1)
        want = "table_b for S0->S1 has"
    pq.write_table(t, f)
    with pytest.raises(InputError) as e:
        load_tables(tmp_path, ln.line_id, res.direction, res.train_type)
    assert want in str(e.value) and "\n" not in str(e.value)
