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
import pyarrow.compute as pc

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


def datasets(results: Sequence[InterstationTables], names: Sequence[str] | None = None) -> dict[str, pa.Table]:
    """The ``eval_points`` and ``table_a`` … ``table_d`` rows, with partition columns, in task order (``names``:
    only these datasets; tables (c) and (d) where there are rows)."""
    want = set(SCHEMAS if names is None else names)
    ep, ta, tb, tc, td = [], [], [], [], []
    for t in results:
        keys, n_r, n_x = _keys(t), len(t.ratios), len(t.points)
        if "eval_points" in want:
            ep.append((keys, n_x, {
                "eval_point_id": [p.eval_point_id for p in t.points],
                "eval_position_m": [p.position_m for p in t.points],
                "eval_distance_m": [p.s_m for p in t.points],
                "eval_point_kind": [p.kind for p in t.points],
            }))
        if "table_a" in want:
            ta.append((keys, n_r, {
                "ratio": t.ratios, "running_time_s": t.time_a_s, "energy_kwh": t.energy_a_kwh,
                "ref_stall_position_m": _null_nan(np.full(n_r, np.nan) if t.ref_stall_m is None else t.ref_stall_m),
            }))
        # each row's point id taken by Arrow from the leg's few, not a Python list of one per row
        ids = pa.array([p.eval_point_id for p in t.points])
        positions = np.array([p.position_m for p in t.points])
        if "table_b" in want:
            k, i, j = np.indices((n_x, n_r, n_r)).reshape(3, -1)
            tb.append((keys, len(k), {
                "eval_point_id": ids.take(k),
                "eval_position_m": positions[k],
                "ratio_before": t.ratios[i],
                "ratio_after": t.ratios[j],
                "remaining_time_s": t.remaining_s[k, i, j],
                "elapsed_time_s": t.elapsed_s[i, k],
            }))
        if t.ref_remaining_s is not None and "table_c" in want:
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
        if t.approach is not None and "table_d" in want:
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
    out = {name: _concat(rows) for name, rows in (("eval_points", ep), ("table_a", ta), ("table_b", tb))
           if name in want}
    if tc:
        out["table_c"] = _concat(tc)
    if td:
        out["table_d"] = _concat(td)
    return out


SCHEMAS = {"eval_points": EVAL_POINTS_SCHEMA, "table_a": TABLE_A_SCHEMA, "table_b": TABLE_B_SCHEMA,
           "table_c": TABLE_C_SCHEMA, "table_d": TABLE_D_SCHEMA}


def write_tables(results: Sequence[InterstationTables], out_dir: str | Path, part: str = "0") -> list[Path]:
    """Write the datasets under ``out_dir`` (atomic per file, deterministic); return the files. ``part``: the
    files' name in each partition folder, ``part-<part>.parquet`` (the nightly job writes a line's interstations
    in parts, :func:`planner.job.steps.partition_keys`)."""
    written: list[Path] = []
    for group in by_partition(results):  # one partition's rows of one dataset in memory at a time (table (d)'s
        for wanted in SCHEMAS:  # rows of a partition of the 10x line: about a hundred megabytes)
            for name, table in datasets(group, [wanted]).items():
                written += write_partitioned(table, Path(out_dir), name, schema=SCHEMAS[name], part=part)
    return written


_KNOWN = ("line", "direction", "train_type", "run_id", "run_date")
"""Columns :func:`load_tables` does not read back: the partition it asks for, and a published run's id and date
(its top partition folders: each value would be repeated on every row)."""
_CODED = ("origin", "destination", "eval_point_id")
"""String columns :func:`load_tables` reads as codes into their values (:meth:`_Rows._codes`)."""


def _read(root: Path, name: str, line_id: str, direction: str, train_type: str) -> pa.Table:
    """One partition of a tables dataset, as :func:`load_tables` reads it (:data:`_KNOWN`, :data:`_CODED`)."""
    return read_dataset(root, name, without=_KNOWN, dictionary=_CODED, line=line_id, direction=direction,
                        train_type=train_type)


def load_tables(
    tables_dir: str | Path, line_id: str, direction: str, train_type: str
) -> dict[tuple[str, str], RunningTimeTables]:
    """Read the ``eval_points``, ``table_a`` and ``table_b`` datasets of one line, direction, type
    (and ``table_c``, ``table_d`` where there are).

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
        ep = _read(root, "eval_points", line_id, direction, train_type)
        ta = _read(root, "table_a", line_id, direction, train_type)
        tb = _read(root, "table_b", line_id, direction, train_type)
    except (FileNotFoundError, OSError) as e:
        raise InputError(f"--tables {root}: cannot read the tables ({e}); run `planner tables` first") from None
    tc = _optional(root, "table_c", line_id, direction, train_type)  # only the adaptive mode needs
    td = _optional(root, "table_d", line_id, direction, train_type)  # tables (c) and (d)
    if not ta.num_rows:
        raise InputError(
            f"--tables {root}: no table_a rows for line={line_id} direction={direction} "
            f"train_type={train_type}; run `planner tables` for it"
        )
    # each dataset split by interstation once (row numbers by pair, from Arrow's dictionary codes), its
    # columns converted to numpy once and indexed by those rows: the margin report reads every table
    # back, and a pandas groupby, sort and Index per interstation cost several times the reading
    ta, ep, tb = _Rows(ta), _Rows(ep), _Rows(tb)
    tc, td = (None if t is None else _Rows(t) for t in (tc, td))
    no_rows = np.zeros(0, np.intp)
    for (o, d), a in ta.pairs.items():
        a = a[_sort_order(ta.floats("ratio")[a], descending=True)]
        ratios = ta.floats("ratio")[a]
        p, b, c, g = (None if f is None else f.pairs.get((o, d), no_rows) for f in (ep, tb, tc, td))
        p = p[_sort_order(ep.floats("eval_distance_m")[p])]
        ids = ep.strings("eval_point_id", p)
        n_r, n_x = len(ratios), len(p)
        if len(b) != n_x * n_r * n_r:
            raise InputError(
                f"--tables {root}: table_b for {o}->{d} has {len(b)} rows, expected "
                f"{n_x} points x {n_r}^2 ratios; rebuild the tables"
            )
        rem = np.full((n_x, n_r, n_r), np.nan)
        at = _positions(root, "table_b", o, d, tb.lookup("eval_point_id", b, ids),
                        tb.lookup("ratio_before", b, ratios), tb.lookup("ratio_after", b, ratios))
        rem[at] = tb.floats("remaining_time_s")[b]
        if np.isnan(rem).any():
            raise InputError(f"--tables {root}: table_b for {o}->{d} is incomplete; rebuild the tables")
        ref = spd = None
        if c is not None and len(c) == n_x * n_r:
            at = _positions(root, "table_c", o, d, tc.lookup("eval_point_id", c, ids), tc.lookup("ratio", c, ratios))
            ref = np.full((n_x, n_r), np.nan)
            ref[at] = tc.floats("remaining_time_ref_s")[c]
            if np.isnan(ref).any():
                ref = None
            if "speed_kmh" in tc:
                spd = np.full((n_x, n_r), np.nan)
                spd[at] = ms(tc.floats("speed_kmh")[c])
                if np.isnan(spd).any():
                    spd = None
        out[(o, d)] = RunningTimeTables(
            approach=_approach(td, g, o, d, ids[-1], root) if g is not None and n_x > 1 else None,
            origin=o,
            destination=d,
            ratios=ratios,
            time_a_s=ta.floats("running_time_s")[a],
            eval_point_ids=tuple(ids),
            eval_distance_m=ep.floats("eval_distance_m")[p],
            eval_position_m=ep.floats("eval_position_m")[p],
            remaining_s=rem,
            ref_remaining_s=ref,
            speed_ms=spd,
            flags=_reference_flags(ta, a, ratios, ref is None),
        )
    return out


class _Rows:
    """One partition of a dataset read back: its rows by interstation and its columns as numpy arrays,
    each converted once, on first use.

    Parameters
    ----------
    table : pyarrow.Table
        The rows, with ``origin`` and ``destination`` columns.

    Attributes
    ----------
    pairs : dict
        ``(origin, destination) -> row numbers`` (ascending), the pairs in the order of their first row,
        rows with a null origin or destination in none (as pandas' ``groupby`` drops them).
    """

    def __init__(self, table: pa.Table):
        self.table = table
        self._cols: dict = {}
        o, o_values = self._codes("origin")
        d, d_values = self._codes("destination")
        code = o * len(d_values) + d
        order = np.argsort(code, kind="stable")  # each pair's rows stay in file order
        first = np.flatnonzero(np.diff(code[order], prepend=-1))
        bounds = np.append(first, len(code)).tolist()
        rows = {int(code[order[f]]): order[f:e] for f, e in zip(bounds, bounds[1:])}
        self.pairs = {}
        for k in sorted(rows, key=lambda k: rows[k][0]):
            pair = (o_values[k // len(d_values)], d_values[k % len(d_values)])
            if None not in pair:
                self.pairs[pair] = rows[k]

    def __contains__(self, name: str) -> bool:
        return name in self.table.column_names

    def _codes(self, name: str) -> tuple[np.ndarray, list]:
        """A string column as codes into its distinct values (null one of them, as None)."""
        if (name, str) not in self._cols:
            col = self.table.column(name)
            if not pa.types.is_dictionary(col.type):  # not read as codes (read_dataset(dictionary=))
                col = pc.dictionary_encode(col)
            enc = col.unify_dictionaries().combine_chunks()
            values = enc.dictionary.to_pylist()  # null: a value of its own, after them
            self._cols[name, str] = (enc.indices.fill_null(len(values)).to_numpy().astype(np.intp), values + [None])
        return self._cols[name, str]

    def floats(self, name: str) -> np.ndarray:
        """A column as float64 (null as NaN)."""
        if (name, float) not in self._cols:
            self._cols[name, float] = np.asarray(self.table.column(name).to_numpy(), float)
        return self._cols[name, float]

    def bools(self, name: str) -> np.ndarray:
        """A column as bool (null as False)."""
        if (name, bool) not in self._cols:
            self._cols[name, bool] = np.asarray(self.table.column(name).to_numpy(), bool)
        return self._cols[name, bool]

    def strings(self, name: str, rows: np.ndarray) -> list:
        """A string column's values at ``rows`` (null as None)."""
        codes, values = self._codes(name)
        return [values[i] for i in codes[rows].tolist()]

    def distinct_strings(self, name: str, rows: np.ndarray) -> set:
        """A string column's distinct values at ``rows`` (null as None)."""
        codes, values = self._codes(name)
        return {values[i] for i in np.unique(codes[rows]).tolist()}

    def lookup(self, name: str, rows: np.ndarray, index: Sequence) -> tuple[str, np.ndarray]:
        """``(name, positions)``: where each of ``rows``' values of the column is in ``index`` (the
        interstation's point ids or ratios), -1 where it is not there."""
        if isinstance(index, np.ndarray):
            return name, _float_positions(index, self.floats(name)[rows])
        codes, values = self._codes(name)
        at = {v: i for i, v in enumerate(index)}
        if len(at) < len(index):  # a point id twice: pandas' Index raises for it, as it always did
            import pandas as pd

            return name, pd.Index(list(index)).get_indexer(values)[codes[rows]]
        return name, np.array([at.get(v, -1) for v in values], np.intp)[codes[rows]]


def _float_positions(index: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The position of each of ``x`` in ``index`` (exact values), -1 where it is not there: what
    ``pd.Index(index).get_indexer(x)`` gives, by sorting the few ``index`` values."""
    order = np.argsort(index, kind="stable")
    s = index[order]
    if not len(s) or np.isnan(s[-1]) or (s[1:] == s[:-1]).any():  # NaN, values twice: as pandas does (or raises)
        import pandas as pd

        return pd.Index(index).get_indexer(x)
    at = np.minimum(np.searchsorted(s, x), len(s) - 1)
    return np.where(s[at] == x, order[at], -1)


def _sort_order(x: np.ndarray, descending: bool = False) -> np.ndarray:
    """The row order of pandas' ``sort_values`` on the float column ``x`` (numpy's quicksort of the
    same values, NaN last, ties in the same order), so the rows come back as they always did."""
    nan = np.isnan(x)
    at, v = np.flatnonzero(~nan), x[~nan]
    if descending:  # as pandas' nargsort: sorted reversed, then reversed back
        at, v = at[::-1], v[::-1]
    order = at[v.argsort(kind="quicksort")]
    if descending:
        order = order[::-1]
    return np.concatenate([order, np.flatnonzero(nan)])


def _reference_flags(ta: _Rows, a: np.ndarray, ratios: np.ndarray, no_table_c: bool) -> tuple:
    """The leg's reference-stall flag from its ``table_a`` rows ``a`` (ratios descending), as the build
    gave it."""
    if not no_table_c or "ref_stall_position_m" not in ta:
        return ()
    x = ta.floats("ref_stall_position_m")[a]
    at = np.flatnonzero(np.isfinite(x))
    if not at.size:
        return ()
    # the job's tables always use the reference train REF_LOAD, REF_TRACTION (table_c, absent here, would say)
    return (LegFlag.reference_stall(float(ratios[at[0]]), float(x[at[0]]), REF_LOAD, REF_TRACTION),)


def _positions(root: Path, name: str, o: str, d: str, *axes: tuple[str, np.ndarray]) -> tuple:
    """Index arrays of a table's rows from :meth:`_Rows.lookup`'s ``(column, positions)`` (an InputError
    when a value is not there: the tables do not fit together)."""
    for col, at in axes:
        if (at < 0).any():
            raise InputError(f"--tables {root}: {name} for {o}->{d} has a {col} the other tables do not "
                             "have; rebuild the tables")
    return tuple(at for _, at in axes)


def _optional(root: Path, name: str, line_id: str, direction: str, train_type: str) -> pa.Table | None:
    """One partition of an optional dataset, or None when the dataset is absent or has no rows there."""
    try:
        t = _read(root, name, line_id, direction, train_type)
    except (FileNotFoundError, OSError):
        return None
    return t if t.num_rows else None


def _unique(x: np.ndarray) -> np.ndarray:
    """The distinct values of ``x`` in the order they first occur (NaN once; of equal values such as
    -0.0 and 0.0 the first), as ``pd.unique(x)``: ``np.unique`` gives each value's first row."""
    return x[np.sort(np.unique(x, return_index=True)[1])]


def _approach(td: _Rows, g: np.ndarray, origin: str, destination: str, last_point: str,
              root: Path) -> ApproachTable | None:
    """Table (d) of one interstation from its dataset rows ``g`` (None when it has none)."""
    if not len(g):
        return None
    if td.distinct_strings("eval_point_id", g) != {last_point}:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} is not at the last "
                         f"evaluation point {last_point!r}; rebuild the tables")
    speed_kmh, ratio_after = td.floats("speed_kmh")[g], td.floats("ratio_after")[g]
    on = td.bools("powering")[g]
    speeds = ms(np.sort(_unique(speed_kmh)))
    ratios = np.sort(_unique(ratio_after))[::-1]
    powering = tuple(sorted({bool(x) for x in _unique(on)}, reverse=True))
    n_p, n_v, n_a = len(powering), len(speeds), len(ratios)
    if len(g) != n_p * n_v * n_a:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} has {len(g)} rows, expected "
                         f"{n_p} phases x {n_v} speeds x {n_a} ratios; rebuild the tables")
    t = np.full((2, n_p, n_v, n_a), np.nan)
    ip = (on != powering[0]).astype(np.intp)  # (True, False), or the one phase there is
    iv = np.searchsorted(speeds, ms(speed_kmh))
    ia = _float_positions(ratios, ratio_after)
    t[0, ip, iv, ia] = td.floats("remaining_time_s")[g]
    t[1, ip, iv, ia] = td.floats("remaining_time_ref_s")[g]
    if np.isnan(t).any():
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} is incomplete; rebuild the tables")
    vmax = ms(_unique(td.floats("vmax_kmh")[g])) if "vmax_kmh" in td else np.array([np.inf])
    if len(vmax) != 1:
        raise InputError(f"--tables {root}: table_d for {origin}->{destination} has several vmax_kmh; "
                         "rebuild the tables")
    band = ms(_unique(td.floats("coast_band_kmh")[g])) if "coast_band_kmh" in td else np.array([0.0])
    return ApproachTable(speeds_ms=speeds, powering=powering, ratios=ratios, time_s=t[0], ref_time_s=t[1],
                         vmax_ms=float(vmax[0]), coast_band_ms=float(band[0]))
