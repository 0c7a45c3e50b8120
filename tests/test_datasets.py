"""Hive-partitioned dataset writes: layout, determinism, declared schema, read-back."""
import hashlib

import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.parquet as pq

from planner.io.parquet import declare, read_dataset, write_partitioned

SCHEMA = declare(
    [("ratio", pa.float64(), "target-speed ratio"), ("running_time_s", pa.float64(), "running time [s]")],
    name="table_a",
)


def _table():
    return pa.table({
        "line": ["L"] * 4,
        "direction": ["up", "down", "down", "up"],
        "train_type": ["T"] * 4,
        "ratio": [1.0, 0.9, 1.0, 0.9],
        "running_time_s": [100, 111.5, 99.0, 120.0],
    })


def test_layout_and_readback(tmp_path):
    files = write_partitioned(_table(), tmp_path, "table_a", schema=SCHEMA, sort_by=["ratio"])
    rel = [f.relative_to(tmp_path).as_posix() for f in files]
    assert rel == [
        "table_a/line=L/direction=down/train_type=T/part-0.parquet",
        "table_a/line=L/direction=up/train_type=T/part-0.parquet",
    ]
    t = ds.dataset(tmp_path / "table_a", partitioning="hive").to_table()
    assert t.num_rows == 4
    down = read_dataset(tmp_path, "table_a", direction="down").to_pydict()
    # sorted by ratio inside the file, integer input cast to the declared double
    assert down["ratio"] == [0.9, 1.0]
    assert down["running_time_s"] == [111.5, 99.0]
    assert down["direction"] == ["down", "down"]
    f = ds.dataset(files[0]).schema
    assert f.field("running_time_s").metadata[b"description"] == b"running time [s]"


def test_same_table_same_bytes(tmp_path):
    a = write_partitioned(_table(), tmp_path / "a", "x", schema=SCHEMA)
    b = write_partitioned(_table(), tmp_path / "b", "x", schema=SCHEMA)
    digest = lambda fs: [hashlib.sha256(f.read_bytes()).hexdigest() for f in fs]  # noqa: E731
    assert digest(a) == digest(b)
    assert not list((tmp_path / "a").rglob("*.tmp"))


def test_a_table_made_from_a_frame_is_the_same_bytes_as_from_arrays_whatever_the_pandas_version(tmp_path):
    """pandas records its own version in a table made from a frame: a file written from one would be other bytes
    after a pandas update (a fresh install got 3.1.2 where the team's had 3.1.1, and five datasets differed).
    The writer leaves that record out, and keeps the planner's own metadata."""
    import pandas as pd

    from planner.io.parquet import write_parquet_atomic

    frame = pd.DataFrame({"ratio": [1.0, 0.9], "running_time_s": [100.0, 111.5]})
    made = pa.Table.from_pandas(frame, preserve_index=False)
    assert b"pandas" in made.schema.metadata  # what pandas adds, here as in the planner's writers
    other = made.replace_schema_metadata({**made.schema.metadata, b"pandas": made.schema.metadata[b"pandas"]
                                          .replace(pd.__version__.encode(), b"0.0.0-other")})
    plain = pa.table({"ratio": [1.0, 0.9], "running_time_s": [100.0, 111.5]})
    for name, t in (("frame", made), ("other", other), ("plain", plain)):
        write_parquet_atomic(t, tmp_path / f"{name}.parquet")
    read = lambda n: (tmp_path / f"{n}.parquet").read_bytes()  # noqa: E731
    assert read("frame") == read("other") == read("plain")
    assert b"pandas" not in (pq.read_metadata(tmp_path / "frame.parquet").metadata or {})
    kept = pa.table({"x": [1]}).replace_schema_metadata({b"planner": b"mine", b"pandas": b"{}"})
    write_parquet_atomic(kept, tmp_path / "kept.parquet")
    assert pq.read_schema(tmp_path / "kept.parquet").metadata == {b"planner": b"mine"}


def test_partitions_keep_row_order_and_name_folders_by_the_values_text(tmp_path):
    """Grouped in Arrow, not per row in Python: rows keep their order inside a partition, a folder is
    named by str() of its value (ints included), and a missing value is a 'None' folder."""
    t = pa.table({"line": ["b", "a", "b", None, "a"], "k": [2, 1, 2, 3, 1], "x": [5, 4, 3, 2, 1]})
    files = write_partitioned(t, tmp_path, "ds", partition_cols=("line", "k"))
    got = {f.relative_to(tmp_path).as_posix(): pq.read_table(f).column("x").to_pylist() for f in files}
    assert got == {"ds/line=None/k=3/part-0.parquet": [2], "ds/line=a/k=1/part-0.parquet": [4, 1],
                   "ds/line=b/k=2/part-0.parquet": [5, 3]}
    assert [f.relative_to(tmp_path).as_posix() for f in files] == sorted(got)  # sorted partition order
