"""Stage 1 of validation: each raw table against its declared schema (:mod:`planner.line.schema`).

Required columns present, column types (with the leniency documented in
:mod:`planner.line.validate`), row counts, nulls in non-nullable columns, NaN and
±inf. Gives a :class:`TableView` (typed numpy columns and a per-row "good" mask
the rules of stage 2 use) and the violations found.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from planner.errors import Violation
from planner.line.schema import (
    Range,
    TableSpec,
    column_range,
    fmt_bound,
    missing_column_hint,
)


# --------------------------------------------------------------------------- formatting
def fmt(x) -> str:
    """A value as it appears in messages: floats as ``4200.0``, strings quoted-free."""
    if isinstance(x, (float, np.floating)):
        return repr(float(x))
    if isinstance(x, (np.integer,)):
        return str(int(x))
    return str(x)


def out_of_range(rng: Range, x: float) -> str:
    """The message for a value outside its column's declared range."""
    if rng.below(x):
        need = f"must be {'>' if rng.lo_open else '>='} {fmt_bound(rng.lo)}"
    else:
        need = f"must be <= {fmt_bound(rng.hi)}"
    return f"{need}, found {fmt(x)} (accepted {rng}: {rng.why})"


# --------------------------------------------------------------------------- stage 1: schema
@dataclass(eq=False)
class TableView:
    """A table that conforms to its declared schema, as plain column arrays.

    ``cols`` maps each declared column present in the file to a numpy array:
    float64 for double columns (NaN where null), object arrays of Python values
    (None where null) for string, bool and int32 columns. ``good[i]`` is False
    for rows with a null, NaN or inf in a cell that must hold a value; the row
    rules skip those rows (the cell problem is already reported).
    """

    spec: TableSpec
    n: int
    cols: dict[str, np.ndarray]
    good: np.ndarray

    @property
    def file(self) -> str:
        return self.spec.file

    def __getitem__(self, column: str) -> np.ndarray:
        return self.cols[column]

    def has(self, column: str) -> bool:
        return column in self.cols

    def rows(self) -> list[int]:
        """Indices of the rows whose cells are all usable, in file order."""
        return [int(i) for i in np.flatnonzero(self.good)]

    def row_id(self, i: int) -> str:
        parts = []
        for c in self.spec.row_id:
            v = self.cols[c][i] if c in self.cols else None
            if v is None or (isinstance(v, float) and math.isnan(v)):
                continue
            parts.append(f"{c}={fmt(v)}")
        return " ".join(parts)

    def err(self, i: int | None, column: str | None, message: str) -> Violation:
        rid = self.row_id(i) if i is not None else None
        return Violation(self.file, i, column, message, rid or None)


def _string_like(t: pa.DataType) -> bool:
    is_view = getattr(pa.types, "is_string_view", lambda _t: False)
    return pa.types.is_string(t) or pa.types.is_large_string(t) or is_view(t)


def _cast_column(arr: pa.ChunkedArray, want: pa.DataType) -> tuple[pa.ChunkedArray | None, str | None]:
    """Cast ``arr`` to ``want`` where the schema allows it; else an error message."""
    have = arr.type
    if have == want:
        return arr, None
    if pa.types.is_null(have):
        return pa.chunked_array([pa.nulls(len(arr), want)], type=want), None
    if pa.types.is_floating(want):
        ok = pa.types.is_floating(have) or pa.types.is_integer(have)
    elif pa.types.is_integer(want):
        ok = pa.types.is_integer(have)
    elif pa.types.is_string(want):
        ok = _string_like(have) or (
            pa.types.is_dictionary(have) and _string_like(have.value_type)
        )
    else:
        ok = False
    if not ok:
        return None, f"expected {want}, found {have}"
    try:
        return arr.cast(want, safe=True), None
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as e:
        return None, f"expected {want}; found {have} values that do not convert ({e})"


def _to_numpy(arr: pa.ChunkedArray) -> np.ndarray:
    if pa.types.is_floating(arr.type):
        return _floats(arr)
    if _string_like(arr.type):
        return _strings(arr)
    return np.array(arr.to_pylist(), dtype=object)


def _strings(arr: pa.ChunkedArray) -> np.ndarray:
    """A text column as an object array with one Python string per distinct value (None for nulls): the line's
    objects hold these strings for the whole run, and a timetable repeats a few thousand station ids over
    hundreds of thousands of rows (on a 100x line one string a row held 100 MB of the job process)."""
    d = arr.combine_chunks().dictionary_encode()
    values = np.array(d.dictionary.to_pylist() + [None], dtype=object)
    idx = d.indices  # the codes, read from their buffer as _floats reads (compute's fill_null imports pandas)
    n = len(idx)
    if n == 0:
        return np.empty(0, dtype=object)
    codes = np.frombuffer(idx.buffers()[1], dtype=f"<i{idx.type.bit_width // 8}", count=idx.offset + n)[idx.offset:]
    codes = codes.astype(np.intp)
    codes[_null_mask(idx)] = len(values) - 1  # a null: None
    return values[codes]


def _floats(arr: pa.ChunkedArray) -> np.ndarray:
    """A float column as float64 with NaN for nulls, read from its buffers: Arrow's ``to_numpy`` imports
    pandas (a third of a second at the start of every run, before the first unit can start)."""
    a = arr.combine_chunks()
    if a.type != pa.float64():
        a = a.cast(pa.float64())
    n = len(a)
    if n == 0:
        return np.empty(0, dtype=np.float64)
    out = np.frombuffer(a.buffers()[1], dtype=np.float64, count=a.offset + n)[a.offset:].copy()
    out[_null_mask(a)] = np.nan
    return out


def _null_mask(a: pa.Array) -> np.ndarray:
    """Which values of ``a`` are null, from its validity bitmap (none without one)."""
    if not a.null_count:
        return np.zeros(len(a), dtype=bool)
    valid = np.unpackbits(np.frombuffer(a.buffers()[0], dtype=np.uint8), bitorder="little")
    return valid[a.offset:a.offset + len(a)] == 0


def _nulls(arr: pa.ChunkedArray) -> np.ndarray:
    """Which values of a column are null (:func:`_floats`: without Arrow's ``to_numpy``)."""
    return _null_mask(arr.combine_chunks())


def conform(spec: TableSpec, table: pa.Table) -> tuple[TableView | None, list[Violation]]:
    """Check ``table`` against ``spec``; return the view (None if unusable) and violations."""
    out: list[Violation] = []
    names = set(table.column_names)
    cast: dict[str, pa.ChunkedArray] = {}
    for field in spec.schema:
        if field.name not in names:
            if field.name not in spec.optional_columns:
                out.append(Violation(spec.file, None, field.name,
                                     f"required column is missing (expected {field.type})"
                                     + missing_column_hint(spec.name, field.name, names)))
            continue
        arr, problem = _cast_column(table.column(field.name), field.type)
        if problem:
            out.append(Violation(spec.file, None, field.name, problem))
        else:
            cast[field.name] = arr
    if out:
        return None, out

    n = table.num_rows
    view = TableView(spec, n, {c: _to_numpy(a) for c, a in cast.items()}, np.ones(n, dtype=bool))
    if n < spec.min_rows or (spec.max_rows is not None and n > spec.max_rows):
        if spec.max_rows == spec.min_rows:
            need = f"exactly {spec.min_rows} row"
        else:
            need = f"at least {spec.min_rows} row{'s' if spec.min_rows > 1 else ''}"
        out.append(Violation(spec.file, None, None, f"has {n} row{'' if n == 1 else 's'}; it needs {need}"))

    for field in spec.schema:
        if field.name not in cast:
            continue
        nulls = _nulls(cast[field.name])
        if not field.nullable:
            for i in np.flatnonzero(nulls):
                view.good[i] = False
                out.append(view.err(int(i), field.name, "null value; this column needs a value in every row"))
        if pa.types.is_floating(field.type):
            vals = view.cols[field.name]
            for i in np.flatnonzero(np.isnan(vals) & ~nulls):
                view.good[i] = False
                out.append(view.err(int(i), field.name,
                                    "value is NaN; write a finite number (or null where the column allows it)"))
            for i in np.flatnonzero(np.isinf(vals)):
                view.good[i] = False
                out.append(view.err(int(i), field.name, f"value is {fmt(vals[i])}; write a finite number"))
            rng = column_range(field)
            if rng is not None:
                with np.errstate(invalid="ignore"):
                    bad = np.isfinite(vals) & (rng.below(vals) | rng.above(vals))
                for i in np.flatnonzero(bad):
                    view.good[i] = False
                    out.append(view.err(int(i), field.name, out_of_range(rng, float(vals[i]))))
    return view, out
