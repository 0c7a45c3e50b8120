"""CSV ⇄ line database: one ``<table>.csv`` per table, the same columns as the Parquet tables.

Format (what :func:`export_csv` writes and :func:`import_csv` reads):

- one file per table, named ``<table>.csv`` (``gradients.csv``, ...); ``signals``,
  ``nodes`` and ``edges`` may be left out, like their Parquet files;
- lines starting with ``#`` before the header are comments (the templates explain
  every column there); the header names the columns, units in the names;
- numbers as written by Python (``repr``), so a float survives the round trip
  bit for bit; booleans ``true``/``false``; an empty cell is null in a nullable
  column and the empty string in a text column (so a nullable text column cannot
  hold an empty string);
- every value of a number column must be a number: units are in the header only.

Errors name the file, the physical line, the column and the fix.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from planner.io.atomic import write_bytes_atomic
from planner.errors import InputError, SourceError, Violation
from planner.line.schema import TABLES, TableSpec, missing_column_hint
from planner.line.schema_doc import DOC_PATH
from planner.line.importers.common import ImportSummary, braking_note, write_line
from planner.line.importers.timetable import CLOCK_COLUMNS, clock_seconds

_TRUE, _FALSE = {"true", "1", "yes"}, {"false", "0", "no"}


def _cell(value, typ: pa.DataType) -> str:
    if value is None:
        return ""
    if pa.types.is_boolean(typ):
        return "true" if value else "false"
    if pa.types.is_floating(typ):
        return repr(float(value))
    return str(value)


def table_csv(name: str, table: pa.Table, *, comments: bool = False, spec: TableSpec | None = None) -> str:
    """The CSV text of one table (declared columns only, in declared order); ``spec``: another declared table
    than the line database's ``name`` (a daily feed's, :mod:`planner.line.daily`)."""
    spec = spec or TABLES[name]
    fields = [f for f in spec.schema if f.name in table.column_names]
    fields += [f for f in table.schema if f.name not in spec.schema.names]  # the user's own columns
    buf = io.StringIO()
    if comments:
        need = "required" if spec.required else "optional: delete this file if you have none"
        buf.write(f"# {name}.csv ({need}). Lines starting with # before the header are ignored.\n")
        buf.write(f"# Columns, units in the names (rules: {DOC_PATH} or `planner schema`):\n")
        for f in spec.schema:
            desc = f.metadata[b"description"].decode()
            null = "; empty = null" if f.nullable else ""
            buf.write(f"#   {f.name} ({f.type}{null}): {desc}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([f.name for f in fields])
    cols = [table.column(f.name).to_pylist() for f in fields]
    for row in zip(*cols):
        w.writerow([_cell(v, f.type) for v, f in zip(row, fields)])
    return buf.getvalue()


def export_csv(line_dir: str | Path, out: str | Path) -> list[Path]:
    """Write every table of the line database ``line_dir`` as ``out/<table>.csv``."""
    line_dir, out = Path(line_dir), Path(out)
    if not (line_dir / "line.parquet").is_file():
        raise InputError(f"{line_dir}: not a line database (no line.parquet)")
    written = []
    for name, spec in TABLES.items():
        f = line_dir / spec.file
        if f.is_file():
            path = out / f"{name}.csv"
            write_bytes_atomic(path, table_csv(name, pq.read_table(f)).encode("utf-8"))
            written.append(path)
    return written


def write_templates(out: str | Path) -> list[Path]:
    """Empty, commented ``<table>.csv`` templates for a planner to fill in a spreadsheet."""
    out = Path(out)
    written = []
    for name, spec in TABLES.items():
        path = out / f"{name}.csv"
        if path.exists():
            raise InputError(f"{path}: already exists; templates never overwrite a file")
        empty = pa.Table.from_pylist([], schema=spec.schema)
        write_bytes_atomic(path, table_csv(name, empty, comments=True).encode("utf-8"))
        written.append(path)
    return written


# --------------------------------------------------------------------------- reading
def _same_stem(col: str, want: str) -> bool:
    """``gradient_percent`` for ``gradient_permil``, ``limit_ms`` for ``limit_kmh``: same name, other unit."""
    a, b = col.lower().split("_"), want.split("_")
    return a[0] == b[0] and col != want


def _parse(value: str, f: pa.Field, where: str):
    if value == "":
        if f.nullable:
            return None
        if pa.types.is_string(f.type):
            return ""
        raise SourceError(f"{where}: empty cell; this column needs a value in every row")
    if pa.types.is_floating(f.type):
        if f.name in CLOCK_COLUMNS:
            return clock_seconds(value, where)
        try:
            x = float(value)
        except ValueError:
            raise SourceError(f"{where}: {value!r} is not a number; write a plain number in the unit of "
                              f"the column name (e.g. 1200.0, no unit suffix)") from None
        if not math.isfinite(x):
            raise SourceError(f"{where}: {value!r} is not a finite number")
        return x
    if pa.types.is_integer(f.type):
        try:
            return int(value)
        except ValueError:
            raise SourceError(f"{where}: {value!r} is not a whole number") from None
    if pa.types.is_boolean(f.type):
        v = value.strip().lower()
        if v in _TRUE or v in _FALSE:
            return v in _TRUE
        raise SourceError(f"{where}: {value!r} is not a boolean; write true or false")
    return value


def read_table_csv(path: Path, name: str, spec: TableSpec | None = None,
                   notes: list[str] | None = None) -> tuple[pa.Table, list[int]]:
    """One CSV file as a pyarrow table of the declared types, and the physical line number of each row.

    Values go straight from text to Python objects to Arrow (no DataFrame in between), so a
    null stays a null and a float keeps every bit. ``spec``: another declared table than the line
    database's ``name`` (a daily feed's, :mod:`planner.line.daily`). A column under the name an earlier
    schema version gave it is read under the current one, with a sentence in ``notes``
    (:mod:`planner.line.upgrade`).
    """
    from planner.line.upgrade import renamed

    old_names = renamed(name) if spec is None else {}
    spec = spec or TABLES[name]
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise SourceError(f"{path.name}: not UTF-8 text ({e.reason} at byte {e.start}); save it as UTF-8 CSV") \
            from None
    lines = text.splitlines(keepends=True)
    skip = 0
    while skip < len(lines) and (lines[skip].startswith("#") or not lines[skip].strip()):
        skip += 1
    if skip == len(lines):
        raise SourceError(f"{path.name}: no header line; the first line that is not a comment must name "
                          f"the columns")
    reader = csv.reader(io.StringIO("".join(lines[skip:])))
    header = [h.strip() for h in next(reader)]
    for k, h in enumerate(header):
        if h in old_names and old_names[h][0] not in header:
            header[k] = old_names[h][0]
            if notes is not None:
                notes.append(f"{path.name}: column {h} read as {old_names[h][0]}, {old_names[h][1]}")
    if len(header) == 1 and ";" in header[0]:
        raise SourceError(f"{path.name} line {skip + 1}: the header has no commas but semicolons; save the "
                          f"sheet as CSV with comma separators (and . as the decimal mark)")
    declared = {f.name: f for f in spec.schema}
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise SourceError(f"{path.name} line {skip + 1}: column {sorted(dup)[0]} appears twice in the header")
    missing = [c for c in declared if c not in header and c not in spec.optional_columns]
    if missing:
        extra = [h for h in header if h not in declared]
        hint = missing_column_hint(name, missing[0], header) or next(
            (f"; found {h!r}: units are part of the column name, convert the values to "
             f"{missing[0]!r}" for h in extra if _same_stem(h, missing[0])), "")
        raise SourceError(f"{path.name} line {skip + 1}: required column {missing[0]} is missing "
                          f"(expected {declared[missing[0]].type}){hint}")
    # your own columns are kept, as text (docs/line-database.md: extra columns are allowed)
    fields = [declared.get(h) or pa.field(h, pa.string(), nullable=True) for h in header]
    rows, line_no = [], []
    for rec in reader:
        ln = skip + reader.line_num
        if not rec or all(not c.strip() for c in rec):
            continue
        if len(rec) != len(header):
            raise SourceError(f"{path.name} line {ln}: {len(rec)} cells for {len(header)} columns; "
                              f"quote cells that contain commas")
        rows.append([_parse(v.strip() if not pa.types.is_string(f.type) else v, f,
                            f"{path.name} line {ln} column {f.name}") for v, f in zip(rec, fields)])
        line_no.append(ln)
    arrays = []
    for k, f in enumerate(fields):
        try:
            arrays.append(pa.array([r[k] for r in rows], type=f.type))
        except (pa.ArrowInvalid, OverflowError) as e:
            raise SourceError(f"{path.name} column {f.name}: values do not fit {f.type} ({e})") from None
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=spec.schema.metadata)), line_no


def import_csv(src: str | Path, out: str | Path, *, force: bool = False) -> ImportSummary:
    """Read ``src/<table>.csv`` for every table and write the line database ``out`` (validated)."""
    src = Path(src)
    if not src.is_dir():
        raise SourceError(f"{src}: not a folder; give the folder that holds line.csv, stations.csv, ...")
    for p in sorted(src.glob("*.csv")):
        if p.stem not in TABLES:
            raise SourceError(f"{p.name}: unknown table; the tables are {', '.join(TABLES)} "
                              f"(see {DOC_PATH})")
    summary = ImportSummary(source=str(src))
    tables: dict[str, pa.Table] = {}
    line_nos: dict[str, list[int]] = {}
    for name, spec in TABLES.items():
        p = src / f"{name}.csv"
        if not p.is_file():
            if spec.required:
                raise SourceError(f"{src}: {name}.csv is missing; every line needs it, even with no rows "
                                  f"(`planner import csv --template DIR` writes one)")
            continue
        tables[name], line_nos[name] = read_table_csv(p, name, notes=summary.notes)
    from planner.line.upgrade import upgrade_tables

    tables, _ = upgrade_tables(tables)  # an earlier schema version's line.csv: written as the current one

    def where(v: Violation) -> str:
        name = v.file.removesuffix(".parquet")
        s = f"{name}.csv"
        if v.row is not None and name in line_nos and v.row < len(line_nos[name]):
            s += f" line {line_nos[name][v.row]}"
        if v.column:
            s += f" column {v.column}"
        return f"{s}: {v.message}"

    summary.describe = where
    summary.line_id = str(tables["line"].column("line_id")[0]) if tables["line"].num_rows else ""
    write_line(tables, out, summary, force=force)
    for row in tables["rolling_stock"].to_pylist():  # column for column: the summary still says what each limit is
        summary.notes.append(braking_note(row, "rolling_stock.csv"))
    return summary
