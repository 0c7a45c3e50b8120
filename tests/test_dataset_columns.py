"""The stops and closed-loop datasets' columns, built in Arrow, against the same rows built one by one in Python.

``planner.datasets.stops.datasets`` and ``planner.datasets.closed_loop.datasets`` repeat the values a
pattern's or a result's rows share with ``take``, concatenate the runs' arrays and build the list columns
from offsets; the writers' Parquet bytes depend on those tables being the same as the straightforward
row-by-row tables (types, values to the bit, nulls, NaN), which these references build.
"""
from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest

from planner.datasets import closed_loop as dcl
from planner.datasets import stops as dstops
from planner.line.units import kmh, kmh_s
from planner.stopping.pattern import solve_stop
from planner.stopping.result import StopPattern
from planner.stopping.sweep import ApproachResult
from planner.tables.closed_loop import ClosedLoopResult, summary_row
from planner.tables.flags import LegFlag


def _same(got: pa.Table, want: pa.Table) -> None:
    """Same schema and the same values to the bit (repr: NaN, -0.0 and None told apart)."""
    assert got.schema.equals(want.schema, check_metadata=True), (got.schema, want.schema)
    assert got.num_rows == want.num_rows
    for c in want.column_names:
        assert repr(got[c].to_pylist()) == repr(want[c].to_pylist()), c
        assert got[c].null_count == want[c].null_count, c


# --- stops -------------------------------------------------------------------------------------------


def _stops_by_row(results, dt_s):
    """The samples one Python dict per row (what the columns must equal)."""
    rows = []
    for r in results:
        for a, p in zip(r.adhesion_ms2, r.patterns):
            if not p.feasible:
                continue
            s = p.sample(dt_s)
            pos, dist, v = r.chainage_m(s.x_m), r.approach_length_m - s.x_m, kmh(s.v_ms)
            for i in range(s.t_s.size):
                rows.append({"line": r.line_id, "direction": r.direction, "train_type": r.train_type,
                             "station_id": r.station_id, "adhesion_ms2": a, "adhesion_kmh_s": kmh_s(a),
                             "t_s": float(s.t_s[i]), "position_m": float(pos[i]),
                             "distance_to_stop_m": float(dist[i]), "speed_kmh": float(v[i]),
                             "accel_ms2": float(s.a_ms2[i]), "jerk_ms3": float(s.j_ms3[i])})
    names = ("line", "direction", "train_type", *dstops.STOP_SAMPLES_SCHEMA.names)
    return pa.table({k: pa.array([row[k] for row in rows], type=dstops._type(k, dstops.STOP_SAMPLES_SCHEMA))
                     for k in names})


def _approach(direction, station, patterns, *, line="L1", v_start_ms=12.0, start_m=1000.0):
    return ApproachResult(
        line_id=line, train_type="T", direction=direction, origin="A", station_id=station, stop_m=start_m + 300.0,
        approach_start_m=start_m, approach_length_m=300.0, tasc_beacon_id="", v_start_ms=v_start_ms,
        run_phase="coast", jerk_max_ms3=1.0, comfort_ms2=1.0, speed_limits=((0.0, 30.0),),
        gradients_permil=((0.0, 0.0),), adhesion_ms2=tuple(0.6 + 0.1 * i for i in range(len(patterns))),
        decel_limits=tuple(((0.0, 1.0),) for _ in patterns), patterns=tuple(patterns), warnings=())


def _pattern(v, x):
    return solve_stop(v, x, jerk_max=1.0, decel_limits=[(0.0, 0.8)], speed_limits=[(0.0, 30.0)])


NO = StopPattern(feasible=False, reason="needs 400 m", v_start_ms=12.0, x_stop_m=300.0, jerk_max_ms3=1.0,
                 braking_distance_m=400.0)
STANDING = StopPattern(feasible=True, reason="", v_start_ms=0.0, x_stop_m=0.0, jerk_max_ms3=1.0,
                       duration_s=0.0, brake_start_m=0.0, braking_distance_m=0.0,
                       t_s=(0.0,), x_m=(0.0,), v_ms=(0.0,), a_ms2=(0.0,), j_ms3=())


@pytest.mark.parametrize("case", ["mixed", "infeasible_only", "none"])
def test_stop_samples_equal_the_rows_built_one_by_one(case):
    if case == "mixed":
        results = [_approach("down", "S2", [_pattern(12.0, 300.0), NO, _pattern(8.0, 300.0)]),
                   _approach("up", "S1", [STANDING, _pattern(12.0, 290.0)], v_start_ms=math.nan, start_m=900.0),
                   _approach("down", "S3", [])]
    elif case == "infeasible_only":
        results = [_approach("down", "S2", [NO, NO])]
    else:
        results = []
    for dt_s in (0.1, 0.7):
        got = dstops.datasets(results, dt_s=dt_s)
        _same(got["stop_samples"], _stops_by_row(results, dt_s))
        assert got["stop_summary"].num_rows == sum(len(r.patterns) for r in results)
    if case == "mixed":  # the case does what it says: two approaches' samples, one of them a single row
        samples = got["stop_samples"]
        assert samples.num_rows > 20 and set(samples["station_id"].to_pylist()) == {"S1", "S2"}
        assert samples.filter(pa.compute.equal(samples["t_s"], 0.0)).num_rows == 4


# --- closed loop -------------------------------------------------------------------------------------


def _closed_loop_by_row(results):
    """The runs one Python dict per row, types inferred by Arrow (what the columns must equal)."""
    cols: dict[str, list] = {}
    for r in results:
        for i in range(r.designated_s.size):
            row = {"line": r.line_id, "direction": r.direction, "train_type": r.train_type,
                   "scenario": r.scenario, "mode": r.mode, "origin": r.origin, "destination": r.destination,
                   "designated_s": float(r.designated_s[i]), "actual_s": float(r.actual_s[i]),
                   "error_s": float(r.error_s[i]), "feasible": bool(r.feasible[i]), "min_time_s": r.min_time_s,
                   "eval_point_ids": list(r.eval_point_ids),
                   "ratios": [float(x) for x in np.asarray(r.ratios, float).reshape(r.designated_s.size, -1)[i]]}
            for k, v in row.items():
                cols.setdefault(k, []).append(v)
    return pa.table(cols)


def _summary_by_row(results):
    cols: dict[str, list] = {}
    for r in results:
        row = {"line": r.line_id, "direction": r.direction, "train_type": r.train_type, "scenario": r.scenario,
               "mode": r.mode, **summary_row(r)}
        if not math.isfinite(row["flag_position_m"]):
            row["flag_position_m"] = None
        for k, v in row.items():
            cols.setdefault(k, []).append(v)
    return pa.table(cols)


def _loop(designated, actual, ratios, ids, *, mode="nearest", min_time_s=100.0, flags=(), direction="down"):
    d = np.asarray(designated, float)
    return ClosedLoopResult(
        line_id="L1", direction=direction, train_type="T", origin="A", destination="B", scenario="nominal",
        mode=mode, designated_s=d, actual_s=np.asarray(actual, float), ratios=np.asarray(ratios, float),
        eval_point_ids=tuple(ids), min_time_s=min_time_s, max_time_s=200.0,
        stop_error_m=np.zeros(d.size), flags=tuple(flags))


STALL = LegFlag(kind="stall", scenario="perturbed", position_m=1234.5, reason="stalls at 1234.5 m")
NOWHERE = LegFlag(kind="stall", scenario="reference", position_m=math.nan, reason="no table (c)")

CASES = {
    "mixed": [
        _loop([100.0, 101.0, 102.0], [99.5, math.nan, -0.0], [[1.0, 0.9], [0.8, math.nan], [0.7, 0.7]],
              ["dep", "b1"], flags=[STALL]),
        _loop([], [], np.zeros((0, 3)), ["dep", "b1", "b2"]),  # no runs: a summary row only
        _loop([50.0, 51.0], [math.nan, math.nan], [[math.nan] * 3] * 2, ["dep", "o1", "o2"], mode="timekeeping",
              min_time_s=49, flags=[NOWHERE], direction="up"),  # an int minimum beside floats: double
        _loop([10.0], [10.5], [[1.0]], ["dep"], min_time_s=9.0),
    ],
    "int_minimum": [_loop([100.0, 101.0], [101.0, 101.0], [[1.0], [0.9]], ["dep"], min_time_s=100)],
    "no_points": [_loop([100.0], [101.0], np.zeros((1, 0)), [])],  # empty lists: list<null> as inferred
    "no_points_beside_points": [_loop([100.0], [101.0], np.zeros((1, 0)), []),
                                _loop([100.0], [101.0], [[1.0]], ["dep"])],
    "no_runs": [_loop([], [], np.zeros((0, 1)), ["dep"])],  # no columns at all, as from no rows
    "none": [],
}


@pytest.mark.parametrize("case", list(CASES))
def test_closed_loop_columns_equal_the_rows_built_one_by_one(case):
    results = CASES[case]
    got = dcl.datasets(results)
    _same(got["closed_loop"], _closed_loop_by_row(results))
    _same(got["closed_loop_summary"], _summary_by_row(results))
    if case == "mixed":  # the case does what it says
        t = got["closed_loop"]
        assert t.num_rows == 6 and t.schema.field("ratios").type == pa.list_(pa.float64())
        assert t["min_time_s"].type == pa.float64() and t["eval_point_ids"][3].as_py() == ["dep", "o1", "o2"]
    if case == "int_minimum":
        assert got["closed_loop"]["min_time_s"].type == pa.int64()
    if case == "no_points":
        assert got["closed_loop"]["ratios"].type == pa.list_(pa.null())
    if case == "no_runs":
        assert got["closed_loop"].num_columns == 0 and got["closed_loop_summary"].num_rows == 1
