"""Validation of a line database against schema v1 (docs/line-database.md) and the cross-table rules.

The validator works on the raw pyarrow tables the loader has read and returns
*every* violation it finds, each a :class:`planner.errors.Violation` naming the
file, the 0-based row (with the row's id), the column and what is wrong. The
loader refuses to build a :class:`planner.line.model.Line` when there is any.

It runs in two stages:

1. :func:`planner.line.conform.conform` checks each table against its declared schema
   (:mod:`planner.line.schema`): required columns present, column types, row
   counts, nulls in non-nullable columns, NaN and ±inf. A table that is
   structurally broken (missing file or column, wrong type) is left out of the
   second stage; rows with bad cells are skipped by the row rules so that one
   bad cell does not cascade into follow-up messages.
2. The row and cross-table rules: small functions registered with
   :func:`planner.line.rules.rule`, each naming the tables it needs; a rule runs only when all its
   tables passed stage 1.

Type leniency (documented decision): where ``double`` is declared, integer and
narrower float columns are accepted and cast (pandas writes ``[0, 100]`` as
int64, a harmless and common way to write whole metres); where ``int32`` is
declared, any integer type is accepted if every value fits; string columns may
be ``large_string``, ``string_view`` or dictionary-encoded strings; an all-null
column (pyarrow ``null`` type, what pandas writes for an empty or all-None
object column) is accepted as the declared type, and its nulls are then checked
like any other. Nothing else is cast: a string where a number is declared is an
error ("expected double, found string").

NaN is never accepted, not even in a nullable column: a missing value is
written as null (pandas converts NaN to null when it writes Parquet).
"""
from __future__ import annotations

import dataclasses
import re

import pyarrow as pa

from planner.errors import Violation
from planner.line.conform import TableView, conform
from planner.line import plausibility  # noqa: F401  (registers its rules)
from planner.line.rules import ADVICE, RULES, Db
from planner.line.schema import TABLES

MAX_PRINTED = 50
"""How many violations a report prints before "… and N more"."""


def format_violations(violations: list[Violation], limit: int = MAX_PRINTED) -> list[str]:
    """One line per violation, at most ``limit`` of them, then ``… and N more``."""
    lines = [str(v) for v in violations[:limit]]
    if len(violations) > limit:
        lines.append(f"… and {len(violations) - limit} more")
    return lines


WARNINGS_SHOWN = 3
"""How many findings of one warning rule are printed in full (the count says how many there are)."""


def format_warnings(warnings: list[Violation], first: int = WARNINGS_SHOWN) -> list[str]:
    """Warnings grouped by the rule that found them: a line with the rule, what it means and how many rows,
    then the first ``first`` of them (one freight type at 200 m platforms printed 792 lines, 34 per train)."""
    groups: dict[str, list[Violation]] = {}
    for v in warnings:
        groups.setdefault(v.rule, []).append(v)
    out = []
    for name, vs in groups.items():
        fn = next((f for _, f in ADVICE if f.__name__ == name), None)
        what = re.sub(r"^Warn (where|when|if) |\s*\(issue \d+\)", "", (fn.__doc__ or "").strip().splitlines()[0]) \
            if fn else ""
        head = f"{name or 'warning'}: {len(vs)} row{'s' * (len(vs) != 1)}" + (f" ({what.rstrip('.')})" if what else "")
        out.append(head + (f"; the first {first}:" if len(vs) > first else ":"))
        out += [f"  {v}" for v in vs[:first]]
        if len(vs) > first:
            out.append(f"  … and {len(vs) - first} more of this rule")
    return out


# --------------------------------------------------------------------------- entry point
_FILE_ORDER = {spec.file: k for k, spec in enumerate(TABLES.values())}


def _sort_key(v: Violation):
    return (_FILE_ORDER.get(v.file, len(_FILE_ORDER)), v.file, -1 if v.row is None else v.row)


def check_tables(
    folder_name: str, raw: dict[str, pa.Table | Violation | None], warnings: list[Violation] | None = None
) -> tuple[dict[str, TableView], list[Violation]]:
    """Validate the raw tables of one line folder.

    Parameters
    ----------
    folder_name : str
        Name of the line folder; ``line_id`` must equal it.
    raw : dict
        For each table name of :data:`planner.line.schema.TABLES`: the pyarrow table
        read from its file, a :class:`Violation` if it could not be read, or
        None if the file does not exist.
    warnings : list, optional
        When given, the findings of the warning rules (legitimate on some
        railways, never refused) are appended to it, sorted like violations.

    Returns
    -------
    views : dict of str to TableView
        The tables that conform to their schema.
    violations : list of Violation
        Every problem found, sorted by file (docs/line-database.md order) then row; empty
        when the database is valid.
    """
    out: list[Violation] = []
    views: dict[str, TableView] = {}
    for name, spec in TABLES.items():
        got = raw.get(name)
        if got is None:
            if spec.required:
                out.append(Violation(spec.file, None, None,
                                     "file is missing; every line database needs it, even if it has no rows "
                                     "(see docs/line-database.md or `planner schema`)"))
        elif isinstance(got, Violation):
            out.append(got)
        else:
            view, problems = conform(spec, got)
            out.extend(problems)
            if view is not None:
                views[name] = view
    present = frozenset(k for k, v in raw.items() if v is not None)
    db = Db(folder_name, views, present)
    for needs, fn in RULES:
        if all(n in views for n in needs):
            out.extend(fn(db))
    out.sort(key=_sort_key)
    if warnings is not None:
        found = [dataclasses.replace(v, rule=fn.__name__) for needs, fn in ADVICE if all(n in views for n in needs)
                 for v in fn(db)]
        warnings.extend(sorted(found, key=_sort_key))
    return views, out
