"""A bundle's large tables read, checked and encoded a file at a time (``container.streamed_bytes``): the bundle
holds what the whole-table path gives, verifies, and every check still refuses what it refused."""
from __future__ import annotations

import io
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from planner.bundle.archive import unpack
from planner.bundle.assemble import Partition, partition, read_partition
from planner.bundle.container import build_bundle
from planner.bundle.contents import STREAMED
from planner.bundle.verify import read_bundle, verify_bundle
from planner.errors import BundleError
from test_bundle_support import LINE_ID, all_tables, make_line, release

PIECES = 3


@pytest.fixture(scope="module")
def line():
    return make_line()


def _write_partition(root: Path, name: str, t: pa.Table, pieces: int = PIECES) -> None:
    """``t`` as a hive partition of ``pieces`` files, the partition columns left out (as the datasets are)."""
    folder = root / name / f"line={LINE_ID}" / "direction=down" / "train_type=E10"
    folder.mkdir(parents=True)
    t = t.drop_columns([c for c in ("line", "direction", "train_type") if c in t.column_names])
    step = -(-t.num_rows // pieces)
    for i in range(pieces):
        pq.write_table(t.slice(i * step, step), folder / f"part-{i}.parquet")


def _build(tables, out, priv):
    return build_bundle(tables, line_id=LINE_ID, direction="down", train_type="E10", out_dir=out,
                        private_key=priv, release=release(), line_digest="ab" * 32)


def _datasets(tmp_path: Path, line, **edit) -> tuple[dict, Path]:
    tables = all_tables(line)
    root = tmp_path / "steps"
    for name in STREAMED:
        if name in tables:
            _write_partition(root, name, edit.get(name, tables[name]))
    return tables, root


def test_streamed_tables_are_the_whole_tables(tmp_path, keys, line):
    """Built from the partitions a file at a time, the bundle's tables are those read whole; it verifies, and
    each streamed member has a row group per file."""
    tables, root = _datasets(tmp_path, line)
    names = [n for n in STREAMED if n in tables]
    assert {"table_b", "table_d", "stop_samples"} <= set(names)
    whole = dict(tables) | {n: read_partition(root, n, LINE_ID, "down", "E10") for n in names}
    parts = dict(tables) | {n: partition(root, n, LINE_ID, "down", "E10") for n in names}
    assert all(isinstance(parts[n], Partition) and len(parts[n].files) == PIECES for n in names)
    a = _build(whole, tmp_path / "whole", keys[0])
    b = _build(parts, tmp_path / "streamed", keys[0])
    assert verify_bundle(b.path, keys[1]) == b
    got_a, got_b = read_bundle(a.path, keys[1]).tables, read_bundle(b.path, keys[1]).tables
    assert got_a.keys() == got_b.keys()
    for n in got_a:
        assert got_b[n].equals(got_a[n]), n
    assert {f.name: f.rows for f in a.files} == {f.name: f.rows for f in b.files}
    with open(b.path, "rb") as f:
        members = unpack(f, Path(b.path).stat().st_size, b.path)
    for n in names:
        assert pq.ParquetFile(io.BytesIO(members[f"{n}.parquet"])).metadata.num_row_groups == PIECES


def test_streamed_bytes_are_reproducible(tmp_path, keys, line):
    _, root = _datasets(tmp_path, line)
    tables = all_tables(line)
    out = []
    for k in ("one", "two"):
        parts = dict(tables) | {n: partition(root, n, LINE_ID, "down", "E10") for n in STREAMED if n in tables}
        out.append(Path(_build(parts, tmp_path / k, keys[0]).path).read_bytes())
    assert out[0] == out[1]


def test_cross_check_of_a_streamed_table_still_refuses(tmp_path, keys, line):
    """A ratio of table (b) that table (a) lacks, in the last file only: refused as on the whole-table path."""
    tb = all_tables(line)["table_b"]
    last = tb.num_rows - 1
    tb = tb.set_column(tb.schema.get_field_index("ratio_after"), "ratio_after",
                       pc.if_else(pa.array([i == last for i in range(tb.num_rows)]), 0.123,
                                  tb.column("ratio_after")))
    tables, root = _datasets(tmp_path, line, table_b=tb)
    parts = dict(tables) | {n: partition(root, n, LINE_ID, "down", "E10") for n in STREAMED if n in tables}
    with pytest.raises(BundleError, match=r"table_b ratio_after 0\.123 for .* is not in table_a"):
        _build(parts, tmp_path / "out", keys[0])
    assert not list((tmp_path / "out").glob("*.pdb"))


def test_a_file_of_another_direction_is_refused(tmp_path, keys, line):
    tables, root = _datasets(tmp_path, line)
    folder = root / "table_d" / f"line={LINE_ID}" / "direction=down" / "train_type=E10"
    t = pq.read_table(folder / "part-2.parquet")
    pq.write_table(t.append_column("direction", pa.array(["up"] * t.num_rows)), folder / "part-2.parquet")
    parts = dict(tables) | {"table_d": partition(root, "table_d", LINE_ID, "down", "E10")}
    with pytest.raises(BundleError, match="table_d column direction holds \\['up'\\], expected only 'down'"):
        _build(parts, tmp_path / "out", keys[0])


def test_files_of_other_columns_are_refused(tmp_path, keys, line):
    tables, root = _datasets(tmp_path, line)
    folder = root / "stop_samples" / f"line={LINE_ID}" / "direction=down" / "train_type=E10"
    t = pq.read_table(folder / "part-1.parquet")
    pq.write_table(t.drop_columns([t.column_names[-1]]), folder / "part-1.parquet")
    parts = dict(tables) | {"stop_samples": partition(root, "stop_samples", LINE_ID, "down", "E10")}
    with pytest.raises(BundleError, match="table stop_samples: its pieces differ in their columns"):
        _build(parts, tmp_path / "out", keys[0])
    # the whole-table path refuses the same partition too
    with pytest.raises(BundleError, match="cannot read"):
        read_partition(root, "stop_samples", LINE_ID, "down", "E10")
