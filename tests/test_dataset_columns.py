"""The stops dataset's columns, built in Arrow, against the same rows built one by one in Python.

``planner.datasets.stops.datasets`` repeats the values a pattern's rows share with ``take``; the writer's
Parquet bytes depend on that table being the same as the straightforward row-by-row table (types, values
to the bit, nulls, NaN), which the reference builds.
"""
from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
import pytest

from planner.datasets import stops as dstops
from planner.line.units import kmh, kmh_s
from planner.stopping.pattern import solve_stop
from planner.stopping.result import StopPattern
from planner.stopping.sweep import ApproachResult


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
