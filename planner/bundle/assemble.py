"""Assembly of one bundle's tables: a line's own data for a direction and train type, plus the
datasets the tables and stopping steps published.

Takes a :class:`planner.line.model.Line`, a direction and a train type (and the
output folders of ``planner tables`` / ``planner stops``); gives the bundle's
tables by name as pyarrow tables: ``restrictions`` (with the ATS-P pattern
data), ``atsp`` (the telegrams the on-board DB feeds), ``max_profile``,
``beacons`` (with the position-correction flags), ``timetable``, and those of
``eval_points``, ``table_a``..``table_d``, ``stop_summary``, ``stop_samples``
that were found. Their schemas are declared in :mod:`planner.bundle.contents`.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Collection, Iterator, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from planner.bundle import atsp
from planner.bundle.contents import (ATSP_SCHEMA, BEACONS_SCHEMA, MAX_PROFILE_SCHEMA, RESTRICTIONS_SCHEMA,
                                     TIMETABLE_SCHEMA, check_keys)
from planner.errors import BundleError
from planner.io.parquet import RUN_FIELDS, run_dataset_dir
from planner.line.model import Line, sign
from planner.line.units import kmh
from planner.physics.speed_profile import onboard_max_ms, restriction_spans

TABLE_SOURCES = {"tables": ("eval_points", "table_a", "table_b", "table_c", "table_d"),
                 "stops": ("stop_summary", "stop_samples")}
"""Which output folder (``--tables`` / ``--stops``) each expected table is read from."""

_PARTITION_COLS = ("line", "direction", "train_type")


# --- tables built from the line DB ---------------------------------------------
def _keys(n: int, line_id: str, direction: str, train_type: str) -> dict[str, list]:
    return {"line": [line_id] * n, "direction": [direction] * n, "train_type": [train_type] * n}


def _table(cols: dict[str, list], schema: pa.Schema) -> pa.Table:
    return pa.Table.from_arrays([pa.array(cols[f.name], type=f.type) for f in schema], schema=schema)


def line_tables(line: Line, direction: str, train_type: str,
                validity: Mapping[str, tuple[int, int]] | None = None) -> dict[str, pa.Table]:
    """The tables built from the line DB alone: restrictions, max_profile, atsp, beacons, timetable.

    Parameters
    ----------
    line : Line
        Validated line (SI).
    direction : {'down', 'up'}
    train_type : str
        A train type of ``line``.

    Notes
    -----
    The ATS-P approach speed ``v_high`` is min(line maximum, vehicle maximum):
    the fastest a train of this type can approach any restriction. Every
    restriction with a pattern (limit < v_high) takes part in the overwrite
    check, also those with a ground beacon (their telegram replaces the held
    pattern too; their beacon is assumed at the computed pattern start). A
    pattern must be held from its feed point until the train's tail has left
    the restriction, so a telegram fed anywhere in that window overwrites it.
    """
    train = line.train_type(train_type)
    sg = sign(direction)
    target = (line.line_id, direction, train_type)
    x0 = line.start_m if direction == "down" else line.end_m  # s = 0 at the line end the train enters
    to_chain = lambda s: x0 + sg * np.asarray(s, dtype=float)  # noqa: E731

    # Restrictions in running order.
    spans = sorted(restriction_spans(line, train, direction, x0),
                   key=lambda sp: (sp.s_from_m, sp.s_to_m, sp.limit_ms, sp.row, sp.ident))
    restrictions, atsp_table = _restriction_tables(line, train, spans, target, to_chain, validity or {})
    return {"restrictions": restrictions,
            "max_profile": _max_profile(line, train, spans, target, to_chain),
            "atsp": atsp_table,
            "beacons": _beacons(line, target),
            "timetable": _timetable(line, target)}


def _restriction_tables(line: Line, train, spans, target: tuple[str, str, str],
                        to_chain: Callable, validity: Mapping[str, tuple[int, int]]) -> tuple[pa.Table, pa.Table]:
    """``restrictions`` (every span, with its ATS-P pattern) and ``atsp`` (the DB-fed telegrams); ``validity``:
    ``ident`` → (valid from, until) [UTC epoch s] of each temporary restriction (its pattern's window)."""
    direction, train_type = target[1], target[2]
    rows = {r.ident: r for r in line.limits_for(direction, train_type)}
    n = len(spans)
    s_from = np.array([sp.s_from_m for sp in spans], dtype=float)
    s_to = np.array([sp.s_to_m for sp in spans], dtype=float)
    limit = np.array([sp.limit_ms for sp in spans], dtype=float)
    v_high = min(line.max_speed_ms, train.max_speed_ms)
    dist = np.atleast_1d(atsp.pattern_distance_m(v_high, limit, train.atsp_pattern_ms2)) if n else np.zeros(0)
    needed = limit < v_high
    s_start = s_from - dist
    s_feed = np.maximum(s_start, 0.0)  # cannot feed before the train is on the line
    has_beacon = np.array([rows[sp.ident].has_beacon for sp in spans], dtype=bool)
    db_fed = needed & ~has_beacon
    overwrites, conflict = atsp.overwrite_conflicts(s_feed, s_to, needed)
    rid = [sp.ident for sp in spans]
    ow = [rid[i] if i >= 0 else None for i in overwrites]
    restrictions = _table({
        **_keys(n, *target),
        "seq": list(range(n)),
        "restriction_id": rid,
        "kind": [rows[sp.ident].kind for sp in spans],
        "start_m": [rows[sp.ident].start_m for sp in spans],
        "end_m": [rows[sp.ident].end_m for sp in spans],
        "entry_m": to_chain(s_from).tolist(),
        "clear_m": to_chain(s_to).tolist(),
        "limit_kmh": kmh(limit).tolist(),
        "onboard_max_kmh": kmh(np.minimum(limit, v_high) - train.speed_margin_ms).tolist(),
        "has_beacon": has_beacon.tolist(),
        "pattern_needed": needed.tolist(),
        "pattern_distance_m": dist.tolist(),
        "pattern_start_m": to_chain(s_start).tolist(),
        "db_fed": db_fed.tolist(),
        "overwrite_conflict": conflict.tolist(),
        "overwrites": ow,
        "valid_from_utc_s": [validity[x][0] if x in validity else None for x in rid],
        "valid_until_utc_s": [validity[x][1] if x in validity else None for x in rid],
    }, RESTRICTIONS_SCHEMA)

    # DB-fed telegrams, in order of their feed points.
    idx = sorted(np.flatnonzero(db_fed), key=lambda i: (s_feed[i], i))
    m = len(idx)
    hold = [float(s_to[i] - s_from[i]) for i in idx]
    atsp_table = _table({
        **_keys(m, *target),
        "seq": list(range(m)),
        "restriction_id": [rid[i] for i in idx],
        "feed_m": [float(to_chain(s_feed[i])) for i in idx],
        "pattern_start_m": [float(to_chain(s_start[i])) for i in idx],
        "entry_m": [float(to_chain(s_from[i])) for i in idx],
        "distance_m": [float(s_from[i] - s_feed[i]) for i in idx],
        "hold_m": hold,
        "limit_kmh": [float(kmh(limit[i])) for i in idx],
        "telegram": [atsp.restriction_telegram(float(kmh(limit[i])), float(s_from[i] - s_feed[i]), h)
                     for i, h in zip(idx, hold)],
        "feed_clipped": [bool(s_start[i] < 0.0) for i in idx],
        "overwrite_conflict": [bool(conflict[i]) for i in idx],
        "overwrites": [ow[i] for i in idx],
        "valid_from_utc_s": [validity[rid[i]][0] if rid[i] in validity else None for i in idx],
        "valid_until_utc_s": [validity[rid[i]][1] if rid[i] in validity else None for i in idx],
    }, ATSP_SCHEMA)
    return restrictions, atsp_table


def _max_profile(line: Line, train, spans, target: tuple[str, str, str], to_chain: Callable) -> pa.Table:
    """On-board maximum profile: constant between span ends; evaluated at midpoints."""
    length = line.end_m - line.start_m
    s_from = np.array([sp.s_from_m for sp in spans], dtype=float)
    s_to = np.array([sp.s_to_m for sp in spans], dtype=float)
    edges = np.unique(np.clip(np.concatenate([[0.0, length], s_from, s_to]), 0.0, length))
    vmax = onboard_max_ms(0.5 * (edges[:-1] + edges[1:]), spans, line.max_speed_ms, train.max_speed_ms,
                          train.speed_margin_ms)
    keep = np.concatenate([[True], np.diff(vmax) != 0.0])  # merge equal neighbours
    starts = edges[:-1][keep]
    ends = np.append(starts[1:], edges[-1])
    v = vmax[keep]
    k = len(v)
    return _table({
        **_keys(k, *target),
        "seq": list(range(k)),
        "from_m": to_chain(starts).tolist(),
        "to_m": to_chain(ends).tolist(),
        "limit_kmh": kmh(v + train.speed_margin_ms).tolist(),
        "onboard_max_kmh": kmh(v).tolist(),
    }, MAX_PROFILE_SCHEMA)


def _beacons(line: Line, target: tuple[str, str, str]) -> pa.Table:
    """Beacons in running order with the correction flag."""
    bs = line.beacons_for(target[1])
    usable = atsp.correction_usable([b.telegram for b in bs])
    nb = len(bs)
    return _table({
        **_keys(nb, *target),
        "seq": list(range(nb)),
        "beacon_id": [b.beacon_id for b in bs],
        "position_m": [b.position_m for b in bs],
        "kind": [b.kind for b in bs],
        "telegram": [b.telegram for b in bs],
        "evaluation_point": [b.evaluation_point for b in bs],
        "correction_usable": usable.tolist(),
    }, BEACONS_SCHEMA)


def _timetable(line: Line, target: tuple[str, str, str]) -> pa.Table:
    """Timetable slice, trains ordered by first departure then number."""
    direction, train_type = target[1], target[2]

    def first_dep(t):
        deps = [c.departure_s for c in t.calls if not math.isnan(c.departure_s)]
        return min(deps) if deps else math.inf

    trains = sorted((t for t in line.trains if t.train_type == train_type and t.direction == direction),
                    key=lambda t: (first_dep(t), t.train_id))
    calls = [(t, c) for t in trains for c in sorted(t.calls, key=lambda c: c.seq)]
    nan_none = lambda x: None if math.isnan(x) else float(x)  # noqa: E731
    return _table({
        **_keys(len(calls), *target),
        "train_id": [t.train_id for t, _ in calls],
        "seq": [c.seq for _, c in calls],
        "station_id": [c.station_id for _, c in calls],
        "arrival_s": [nan_none(c.arrival_s) for _, c in calls],
        "departure_s": [nan_none(c.departure_s) for _, c in calls],
        "stops": [c.stops for _, c in calls],
    }, TIMETABLE_SCHEMA)


# --- reading the other steps' datasets -----------------------------------------
@dataclass(frozen=True)
class Partition:
    """One partition's files of a step's dataset (``dataset/line=/direction=/train_type=``), read a file at a time
    (:meth:`pieces`): a bundle's large tables (millions of rows on a long line) are checked and encoded piece by
    piece (:func:`planner.bundle.contents.streamed`), never held whole."""

    dataset: str
    folder: Path
    files: tuple[Path, ...]
    values: tuple[str, str, str]
    """The partition's line, direction and train type."""

    def pieces(self) -> Iterator[pa.Table]:
        """Each file's rows, in sorted name order (the writer's row order), the partition columns added as plain
        strings."""
        old_run = {c for c, _, _ in RUN_FIELDS}
        for f in self.files:
            try:
                # a run published before the run's fields became folders has them in its files; a bundle does not
                # read them
                t = pq.read_table(f, partitioning=None,
                                  columns=[c for c in pq.read_schema(f).names if c not in old_run])
            except (pa.ArrowInvalid, OSError) as e:
                raise BundleError(f"cannot read {self.folder}: {e}; rebuild the {self.dataset} dataset") from None
            for col, val in zip(_PARTITION_COLS, self.values):
                if col in t.column_names:  # hive files normally leave it out; if stored, it must agree
                    check_keys(self.dataset, t.select([col]), *self.values, str(self.folder))
                    t = t.drop_columns([col])
                t = t.append_column(pa.field(col, pa.string()), pa.repeat(pa.scalar(val, pa.string()), t.num_rows))
            yield t


def partition(root: str | os.PathLike, dataset: str, line_id: str, direction: str,
              train_type: str) -> Partition | None:
    """One partition of a hive dataset ``root/dataset/line=/direction=/train_type=``, or None if absent."""
    # a published run's datasets are under its run_id= and run_date= folders; a step's own output is not
    folder = run_dataset_dir(root, dataset) / f"line={line_id}" / f"direction={direction}" / f"train_type={train_type}"
    files = sorted(folder.glob("*.parquet"), key=lambda p: p.name) if folder.is_dir() else []
    return Partition(dataset, folder, tuple(files), (line_id, direction, train_type)) if files else None


def read_partition(root: str | os.PathLike, dataset: str, line_id: str, direction: str,
                   train_type: str) -> pa.Table | None:
    """One partition of a hive dataset ``root/dataset/line=/direction=/train_type=`` as one table, or None if
    absent: its files (:meth:`Partition.pieces`) concatenated."""
    p = partition(root, dataset, line_id, direction, train_type)
    if p is None:
        return None
    parts = list(p.pieces())
    try:
        return pa.concat_tables(parts) if len(parts) > 1 else parts[0]
    except pa.ArrowInvalid as e:
        raise BundleError(f"cannot read {p.folder}: {e}; rebuild the {dataset} dataset") from None


def assemble(line: Line, direction: str, train_type: str, *, tables_dir=None,
             stops_dir=None, validity: Mapping[str, tuple[int, int]] | None = None,
             streamed: Collection[str] = (), given: Collection[str] = ()) -> dict[str, pa.Table | Partition]:
    """Every table of one bundle that exists: the line's own tables plus the datasets found.

    ``tables_dir`` is the output folder of ``planner tables`` (``eval_points``,
    ``table_a``, ``table_b``), ``stops_dir`` that of the stopping step
    (``stop_summary``, ``stop_samples``). Tables not found are left out; the
    builder records them as missing in the manifest. The datasets named in ``streamed`` are given as their
    :class:`Partition`, to be read a file at a time (:func:`planner.bundle.container.bundle_bytes`); those named in
    ``given`` are not read (the build has their bytes already).
    """
    tables = line_tables(line, direction, train_type, validity)
    for key, root in (("tables", tables_dir), ("stops", stops_dir)):
        if root is None:
            continue
        if not Path(root).is_dir():
            raise BundleError(f"--{key} {root} is not a folder; give the output folder of that step")
        for name in (n for n in TABLE_SOURCES[key] if n not in given):
            t = (partition if name in streamed else read_partition)(root, name, line.line_id, direction, train_type)
            if t is not None:
                tables[name] = t
    return tables
