"""The dataset writer's and reader's shortcuts give what the general path gives: the same partitions,
rows, chunks and bytes when writing; the same table (or error) as ``pyarrow.dataset`` when reading."""
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from planner.io.parquet import (_grouped_partitions, _only_value, _partitions, _string_partitions,
                                conform, declare, stamping, write_parquet_atomic, write_partitioned)

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


@pytest.mark.parametrize("name", CASES)
def test_string_partitions_come_out_as_from_the_group_by(name):
    """Keys, rows and chunk layout of every partition equal the general grouping's (so the bytes do);
    the shortcut is the one taken for these tables."""
    t = CASES[name]
    assert _string_partitions(t, PARTS) is not None
    fast, general = list(_partitions(t, PARTS)), list(_grouped_partitions(t, PARTS))
    assert [k for k, _ in fast] == [k for k, _ in general]
    for (_, a), (_, b) in zip(fast, general):
        assert a.equals(b, check_metadata=True)
        assert _layout(a) == _layout(b)


def test_the_general_grouping_for_the_rest():
    """Ints, nulls, columns chunked differently or empty chunks, several chunks and partitions: the
    group_by (the shortcut would change folders or chunks)."""
    mixed = pa.table({"line": pa.chunked_array([["L"] * 3, ["L"] * 3]), "x": pa.chunked_array([[1.0] * 6])})
    empty_chunk = pa.table({"line": pa.chunked_array([[], ["L"] * 3], pa.string()),
                            "x": pa.chunked_array([[], [1.0] * 3], pa.float64())})
    several = _chunked(MANY, [30, 30])
    for t, parts in [(pa.table({"line": [1, 1], "x": [1.0, 2.0]}), ["line"]),
                     (pa.table({"line": ["a", None], "x": [1.0, 2.0]}), ["line"]),
                     (mixed, ["line"]), (empty_chunk, ["line"]), (several, PARTS)]:
        assert _string_partitions(t, parts) is None
    assert [k for k, _ in _partitions(several, PARTS)] == [k for k, _ in _grouped_partitions(several, PARTS)]


def test_only_value():
    assert _only_value(pa.chunked_array([["E10"] * 5, ["E10"]])) == "E10"
    assert _only_value(pa.chunked_array([pa.array(["x", "y", "y", "y"]).slice(1)])) == "y"
    assert _only_value(pa.chunked_array([pa.array(["y", "y", "x"]).slice(0, 2)])) == "y"
    assert _only_value(pa.chunked_array([["", ""]])) == ""
    assert _only_value(pa.chunked_array([pa.array(["é", "é"], pa.large_string())])) == "é"
    for other in (["ab", "ba"], ["ab", "a", "b"], ["a", "aa"], ["a", "a", "b"]):
        assert _only_value(pa.chunked_array([other])) is None
    assert _only_value(pa.chunked_array([["a"], ["b"]])) is None


@pytest.mark.parametrize("name", CASES)
def test_same_bytes_as_the_group_by(tmp_path, name):
    """Files of write_partitioned (stamped, declared schema, sorted) are the bytes of the general grouping's."""
    t = CASES[name]
    with stamping("r0001-0000000000", "2026-12-01"):
        written = write_partitioned(t, tmp_path / "a", "ds", schema=SCHEMA, sort_by=["name"])
        for key, sub in _grouped_partitions(t, PARTS):
            folder = tmp_path / "b" / "ds" / "/".join(f"{c}={v}" for c, v in zip(PARTS, key))
            write_parquet_atomic(conform(sub.sort_by([("name", "ascending")]), SCHEMA), folder / "part-0.parquet")
    got = sorted(p.relative_to(tmp_path / "a").as_posix() for p in written)
    assert got == sorted(p.relative_to(tmp_path / "b").as_posix() for p in (tmp_path / "b").rglob("*.parquet"))
    for rel in got:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes()
    assert pq.read_table(tmp_path / "a" / got[0]).column("run_id")[0].as_py() == "r0001-0000000000"
