"""On-board ratio choice on synthetic tables with closed-form times, and the Parquet round trip.

The synthetic tables are T(r) = a + b / r (a cruise-dominated run: time affine
in 1/r), for which interpolation in u = 1/r is exact, so the interpolating mode
must hit the wanted time to round-off and the nearest rule must pick the grid
ratio that is provably nearest.
"""
import numpy as np
import pytest
from hypothesis import given, strategies as st

from planner.tables.eval_points import EvalPoint
from planner.tables.onboard import (
    CHOOSERS,
    InterpolateRule,
    NearestRule,
    RunningTimeTables,
    chooser,
    make_controller,
    row_at,
    solve_ratio,
)
from planner.datasets.tables import load_tables
from planner.errors import InputError
from planner.tables.ratios import ratio_grid
from planner.tables.build import InterstationTables
from planner.datasets.tables import write_tables

RATIOS = ratio_grid(line_max_speed_ms=100 / 3.6)
ROUNDOFF_S = 1e-9  # exact arithmetic up to float round-off on ~100 s values


def synthetic(a=20.0, b=100.0, s_pts=(0.0, 200.0, 900.0)):
    """Remaining time after X: a_x + b_x(before) / r_after, with a before-dependent offset."""
    n_r, n_x = len(RATIOS), len(s_pts)
    frac = [1.0 - s / 1000.0 for s in s_pts]  # share of the run left at X
    time_a = a + b / RATIOS
    rem = np.empty((n_x, n_r, n_r))
    for k, f in enumerate(frac):
        # arriving at X at a lower speed (lower r_before) costs 0..2 s extra, affine in 1/r_before
        extra = (k > 0) * 2.0 * (1 / RATIOS - 1)
        rem[k] = f * a + extra[:, None] + f * b / RATIOS[None, :]
    return RunningTimeTables("S0", "S1", RATIOS, time_a, tuple(f"p{k}" for k in range(n_x)),
                             np.array(s_pts), np.array(s_pts) + 50.0, rem)


def test_nearest_departure_picks_nearest_grid_time():
    t = synthetic()
    want = np.array([t.time_a_s[0] - 5, t.time_a_s[3] + 0.1, 0.5 * (t.time_a_s[5] + t.time_a_s[6]) - 0.01, 1e6])
    got = NearestRule().depart(t, want)
    assert got.tolist() == [RATIOS[0], RATIOS[3], RATIOS[5], RATIOS[-1]]


def test_nearest_tie_goes_to_higher_ratio():
    t = synthetic()
    mid = 0.5 * (t.time_a_s[1] + t.time_a_s[2])
    assert NearestRule().depart(t, np.array([mid]))[0] == RATIOS[1]


def test_nearest_at_point_uses_row_of_current_ratio():
    t = synthetic()
    k, i = 2, 5
    row = t.remaining_s[k, i]
    want = row[7] + 0.2
    got = NearestRule().at_point(t, k, np.array([RATIOS[i]]), np.array([want]))
    assert got[0] == RATIOS[7]
    # a different current ratio shifts the row: the same remaining time picks another column
    other = NearestRule().at_point(t, k, np.array([RATIOS[-1]]), np.array([want]))
    assert other[0] != got[0]


@given(frac=st.floats(0.0, 1.0))
def test_interpolate_departure_exact_for_affine_in_inverse_ratio(frac):
    t = synthetic()
    want = t.time_a_s[0] + frac * (t.time_a_s[-1] - t.time_a_s[0])
    r = InterpolateRule().depart(t, np.array([want]))[0]
    assert 20.0 + 100.0 / r == pytest.approx(want, abs=ROUNDOFF_S)


@given(rb=st.floats(float(RATIOS[-1]), 1.0), frac=st.floats(0.0, 1.0))
def test_interpolate_at_point_exact(rb, frac):
    t = synthetic()
    k, f = 2, 1 - 0.9
    # closed form of the synthetic row for a fractional ratio before
    row = lambda ra: f * 20.0 + 2.0 * (1 / rb - 1) + f * 100.0 / ra
    lo, hi = row(1.0), row(RATIOS[-1])
    want = lo + frac * (hi - lo)
    np.testing.assert_allclose(row_at(t, k, rb)[0], row(RATIOS), atol=1e-9)
    ra = InterpolateRule().at_point(t, k, np.array([rb]), np.array([want]))[0]
    assert row(ra) == pytest.approx(want, abs=1e-9)


def test_solve_ratio_clamps_and_handles_flat_top():
    r = np.array([1.0, 0.9, 0.8, 0.7])
    # the top two ratios are equally fast (target never reached): the higher one is kept
    t = np.array([100.0, 100.0, 110.0, 125.0])
    assert solve_ratio(r, t, 90.0) == 1.0
    assert solve_ratio(r, t, 100.0) == 1.0
    assert solve_ratio(r, t, 200.0) == 0.7
    x = solve_ratio(r, t, 105.0)
    assert 0.8 < x < 0.9


def test_unknown_mode():
    with pytest.raises(InputError, match="known: nearest, interpolate"):
        chooser("psychic")
    assert set(CHOOSERS) >= {"nearest", "interpolate"}


def test_controller_ignores_other_decisions_and_records_choices():
    t = synthetic()

    class S:  # minimal RunState stand-in
        ratio = np.array([1.0, 0.5])
        t_s = np.array([10.0, 10.0])
        v_ms = np.array([20.0, 10.0])
        phase = np.array([0, 2], dtype=np.int8)

    ctl, decision_m, chosen = make_controller(t, "nearest", np.array([200.0, 200.0]))
    assert decision_m == [200.0, 900.0]
    np.testing.assert_array_equal(ctl(555.0, S), S.ratio)
    out = ctl(200.0, S)
    assert len(chosen) == 1 and np.array_equal(chosen[0], out)


def test_tables_round_trip_through_parquet(tmp_path):
    t = synthetic()
    n_r = len(t.ratios)
    it = InterstationTables(
        line_id="L", direction="down", train_type="EMU", origin="S0", destination="S1", ratios=t.ratios,
        points=tuple(EvalPoint(i, s, p) for i, s, p in zip(t.eval_point_ids, t.eval_distance_m, t.eval_position_m)),
        time_a_s=t.time_a_s, energy_a_kwh=np.linspace(50, 20, n_r),
        elapsed_s=np.zeros((n_r, len(t.eval_point_ids))), remaining_s=t.remaining_s,
    )
    files = write_tables([it], tmp_path)
    assert {f.parent.parent.parent.parent.name for f in files} == {"eval_points", "table_a", "table_b"}
    back = load_tables(tmp_path, "L", "down", "EMU")[("S0", "S1")]
    np.testing.assert_array_equal(back.ratios, t.ratios)
    np.testing.assert_array_equal(back.time_a_s, t.time_a_s)
    np.testing.assert_array_equal(back.remaining_s, t.remaining_s)
    np.testing.assert_array_equal(back.eval_distance_m, t.eval_distance_m)
    assert back.eval_point_ids == t.eval_point_ids
    with pytest.raises(InputError):
        load_tables(tmp_path, "L", "up", "EMU")
    with pytest.raises(InputError):
        load_tables(tmp_path / "nowhere", "L", "down", "EMU")


@given(theta=st.floats(0.0, 2.0), frac=st.floats(0.05, 0.6), sawtooth=st.booleans())
def test_adaptive_learns_the_train_and_arrives_exactly(theta, frac, sawtooth):
    """A train slower than the tables by exactly theta x (reference - table), everything affine in
    1/r: after one leg the rule knows theta, and its choice at the next point (p1, not the last)
    arrives on time, or exactly ``AIM_EARLY_S`` early for a sawtooth vehicle (one whose tables
    hold table (d)); at the last point (p2) both arrive on time."""
    from planner.tables.onboard import AdaptiveRule, ApproachTable

    c = 30.0
    t = synthetic()
    f = np.array([1.0 - s / 1000.0 for s in t.eval_distance_m])
    delta = f[:, None] * c / RATIOS[None, :]  # reference - table, at constant ratio
    diag = np.stack([np.diagonal(t.remaining_s[k]) for k in range(3)])
    # table (d) marks a sawtooth vehicle; the look-up itself needs the measured speed, not given here
    ap = ApproachTable(np.array([0.0, 1.0]), (True,), RATIOS, np.zeros((1, 2, len(RATIOS))),
                       np.zeros((1, 2, len(RATIOS)))) if sawtooth else None
    t = RunningTimeTables(t.origin, t.destination, t.ratios, t.time_a_s, t.eval_point_ids, t.eval_distance_m,
                          t.eval_position_m, t.remaining_s, ref_remaining_s=diag + delta, approach=ap)
    early = AdaptiveRule.AIM_EARLY_S if sawtooth else 0.0
    assert AdaptiveRule.AIM_EARLY_S > 0.0
    lo, hi = t.time_a_s[0] + theta * delta[0, 0], t.time_a_s[-1]
    designated = lo + frac * (hi - lo)

    def true_remaining(k, rb, ra):  # the real train: table row + theta * Δ(ra)
        # the synthetic table (b) entry in closed form, plus the train's own extra time
        return f[k] * 20.0 + (k > 0) * 2.0 * (1 / rb - 1) + f[k] * 100.0 / ra + theta * f[k] * c / ra

    rule = AdaptiveRule()
    r0 = rule.depart(t, np.array([designated]))[0]
    leg = true_remaining(0, r0, r0) - true_remaining(1, r0, r0)
    rem1 = designated - leg
    r1 = rule.at_point(t, 1, np.array([r0]), np.array([rem1]))[0]
    if r1 in (RATIOS[0], RATIOS[-1]):
        return  # clamped: the designated time is outside what the real train can do
    assert true_remaining(1, r0, r1) == pytest.approx(rem1 - early, abs=1e-6)
    # the last point aims on time, and the early running so far is not mistaken for a faster train
    rem2 = rem1 - (true_remaining(1, r0, r1) - true_remaining(2, r1, r1))
    r2 = rule.at_point(t, 2, np.array([r1]), np.array([rem2]))[0]
    if r2 in (RATIOS[0], RATIOS[-1]):
        return
    assert true_remaining(2, r1, r2) == pytest.approx(rem2, abs=1e-6)


def test_solve_piecewise_equals_the_one_run_rule_to_the_bit():
    """The batch form of solve_piecewise against the same rule written for one run (crossings by
    linear interpolation in 1/r, whole segments on the wanted time, else the nearest grid value), on
    random rows with repeated values, plateaus and exact hits, all solved in one batch."""
    from planner.tables.onboard import solve_piecewise

    def by_arrays(ratios, f, want, prefer):
        u = 1.0 / ratios
        up = 1.0 / min(max(prefer, ratios[-1]), ratios[0])
        d0, d1 = f[:-1] - want, f[1:] - want
        cross = (d0 * d1 <= 0.0) & (f[:-1] != f[1:])
        w = np.where(cross, d0 / np.where(cross, d0 - d1, 1.0), 0.0)
        cand = list(u[:-1][cross] + w[cross] * np.diff(u)[cross])
        flat = (d0 == 0.0) & (d1 == 0.0)
        cand += list(np.clip(up, u[:-1][flat], u[1:][flat]))
        if cand:
            c = np.asarray(cand)
            return float(1.0 / c[np.argmin(np.abs(c - up))])
        err = np.abs(f - want)
        best = np.flatnonzero(err <= err.min() + 1e-12)
        return float(1.0 / u[best[np.argmin(np.abs(u[best] - up))]])

    rng = np.random.default_rng(7)
    ratios = np.array([1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3])
    rows, wants, prefers = [], [], []
    for _ in range(3000):
        f = np.round(rng.uniform(100.0, 140.0, ratios.size), int(rng.integers(0, 3)))  # ties and plateaus
        if rng.random() < 0.3:
            f = np.sort(f)
        rows.append(f)
        wants.append(float(rng.choice(f)) if rng.random() < 0.3 else float(rng.uniform(90.0, 150.0)))
        prefers.append(float(rng.uniform(0.2, 1.1)))
    got = solve_piecewise(ratios, np.array(rows), np.array(wants), np.array(prefers))
    assert got.shape == (3000,)
    for f, want, prefer, g in zip(rows, wants, prefers, got):
        ref = by_arrays(ratios, f, want, prefer)
        assert g == ref, (f.tolist(), want, prefer, g, ref)


def test_interp_u_equals_np_interp_to_the_bit():
    """The batch interpolation of the on-board logic against np.interp in 1/r run by run, at random
    ratios, at every grid ratio exactly, outside the grid and on infinite values; with one row for
    every run and with a row per run."""
    from planner.tables.piecewise import interp_u

    rng = np.random.default_rng(11)
    ratios = np.array([1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3])
    u = 1.0 / ratios
    rs = np.concatenate([rng.uniform(0.25, 1.05, 4000), ratios, [0.1, 2.0]])
    for k in range(60):
        vals = rng.uniform(50.0, 300.0, ratios.size)
        if k % 3 == 0:
            vals[rng.integers(0, ratios.size, 2)] = np.inf  # a stalled entry
        shared = interp_u(ratios, vals, rs)
        per_run = interp_u(ratios, np.tile(vals, (rs.size, 1)), rs)
        for r, got, got_row in zip(rs, shared, per_run):
            ref = float(np.interp(1.0 / min(max(r, ratios[-1]), ratios[0]), u, vals))
            assert got == ref or (np.isnan(got) and np.isnan(ref)), (vals.tolist(), r, got, ref)
            assert got_row == got or (np.isnan(got) and np.isnan(got_row))
