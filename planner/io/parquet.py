"""Parquet datasets: declared schemas and deterministic, atomic, hive-partitioned writes.

Every dataset the planner writes is laid out as

    ROOT/<dataset>/line=L/direction=D/train_type=T/part-0.parquet

and a published run puts its own two partition folders on top
(``<dataset>/run_id=R/run_date=D/line=L/...``, :func:`place_in_run`), so
analysts can filter by partition without reading everything
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

import os
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


def without_pandas_metadata(table: pa.Table) -> pa.Table:
    """``table`` without the record pandas adds to a table made from a frame (it names pandas' version: the same rows
    would be other bytes after a pandas update); its other metadata kept."""
    meta = table.schema.metadata
    if not meta or b"pandas" not in meta:
        return table
    return table.replace_schema_metadata({k: v for k, v in meta.items() if k != b"pandas"} or None)


def write_parquet_atomic(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` deterministically; the final name appears only when complete. The bytes depend
    on the table alone: no run's id or date is in a file (a run's are folders, :func:`place_in_run`), nor the
    record pandas adds to a table made from a frame (it names pandas' version, so the same rows would be other
    bytes after a pandas update)."""
    with atomic_path(path) as tmp:
        pq.write_table(
            without_pandas_metadata(table),
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
    # Partition columns inferred as dictionary/int by pyarrow; make them plain strings (a published run's too).
    for name in (*PARTITION_COLS, *(c for c, _, _ in RUN_FIELDS)):
        if name in t.column_names:
            idx = t.column_names.index(name)
            t = t.set_column(idx, name, pc.cast(t.column(name), pa.string()))
    return t


RUN_FIELDS = (
    ("run_id", pa.string(), "the published run these rows belong to (outputs/<run_id>/), e.g. r0007-3f9a2c01d4; "
                            "a partition folder (run_id=...), not stored in the files"),
    ("run_date", pa.string(), "the run's date, YYYY-MM-DD: [job] run_date, else the UTC date when `planner run` "
                              "started (part of the run's inputs digest, so one run id always has one date); a "
                              "partition folder (run_date=...), not stored in the files (DuckDB reads it as a DATE)"),
)
"""The partition columns a published run puts above every dataset's own (:func:`place_in_run`), so runs compare in
one query while a file's bytes do not depend on the run that wrote it."""


def with_run_fields(schema: pa.Schema) -> pa.Schema:
    """``schema`` plus the :data:`RUN_FIELDS` (what a reader of a published dataset sees)."""
    out = schema
    for col, typ, desc in RUN_FIELDS:
        if col not in out.names:
            out = out.append(pa.field(col, typ, metadata={"description": desc}))
    return out


def run_folders(run_id: str, run_date) -> tuple[str, str]:
    """The two partition folders of a published run's datasets, ``run_id=R`` and ``run_date=YYYY-MM-DD``."""
    import datetime

    if not isinstance(run_date, datetime.date):
        run_date = datetime.date.fromisoformat(str(run_date))
    return (f"run_id={check_path_id(run_id, 'run id ')}", f"run_date={run_date.isoformat()}")


def place_in_run(stage: Path, run_id: str, run_date) -> list[str]:
    """Put every dataset of a staged run under its run's partition folders: ``<dataset>/line=L/...`` becomes
    ``<dataset>/run_id=R/run_date=D/line=L/...`` (renames of the ``line=`` folders, no file rewritten). A dataset is
    a folder of ``stage`` holding ``line=`` folders; the run's other folders (inputs, pages, bundles) have none.
    The datasets moved, sorted."""
    stage = Path(stage)
    top = run_folders(run_id, run_date)
    moved = []
    for ds in sorted(p for p in stage.iterdir() if p.is_dir() and not p.is_symlink()):
        lines = sorted(p for p in ds.iterdir() if p.is_dir() and p.name.startswith("line="))
        if not lines:
            continue
        into = ds.joinpath(*top)
        into.mkdir(parents=True)
        for p in lines:
            os.replace(p, into / p.name)
        moved.append(ds.name)
    return moved


def without_run(rel: str) -> str:
    """A published file's path relative to its run folder without the run's partition folders (``run_id=``,
    ``run_date=``): the same for the same file of two runs, so their files pair up to be compared."""
    return "/".join(p for p in Path(rel).as_posix().split("/")
                    if not p.startswith(tuple(f"{c}=" for c, _, _ in RUN_FIELDS)))


def run_dataset_dir(root: Path, dataset: str) -> Path:
    """The folder holding ``dataset``'s ``line=`` folders under ``root``: a published run's
    ``<dataset>/run_id=R/run_date=D`` (:func:`place_in_run`), else ``<dataset>`` (a staged run, or a step's own
    output folder)."""
    base = Path(root) / dataset
    runs = sorted(base.glob("run_id=*/run_date=*")) if base.is_dir() else []
    if len(runs) > 1:
        raise ValueError(f"{base}: {len(runs)} runs' folders in one dataset; a run folder holds one run")
    return runs[0] if runs else base
