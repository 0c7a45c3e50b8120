"""Evaluation points on legs without beacons (issue 33): a fill interval from the train's speed, and a
flag where the closed loop still misses the arrival.

A leg with no beacon evaluation point used to get nothing after ``dep+200``: the nearest rule then
runs the whole leg at the ratio it chose at departure, and misses the designated time by up to half
the gap between neighbouring ratios' running times. On the 25 km flat leg below at 130 km/h that
gap is large: the cruise alone takes L / (r v) and between ratios 0.75 and 0.7 that is
25,000 / 36.1 · (1/0.7 − 1/0.75) ≈ 66 s, so designated times between them are missed by up to
≈ 33 s, far above the 10 s threshold. With a point every 30 s of running, the last decision
is at most 30 s of running before the stop and the error shrinks below the threshold.
"""
from __future__ import annotations

import numpy as np
import pytest

from planner.errors import InputError, JobError
from planner.job.config import load_job
from planner.line import testing
from planner.tables.build import interstation_tables
from planner.tables.eval_points import (
    DEFAULT_AUTO_S,
    MIN_INTERVAL_M,
    auto_interval_m,
    evaluation_points,
    train_evaluation_points,
)
from planner.tables.ratios import ratio_grid

VMAX_KMH = 130.0
LENGTH_M = 25_000.0


def _long_line():
    emu = testing.train_type("EMU", max_speed_kmh=VMAX_KMH, max_accel_kmh_s=3.0, davis_a_kN=5.0,
                             davis_b_kN_per_kmh=0.036, davis_c_kN_per_kmh2=0.0036, empty_mass_t=320.0,
                             full_load_mass_t=150.0, traction=((0.0, 300.0), (40.0, 300.0), (130.0, 90.0)))
    return testing.line(length_m=LENGTH_M, max_speed_kmh=VMAX_KMH, train_types=[emu], line_id="long")


def test_auto_interval_is_the_distance_run_in_the_seconds_rounded():
    assert auto_interval_m(VMAX_KMH / 3.6, 30.0) == 1080.0  # 36.11 m/s × 30 s = 1083 m → 1080
    assert auto_interval_m(0.5, 30.0) == MIN_INTERVAL_M  # never finer than the odometer's floor
    assert auto_interval_m(30.0, None) is None and auto_interval_m(30.0, 0) is None
    with pytest.raises(InputError, match="--eval-auto"):
        auto_interval_m(30.0, -5.0)


def test_fill_applies_only_where_a_leg_has_no_beacon_and_no_interval():
    line = _long_line()
    pts = train_evaluation_points(line, "EMU", "S0", "S1", auto_s=30.0)
    s = [p.s_m for p in pts]
    # dep, dep+200, then 200 + 1080 k short of the stop: (25,000 − 200) / 1080 = 22.96 → 22 points
    assert s[:2] == [0.0, 200.0] and len(s) == 2 + 22
    np.testing.assert_allclose(np.diff(s[1:]), 1080.0)
    assert all(p.kind == "interval" for p in pts[2:]) and pts[-1].eval_point_id == "dep+23960"
    # an explicit interval wins; no auto seconds leaves the leg as before
    assert [p.s_m for p in train_evaluation_points(line, "EMU", "S0", "S1", interval_m=5000.0, auto_s=30.0)] == \
        [0.0, 200.0, 5200.0, 10200.0, 15200.0, 20200.0]
    assert [p.eval_point_id for p in train_evaluation_points(line, "EMU", "S0", "S1")] == ["dep", "dep+200"]


def test_a_leg_with_beacons_keeps_exactly_its_beacons(sample_line):
    for d in ("down", "up"):
        for a, b in sample_line.interstations(d):
            for tt in sample_line.train_types:
                got = train_evaluation_points(sample_line, tt.train_type, a.station_id, b.station_id, auto_s=30.0)
                assert got == evaluation_points(sample_line, a.station_id, b.station_id)


def test_job_and_cli_defaults_are_the_same_and_checked(tmp_path):
    import inspect

    from planner.cli.tables import tables

    (tmp_path / "lines" / "x").mkdir(parents=True)
    (tmp_path / "jobs").mkdir()
    job = tmp_path / "jobs" / "j.toml"
    job.write_text('[job]\nlines = ["lines/x"]\n')
    assert load_job(job).tables.eval_auto_s == DEFAULT_AUTO_S
    assert load_job(job).margins.arrival_error_threshold_s == 10.0
    assert inspect.signature(tables).parameters["eval_auto_s"].default.default == DEFAULT_AUTO_S
    for bad, key in (("[tables]\neval_auto_s = -1", "eval_auto_s"),
                     ("[margins]\narrival_error_threshold_s = -1", "arrival_error_threshold_s")):
        job.write_text('[job]\nlines = ["lines/x"]\n' + bad + "\n")
        with pytest.raises(JobError, match=rf"\] {key}"):
            load_job(job)


@pytest.fixture(scope="module")
def before_after(tmp_path_factory):
    """The closed loop and the margins of the long leg without and with the fill interval."""
    from planner.datasets.closed_loop import write_closed_loop
    from planner.report.margins import compute_margins
    from planner.tables.closed_loop import closed_loop_batch

    line = _long_line()
    grid = [float(x) for x in ratio_grid("1.0:0.7:0.1,0.7:floor:0.05", line_max_speed_ms=line.max_speed_ms)]
    out = {}
    for name, auto in (("before", None), ("after", 30.0)):
        tab = interstation_tables(line, "EMU", "S0", "S1", grid, eval_auto_s=auto)
        res = closed_loop_batch(line, "EMU", tab.onboard(), scenarios=["nominal", "perturbed"], modes=["nearest"])
        d = tmp_path_factory.mktemp(name)
        write_closed_loop(res, d)
        rep = compute_margins(line, train_types=["EMU"], ratios=grid, closed_loop_dir=d, eval_auto_s=auto,
                              conflicts=False)
        out[name] = (res, rep.rows[(rep.rows.direction == "down")].iloc[0], rep.totals)
    return out


def test_without_points_the_long_leg_misses_and_is_flagged(before_after):
    res, row, totals = before_after["before"]
    worst = max(float(np.max(np.abs(r.error_s[r.feasible]))) for r in res)
    assert worst > 20.0  # module doc: up to ≈ 33 s
    assert row.closed_loop_max_error_s == pytest.approx(worst) and bool(row.inaccurate)
    # the line's one train runs the leg: its totals count the flagged run
    assert totals.set_index("level").loc["train", "n_inaccurate"] == 1


def test_with_the_fill_interval_it_keeps_the_time_and_is_not_flagged(before_after):
    res, row, totals = before_after["after"]
    worst = max(float(np.max(np.abs(r.error_s[r.feasible]))) for r in res)
    assert worst < 10.0
    assert row.closed_loop_max_error_s == pytest.approx(worst) and not bool(row.inaccurate)
    assert totals.set_index("level").loc["train", "n_inaccurate"] == 0
