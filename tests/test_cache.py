"""The work cache on its own: the pickle-free codec round-trips exactly, and no damaged,
swapped, forged or planted entry is ever returned (nor runs any code)."""
from __future__ import annotations

import hashlib
import json
import math
import pickle
import struct
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from planner.job.cache import MAGIC, Cache, CacheEntryError, decode, encode, pack, unpack
from planner.line.model import Segments, Station
from planner.job.publish import digest
from planner.stopping.pattern import PatternSamples
from planner.line.testing import train_type

KEY = digest(["unit", 1])
OTHER = digest(["unit", 2])


def _sample():
    """A result shaped like the pipeline's: dataclasses, arrays, frames with text and list columns."""
    frame = pd.DataFrame({
        "line": pd.array(["tiny", "tiny", None], dtype="str"),
        "n": np.array([1, 2, 3], dtype=np.int64),
        "seq": np.array([0, 1, 2], dtype=np.int32),
        "x_m": [0.5, math.nan, -0.0],
        "ok": [True, False, True],
        "train_ids": pd.Series([["101"], [], ["101", "202"]], dtype=object),
    })
    return {
        "station": Station("A", "Aoba", 200.0, 260.0, 140.0, 200.0),
        "segments": Segments(np.array([0.0, 1.0]), np.array([1.0, 2.5]), np.array([1e-3, -2e-3])),
        "train": train_type("EMU", length_m=123.0),
        "samples": PatternSamples(*(np.linspace(0, 1, 4) * k for k in range(1, 6))),
        "floats": (math.inf, -math.inf, 0.1, 1e-310, 2.0 ** 60),
        "ints": [0, -1, 2 ** 70],
        "text": ("", "é→", None, True),
        7: {"nested": {(1, "a"): np.arange(6, dtype=np.int16).reshape(2, 3)}},
        "scalar": np.float32(1.5),
        "frame": frame,
        "strings": np.array(["dep", "B1"]),
    }


def _same(a, b, path="obj"):
    """Exact equality, type by type (independent of the codec)."""
    import dataclasses

    assert type(a) is type(b), (path, type(a), type(b))
    if isinstance(a, pd.DataFrame):
        pd.testing.assert_frame_equal(a, b, check_exact=True)
        assert list(a.dtypes.astype(str)) == list(b.dtypes.astype(str)) and a.columns.dtype == b.columns.dtype
        for c in a.columns:
            _same(a[c].tolist(), b[c].tolist(), f"{path}[{c}]")
    elif dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _same(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), path
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, dict):
        assert list(a) == list(b), path
        for k in a:
            _same(a[k], b[k], f"{path}[{k!r}]")
    elif isinstance(a, float):
        assert math.copysign(1, a) == math.copysign(1, b) and (a == b or (math.isnan(a) and math.isnan(b))), path
    else:
        assert a == b, path


def test_codec_round_trips_exactly():
    obj = _sample()
    _same(obj, decode(encode(obj)))


def test_codec_refuses_what_it_cannot_store_exactly():
    class Local:
        pass

    for bad in (Local(), object(), np.array([Local()], dtype=object), pd.Series([1.0]), Path("x")):
        with pytest.raises(TypeError):
            encode(bad)


def test_a_good_entry_is_a_hit(tmp_path):
    c = Cache(tmp_path)
    c.put("tables", KEY, _sample())
    _same(c.get("tables", KEY), _sample())
    assert (c.hits, c.misses, c.rejected) == (1, 0, 0)
    assert c.path("tables", KEY).read_bytes().startswith(MAGIC)


def test_an_entry_is_written_as_pack_makes_it_without_being_joined(tmp_path, monkeypatch):
    """Cache.put writes the entry in pieces (its header, then the payload straight from the buffer it was encoded
    into: a line's conflict report is tens of megabytes, once, not three times): the file holds exactly pack()'s
    bytes, also when the payload is larger than one write, and reads back as the object."""
    import planner.io.atomic as atomic

    obj = {"big": np.arange(50_000, dtype=float), "small": [1, "two", None]}
    monkeypatch.setattr(atomic, "_CHUNK", 1 << 12)  # the payload (~400 kB) is written as it is, in many writes
    c = Cache(tmp_path / "cache")
    c.put("tables", KEY, obj)
    data = c.path("tables", KEY).read_bytes()
    assert data == pack("tables", KEY, obj) and len(data) > 50 * (1 << 12)
    got = c.get("tables", KEY)
    assert np.array_equal(got["big"], obj["big"]) and got["small"] == obj["small"]



def test_an_entry_is_written_from_its_arrays_own_memory(tmp_path):
    """An entry is hashed and written piece by piece, each array's piece a view of the array: storing 40 MB of
    arrays allocates well under one more copy of them (tracemalloc sees numpy's buffers), the file holds exactly
    pack()'s bytes, it reads back as the object, and nothing else is left in the folder."""
    import tracemalloc

    obj = _sample() | {"big": np.arange(5_000_000, dtype=float)}  # 40 MB of members
    c = Cache(tmp_path / "cache")
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        c.put("tables", KEY, obj)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20, f"storing 40 MB of arrays allocated {peak / 2**20:.1f} MB"
    data = c.path("tables", KEY).read_bytes()
    assert data == pack("tables", KEY, obj) and len(data) > 5_000_000 * 8
    _same(c.get("tables", KEY), obj)
    assert [p.name for p in c.path("tables", KEY).parent.iterdir()] == [c.path("tables", KEY).name]


def test_an_entry_that_fails_part_way_leaves_the_old_one(tmp_path, monkeypatch):
    """An entry whose writing fails part-way (a full disk after its first bytes) leaves the entry that was
    there, and no file of its own."""
    import planner.io.atomic as atomic

    c = Cache(tmp_path / "cache")
    c.put("tables", KEY, {"old": 1})
    before = c.path("tables", KEY).read_bytes()
    real = atomic._write_all

    def full(fd, data):
        real(fd, memoryview(data)[:100])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic, "_write_all", full)
    with pytest.raises(OSError):
        c.put("tables", KEY, {"big": np.arange(1_000_000.0)})
    monkeypatch.undo()
    assert c.path("tables", KEY).read_bytes() == before
    assert [p.name for p in c.path("tables", KEY).parent.iterdir()] == [c.path("tables", KEY).name]


def test_every_single_bit_flip_of_an_entry_is_rejected():
    data = pack("stops", KEY, {"t_s": np.array([0.0, 1.5]), "id": "B", "ok": True})
    assert len(data) > 300  # header, directory, tree and two arrays
    unpack(data, "stops", KEY)  # the intact entry passes
    accepted = 0
    for i in range(len(data)):
        for bit in range(8):
            flipped = bytearray(data)
            flipped[i] ^= 1 << bit
            try:
                unpack(bytes(flipped), "stops", KEY)
            except CacheEntryError:
                continue
            accepted += 1
    assert accepted == 0, f"{accepted} of {8 * len(data)} single-bit flips were accepted"


@pytest.mark.parametrize("damage", ["truncated", "empty", "other_key", "other_kind", "header_only", "folder"])
def test_damaged_or_misplaced_entries_are_misses(tmp_path, damage):
    c = Cache(tmp_path)
    c.put("tables", KEY, _sample())
    c.put("tables", OTHER, {"x": 1})
    c.put("stops", KEY, {"x": 2})
    p = c.path("tables", KEY)
    good = p.read_bytes()
    if damage == "truncated":
        p.write_bytes(good[: len(good) // 2])
    elif damage == "empty":
        p.write_bytes(b"")
    elif damage == "other_key":
        p.write_bytes(c.path("tables", OTHER).read_bytes())
    elif damage == "other_kind":
        p.write_bytes(c.path("stops", KEY).read_bytes())
    elif damage == "header_only":
        p.write_bytes(good[: good.index(b"\n", len(MAGIC)) + 1])
    elif damage == "folder":
        p.unlink()
        p.mkdir()
    assert c.get("tables", KEY) is None
    assert (c.hits, c.misses, c.rejected) == (0, 1, 1)
    c.put("tables", KEY, _sample())  # the recomputed result replaces it
    _same(c.get("tables", KEY), _sample())


def _evil_pickle(marker: Path) -> bytes:
    """A pickle that writes ``marker`` when it is loaded (the planted file of the hostile test)."""

    class Evil:
        def __reduce__(self):
            return (Path.write_text, (marker, "code ran"))

    return pickle.dumps(Evil())


def _forge(kind: str, key: str, payload: bytes) -> bytes:
    """An entry with a correct header and digest around any payload (what a forger could write)."""
    header = {"kind": kind, "key": key, "payload_bytes": len(payload),
              "payload_sha256": hashlib.sha256(payload).hexdigest()}
    return MAGIC + json.dumps(header).encode() + b"\n" + payload


def _raw(directory, tree: bytes, data: bytes = b"") -> bytes:
    """A payload laid out as planner.job.codec documents it, written here independently of it: magic, the two
    lengths, the directory, the tree, zeros to a multiple of 64, the data section."""
    head = json.dumps({"arrays": directory}, separators=(",", ":")).encode()
    lead = b"PCP1" + struct.pack("<QQ", len(head), len(tree)) + head + tree
    return lead + bytes(-len(lead) % 64) + data


def _payload(node, **arrays) -> bytes:
    """The payload of a tree (a JSON node, or bytes as they are) and arrays, each at a multiple of 64."""
    directory, data = [], b""
    for name, a in arrays.items():
        data += bytes(-len(data) % 64)
        directory.append([name, a.dtype.str, list(a.shape), len(data)])
        data += np.ascontiguousarray(a).tobytes()
    tree = node if isinstance(node, bytes) else json.dumps(node, separators=(",", ":")).encode()
    return _raw(directory, tree, data)


def test_the_payload_is_laid_out_as_documented():
    """The codec's payload equals one written from the layout its documentation gives (two arrays: the second
    starts at the next multiple of 64), and reads back."""
    from planner.job.codec import decode, encode

    obj = {"x": np.arange(3.0), "n": np.array([[1, 2], [3, 4]], dtype="<i4")}
    tree = {"$d": [["x", {"$a": "a0"}], ["n", {"$a": "a1"}]]}
    assert encode(obj) == _payload(tree, a0=obj["x"], a1=obj["n"])
    _same(decode(encode(obj)), obj)


def test_planted_files_never_run_code(tmp_path):
    marker = tmp_path / "marker"
    evil = _evil_pickle(marker)
    pickle.loads(evil)  # positive control: this file does run code when unpickled
    assert marker.read_text() == "code ran"
    marker.unlink()

    c = Cache(tmp_path / "cache")
    p = c.path("tables", KEY)
    p.parent.mkdir(parents=True)
    payloads = {
        "bare pickle": evil,
        "pickle behind a valid header": _forge("tables", KEY, evil),
        "a pickle as an object array's bytes": _forge("tables", KEY, _raw(
            [["a0", "|O", [1], 0]], b'{"$a":"a0"}', evil)),
        "tree naming a builtin": _forge("tables", KEY, _payload({"$dc": "builtins:eval", "f": {}})),
        "tree naming os.system": _forge("tables", KEY, _payload({"$dc": "os:system", "f": {}})),
        "tree naming a planner class with other fields": _forge("tables", KEY, _payload(
            {"$dc": "planner.line.model:Station", "f": {"station_id": "A"}})),
        "tree naming a planner function": _forge("tables", KEY, _payload(
            {"$dc": "planner.io.atomic:write_bytes_atomic", "f": {}})),
        "dotted path out of the package": _forge("tables", KEY, _payload(
            {"$dc": "planner.job.cache:np.lib.format", "f": {}})),
    }
    for name, data in payloads.items():
        p.write_bytes(data)
        assert c.get("tables", KEY) is None, name
    assert c.rejected == len(payloads) and c.hits == 0
    # and in the old layout's place (``.pkl``), which nothing reads any more
    (p.parent / f"{KEY}.pkl").write_bytes(evil)
    assert c.get("tables", KEY) is None
    assert not marker.exists()
    rep = c.verify()
    assert rep.good == 0 and len(rep.bad) == 1 and len(rep.foreign) == 1
    assert not marker.exists()


@pytest.mark.parametrize("kind,key", [("../x", KEY), ("tables", "../" + KEY[3:]), ("tables", KEY.upper()),
                                      ("Tables", KEY), ("tables", KEY[:-1])])
def test_names_that_could_leave_the_cache_are_refused(tmp_path, kind, key):
    with pytest.raises(ValueError):
        Cache(tmp_path).path(kind, key)


def test_no_cache_reads_nothing_but_writes(tmp_path):
    Cache(tmp_path).put("tables", KEY, {"x": 1})
    c = Cache(tmp_path, enabled=False)
    assert c.get("tables", KEY) is None and c.misses == 1 and c.rejected == 0
    c.put("tables", KEY, {"x": 2})
    assert Cache(tmp_path).get("tables", KEY) == {"x": 2}


def test_verify_and_clear(tmp_path):
    c = Cache(tmp_path / ".cache")
    for i in range(3):
        c.put("tables", digest(i), {"i": i})
    p = c.path("tables", digest(1))
    data = bytearray(p.read_bytes())
    data[-1] ^= 0x10
    p.write_bytes(bytes(data))
    (c.root / "stray.tmp").write_bytes(b"x")
    rep = c.verify()
    assert (rep.good, [q for q, _ in rep.bad], rep.foreign) == (2, [p], [c.root / "stray.tmp"])
    rep = c.verify(remove_bad=True)
    assert rep.removed == 2 and not p.exists()
    assert c.verify().good == 2 and not c.verify().bad
    assert c.clear() == 2 and not c.root.exists()


def test_forged_payloads_that_do_not_decode_are_misses(tmp_path):
    c = Cache(tmp_path)
    p = c.path("tables", KEY)
    p.parent.mkdir(parents=True)
    deep = "[" * 100_000 + "]" * 100_000
    ref = b'{"$a":"a0"}'
    payloads = [
        b"PK\x03\x04 a zip, not a payload",
        b"PCP1\x00",  # shorter than its lengths
        b"PCP1" + struct.pack("<QQ", 10**9, 0) + b"{}",  # lengths past the end
        _raw([["a0", "<f8", [4], 0]], ref, bytes(16)),  # an array past the end
        _raw([["a0", "<f8", [2], 8]], ref, bytes(64)),  # not aligned
        _raw([["a0", "<f8", [-2], 0]], ref, bytes(64)),  # negative shape
        _raw([["a0", "<f8,<i4", [1], 0]], ref, bytes(64)),  # structured
        _raw([["a0", "(2,)<f8", [1], 0]], ref, bytes(64)),  # sub-array
        _raw([["a0", "f8", [1], 0]], ref, bytes(64)),  # not numpy's own spelling
        _raw([["a0", "<f8", [1], 0], ["a0", "<f8", [1], 0]], ref, bytes(64)),  # a name twice
        _raw([["../a0", "<f8", [1], 0]], ref, bytes(64)),
        _raw({"a0": 1}, ref),
        _raw([["a0", "<f8", [0] + [2**39] * 31, 0]], ref),  # empty, but too big a shape for numpy
        _raw([["a0", "<U0", [2**39] * 32, 0]], ref),  # no bytes, but too big a shape for numpy
        _payload(deep.encode()),
        _payload({"$d": [[[1], 2]]}),  # unhashable key
        _payload({"$df": {"columns": ["a"], "data": [{"dtype": "<f8", "v": {"$a": "a0"}}],
                          "index": {"range": [0, 5, 1]}}}, a0=np.zeros(3)),  # length mismatch
        _payload({"$a": "missing"}),
        _payload({"$np": "<f8", "v": {"$a": "a0"}}, a0=np.zeros(2)),
        _payload({"$dc": "planner.line.model:Station"}),
    ]
    assert decode(_payload({"$np": "<f8", "v": {"$a": "a0"}}, a0=np.array(2.5))) == 2.5  # the control reads
    for payload in payloads:
        p.write_bytes(_forge("tables", KEY, payload))
        assert c.get("tables", KEY) is None
    assert c.rejected == len(payloads)


def test_a_read_back_checks_every_entry_and_decodes_only_what_the_job_keeps(tmp_path):
    """planner.job.units._read_kept: an entry is always checked by its digest; a unit whose result the job keeps
    nothing of is not decoded (a forged payload with a good digest passes the check and fails get), and what the
    job keeps is read from beside the result when stored there, made again from the result when that is missing."""
    from planner.job.units import _read_kept, _stored, kept_beside, nothing_kept

    c = Cache(tmp_path)
    p = c.path("charts", KEY)
    p.parent.mkdir(parents=True)
    p.write_bytes(_forge("charts", KEY, b"PK\x03\x04 not a payload"))  # its digest is right
    assert _read_kept(c, "charts", KEY, nothing_kept) == (None, None)  # checked, not decoded
    assert c.get("charts", KEY) is None and c.rejected == 1  # a get would refuse it
    data = bytearray(p.read_bytes())
    data[-1] ^= 1
    p.write_bytes(bytes(data))
    kept, why = _read_kept(c, "charts", KEY, nothing_kept)
    assert kept is None and "digest" in why

    @kept_beside
    def first(r):
        return r[0]

    assert _stored(c, "stops", KEY, first, [7, 8, 9]) == 7
    assert c.get("stops_kept", KEY) == 7  # stored beside the result
    c.put("stops_kept", KEY, 70)  # read from beside: the result is not decoded
    assert _read_kept(c, "stops", KEY, first) == (70, None)
    c.path("stops_kept", KEY).write_bytes(b"damaged")  # not trusted: made again from the result, and stored
    assert _read_kept(c, "stops", KEY, first) == (7, None) and c.get("stops_kept", KEY) == 7
    c.path("stops_kept", KEY).unlink()
    assert _read_kept(c, "stops", KEY, first) == (7, None) and c.get("stops_kept", KEY) == 7
    c.put("stops", KEY, [1, 2])  # a result not trusted is not vouched for by what is beside it
    c.path("stops", KEY).write_bytes(c.path("stops", KEY).read_bytes()[:-3])
    kept, why = _read_kept(c, "stops", KEY, first)
    assert kept is None and "bytes" in why
    assert _read_kept(c, "stops", OTHER, first) == (None, "missing")
