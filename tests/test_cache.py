"""The work cache on its own: the pickle-free codec round-trips exactly, and no damaged,
swapped, forged or planted entry is ever returned (nor runs any code)."""
from __future__ import annotations

import hashlib
import io
import json
import math
import pickle
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



def test_a_large_entry_is_written_through_a_file_as_pack_makes_it(tmp_path, monkeypatch):
    """An entry whose members pass BIG_ENTRY_BYTES is encoded into an unnamed file beside it, hashed and copied
    from there (its bytes never held whole): the file holds exactly pack()'s bytes, it reads back as the object,
    and nothing else is left in the folder; the encoded buffer is never made on that route."""
    import planner.job.cache as cache

    obj = _sample() | {"big": np.arange(60_000, dtype=float)}  # ~480 kB of members
    monkeypatch.setattr(cache, "BIG_ENTRY_BYTES", 100_000)
    monkeypatch.setattr(cache, "_COPY", 1 << 12)  # hashed and copied in many pieces
    monkeypatch.setattr(cache, "npz_buffer", lambda *a: pytest.fail("a large entry was encoded in memory"))
    c = Cache(tmp_path / "cache")
    c.put("tables", KEY, obj)
    monkeypatch.undo()
    data = c.path("tables", KEY).read_bytes()
    assert data == pack("tables", KEY, obj) and len(data) > 60_000 * 8
    _same(c.get("tables", KEY), obj)
    assert [p.name for p in c.path("tables", KEY).parent.iterdir()] == [c.path("tables", KEY).name]


def test_a_large_entry_that_fails_part_way_leaves_the_old_one(tmp_path, monkeypatch):
    """A large entry whose writing fails (a full disk while it is encoded into the file beside it) leaves the entry
    that was there, and no file of its own."""
    import planner.job.cache as cache

    c = Cache(tmp_path / "cache")
    c.put("tables", KEY, {"old": 1})
    before = c.path("tables", KEY).read_bytes()
    monkeypatch.setattr(cache, "BIG_ENTRY_BYTES", 1000)

    def full(f, *a, **k):
        f.write(b"x" * 100)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(cache.np, "savez", full)
    with pytest.raises(OSError):
        c.put("tables", KEY, {"big": np.arange(1000.0)})
    monkeypatch.undo()
    assert c.path("tables", KEY).read_bytes() == before
    assert [p.name for p in c.path("tables", KEY).parent.iterdir()] == [c.path("tables", KEY).name]

def test_every_single_bit_flip_of_an_entry_is_rejected():
    data = pack("stops", KEY, {"t_s": np.array([0.0, 1.5]), "id": "B", "ok": True})
    assert len(data) > 500
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


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _tree(node) -> np.ndarray:
    return np.frombuffer(json.dumps(node).encode(), dtype=np.uint8)


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
        "npz with a pickled object array": _forge("tables", KEY, _npz(tree=_tree(None), a0=np.array(
            [_Reducer(marker)], dtype=object))),
        "tree naming a builtin": _forge("tables", KEY, _npz(tree=_tree(
            {"$dc": "builtins:eval", "f": {}}))),
        "tree naming os.system": _forge("tables", KEY, _npz(tree=_tree(
            {"$dc": "os:system", "f": {}}))),
        "tree naming a planner class with other fields": _forge("tables", KEY, _npz(tree=_tree(
            {"$dc": "planner.line.model:Station", "f": {"station_id": "A"}}))),
        "tree naming a planner function": _forge("tables", KEY, _npz(tree=_tree(
            {"$dc": "planner.io.atomic:write_bytes_atomic", "f": {}}))),
        "dotted path out of the package": _forge("tables", KEY, _npz(tree=_tree(
            {"$dc": "planner.job.cache:np.lib.format", "f": {}}))),
    }
    # positive control for the object array: numpy would unpickle it if allowed to
    np.load(io.BytesIO(unpack(payloads["npz with a pickled object array"])[1]), allow_pickle=True)["a0"]
    assert marker.exists()
    marker.unlink()
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


class _Reducer:
    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.write_text, (self.marker, "code ran"))


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
    buf = io.BytesIO()
    import zipfile

    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("tree.npy", b"not an npy")
        z.writestr("notes.txt", b"raw bytes")
    deep = "[" * 100_000 + "]" * 100_000
    payloads = [
        buf.getvalue(),
        _npz(tree=np.frombuffer(deep.encode(), dtype=np.uint8)),
        _npz(tree=_tree({"$d": [[[1], 2]]})),  # unhashable key
        _npz(tree=_tree({"$df": {"columns": ["a"], "data": [{"dtype": "<f8", "v": {"$a": "a0"}}],
                                 "index": {"range": [0, 5, 1]}}}), a0=np.zeros(3)),  # length mismatch
        _npz(tree=_tree({"$a": "missing"})),
        _npz(tree=_tree({"$np": "<f8", "v": {"$a": "a0"}}), a0=np.zeros(2)),
        _npz(tree=_tree({"$dc": "planner.line.model:Station"})),
    ]
    for payload in payloads:
        p.write_bytes(_forge("tables", KEY, payload))
        assert c.get("tables", KEY) is None
    assert c.rejected == len(payloads)
