"""The dataset writer's shortcut for a table of one partition gives what the general grouping gives: the
same partitions, rows, chunks and bytes."""
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from planner.io.parquet import (_grouped_partitions, _one_partition, _partitions, conform, declare,
                                write_parquet_atomic, write_partitioned)

PARTS = ["line", "direction", "train_type"]
SCHEMA = declare([("x", pa.float64(), "a value"), ("name", pa.string(), "a name")], name="ds")


def _layout(t: pa.Table) -> list[list[int]]:
    return [[len(c) for c in col.chunks] for col in t.columns]


def _rows(n: int, directions, types, line="L", string=pa.string()) -> pa.Table:
    return pa.table({
        "line": pa.array([line] * n, string),
        "x": pa.array([float(i) for i in range(n)]),
        "direction": pa.array([directions[i % len(directions)] for i in range(n)], string),
        "name": pa.array([f"n{i % 7}" for i in range(n)]),
        "train_type": pa.array([types[(i // 3) % len(types)] for i in range(n)], string),
    })


def _chunked(t: pa.Table, sizes) -> pa.Table:
    """``t`` with every column cut into chunks of ``sizes`` rows (as the job's tables come, concatenated)."""
    cuts, at = [], 0
    for s in sizes:
        cuts.append(t.slice(at, s))
        at += s
    return pa.concat_tables(cuts)


ONE = _chunked(_rows(60, ["up"], ["E10"]), [6, 13, 5, 36])
MANY = _rows(60, ["up", "down"], ["E10", "E6", "E8"])
CASES = {
    "one partition, several chunks": ONE,
    "one partition, large strings": _rows(20, ["up"], ["E10"], string=pa.large_string()),
    "one partition, filtered": _rows(30, ["up", "down"], ["E10"]).filter(pa.array([i % 2 == 0 for i in range(30)])),
    "one partition, sliced chunk": pa.concat_tables([_rows(40, ["down"], ["E6"]).slice(7, 20)]),
    "several partitions": MANY,
    "several partitions, large strings": _rows(60, ["up", "down"], ["E10", "E6"], string=pa.large_string()),
    "several partitions, values sharing prefixes": _rows(30, ["up", "upup", "u"], ["E1", "E10", "E"]),
    "same bytes, other rows": _rows(4, ["ab", "ba"], ["x"]),
}


ONE_PARTITION = {name for name in CASES if name.startswith("one partition")}


@pytest.mark.parametrize("name", CASES)
def test_partitions_come_out_as_from_the_group_by(name):
    """Keys, rows and chunk layout of every partition equal the general grouping's (so the bytes do);
    the shortcut is the one taken for the tables of one partition."""
    t = CASES[name]
    assert (_one_partition(t, PARTS) is not None) == (name in ONE_PARTITION)
    fast, general = list(_partitions(t, PARTS)), list(_grouped_partitions(t, PARTS))
    assert [k for k, _ in fast] == [k for k, _ in general]
    for (_, a), (_, b) in zip(fast, general):
        assert a.equals(b, check_metadata=True)
        assert _layout(a) == _layout(b)


def test_the_general_grouping_for_the_rest():
    """Nulls, columns chunked differently or empty chunks: the group_by (the shortcut would change folders or
    chunks); an int partition column of one value takes the shortcut, its folder named as the group_by names it."""
    mixed = pa.table({"line": pa.chunked_array([["L"] * 3, ["L"] * 3]), "x": pa.chunked_array([[1.0] * 6])})
    empty_chunk = pa.table({"line": pa.chunked_array([[], ["L"] * 3], pa.string()),
                            "x": pa.chunked_array([[], [1.0] * 3], pa.float64())})
    for t, parts in [(pa.table({"line": ["a", None], "x": [1.0, 2.0]}), ["line"]),
                     (pa.table({"line": [None, None], "x": [1.0, 2.0]}), ["line"]),
                     (mixed, ["line"]), (empty_chunk, ["line"]), (_chunked(MANY, [30, 30]), PARTS)]:
        assert _one_partition(t, parts) is None
        assert [k for k, _ in _partitions(t, parts)] == [k for k, _ in _grouped_partitions(t, parts)]
    ints = pa.table({"line": [7, 7], "x": [1.0, 2.0]})
    assert _one_partition(ints, ["line"]) == ("7",) == next(_grouped_partitions(ints, ["line"]))[0]


@pytest.mark.parametrize("name", CASES)
def test_same_bytes_as_the_group_by(tmp_path, name):
    """Files of write_partitioned (declared schema, sorted) are the bytes of the general grouping's."""
    t = CASES[name]
    written = write_partitioned(t, tmp_path / "a", "ds", schema=SCHEMA, sort_by=["name"])
    for key, sub in _grouped_partitions(t, PARTS):
        folder = tmp_path / "b" / "ds" / "/".join(f"{c}={v}" for c, v in zip(PARTS, key))
        write_parquet_atomic(conform(sub.sort_by([("name", "ascending")]), SCHEMA), folder / "part-0.parquet")
    got = sorted(p.relative_to(tmp_path / "a").as_posix() for p in written)
    assert got == sorted(p.relative_to(tmp_path / "b").as_posix() for p in (tmp_path / "b").rglob("*.parquet"))
    for rel in got:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes()
