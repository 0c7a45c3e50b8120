"""The dataset writer's and reader's shortcuts give what the general path gives: the same partitions,
rows, chunks and bytes when writing; the same table (or error) as ``pyarrow.dataset`` when reading."""
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from planner.io.parquet import (_MAYBE_INT, _grouped_partitions, _int32s, _only_value, _partitions,
                                _read_partitions, _string_partitions, conform, declare, read_dataset, stamping,
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


# --- reading ---------------------------------------------------------------------------------


def _dataset_layer(root, dataset, **filters):
    """What read_dataset returned before it read files itself: ``pyarrow.dataset``'s table, filtered."""
    import pyarrow.compute as pc
    import pyarrow.dataset as ds

    d = ds.dataset(root / dataset, format="parquet", partitioning="hive")
    expr = None
    for k, v in filters.items():
        expr = pc.field(k) == v if expr is None else expr & (pc.field(k) == v)
    t = d.to_table(filter=expr)
    for name in PARTS:
        if name in t.column_names:
            t = t.set_column(t.column_names.index(name), name, pc.cast(t.column(name), pa.string()))
    return t


def _outcome(fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except Exception as e:  # noqa: BLE001 - the error itself is compared
        return type(e), str(e)


def _check(root, dataset, direct, **filters):
    """read_dataset gives the dataset layer's table (schema, metadata, rows, column order) or error, and
    reads the files itself exactly when ``direct``."""
    want, got = _outcome(_dataset_layer, root, dataset, **filters), _outcome(read_dataset, root, dataset, **filters)
    if isinstance(want, tuple):
        assert got == want
    else:
        assert isinstance(got, pa.Table), got
        assert got.equals(want, check_metadata=True)
        assert got.schema.equals(want.schema, check_metadata=True)
        assert [f.metadata for f in got.schema] == [f.metadata for f in want.schema]
    assert (_read_partitions(root / dataset, filters) is not None) == direct
    return got


@pytest.fixture
def run(tmp_path):
    """A run folder: ``ds`` in six partitions, as the job stamps them."""
    with stamping("r0001-0000000000", "2026-12-01"):
        write_partitioned(MANY, tmp_path, "ds", schema=SCHEMA)
    return tmp_path


FILTERS = [dict(line="L", direction="up", train_type="E6"), dict(direction="down", train_type="E8"),
           dict(line="L"), dict(train_type="E10"), {}, dict(line="L", direction="up", train_type="E99"),
           dict(line="M")]


@pytest.mark.parametrize("filters", FILTERS)
def test_read_partitions_as_the_dataset_layer(run, filters):
    got = _check(run, "ds", True, **filters)
    assert got.column_names[-3:] == PARTS
    assert (got.num_rows == 0) == (filters.get("train_type") == "E99" or filters.get("line") == "M")


def test_read_falls_back_where_it_would_differ(run):
    _check(run, "ds", False, origin="X")  # not a partition column
    _check(run, "ds", False, line=1)  # not text
    _check(run, "missing", False, line="L")  # FileNotFoundError
    (run / "empty").mkdir()
    _check(run, "empty", False)


def test_read_several_files_in_path_order_and_hidden_ones_skipped(run):
    part = run / "ds" / "line=L" / "direction=up" / "train_type=E10"
    with stamping("r0001-0000000000", "2026-12-01"):
        for i, n in ((10, 2), (2, 3), (1, 4)):
            write_parquet_atomic(conform(MANY.slice(0, n), SCHEMA), part / f"part-{i}.parquet")
    (part / ".part-0.parquet.x1.tmp").write_bytes(b"half a file")
    (part / "_SUCCESS").write_bytes(b"")
    (run / "ds" / "_tmp").mkdir()
    (run / "ds" / "_tmp" / "x.parquet").write_bytes(b"not parquet")
    got = _check(run, "ds", True, line="L", direction="up", train_type="E10")
    x = MANY.column("x").to_pylist()
    assert got.column("x").to_pylist()[-9:] == x[:4] + x[:2] + x[:3]  # part-0, then part-1, part-10, part-2
    _check(run, "ds", True, direction="up")


def test_read_an_empty_file_and_a_partition_of_one_key(tmp_path):
    """As the conflicts dataset: one empty file at line=L."""
    with stamping("r0001-0000000000", "2026-12-01"):
        write_parquet_atomic(SCHEMA.empty_table(), tmp_path / "c" / "line=L" / "part-0.parquet")
    assert _check(tmp_path, "c", True).num_rows == 0
    assert _check(tmp_path, "c", True, line="L").num_rows == 0


def test_read_other_files_layouts_and_values_by_the_dataset_layer(run):
    (run / "ds" / "README.md").write_text("not a Parquet file")
    _check(run, "ds", False, line="L")
    (run / "ds" / "README.md").unlink()
    with stamping("r0001-0000000000", "2026-12-01"):
        write_parquet_atomic(conform(MANY, SCHEMA), run / "ds" / "line=M" / "part-0.parquet")  # other depth
    _check(run, "ds", False, line="L")
    for values in (["1", "2"], ["007", "8"], ["0x1F", "2"]):  # all integers: the dataset layer's int32
        t = _rows(6, ["up"], ["E10"], line=values[0])
        write_partitioned(pa.concat_tables([t, _rows(6, ["up"], ["E10"], line=values[1])]), run, values[0],
                          schema=SCHEMA)
        _check(run, values[0], False, line=values[1])
    write_partitioned(_rows(6, ["up"], ["1"]), run, "int_type", schema=SCHEMA)
    _check(run, "int_type", False, line="L")
    odd = run / "odd" / "line=a%20b" / "direction=up" / "train_type=T"  # escaped in the path
    odd.mkdir(parents=True)
    pq.write_table(conform(MANY.slice(0, 3), SCHEMA), odd / "part-0.parquet")
    _check(run, "odd", False)


def test_read_takes_the_first_files_schema_as_the_dataset_layer(tmp_path):
    """Partitions written by two schema versions: the dataset's schema and metadata are those of the
    first file in path order, so a read of the other partition is left to the dataset layer."""
    v2 = declare([("x", pa.float64(), "a value"), ("name", pa.string(), "a name")], name="ds", version=2)
    write_partitioned(MANY.filter(pa.array([d == "down" for d in MANY.column("direction").to_pylist()])),
                      tmp_path, "ds", schema=SCHEMA)
    write_partitioned(MANY.filter(pa.array([d == "up" for d in MANY.column("direction").to_pylist()])),
                      tmp_path, "ds", schema=v2)
    assert _check(tmp_path, "ds", True, direction="down").schema.metadata[b"schema_version"] == b"1"
    assert _check(tmp_path, "ds", False, direction="up").schema.metadata[b"schema_version"] == b"1"
    stored = tmp_path / "ds" / "line=L" / "direction=up" / "train_type=E6" / "part-0.parquet"
    pq.write_table(pa.table({"x": [1.0], "line": ["L"]}), stored)  # a partition key stored as a column
    _check(tmp_path, "ds", False, direction="up", train_type="E6")


def test_maybe_int_holds_every_int32_text():
    """Values not matching _MAYBE_INT are typed string without asking Arrow: none of them parses."""
    import pyarrow.compute as pc

    for v in ["E10", "+5", " 7", "1e3", "1.0", "1_0", "0x", "x1", "-", "ab", "0b1", "0o7", "１"]:
        if not _MAYBE_INT.fullmatch(v):
            with pytest.raises(pa.ArrowInvalid):
                pc.cast(pa.array([v]), pa.int32())
    for v in ["7", "-7", "007", "0x1F", "0X1f", "2147483647"]:
        assert _MAYBE_INT.fullmatch(v) and _int32s([v])
    assert not _int32s(["2147483648"]) and not _int32s(["7", "E10"])
