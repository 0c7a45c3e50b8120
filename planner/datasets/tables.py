"""The running-time tables as datasets: schemas of ``eval_points`` and tables (a)–(d), the writer
(one row per table entry, hive-partitioned by line, direction and train type) and the reader the
closed loop, the margins and the bundles use to get :class:`~planner.tables.onboard.RunningTimeTables`
back from disk.

Takes :class:`~planner.tables.build.InterstationTables`; gives Arrow tables and Parquet files (and back).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import pyarrow as pa

from planner.errors import InputError
from planner.io.parquet import by_partition, declare, read_dataset, write_partitioned
from planner.line.units import kmh, ms
from planner.tables.build import REF_LOAD, REF_TRACTION, InterstationTables
from planner.tables.flags import LegFlag
from planner.tables.onboard import ApproachTable, RunningTimeTables


EVAL_POINTS_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id of the interstation"),
        ("destination", pa.string(), "arrival station id of the interstation"),
        ("eval_point_id", pa.string(), "'dep', 'dep+<m>' (odometer point <m> metres after departure) "
                                       "or the beacon_id"),
        ("eval_position_m", pa.float64(), "chainage of the evaluation point [m]"),
        ("eval_distance_m", pa.float64(), "running distance from the departure stop marker [m]"),
        ("eval_point_kind", pa.string(), "'departure', 'after_departure', 'interval' (odometer point at "
                                         "the regular interval) or 'beacon'"),
    ],
    name="eval_points",
    description="Evaluation points per interstation, in running order (docs/design.md §3).",
)


TABLE_A_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("ratio", pa.float64(), "target-speed ratio (target = ratio x on-board maximum speed), 0..1"),
        ("running_time_s", pa.float64(), "running time stop marker to stop marker at constant ratio [s]"),
        ("energy_kwh", pa.float64(), "traction energy at the wheel over the run [kWh]"),
        ("ref_stall_position_m", pa.float64(),
         "chainage where the reference train of table_c (full load, weak traction) stalls at this ratio [m]; "
         "null where it does not. A leg with any stall has no table_c (nor table_d) and is flagged"),
    ],
    name="table_a",
    description="Table (a): running time per ratio, tables at load 0 and nominal traction (docs/design.md §3).",
)


TABLE_B_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("eval_point_id", pa.string(), "evaluation point id (see eval_points)"),
        ("eval_position_m", pa.float64(), "chainage of the evaluation point [m]"),
        ("ratio_before", pa.float64(), "ratio run from departure up to the evaluation point"),
        ("ratio_after", pa.float64(), "ratio run from the evaluation point to arrival"),
        ("remaining_time_s", pa.float64(), "running time from the evaluation point to arrival [s]"),
        ("elapsed_time_s", pa.float64(), "running time from departure to the evaluation point at ratio_before [s]"),
    ],
    name="table_b",
    description="Table (b): remaining running time per evaluation point and ratio pair (docs/design.md §3).",
)


TABLE_C_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("eval_point_id", pa.string(), "evaluation point id (see eval_points)"),
        ("eval_position_m", pa.float64(), "chainage of the evaluation point [m]"),
        ("ratio", pa.float64(), "ratio run from departure to arrival"),
        ("remaining_time_s", pa.float64(), "running time from the point to arrival, table conditions [s]"),
        ("remaining_time_ref_s", pa.float64(),
         "the same for the reference train (load ref_load, traction x ref_traction_factor) [s]"),
        ("ref_load", pa.float64(), "load factor of the reference train"),
        ("ref_traction_factor", pa.float64(), "traction factor of the reference train"),
        ("speed_kmh", pa.float64(), "speed of the table train at the point at constant ratio [km/h]"),
    ],
    name="table_c",
    description="Table (c): remaining time at constant ratio for the table train and a reference "
                "(full-load, weak-traction) train; lets the on-board 'adaptive' mode learn how far the "
                "real train is from the tables.",
)


TABLE_D_SCHEMA = declare(
    [
        ("origin", pa.string(), "departure station id"),
        ("destination", pa.string(), "arrival station id"),
        ("eval_point_id", pa.string(), "the last evaluation point of the interstation (see eval_points)"),
        ("eval_position_m", pa.float64(), "chainage of the evaluation point [m]"),
        ("speed_kmh", pa.float64(), "speed of the train as it passes the point [km/h] (2 km/h grid)"),
        ("powering", pa.bool_(), "the train passes the point out of its coasting band (it powers "
                                 "whenever below its target); false: in its coasting band, coasting down "
                                 "to the band's lower edge first (only sawtooth vehicles have both)"),
        ("ratio_after", pa.float64(), "ratio run from the point to arrival (1 % grid plus table_a's ratios)"),
        ("vmax_kmh", pa.float64(), "on-board maximum speed just after the point [km/h]; the target "
                                   "there is ratio_after x vmax_kmh"),
        ("coast_band_kmh", pa.float64(), "the vehicle's coasting band [km/h] (sawtooth cruise)"),
        ("remaining_time_s", pa.float64(), "running time from the point to arrival, table conditions [s]"),
        ("remaining_time_ref_s", pa.float64(), "the same for the reference train of table_c [s]"),
    ],
    name="table_d",
    description="Table (d): remaining time from the last evaluation point by the train's own state "
                "(speed, powering) and a fine grid of ratios; the 'adaptive' mode's last decision.",
)


_KEY_COLUMNS = ("line", "direction", "train_type", "origin", "destination")
"""The partition and interstation columns, first in every table of :func:`datasets`."""


def _keys(t: InterstationTables) -> tuple[str, ...]:
    """The values of :data:`_KEY_COLUMNS` for the rows of ``t``."""
    return t.line_id, t.direction, t.train_type, t.origin, t.destination


def _null_nan(x: np.ndarray) -> pa.Array:
    """Floats with NaN written as null (an absent value, which equals itself in Arrow)."""
    x = np.asarray(x, float)
    return pa.array(x, mask=~np.isfinite(x))


def _concat(legs: list[tuple[tuple, int, dict]]) -> pa.Table:
    """One table from per-interstation chunks ``(keys, rows, columns)``, one chunk per interstation
    with rows. Each column is converted once per chunk (numpy arrays without a Python object per value:
    on a 10x line the lists of floats were a gigabyte); the key columns once per table, their values
    repeated by Arrow and sliced into the same chunks (Python lists of repeated strings, and an Arrow
    call per chunk, cost most of the conversion)."""
    legs = [leg for leg in legs if leg[1]]
    if not legs:
        return pa.table({})
    n = np.array([rows for _, rows, _ in legs])
    starts = np.cumsum(n) - n
    of_row = np.repeat(np.arange(len(legs)), n)
    out = {}
    for c, name in enumerate(_KEY_COLUMNS):
        whole = pa.array([keys[c] for keys, _, _ in legs]).take(of_row)
        out[name] = pa.chunked_array([whole.slice(a, m) for a, m in zip(starts.tolist(), n.tolist())])
    for name in legs[0][2]:
        out[name] = pa.chunked_array([v if isinstance(v, pa.Array) else pa.array(v)
                                      for v in (cols[name] for _, _, cols in legs)])
    return pa.table(out)


def datasets(results: Sequence[InterstationTables]) -> dict[str, pa.Table]:
    """The ``eval_points`` and ``table_a`` … ``table_d`` rows, with partition columns, in task order."""
    ep, ta, tb, tc, td = [], [], [], [], []
    for t in results:
        keys, n_r, n_x = _keys(t), len(t.ratios), len(t.points)
        ep.append((keys, n_x, {
            "eval_point_id": [p.eval_point_id for p in t.points],
            "eval_position_m": [p.position_m for p in t.points],
            "eval_distance_m": [p.s_m for p in t.points],
            "eval_point_kind": [p.kind for p in t.points],
        }))
        ta.append((keys, n_r, {
            "ratio": t.ratios, "running_time_s": t.time_a_s, "energy_kwh": t.energy_a_kwh,
            "ref_stall_position_m": _null_nan(np.full(n_r, np.nan) if t.ref_stall_m is None else t.ref_stall_m),
        }))
        # each row's point id taken by Arrow from the leg's few, not a Python list of one per row
        ids = pa.array([p.eval_point_id for p in t.points])
        positions = np.array([p.position_m for p in t.points])
        k, i, j = np.indices((n_x, n_r, n_r)).reshape(3, -1)
        tb.append((keys, len(k), {
            "eval_point_id": ids.take(k),
            "eval_position_m": positions[k],
            "ratio_before": t.ratios[i],
            "ratio_after": t.ratios[j],
            "remaining_time_s": t.remaining_s[k, i, j],
            "elapsed_time_s": t.elapsed_s[i, k],
        }))
        if t.ref_remaining_s is not None:
            k, i = np.indices((n_x, n_r)).reshape(2, -1)
            tc.append((keys, len(k), {
                "eval_point_id": ids.take(k),
                "eval_position_m": positions[k],
                "ratio": t.ratios[i],
                "remaining_time_s": t.remaining_s[k, i, i],
                "remaining_time_ref_s": t.ref_remaining_s[k, i],
                "ref_load": pa.repeat(t.ref_load, len(k)),
                "ref_traction_factor": pa.repeat(t.ref_traction_factor, len(k)),
                "speed_kmh": kmh(t.speed_ms[i, k]) if t.speed_ms is not None else np.full(len(k), np.nan),
            }))
        if t.approach is not None:
            ap, last = t.approach, t.points[-1]
            p, v, a = np.indices((len(ap.powering), len(ap.speeds_ms), len(ap.ratios))).reshape(3, -1)
            td.append((keys, len(p), {
                "eval_point_id": pa.repeat(last.eval_point_id, len(p)),
                "eval_position_m": np.full(len(p), last.position_m),
                "speed_kmh": kmh(ap.speeds_ms[v]),
                "powering": np.asarray(ap.powering, bool)[p],
                "ratio_after": ap.ratios[a],
                "vmax_kmh": np.full(len(p), kmh(ap.vmax_ms)),
                "coast_band_kmh": np.full(len(p), kmh(ap.coast_band_ms)),
                "remaining_time_s": ap.time_s[p, v, a],
                "remaining_time_ref_s": ap.ref_time_s[p, v, a],
            }))
    out = {"eval_points": _concat(ep), "table_a": _concat(ta), "table_b": _concat(tb)}
    if tc:
        out["table_c"] = _concat(tc)
    if td:
        out["table_d"] = _concat(td)
    return out


SCHEMAS = {"eval_points": EVAL_POINTS_SCHEMA, "table_a": TABLE_A_SCHEMA, "table_b": TABLE_B_SCHEMA,
           "table_c": TABLE_C_SCHEMA, "table_d": TABLE_D_SCHEMA}


def write_tables(results: Sequence[InterstationTables], out_dir: str | Path) -> list[Path]:
    """Write the datasets under ``out_dir`` (atomic per file, deterministic); return the files."""
    written: list[Path] = []
    for part in by_partition(results):  # one partition's rows in memory at a time
        for name, table in datasets(part).items():
            written += write_partitioned(table, Path(out_dir), name, schema=SCHEMAS[name])
    return written


def load_tables(
    tables_dir: str | Path, line_id: str, direction: str, train_type: str
) -> dict[tuple[str, str], RunningTimeTables]:
    """Read the ``eval_points``, ``table_a`` and ``table_b`` datasets of one line, direction, type.

    Parameters
    ----------
    tables_dir : path
        The ``--out`` folder of ``planner tables`` (holding ``table_a/`` etc.).
    line_id, direction, train_type : str
        Partition to read.

    Returns
    -------
    dict
        ``(origin, destination) -> RunningTimeTables`` in running order.

    Raises
    ------
    InputError
        Missing datasets or partitions, or tables that do not fit together.
    """
    root = Path(tables_dir)
    out = {}
    try:
        ep = read_dataset(root, "eval_points", line=line_id, direction=direction, train_type=train_type).to_pandas()
        ta = read_dataset(root, "table_a", line=line_id, direction=direction, train_type=train_type).to_pandas()
        tb = read_dataset(root, "table_b", line=line_id, direction=direction, train_type=train_type).to_pandas()
    except (FileNotFoundError, OSError) as e:
        raise InputError(f"--tables {root}: cannot read the tables ({e}); run `planner tables` first") from None
    tc = _optional(root, "table_c", line_id, direction, train_type)  # only the adaptive mode needs
    td = _optional(root, "table_d", line_id, direction, train_type)  # tables (c) and (d)
    if ta.empty:
        raise InputError(
            f"--tables {root}: no table_a rows for line={line_id} direction={direction} "
            f"train_type={train_type}; run `planner tables` for it"
        )
    # each dataset split by interstation once (not filtered per interstation), row positions by
    # hash lookup (not a Python dict per value): the margin report reads every table back
    import pandas as pd

    frames = (ep, tb, tc, td)
    by_pair = [_by_pair(f) for f in frames]
    for (o, d), a in ta.groupby(["origin", "destination"], sort=False):
        a = a.sort_values("ratio", ascending=False)
        ratios = a["ratio"].to_numpy(float)
        p, b, c, g = (None if f is None else parts.get((o, d), f.iloc[:0]) for f, parts in zip(frames, by_pair))
        p = p.sort_values("eval_distance_m")
        n_r, n_x = len(ratios), len(p)
        if len(b) != n_x * n_r * n_r:
            raise InputError(
                f"--tables {root}: table_b for {o}->{d} has {len(b)} rows, expected "
                f"{n_x} points x {n_r}^2 ratios; rebuild the tables"
            )
        k = pd.Index(p["eval_point_id"])
        ri = pd.Index(ratios)
        rem = np.full((n_x, n_r, n_r), np.nan)
        at = _positions(root, "table_b", o, d, (k, b["eval_point_id"]), (ri, b["ratio_before"]), (ri, b["ratio_after"]))
        rem[at] = b["remaining_time_s"].to_numpy(float)
        if np.isnan(rem).any():
            raise InputError(f"--tables {root}: table_b for {o}->{d} is incomplete; rebuild the tables")
        ref = spd = None
        if c is not None and len(c) == n_x * n_r:
            at = _positions(root, "table_c", o, d, (k, c["eval_point_id"]), (ri, c["ratio"]))
            ref = np.full((n_x, n_r), np.nan)
            ref[at] = c["remaining_time_ref_s"].to_numpy(float)
            if np.isnan(ref).any():
                ref = None
            if "speed_kmh" in c:
                spd = np.full((n_x, n_r), np.nan)
                spd[at] = ms(c["speed_kmh"].to_numpy(float))
                if np.isnan(spd).any():
                    spd = None
        out[(o, d)] = RunningTimeTables(
            approach=_approach(g, o, d, p["eval_point_id"].iloc[-1], root) if g is not None and n_x > 1 else None,
            origin=o,
            destination=d,
            ratios=ratios,
            time_a_s=a["running_time_s"].to_numpy(float),
            eval_point_ids=tuple(p["eval_point_id"]),
            eval_distance_m=p["eval_distance_m"].to_numpy(float),
            eval_position_m=p["eval_position_m"].to_numpy(float),
            remaining_s=rem,
            ref_remaining_s=ref,
            speed_ms=spd,
            flags=_reference_flags(a, ref is None),
        )
    return out


def _reference_flags(a, no_table_c: bool) -> tuple:
    """The leg's reference-stall flag from its ``table_a`` rows (ratios descending), as the build gave it."""
    if not no_table_c or "ref_stall_position_m" not in a:
        return ()
    x = a["ref_stall_position_m"].to_numpy(float)
    at = np.flatnonzero(np.isfinite(x))
    if not at.size:
        return ()
    # the job's tables always use the reference train REF_LOAD, REF_TRACTION (table_c, absent here, would say)
    return (LegFlag.reference_stall(float(a["ratio"].iloc[at[0]]), float(x[at[0]]), REF_LOAD, REF_TRACTION),)


def _by_pair(df) -> dict | None:
    """A DataFrame's rows by (origin, destination), in their order; None stays None."""
    if df is None:
        return None
    return {key: part for key, part in df.groupby(["origin", "destination"], sort=False)}


def _positions(root: Path, name: str, o: str, d: str, *axes) -> tuple:
    """Index arrays of a table's rows: for each ``(index, column)`` the position of every value in
    ``index`` (an InputError when a value is not there: the tables do not fit together)."""
    out = []
    for index, col in axes:
        at = index.get_indexer(col.to_numpy())
        if (at < 0).any():
            raise InputError(f"--tables {root}: {name} for {o}->{d} has a {col.name} the other tables do not "
                             "have; rebuild the tables")
        out.append(at)
    return tuple(out)


def _optional(root: Path, name: str, line_id: str, direction: str, train_type: str):
    """One partition of an optional dataset as a DataFrame, or None when the dataset is absent."""
    try:
        df = read_dataset(root, name, line=line_id, direction=direction, train_type=train_type).to_pandas()
    except (FileNotFoundError, OSError):
        return None
    return None if df.empty else df


def _approach(g, origin: str, destination: str, last_point: str, root: Path) -> ApproachTable | None:
    """Table (d) of one interstation from its dataset rows ``g`` (None when it has none)."""
    import pandas as pd

    if g.empty:
        return None
    if set(g["eval_point_id"].unique()) != {last_point}:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} is not at the last "
                         f"evaluation point {last_point!r}; rebuild the tables")
    speeds = ms(np.sort(g["speed_kmh"].unique()))
    ratios = np.sort(g["ratio_after"].unique())[::-1]
    powering = tuple(sorted({bool(x) for x in g["powering"].unique()}, reverse=True))
    n_p, n_v, n_a = len(powering), len(speeds), len(ratios)
    if len(g) != n_p * n_v * n_a:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} has {len(g)} rows, expected "
                         f"{n_p} phases x {n_v} speeds x {n_a} ratios; rebuild the tables")
    t = np.full((2, n_p, n_v, n_a), np.nan)
    ip = pd.Index(powering).get_indexer(g["powering"].to_numpy(bool))
    iv = np.searchsorted(speeds, ms(g["speed_kmh"].to_numpy(float)))
    ia = pd.Index(ratios).get_indexer(g["ratio_after"].to_numpy(float))
    t[0, ip, iv, ia] = g["remaining_time_s"].to_numpy(float)
    t[1, ip, iv, ia] = g["remaining_time_ref_s"].to_numpy(float)
    if np.isnan(t).any():
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} is incomplete; rebuild the tables")
    vmax = ms(g["vmax_kmh"].unique()) if "vmax_kmh" in g else np.array([np.inf])
    if len(vmax) != 1:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} has several vmax_kmh; "
                         "rebuild the tables")
    band = ms(g["coast_band_kmh"].unique()) if "coast_band_kmh" in g else np.array([0.0])
    return ApproachTable(speeds_ms=speeds, powering=powering, ratios=ratios, time_s=t[0], ref_time_s=t[1],
                         vmax_ms=float(vmax[0]), coast_band_ms=float(band[0]))
