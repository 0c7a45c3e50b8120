"""Schema versions of a line database, and the upgrade of an earlier one (old names are never a hard wall).

A line database says its version in ``line.parquet``'s ``schema_version`` (``line.csv`` for an import); this
planner writes :data:`~planner.line.schema.SCHEMA_VERSION`. Every earlier version is read as the current one,
in memory (:func:`upgrade_tables`, called by the loader before validation; the CSV import renames the old
headers the same way), with one note per change; ``planner line upgrade DIR`` rewrites the folder
(:func:`upgrade_folder`), atomically table by table. A version newer than this planner's is refused.

=======  ==========================================================================================
version  what changed
=======  ==========================================================================================
1        the first (``rolling_stock.comfort_accel_kmh_s``)
2        ``rolling_stock.comfort_accel_kmh_s`` renamed ``brake_comfort_kmh_s`` (the ride-comfort limit
         on stop braking)
=======  ==========================================================================================
"""
from __future__ import annotations

from pathlib import Path

import pyarrow as pa

from planner.line.schema import RENAMED_COLUMNS, SCHEMA_VERSION, TABLES


def renamed(table: str) -> dict[str, tuple[str, str]]:
    """``old name → (new name, what it was)`` of the columns of ``table`` that had another name."""
    return {old: (new, why) for (t, new), (old, why) in RENAMED_COLUMNS.items() if t == table}


def upgrade_tables(raw: dict) -> tuple[dict, list[str]]:
    """The tables of a line folder (``read_tables``: a table, a Violation or None each) as the current schema
    reads them, and what was changed (one sentence each; empty for a current folder). Only the old column
    names and the version are touched; the validation that follows checks the rest."""
    out, notes = dict(raw), []
    for name, t in raw.items():
        if not isinstance(t, pa.Table):
            continue
        for old, (new, why) in renamed(name).items():
            if old in t.column_names and new not in t.column_names:
                t = t.rename_columns([new if c == old else c for c in t.column_names])
                notes.append(f"{TABLES[name].file}: column {old} read as {new}, {why}")
        out[name] = t
    t = out.get("line")
    if isinstance(t, pa.Table) and "schema_version" in t.column_names and t.num_rows:
        v = t.column("schema_version").to_pylist()
        if all(isinstance(x, int) and 1 <= x < SCHEMA_VERSION for x in v):
            out["line"] = t.set_column(t.column_names.index("schema_version"), "schema_version",
                                       pa.array([SCHEMA_VERSION] * t.num_rows, pa.int32()))
            if notes:  # an earlier version with nothing else to read differently is just the current one
                notes.insert(0, f"schema {v[0]} read as {SCHEMA_VERSION}")
    return out, notes


def upgrade_folder(path: str | Path) -> list[str]:
    """Rewrite the line database folder ``path`` in the current schema (each changed table atomically, in its
    declared form) and return what changed; the folder must then be valid (else LineValidationError, and
    nothing is written)."""
    from planner.errors import LineValidationError
    from planner.line.loader import _line_dir, read_tables
    from planner.line.schema import write_line_table
    from planner.line.validate import check_tables

    folder = _line_dir(path)
    raw = read_tables(folder)
    new, notes = upgrade_tables(raw)
    version = raw["line"].column("schema_version").to_pylist() if isinstance(raw.get("line"), pa.Table) \
        and "schema_version" in raw["line"].column_names else []
    old_version = version[0] if version else None
    _, bad = check_tables(folder.resolve().name, new)
    if bad:
        raise LineValidationError(str(path), bad)
    changed = [n for n in new if isinstance(new[n], pa.Table) and new[n] is not raw[n]
               and not new[n].equals(raw[n])]
    for name in changed:
        write_line_table(name, new[name], folder / TABLES[name].file)
    if changed and not notes:
        notes.append(f"schema {old_version} rewritten as {SCHEMA_VERSION}")
    return notes
