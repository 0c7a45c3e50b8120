"""The station-approach sweep as datasets: ``stop_summary`` (one row per approach and adhesion
level) and ``stop_samples`` (the feasible patterns sampled in time), their schemas and writer.

Takes :class:`~planner.stopping.sweep.ApproachResult` s; gives Arrow tables and Parquet files
partitioned by line, direction and train type. Speeds in km/h (``*_kmh``), every acceleration in m/s² and jerk in m/s³, as the column names say.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
import pyarrow as pa

from planner.io.parquet import by_partition, declare, write_partitioned
from planner.line.units import kmh, kmh_s
from planner.stopping.sweep import DEFAULT_SAMPLE_DT_S, ApproachResult


STOP_SUMMARY_SCHEMA = declare(
    [
        ("station_id", pa.string(), "station of the stop (arrival of the interstation)"),
        ("origin", pa.string(), "departure station of the interstation"),
        ("tasc_beacon_id", pa.string(), "TASC beacon the approach starts at; empty where there is none "
                                        "(approach_m, or where the train must start braking + 10 %)"),
        ("approach_start_m", pa.float64(), "chainage of the approach (pattern) start [m]"),
        ("stop_m", pa.float64(), "chainage of the stop marker [m]"),
        ("approach_length_m", pa.float64(), "distance from the approach start to the stop marker [m]"),
        ("v_start_kmh", pa.float64(), "speed of the minimum-time run (ratio 1.0, load 0) at the approach start [km/h]"),
        ("run_phase", pa.string(), "phase of that run at the approach start (power, hold, coast, brake, stop)"),
        ("jerk_max_ms3", pa.float64(), "jerk limit of the train type [m/s³]"),
        ("comfort_ms2", pa.float64(), "ride-comfort limit on the braking of a stop of the train type "
                                      "(rolling_stock brake_comfort_kmh_s) [m/s²]"),
        ("adhesion_ms2", pa.float64(), "adhesion-limited braking deceleration of this sweep level [m/s²] "
                                       "(the job's [stops] adhesion_kmh_s level, in SI)"),
        ("adhesion_kmh_s", pa.float64(), "the same level in km/h/s, as the job writes it (rounded to 1e-9, so "
                                         "`adhesion_kmh_s = 2.5` finds the job's 2.5 level)"),
        ("feasible", pa.bool_(), "true when a pattern meeting every limit exists"),
        ("reason", pa.string(), "why there is no pattern (empty when feasible)"),
        ("duration_s", pa.float64(), "pattern duration from the approach start to standstill at the marker [s]"),
        ("brake_start_m", pa.float64(), "chainage where deceleration first begins [m] (null when infeasible)"),
        ("brake_start_distance_m", pa.float64(),
         "distance from the brake start to the stop marker [m]; when infeasible, the distance the limits "
         "would need (longer than the approach), null if unknown"),
        ("time_lost_s", pa.float64(),
         "duration minus the shortest feasible duration of the approach's sweep (the best adhesion) [s]"),
    ],
    name="stop_summary",
    description="Minimum-time jerk-limited stopping patterns: one row per station approach and adhesion level "
                "(docs/design.md §5).",
)


STOP_SAMPLES_SCHEMA = declare(
    [
        ("station_id", pa.string(), "station of the stop"),
        ("adhesion_ms2", pa.float64(), "adhesion level of the pattern [m/s²]"),
        ("adhesion_kmh_s", pa.float64(), "the same level in km/h/s, as the job writes it (see stop_summary)"),
        ("t_s", pa.float64(), "time from the approach start [s]"),
        ("position_m", pa.float64(), "chainage of the train front [m]"),
        ("distance_to_stop_m", pa.float64(), "distance from the front to the stop marker [m]"),
        ("speed_kmh", pa.float64(), "speed [km/h]"),
        ("accel_ms2", pa.float64(), "acceleration [m/s²], negative when braking"),
        ("jerk_ms3", pa.float64(), "jerk of the constant-jerk piece the sample lies in [m/s³]"),
    ],
    name="stop_samples",
    description="Feasible stopping patterns sampled in time (exact values of the cubic pieces) (docs/design.md §5).",
)
SCHEMAS = {"stop_summary": STOP_SUMMARY_SCHEMA, "stop_samples": STOP_SAMPLES_SCHEMA}
SORT_BY = {"stop_summary": ("station_id", "adhesion_ms2"), "stop_samples": ("station_id", "adhesion_ms2", "t_s")}


def _nan_to_none(x: float):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else x


def pattern_samples(r: ApproachResult, p, dt_s: float = DEFAULT_SAMPLE_DT_S) -> dict[str, np.ndarray]:
    """A feasible pattern ``p`` of approach ``r`` sampled every ``dt_s``: the sampled columns of its
    ``stop_samples`` rows (time, chainage, distance to the stop, speed [km/h], acceleration, jerk), in time order."""
    s = p.sample(dt_s)
    return {"t_s": s.t_s, "position_m": r.chainage_m(s.x_m), "distance_to_stop_m": r.approach_length_m - s.x_m,
            "speed_kmh": kmh(s.v_ms), "accel_ms2": s.a_ms2, "jerk_ms3": s.j_ms3}


def extreme_patterns(r: ApproachResult, dt_s: float = DEFAULT_SAMPLE_DT_S) -> dict | None:
    """The samples of approach ``r``'s feasible patterns at its lowest and highest adhesion level (the level in
    km/h/s to 6 decimals, as the charts name it): ``{level: (position_m, speed_kmh)}``, lowest first (one entry
    when they are the same level); None without a feasible pattern. Its ``stop_samples`` rows of those levels,
    in the dataset's order (:data:`SORT_BY`: a level's rows by adhesion, then time). What a leg's speed–distance
    chart draws at its arrival."""
    from planner.line.units import KMH_S

    levels: dict = {}
    for a, p in zip(r.adhesion_ms2, r.patterns):
        if p.feasible:
            levels.setdefault(np.float64(np.round(float(a) / KMH_S, 6)), []).append((float(a), p))
    if not levels:
        return None
    out = {}
    for level in (min(levels), max(levels)):
        got = [(a, pattern_samples(r, p, dt_s)) for a, p in levels[level]]
        t = np.concatenate([g["t_s"] for _a, g in got])
        a = np.concatenate([np.full(g["t_s"].size, a) for a, g in got])
        order = np.lexsort((t, a))  # as the dataset sorts its rows (SORT_BY): by adhesion, then time
        out[level] = tuple(np.concatenate([g[c] for _a, g in got]).astype(float)[order]
                           for c in ("position_m", "speed_kmh"))
    return out


def datasets(results: Sequence[ApproachResult], *, dt_s: float = DEFAULT_SAMPLE_DT_S) -> dict[str, pa.Table]:
    """The ``stop_summary`` and ``stop_samples`` rows (with partition columns line/direction/train_type).

    Parameters
    ----------
    results : sequence of ApproachResult
    dt_s : float
        Sampling step of the patterns [s].
    """
    summ: dict[str, list] = {k: [] for k in ("line", "direction", "train_type", *STOP_SUMMARY_SCHEMA.names)}
    # the samples' columns a pattern's rows share, one value per sampled pattern (repeated in Arrow below),
    # and the sampled ones, one array per pattern
    shared: dict[str, list] = {k: [] for k in ("line", "direction", "train_type", "station_id", "adhesion_ms2",
                                               "adhesion_kmh_s")}
    sampled: dict[str, list] = {k: [] for k in ("t_s", "position_m", "distance_to_stop_m", "speed_kmh",
                                                "accel_ms2", "jerk_ms3")}
    n_rows: list[int] = []
    for r in results:
        lost = r.time_lost_s
        for a, p, tl in zip(r.adhesion_ms2, r.patterns, lost):
            row = {
                "line": r.line_id, "direction": r.direction, "train_type": r.train_type,
                "station_id": r.station_id, "origin": r.origin, "tasc_beacon_id": r.tasc_beacon_id,
                "approach_start_m": r.approach_start_m, "stop_m": r.stop_m,
                "approach_length_m": r.approach_length_m,
                "v_start_kmh": _nan_to_none(kmh(r.v_start_ms)), "run_phase": r.run_phase,
                "jerk_max_ms3": r.jerk_max_ms3, "comfort_ms2": r.comfort_ms2,
                "adhesion_ms2": a, "adhesion_kmh_s": kmh_s(a), "feasible": p.feasible, "reason": p.reason,
                "duration_s": _nan_to_none(p.duration_s),
                "brake_start_m": float(r.chainage_m(p.brake_start_m)) if p.feasible else None,
                "brake_start_distance_m": _nan_to_none(p.braking_distance_m),
                "time_lost_s": _nan_to_none(tl),
            }
            for k, v in row.items():
                summ[k].append(v)
            if not p.feasible:
                continue
            got = pattern_samples(r, p, dt_s)
            n_rows.append(got["t_s"].size)
            for k in shared:
                shared[k].append(row[k])
            for k, v in got.items():
                sampled[k].append(v)
    # a shared value is converted once per pattern and repeated by take (the samples' strings as Python
    # lists, one item per row, were most of this function's time): the same column as converting every
    # row's copy, nulls included
    of_row = np.repeat(np.arange(len(n_rows)), np.asarray(n_rows, dtype=np.int64))  # pattern of each row
    samp = {k: pa.array(v, type=_type(k, STOP_SAMPLES_SCHEMA)).take(of_row) for k, v in shared.items()}
    samp |= {k: pa.array(np.concatenate(v) if v else np.zeros(0), type=_type(k, STOP_SAMPLES_SCHEMA))
             for k, v in sampled.items()}
    summary = pa.table({k: pa.array(v, type=_type(k, STOP_SUMMARY_SCHEMA)) for k, v in summ.items()})
    return {"stop_summary": summary, "stop_samples": pa.table(samp)}


def _type(name: str, schema: pa.Schema) -> pa.DataType:
    return schema.field(name).type if name in schema.names else pa.string()


def write_stops(results: Sequence[ApproachResult], out_dir: str | Path, part: str = "0", *,
                dt_s: float = DEFAULT_SAMPLE_DT_S) -> list[Path]:
    """Write ``stop_summary`` and ``stop_samples`` under ``out_dir`` (atomic per file, deterministic); ``part``:
    the files' name in each partition folder, ``part-<part>.parquet`` (the nightly job writes a line's
    interstations in parts, :func:`planner.job.steps.partition_keys`).

    Returns
    -------
    list of Path
        Files written.
    """
    written: list[Path] = []
    for group in by_partition(results):  # one partition's rows in memory at a time
        for name, table in datasets(group, dt_s=dt_s).items():
            written += write_partitioned(table, Path(out_dir), name, schema=SCHEMAS[name], sort_by=SORT_BY[name],
                                         part=part)
    return written
