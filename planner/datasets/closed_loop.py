"""The closed loop as datasets: the sweep over a line with the tables read back from disk
(:func:`run_closed_loop`), and the ``closed_loop`` / ``closed_loop_summary`` schemas and writer.

Takes a ``Line`` and a tables folder (or :class:`~planner.tables.closed_loop.ClosedLoopResult` s);
gives results and Parquet files partitioned by line, direction, train type, scenario and mode.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pyarrow as pa

from planner.datasets.tables import load_tables
from planner.errors import InputError
from planner.io.parallel import map_tasks
from planner.io.parquet import declare, write_partitioned
from planner.line.model import DIRECTIONS, Line
from planner.tables.closed_loop import (
    DEFAULT_EXTRA_S,
    DEFAULT_STEP_S,
    ClosedLoopResult,
    _runner,
    closed_loop_interstation,
    get_scenario,
    summary_row,
)


PARTITION_COLS = ("line", "direction", "train_type", "scenario", "mode")
"""Closed-loop datasets add scenario and mode to the usual partitions, so runs of
``planner simulate`` with different options into one folder do not overwrite each other."""


def _task(line, train_type, tables, scenario, mode, extra_s, step_s, settings):
    """joblib worker (module level, picklable inputs)."""
    return closed_loop_interstation(line, train_type, tables, scenario=scenario, mode=mode,
                                    extra_s=extra_s, step_s=step_s, settings=settings)


def run_closed_loop(
    line: Line,
    tables_dir: str | Path,
    *,
    train_types: Sequence[str] | None = None,
    scenario: str = "nominal",
    mode: str = "nearest",
    extra_s: float = DEFAULT_EXTRA_S,
    step_s: float = DEFAULT_STEP_S,
    n_jobs: int = -1,
    settings=None,
    progress: Callable[[int, int], None] | None = None,
    scenario_name: str | None = None,
) -> list[ClosedLoopResult]:
    """Closed loop over every interstation × direction × train type, tables read from Parquet.

    Results come in the fixed order train type, direction, interstation
    (running order), independent of ``n_jobs``. ``scenario_name`` is an alias of ``scenario``.
    """
    scenario = scenario_name or scenario
    get_scenario(scenario)
    _runner(mode)
    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    tasks = []
    for t in types:
        line.train_type(t)
        for d in DIRECTIONS:
            tabs = load_tables(tables_dir, line.line_id, d, t)
            for a, b in line.interstations(d):
                key = (a.station_id, b.station_id)
                if key not in tabs:
                    raise InputError(f"--tables {tables_dir}: no tables for {t} {d} {key[0]}->{key[1]}; "
                                     "rebuild them with `planner tables`")
                tasks.append((t, tabs[key]))
    out = map_tasks(_task, [(line, t, tab, scenario, mode, extra_s, step_s, settings) for t, tab in tasks],
                    n_jobs, progress)
    return out


CLOSED_LOOP_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("designated_s", pa.float64(), "designated running time (scheduled arrival - departure) [s]"),
        ("actual_s", pa.float64(), "simulated running time under the scenario [s]; NaN: the run stalled "
                                   "(see closed_loop_summary flag_reason)"),
        ("error_s", pa.float64(), "arrival error actual - designated [s], positive = late"),
        ("feasible", pa.bool_(), "designated time within the scenario's fastest..slowest running time"),
        ("min_time_s", pa.float64(), "scenario minimum running time (ratio 1.0 throughout) [s]"),
        ("eval_point_ids", pa.list_(pa.string()), "evaluation points in running order ('dep' first)"),
        ("ratios", pa.list_(pa.float64()), "ratio chosen at each evaluation point, same order"),
    ],
    name="closed_loop",
    version=2,
    description="Closed-loop runs of the on-board ratio choice, one row per designated time. It has no stop "
                "error column: the simulated train stops exactly at the marker by construction (the stopping "
                "brake curve is part of the speed ceiling and the last grid step ends on the marker), and the "
                "on-board stopping control (TASC positioning and brake response errors) is not modelled, so it "
                "was 0.0 in every row.",
)


CLOSED_LOOP_SUMMARY_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("n_runs", pa.int32(), "designated times simulated"),
        ("n_feasible", pa.int32(), "runs whose designated time the scenario can meet"),
        ("median_abs_error_s", pa.float64(), "median |arrival error| over feasible runs [s]"),
        ("p95_abs_error_s", pa.float64(), "95th percentile |arrival error| over feasible runs [s]"),
        ("max_abs_error_s", pa.float64(), "maximum |arrival error| over feasible runs [s]"),
        ("min_time_s", pa.float64(), "scenario minimum running time [s]"),
        ("infeasible_excess_max_s", pa.float64(),
         "infeasible runs: worst arrival after the scenario minimum [s] (0 if none)"),
        ("n_stalled", pa.int32(),
         "runs that did not arrive: the train stalled under the scenario, or the mode cannot run on the "
         "leg (adaptive without table (c)); their actual_s is NaN"),
        ("flag_kind", pa.string(), "physical verdict on the leg under this scenario and mode: 'stall', or empty"),
        ("flag_position_m", pa.float64(), "chainage where it happens [m] (the stall), null when none or unknown"),
        ("flag_reason", pa.string(), "what, under which load and traction, where; empty when none"),
    ],
    name="closed_loop_summary",
    version=2,
    description="Arrival error statistics per interstation (no stop error: see closed_loop).",
)


def datasets(results: Sequence[ClosedLoopResult]) -> dict[str, pa.Table]:
    """``closed_loop`` and ``closed_loop_summary`` rows with partition columns, in result order."""
    runs: dict[str, list] = {}
    summ: dict[str, list] = {}

    def add(dst, row):
        for k, v in row.items():
            dst.setdefault(k, []).append(v)

    for r in results:
        part = {"line": r.line_id, "direction": r.direction, "train_type": r.train_type,
                "scenario": r.scenario, "mode": r.mode}
        n = r.designated_s.size
        if n:  # a column at a time (a dict per run was most of the step's time in the job's process), the
            # same Python values as row by row, so Arrow infers the same columns
            cols = {**{k: [v] * n for k, v in part.items()},
                    "origin": [r.origin] * n, "destination": [r.destination] * n,
                    "designated_s": np.asarray(r.designated_s, float).tolist(),
                    "actual_s": np.asarray(r.actual_s, float).tolist(),
                    "error_s": np.asarray(r.error_s, float).tolist(),
                    "feasible": np.asarray(r.feasible, bool).tolist(), "min_time_s": [r.min_time_s] * n,
                    "eval_point_ids": [list(r.eval_point_ids) for _ in range(n)],
                    "ratios": np.asarray(r.ratios, float).reshape(n, -1).tolist()}
            for k, v in cols.items():
                runs.setdefault(k, []).extend(v)
        row = summary_row(r)
        if not math.isfinite(row["flag_position_m"]):  # no place: null, not NaN
            row["flag_position_m"] = None
        add(summ, part | row)
    return {"closed_loop": pa.table(runs), "closed_loop_summary": pa.table(summ)}


def write_closed_loop(results: Sequence[ClosedLoopResult] | dict[str, pa.Table], out_dir: str | Path) -> list[Path]:
    """Write ``closed_loop`` and ``closed_loop_summary`` under ``out_dir`` (atomic per file): of the results,
    or their :func:`datasets` made beforehand (the nightly job's margins read those tables while they are
    written)."""
    schemas = {"closed_loop": CLOSED_LOOP_SCHEMA, "closed_loop_summary": CLOSED_LOOP_SUMMARY_SCHEMA}
    written: list[Path] = []
    for name, table in (results if isinstance(results, dict) else datasets(results)).items():
        written += write_partitioned(table, Path(out_dir), name, PARTITION_COLS, schema=schemas[name])
    return written
