"""Parquet datasets: declared schemas and deterministic, atomic, hive-partitioned writes.

Every dataset the planner writes is laid out as

    ROOT/<dataset>/line=L/direction=D/train_type=T/part-0.parquet

so analysts can filter by partition without reading everything
(``pyarrow.dataset.dataset(ROOT/<dataset>, partitioning="hive")``, DuckDB's
``read_parquet('.../**/*.parquet', hive_partitioning=true)``). Partition
columns are not stored inside the files (hive style); each file carries the
schema's field descriptions and the dataset's schema version as metadata.
Partition values must be path ids (:data:`planner.io.paths.PATH_ID_RE`); any
other value is refused here, before a folder is made.

Writes are deterministic (same table, same bytes: no timestamps, fixed
writer settings) and atomic per file (temp file in the same folder, then
``os.replace``).
"""
from __future__ import annotations

import contextvars
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from planner.io.atomic import atomic_path
from planner.io.paths import check_path_id

PARTITION_COLS = ("line", "direction", "train_type")


def read_file(path: str | Path) -> pa.Table:
    """One Parquet file as a table, read by the file reader itself, not through ``pq.read_table``'s dataset
    layer: the same table (columns, types, metadata), without importing ``pyarrow.dataset`` and pandas
    (a quarter of a second at the start of every command that reads a line, before its first unit)."""
    with pq.ParquetFile(path) as f:
        return f.read()


def declare(
    fields: Sequence[tuple[str, pa.DataType, str]],
    *,
    name: str = "",
    version: int = 1,
    description: str = "",
) -> pa.Schema:
    """Declare a dataset schema once: ``(column, type, description)`` triples.

    Units belong in the column name (``running_time_s``); the description says
    what the column means. The schema metadata records the dataset name, its
    version and description, so ``outputs/README.md`` can be generated from it.
    """
    pa_fields = [
        pa.field(col, typ, metadata={"description": desc}) for col, typ, desc in fields
    ]
    meta = {"dataset": name, "schema_version": str(version), "description": description}
    return pa.schema(pa_fields, metadata=meta)


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """Select and cast ``table``'s columns to ``schema`` (order, types, metadata)."""
    cols = [table.column(f.name).cast(f.type) for f in schema]
    return pa.Table.from_arrays(cols, schema=schema)


def write_parquet_atomic(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` deterministically; the final name appears only when complete.

    Inside :func:`stamping` (a run's datasets), every row also gets the run's :data:`RUN_FIELDS`.
    """
    table = _stamped(table)
    with atomic_path(path) as tmp:
        pq.write_table(
            table,
            tmp,
            compression="zstd",
            use_dictionary=True,
            write_statistics=True,
            store_schema=True,
        )


def by_partition(results: Iterable, key=lambda r: (r.line_id, r.direction, r.train_type)) -> list[list]:
    """``results`` grouped by the partition they are written to (default line, direction, train type),
    each group in its original order, the groups in sorted key order: a writer that builds one group's
    table at a time holds one partition in memory, and writes the same files as from all at once."""
    groups: dict = {}
    for r in results:
        groups.setdefault(key(r), []).append(r)
    return [groups[k] for k in sorted(groups)]


def write_partitioned(
    table: pa.Table,
    root: Path,
    dataset: str,
    partition_cols: Iterable[str] = PARTITION_COLS,
    *,
    schema: pa.Schema | None = None,
    sort_by: Sequence[str] = (),
    part: str = "0",
) -> list[Path]:
    """Write ``table`` as a hive-partitioned dataset under ``root/dataset``.

    Parameters
    ----------
    table : pyarrow.Table
        Rows including the partition columns.
    root : Path
        Output root (e.g. a run folder).
    dataset : str
        Dataset name, the first folder level.
    partition_cols : iterable of str
        Columns that become ``col=value`` folders, in that order.
    schema : pyarrow.Schema, optional
        Declared schema of the *stored* columns (without partition columns);
        the stored table is conformed to it.
    sort_by : sequence of str
        Columns to sort rows by inside each file, for determinism.
    part : str
        The file's name in each partition folder, ``part-<part>.parquet``: ``0``, or a section's number where a
        line's rows are written in sections (:mod:`planner.network.sections`).

    Returns
    -------
    list of Path
        Files written, in sorted partition order.
    """
    root = Path(root)
    parts = list(partition_cols)
    written: list[Path] = []
    if table.num_rows == 0:
        return written
    for key, sub in _partitions(table, parts):
        if sort_by:
            sub = sub.sort_by([(c, "ascending") for c in sort_by])
        if schema is not None:
            sub = conform(sub, schema)
        folder = root / dataset
        for c, v in zip(parts, key):  # validated already; checked again where the path is built
            folder = folder / f"{c}={check_path_id(v, f'partition value {c}=')}"
        path = folder / f"part-{check_path_id(part, 'part ')}.parquet"
        write_parquet_atomic(sub, path)
        written.append(path)
    return written


def _partitions(table: pa.Table, parts: list[str]) -> Iterator[tuple[tuple[str, ...], pa.Table]]:
    """``(folder values, rows without the partition columns)`` of each partition of ``table``, in sorted
    folder order, the rows in their order; one partition's rows are made at a time."""
    if not parts:
        yield (), table
        return
    one = _one_partition(table, parts)
    if one is not None:
        # every row in one partition (each job write of tables, stops, closed loop, margins): the rows as they
        # are, as filtering them by an all-true mask gave (same chunks), without a group_by and masks
        yield one, table.drop_columns(parts)
    else:
        yield from _grouped_partitions(table, parts)


def _one_partition(table: pa.Table, parts: list[str]) -> tuple[str, ...] | None:
    """The folder values when every row of ``table`` is in one partition and its rows would come out of a
    filter as they are (every column chunked alike, no empty chunk), else None (the general grouping)."""
    layouts = {tuple(len(chunk) for chunk in col.chunks) for col in table.columns}
    if len(layouts) != 1 or 0 in next(iter(layouts)):
        return None
    values = [pc.unique(table.column(c)) for c in parts]
    if any(len(v) != 1 or v.null_count for v in values):
        return None
    return tuple(str(v[0].as_py()) for v in values)  # a folder is named by str() of the value, as the rows'


def _grouped_partitions(table: pa.Table, parts: list[str]) -> Iterator[tuple[tuple[str, ...], pa.Table]]:
    """:func:`_partitions` for any partition columns (ints, nulls, several chunks)."""
    # the distinct partition values, grouped in Arrow (one Python object per partition, not per
    # row); a folder is named by str() of the value, as the rows' values
    groups: dict[tuple, list[dict]] = {}
    for d in table.select(parts).group_by(parts).aggregate([]).to_pylist():
        groups.setdefault(tuple(str(d[c]) for c in parts), []).append(d)
    for key in sorted(groups):
        mask = None
        for vals in groups[key]:  # values that print the same share a folder, as before
            m = None
            for c in parts:
                v = vals[c]
                e = pc.is_null(table[c]) if v is None else pc.fill_null(pc.equal(table[c], v), False)
                m = e if m is None else pc.and_(m, e)
            mask = m if mask is None else pc.or_(mask, m)
        yield key, table.filter(mask).drop_columns(parts)  # rows keep their order


def read_dataset(root: Path, dataset: str, *, without: Sequence[str] = (), dictionary: Sequence[str] = (),
                 columns: Sequence[str] | None = None, **filters) -> pa.Table:
    """Read a hive-partitioned dataset, optionally filtered by partition values.

    ``read_dataset(out, "table_a", direction="down", train_type="E10")``.
    Partition columns come back as strings. ``without``: columns not to read (a reader that knows the partition
    it asked for need not have its values repeated on every row, nor the run's stamp); ``dictionary``: string
    columns to read as dictionary arrays, as the files store them (a value once, a code per row); ``columns``:
    only these, in this order (a reader of a few of many columns: the train graph's of the occupation windows).
    """
    import pyarrow.dataset as ds

    path = Path(root) / dataset
    fmt = ds.ParquetFileFormat(read_options=ds.ParquetReadOptions(dictionary_columns=list(dictionary))) \
        if dictionary else "parquet"
    d = ds.dataset(path, format=fmt, partitioning="hive")
    expr = None
    for k, v in filters.items():
        e = pc.field(k) == v
        expr = e if expr is None else expr & e
    if without:
        columns = [c for c in (d.schema.names if columns is None else columns) if c not in without]
    t = d.to_table(filter=expr, columns=columns)
    # Partition columns inferred as dictionary/int by pyarrow; make them plain strings.
    for name in PARTITION_COLS:
        if name in t.column_names:
            idx = t.column_names.index(name)
            t = t.set_column(idx, name, pc.cast(t.column(name), pa.string()))
    return t


RUN_FIELDS = (
    ("run_id", pa.string(), "the published run these rows belong to (outputs/<run_id>/), e.g. r0007-3f9a2c01d4"),
    ("run_date", pa.date32(), "the run's date: [job] run_date, else the UTC date when `planner run` started "
                              "(part of the run's inputs digest, so one run id always has one date)"),
)
"""Columns `planner run` appends to every row of every published dataset, so runs compare in one query."""


def with_run_fields(schema: pa.Schema) -> pa.Schema:
    """``schema`` plus the :data:`RUN_FIELDS` (what a published file holds)."""
    out = schema
    for col, typ, desc in RUN_FIELDS:
        if col not in out.names:
            out = out.append(pa.field(col, typ, metadata={"description": desc}))
    return out


_STAMP = contextvars.ContextVar("planner_run_stamp", default=None)


@contextmanager
def stamping(run_id: str, run_date) -> Iterator[None]:
    """Within this context (and the threads given it by :func:`planner.io.atomic.in_this_context`),
    every Parquet file written gets ``run_id`` and ``run_date`` appended to every row.

    `planner run` writes its datasets in it, so a published file holds its run's columns from its
    first write and nothing is rewritten at the end.
    """
    import datetime

    if not isinstance(run_date, datetime.date):
        run_date = datetime.date.fromisoformat(str(run_date))
    token = _STAMP.set((run_id, run_date))
    try:
        yield
    finally:
        _STAMP.reset(token)


def current_stamp() -> tuple | None:
    """The ``(run_id, run_date)`` of the :func:`stamping` around this call, or None: what a worker process is given
    to stamp the files it writes for the run as this process would."""
    return _STAMP.get()


def _stamped(table: pa.Table) -> pa.Table:
    """``table`` with the :data:`RUN_FIELDS` of the current :func:`stamping` appended (replacing any
    it has), or as it is outside one."""
    stamp = _STAMP.get()
    if stamp is None:
        return table
    for (col, typ, desc), val in zip(RUN_FIELDS, stamp):
        if col in table.column_names:
            table = table.drop_columns([col])
        # the value repeated by Arrow, not a Python list of it per row (the same column)
        table = table.append_column(pa.field(col, typ, metadata={"description": desc}),
                                    pa.repeat(pa.scalar(val, type=typ), table.num_rows))
    return table
