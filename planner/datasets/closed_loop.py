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
    """``closed_loop`` and ``closed_loop_summary`` rows with partition columns, in result order.

    The columns are those Arrow infers from the rows' Python values (``closed_loop`` has no columns at
    all when no result has a run); the writer conforms them to the declared schemas.
    """
    summ: dict[str, list] = {}
    for r in results:
        row = summary_row(r)
        if not math.isfinite(row["flag_position_m"]):  # no place: null, not NaN
            row["flag_position_m"] = None
        for k, v in (_partition(r) | row).items():
            summ.setdefault(k, []).append(v)
    return {"closed_loop": _runs([r for r in results if r.designated_s.size]),
            "closed_loop_summary": pa.table(summ)}


def _partition(r: ClosedLoopResult) -> dict:
    return {"line": r.line_id, "direction": r.direction, "train_type": r.train_type,
            "scenario": r.scenario, "mode": r.mode}


def _runs(results: Sequence[ClosedLoopResult]) -> pa.Table:
    """The ``closed_loop`` rows of ``results`` (each with at least one run), built in Arrow.

    Equal to the table of the rows' Python values (``pa.table`` of lists, one value per run), which
    took most of the step's time in the job's process: a value the rows of a result share is
    typed as Arrow infers it from one value per result and repeated by ``take`` (inference looks
    at which values occur, not how often), the run columns are the results' arrays concatenated,
    and the ratios one list per run over the concatenated rows.
    """
    if not results:
        return pa.table({})
    n = np.array([r.designated_s.size for r in results], dtype=np.int64)
    of_row = np.repeat(np.arange(n.size), n)  # the result each row comes from

    def shared(values: list) -> pa.Array:
        return pa.array(values).take(of_row)

    def runs(name: str, dtype=float) -> np.ndarray:
        return np.concatenate([np.asarray(getattr(r, name), dtype) for r in results])

    ratios = [np.asarray(r.ratios, float).reshape(k, -1) for r, k in zip(results, n)]
    width = np.repeat([a.shape[1] for a in ratios], n)  # each run's number of ratios
    offsets = np.zeros(width.size + 1, dtype=np.int32)
    np.cumsum(width, out=offsets[1:])
    values = np.concatenate([a.ravel() for a in ratios])
    parts = [_partition(r) for r in results]
    cols = {k: shared([p[k] for p in parts]) for k in PARTITION_COLS}
    cols |= {"origin": shared([r.origin for r in results]),
             "destination": shared([r.destination for r in results]),
             "designated_s": runs("designated_s"), "actual_s": runs("actual_s"), "error_s": runs("error_s"),
             "feasible": runs("feasible", bool), "min_time_s": shared([r.min_time_s for r in results]),
             "eval_point_ids": shared([list(r.eval_point_ids) for r in results]),
             # no ratio at all: lists of null, as inferred from empty lists
             "ratios": pa.ListArray.from_arrays(offsets, values if values.size else pa.nulls(0))}
    return pa.table(cols)


def write_closed_loop(results: Sequence[ClosedLoopResult] | dict[str, pa.Table], out_dir: str | Path,
                      part: str = "0") -> list[Path]:
    """Write ``closed_loop`` and ``closed_loop_summary`` under ``out_dir`` (atomic per file): of the results,
    or their :func:`datasets` made beforehand (the nightly job's margins read those tables while they are
    written); ``part``: the files' name in each partition folder, ``part-<part>.parquet`` (the nightly job writes a
    line's interstations in parts, :func:`planner.job.steps.partition_keys`)."""
    schemas = {"closed_loop": CLOSED_LOOP_SCHEMA, "closed_loop_summary": CLOSED_LOOP_SUMMARY_SCHEMA}
    written: list[Path] = []
    for name, table in (results if isinstance(results, dict) else datasets(results)).items():
        written += write_partitioned(table, Path(out_dir), name, PARTITION_COLS, schema=schemas[name], part=part)
    return written
