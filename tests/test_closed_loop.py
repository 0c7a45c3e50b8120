"""Closed loop: the on-board choice driving the simulator, error bounds, feasibility, datasets, CLI."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from planner.line import testing
from planner.cli import app
from planner.tables.closed_loop import closed_loop_interstation, designated_times, overall
from planner.datasets.closed_loop import run_closed_loop, write_closed_loop
from planner.io.parquet import read_dataset
from planner.errors import InputError
from planner.line.model import Beacon
from planner.datasets.tables import load_tables
from planner.tables.build import build_tables
from planner.datasets.tables import write_tables

from linedb import write_line_db

VMAX = 100 / 3.6
L = 3000.0
INTEGRATION_TOL_S = 0.05
"""docs/design.md §2 accuracy of a simulated running time against its closed form."""


def flat_line():
    """Flat, no resistance, 1 m/s² traction (300 kN / 300 t, 400 t at full load), 1 m/s² brakes."""
    ln = testing.line(length_m=L)
    b = (Beacon("B1", 1000.0, "down", "signal", "a", True), Beacon("B2", 2200.0, "down", "signal", "b", True))
    return dataclasses.replace(ln, beacons=b)


@pytest.fixture(scope="module")
def flat(tmp_path_factory):
    ln = flat_line()
    d = tmp_path_factory.mktemp("tables")
    write_tables(build_tables(ln, n_jobs=1), d)
    return ln, d, load_tables(d, "test", "down", "T")[("S0", "S1")]


def test_designated_sweep(flat):
    _, _, tabs = flat
    d = designated_times(tabs)
    assert d[0] == math.ceil(VMAX + L / VMAX) and d[-1] == d[0] + 60 and np.all(np.diff(d) == 1.0)


def test_nearest_error_bounded_by_half_the_gap_at_the_last_point(flat):
    """Nominal runs are exactly what the tables predict, so the nearest rule's final error is the
    distance from the remaining time at the last point to the nearest entry of that row: never
    more than half the largest gap between neighbouring entries of any row there."""
    ln, _, tabs = flat
    r = closed_loop_interstation(ln, "T", tabs, mode="nearest")
    last = tabs.remaining_s[-1]
    bound = 0.5 * np.max(np.diff(last, axis=1)) + INTEGRATION_TOL_S
    assert np.all(np.abs(r.error_s) <= bound)
    assert set(np.unique(r.ratios)) <= set(tabs.ratios)  # grid ratios only
    assert r.feasible.all()


def test_interpolate_hits_the_designated_time(flat):
    """Flat line: a fractional ratio r gives T = v + L/v exactly (v = r VMAX), which is affine in
    1/r plus v: interpolation in 1/r between 5 % grid points is close, and the re-evaluation at
    the beacons removes most of the rest."""
    ln, _, tabs = flat
    r = closed_loop_interstation(ln, "T", tabs, mode="interpolate")
    assert np.max(np.abs(r.error_s)) < 0.3
    assert np.median(np.abs(r.error_s)) < 0.1


def test_perturbed_infeasible_runs_are_physics_not_controller(flat):
    """Full load (+1/3 mass) and traction x 0.9: acceleration 0.675 m/s², brakes unchanged. The
    scenario minimum has a closed form; designated times below it are flagged infeasible and the
    logic then runs at (nearly) full ratio, so it arrives close to that minimum."""
    ln, _, tabs = flat
    r = closed_loop_interstation(ln, "T", tabs, mode="interpolate", scenario="perturbed")
    a, v = 0.9 * 300e3 / 400e3, VMAX
    t_min = v / a + (L - v**2 / (2 * a) - v**2 / 2) / v + v  # accelerate, cruise, stop at 1 m/s²
    assert r.min_time_s == pytest.approx(t_min, abs=INTEGRATION_TOL_S)
    inf = ~r.feasible
    assert inf.any() and r.feasible.any()
    np.testing.assert_array_equal(inf, r.designated_s < r.min_time_s)
    assert np.all(r.actual_s >= r.min_time_s - INTEGRATION_TOL_S)
    assert np.max(r.actual_s[inf] - r.min_time_s) < 3.0


def test_adaptive_learns_the_perturbed_train(flat):
    """Tables for the empty train, run full and weak: plain interpolation trusts the tables and
    arrives late; the adaptive mode learns the difference from the legs already run (table (c))."""
    ln, _, tabs = flat
    assert tabs.ref_remaining_s is not None
    plain = closed_loop_interstation(ln, "T", tabs, mode="interpolate", scenario="perturbed")
    adapt = closed_loop_interstation(ln, "T", tabs, mode="adaptive", scenario="perturbed")
    f = adapt.feasible
    assert np.max(np.abs(adapt.error_s[f])) < 0.3
    assert np.max(np.abs(adapt.error_s[f])) < np.max(np.abs(plain.error_s[f]))
    nominal = closed_loop_interstation(ln, "T", tabs, mode="adaptive")
    assert np.max(np.abs(nominal.error_s)) < 0.3


def test_datasets_and_summary_recomputed_from_rows(flat, tmp_path):
    ln, d, _ = flat
    res = run_closed_loop(ln, d, scenario="perturbed", mode="nearest", n_jobs=1)
    write_closed_loop(res, tmp_path)
    runs = read_dataset(tmp_path, "closed_loop", direction="down").to_pandas()
    assert (tmp_path / "closed_loop" / "line=test" / "direction=down" / "train_type=T" / "scenario=perturbed"
            / "mode=nearest" / "part-0.parquet").exists()
    g = runs[(runs.origin == "S0")]
    assert len(g) == 61
    np.testing.assert_allclose(g.error_s, g.actual_s - g.designated_s)
    assert all(len(x) == 4 for x in g.ratios) and list(g.eval_point_ids.iloc[0]) == ["dep", "dep+200", "B1", "B2"]
    summ = read_dataset(tmp_path, "closed_loop_summary", direction="down").to_pandas().iloc[0]
    feas = g[g.feasible]
    assert summ.n_feasible == len(feas)
    assert summ.median_abs_error_s == pytest.approx(np.median(np.abs(feas.error_s)))
    assert summ.p95_abs_error_s == pytest.approx(np.percentile(np.abs(feas.error_s), 95))
    assert summ.max_abs_error_s == pytest.approx(np.abs(feas.error_s).max())
    o = overall([x for x in res if x.direction == "down"])
    assert o["max_abs_error_s"] == pytest.approx(summ.max_abs_error_s)
    # no stop-error columns: every run of the sweep stands exactly on the marker (the stopping curve is in
    # the ceiling), so such a column would be 0.0 in every row and say nothing
    assert all(np.all(x.stop_error_m == 0.0) for x in res)
    assert "stop_error_m" not in runs.columns and "max_abs_stop_error_m" not in summ.index


def test_unknown_mode_and_scenario(flat):
    ln, d, tabs = flat
    with pytest.raises(InputError, match="--mode"):
        closed_loop_interstation(ln, "T", tabs, mode="psychic")
    with pytest.raises(InputError, match="--scenario"):
        run_closed_loop(ln, d, scenario="stormy")


def test_cli_tables_and_simulate(tmp_path):
    line_dir = write_line_db(tmp_path / "tiny")
    runner = CliRunner()
    out = tmp_path / "tables"
    r = runner.invoke(app, ["tables", str(line_dir), "--out", str(out), "--train-type", "EMU10",
                            "--ratios", "1.0:0.6:0.1", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert "tables for 4 interstation" in r.output
    assert (out / "table_b" / "line=tiny" / "direction=up" / "train_type=EMU10" / "part-0.parquet").exists()
    sim = tmp_path / "sim"
    r = runner.invoke(app, ["simulate", str(line_dir), "--tables", str(out), "--out", str(sim),
                            "--train-type", "EMU10", "--mode", "interpolate", "--extra", "10", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert "median" in r.output and (sim / "closed_loop_summary").is_dir()
    # bad input: one line, no traceback, non-zero exit
    r = runner.invoke(app, ["tables", str(line_dir), "--out", str(out), "--ratios", "1.0:0.7", "--jobs", "1"])
    assert r.exit_code != 0 and "error: --ratios" in r.output and "Traceback" not in r.output
    r = runner.invoke(app, ["simulate", str(line_dir), "--tables", str(tmp_path / "none"), "--out", str(sim)])
    assert r.exit_code != 0 and "error:" in r.output


def test_one_batch_of_every_scenario_and_mode_equals_separate_batches(flat):
    """Runs in a batch do not interact, so stacking scenarios × modes (how the nightly job runs them,
    several times cheaper) must give exactly the separate results: same times, same ratio choices."""
    from planner.tables.closed_loop import closed_loop_batch

    ln, _, tabs = flat
    modes = ("nearest", "interpolate", "adaptive")
    stacked = closed_loop_batch(ln, "T", tabs, scenarios=("nominal", "perturbed"), modes=modes)
    assert [(r.scenario, r.mode) for r in stacked] == [(s, m) for s in ("nominal", "perturbed") for m in modes]
    for r in stacked:
        alone = closed_loop_interstation(ln, "T", tabs, scenario=r.scenario, mode=r.mode)
        np.testing.assert_array_equal(r.actual_s, alone.actual_s)
        np.testing.assert_array_equal(r.ratios, alone.ratios)
        assert (r.min_time_s, r.max_time_s) == (alone.min_time_s, alone.max_time_s)


def test_timekeeping_is_a_closed_loop_mode(flat):
    """Issue 14: `mode="timekeeping"` runs the sweep through the one integrator; the on-board logic has the
    nominal model, the plant is perturbed; arrival within 0.5 s wherever the plant can make it, and the
    stop error is where the plant stood."""
    ln, _, tabs = flat
    r = closed_loop_interstation(ln, "T", tabs, scenario="perturbed", mode="timekeeping", step_s=5.0)
    assert r.mode == "timekeeping" and np.isnan(r.ratios).all()
    f = r.feasible
    assert r.max_time_s == np.inf  # no ratio grid: any designated time above the minimum can be met
    assert f.sum() >= 10 and np.array_equal(f, r.designated_s >= r.min_time_s - 1e-6)
    assert np.abs(r.error_s[f]).max() <= 0.5
    assert r.stop_error_m.shape == r.actual_s.shape and np.abs(r.stop_error_m).max() <= 0.2
    # infeasible designated times: it ran flat out, so it arrives at the plant's minimum
    if (~f).any():
        assert np.abs(r.actual_s[~f] - r.min_time_s).max() <= 0.5


def test_stop_position_is_measured_from_the_plant(flat):
    """BatchResult.stop_m: a run forced to stand at the marker from above the stopping curve overran
    by v²/(2 β) − Δs (closed form); a run on the curve stands on the marker."""
    from planner.physics.run_curve import RunState, simulate
    from planner.physics.track import make_track

    ln, _, _ = flat
    train = ln.train_type("T")
    tr = make_track(ln, "T", "S0", "S1")
    k = len(tr.s_m) - 2
    ds = tr.s_m[-1] - tr.s_m[-2]
    v = np.array([10.0, 0.5 * np.sqrt(2 * train.stop_brake_ms2 * ds)])
    st = RunState(np.full(2, tr.s_m[k]), np.zeros(2), v, np.full(2, 3, dtype=np.int8), np.ones(2))
    res = simulate(tr, train, 1.0, start=st)
    assert res.stop_m[0] == pytest.approx(tr.length_m + 100.0 / (2 * train.stop_brake_ms2) - ds)
    assert res.stop_m[1] == tr.length_m
    assert simulate(tr, train, 0.8).stop_m[0] == tr.length_m
