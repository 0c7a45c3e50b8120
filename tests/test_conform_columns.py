"""Columns read from their buffers (planner.line.conform): the same values as Arrow's own conversion, which
imports pandas (a third of a second before a run's first unit), on the shapes Arrow gives: several chunks,
offsets (slices), nulls, float32, empty."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from planner.line.conform import _floats, _nulls, _to_numpy

CASES = [
    pa.chunked_array([[1.0, None, 3.0], [None, 5.0]]),
    pa.chunked_array([pa.array([1.0, None, 3.0, 4.0, None, 6.0, 7.0, 8.0, 9.0, None]).slice(1, 8)]),
    pa.chunked_array([pa.array([0.5, 1.5])], type=pa.float64()),
    pa.chunked_array([pa.array([1.5, None, -2.25], type=pa.float32())]),
    pa.chunked_array([], type=pa.float64()),
]


@pytest.mark.parametrize("col", CASES, ids=range(len(CASES)))
def test_floats_and_nulls_as_arrow_converts_them(col):
    want = np.asarray(col.to_numpy(), dtype=np.float64)
    got = _floats(col)
    assert got.dtype == np.float64 and got.flags.writeable
    assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(_nulls(col), np.asarray(pc.is_null(col).to_numpy(zero_copy_only=False), dtype=bool))


def test_nulls_of_a_text_column_with_an_offset():
    col = pa.chunked_array([pa.array(["a", None, "b", None, "c"]).slice(1, 3), pa.array([None, "d"])])
    assert _nulls(col).tolist() == [True, False, True, True, False]


def test_reading_a_line_does_not_import_pandas():
    """The point of reading the buffers: a line is loaded (and checked) before any unit starts."""
    code = ("import sys\nfrom planner.line.loader import load_line\nload_line('lines/sample')\n"
            "print('pandas' in sys.modules, 'pyarrow.dataset' in sys.modules)")
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


@pytest.mark.parametrize("col", [
    pa.chunked_array([pa.array(["stn-a", "stn-b", None, "stn-a"])]),
    pa.chunked_array([pa.array(["stn-x", None, "stn-y", "stn-x"]).slice(1, 3), pa.array([None, "stn-z", "stn-y"])]),
    pa.chunked_array([pa.array([None, None], type=pa.string())]),
    pa.chunked_array([], type=pa.string()),
    pa.chunked_array([pa.array(["train-q", "train-r", "train-q"], type=pa.large_string())]),
])
def test_a_text_column_reads_as_its_values_with_one_string_per_distinct_value(col):
    """What Arrow's to_pylist gives, nulls as None, offsets and chunks read right; and each distinct value one
    Python string, which every row that holds it shares (the line's objects keep them for the whole run)."""
    got = _to_numpy(col)
    assert got.dtype == object and got.tolist() == col.to_pylist()
    first: dict = {}
    for v in got:
        if v is not None:
            assert first.setdefault(v, v) is v
