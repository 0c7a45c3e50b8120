"""The work cache of the nightly job: verified, pickle-free entries.

A cache entry is trusted no more than the inputs it stands for. Each entry is
one file ``OUTPUT_ROOT/.cache/<kind>/<ab>/<key>.pce`` (``ab`` = the first two
hex digits of the key) laid out as::

    PLANNER-CACHE 1\\n                   magic line (format version)
    {"kind": ..., "key": ..., "payload_bytes": N, "payload_sha256": ...}\\n
    <payload: N bytes, an NPZ archive>

The payload is an NPZ archive (numpy's zip of ``.npy`` members, read with
``allow_pickle=False``): member ``tree`` holds the result's structure as UTF-8
JSON and the other members its numeric arrays. DataFrames are stored column by
column (numeric columns as arrays, text columns as one Arrow stream each, list columns in the JSON).
Dataclasses and named tuples are rebuilt only when the JSON names a class of
the ``planner`` package of that kind, with exactly its fields; nothing read
back can import or run anything else. A planted pickle is just bytes that fail
the magic line.

On :meth:`Cache.get` the entry must carry the requested kind and key (an entry
copied or swapped under another name is refused), its payload must have the
stated length and SHA-256 (a flipped bit or a truncated file is refused), and
it must decode. Anything else is a *rejected* entry: treated as a miss (the
caller recomputes and :meth:`Cache.put` replaces it) and counted in
:attr:`Cache.rejected`, which the nightly job reports once per run.

The digest guards against damage, not against someone who can write the
output root: such a person could also write the published runs. Protect the
output root like the signing key's folder.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import io
import json
import re
import shutil
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from planner.io.atomic import write_chunks_atomic
from planner.io.memory import give_back

MAGIC = b"PLANNER-CACHE 1\n"
"""First line of every entry; bump the number when the layout changes (old entries then miss)."""
SUFFIX = ".pce"
"""Entry file suffix (planner cache entry)."""
MAX_HEADER_BYTES = 4096
KEY_RE = re.compile(r"^[0-9a-f]{64}$")
KIND_RE = re.compile(r"^[a-z][a-z0-9_]{0,31}$")


class CacheEntryError(ValueError):
    """An entry that cannot be trusted or decoded (the caller treats it as a miss)."""


# --- the pickle-free codec -----------------------------------------------------------------
def _class_name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


def _is_namedtuple(obj: Any) -> bool:
    return isinstance(obj, tuple) and hasattr(type(obj), "_fields")


def _resolve(name: Any, want: str) -> type:
    """The planner class ``module:qualname`` names, if it is a dataclass (``want="dc"``) or a named tuple."""
    if not isinstance(name, str) or ":" not in name:
        raise CacheEntryError(f"bad class name {name!r}")
    mod, qual = name.split(":", 1)
    if not (mod == "planner" or mod.startswith("planner.")) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.]*", mod) \
            or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", qual):
        raise CacheEntryError(f"class {name!r} is not a planner class")
    try:
        cls = getattr(importlib.import_module(mod), qual)
    except (ImportError, AttributeError):
        raise CacheEntryError(f"no class {name!r}") from None
    ok = (isinstance(cls, type) and dataclasses.is_dataclass(cls)) if want == "dc" else (
        isinstance(cls, type) and issubclass(cls, tuple) and hasattr(cls, "_fields"))
    if not ok:
        raise CacheEntryError(f"{name!r} is not a {'dataclass' if want == 'dc' else 'named tuple'}")
    return cls


class _Encoder:
    """Python object → (JSON-able tree, arrays). Raises TypeError for anything it cannot store exactly."""

    def __init__(self) -> None:
        self.arrays: dict[str, np.ndarray] = {}

    def array(self, a: np.ndarray) -> dict:
        if a.dtype.hasobject or a.dtype.kind not in "biufcSUMm" or a.dtype.fields is not None:
            raise TypeError(f"cannot cache an array of dtype {a.dtype}")
        name = f"a{len(self.arrays)}"
        self.arrays[name] = a if a.flags.c_contiguous else a.copy(order="C")
        return {"$a": name}

    def __call__(self, o: Any) -> Any:
        if o is None or isinstance(o, (bool, str)):
            return o
        if isinstance(o, int) and type(o) is int:
            return o
        if type(o) is float:
            return {"$f": o.hex()}
        if isinstance(o, np.ndarray):
            if o.dtype.hasobject:
                return {"$ao": [self(x) for x in o.tolist()], "shape": list(o.shape)}
            return self.array(o)
        if isinstance(o, np.generic):
            return {"$np": o.dtype.str, "v": self.array(np.asarray(o))}
        if dataclasses.is_dataclass(o) and not isinstance(o, type):
            cls = type(o)
            _resolve(_class_name(cls), "dc")  # fail now, not when reading back
            names = {f.name for f in dataclasses.fields(o)}
            if hasattr(o, "__dict__") and set(vars(o)) - names:  # would be lost: refuse rather than differ
                raise TypeError(f"cannot cache {_class_name(cls)}: attributes beyond its fields "
                                f"{sorted(set(vars(o)) - names)}")
            return {"$dc": _class_name(cls), "f": {f.name: self(getattr(o, f.name)) for f in dataclasses.fields(o)}}
        if _is_namedtuple(o):
            _resolve(_class_name(type(o)), "nt")
            return {"$nt": _class_name(type(o)), "v": [self(x) for x in o]}
        if type(o) is tuple:
            return {"$t": [self(x) for x in o]}
        if type(o) is list:
            return [self(x) for x in o]
        if type(o) is dict:
            return {"$d": [[self(k), self(v)] for k, v in o.items()]}
        if type(o) in (set, frozenset):
            return {"$s" if type(o) is set else "$fs": [self(x) for x in sorted(o, key=repr)]}
        import pandas as pd

        if type(o) is pd.DataFrame:
            return self.frame(o)
        import pyarrow as pa

        if isinstance(o, pa.Table):
            return {"$pa": self.array(np.frombuffer(_arrow_bytes(o), dtype=np.uint8))}
        raise TypeError(f"cannot cache a {type(o).__module__}.{type(o).__qualname__}")

    def frame(self, df) -> dict:
        import pandas as pd

        if df.attrs:
            raise TypeError("cannot cache a DataFrame with attrs")
        if not df.columns.is_unique:
            raise TypeError("cannot cache a DataFrame with duplicate column names")
        idx = df.index
        if type(idx) is pd.RangeIndex and idx.name is None:
            index = {"range": [idx.start, idx.stop, idx.step]}
        else:
            index = {"values": self.column(pd.Series(idx)), "name": self(idx.name)}
        return {"$df": {
            "columns": [self(c) for c in df.columns],
            "columns_dtype": str(df.columns.dtype),
            "data": [self.column(df[c]) for c in df.columns],
            "index": index,
        }}

    def column(self, s) -> dict:
        dt = s.dtype
        if isinstance(dt, np.dtype) and not dt.hasobject:
            return {"dtype": dt.str, "v": self.array(s.to_numpy())}
        if isinstance(dt, np.dtype):  # object: any values the tree can hold
            return {"dtype": "object", "v": [self(x) for x in s.tolist()]}
        name = str(dt)
        if name in ("str", "string"):  # every value a str or missing (null): one Arrow array, no str per value
            import pyarrow as pa

            text = pa.array(s, type=pa.large_string())
            return {"dtype": name, "arrow": self.array(np.frombuffer(_arrow_bytes(pa.table({"v": text})), np.uint8))}
        raise TypeError(f"cannot cache a DataFrame column of dtype {name}")


def _arrow_bytes(table) -> bytes:
    import pyarrow as pa

    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, table.schema) as w:
        w.write_table(table)
    return sink.getvalue().to_pybytes()


def _arrow_text(a: np.ndarray) -> list:
    """The values of a text column stored as an Arrow stream (:meth:`_Encoder.column`): str or None each."""
    import pyarrow as pa

    try:
        t = pa.ipc.open_stream(pa.py_buffer(a.tobytes())).read_all()
    except (pa.ArrowException, ValueError) as e:
        raise CacheEntryError(f"text column is not an Arrow stream ({type(e).__name__})") from None
    if t.column_names != ["v"] or not pa.types.is_large_string(t.schema.field("v").type):
        raise CacheEntryError("bad text column")
    return t.column("v").to_pylist()


class _Decoder:
    """(tree, arrays) → Python object; every node is checked, anything unexpected is a CacheEntryError."""

    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        self.arrays = arrays
        self.depth = 0

    def array(self, ref: Any) -> np.ndarray:
        if not isinstance(ref, dict) or set(ref) != {"$a"} or ref["$a"] not in self.arrays:
            raise CacheEntryError("bad array reference")
        return self.arrays[ref["$a"]]

    def __call__(self, n: Any) -> Any:
        self.depth += 1
        if self.depth > 200:
            raise CacheEntryError("tree too deep")
        try:
            return self._node(n)
        finally:
            self.depth -= 1

    def _node(self, n: Any) -> Any:
        if n is None or isinstance(n, (bool, str, int)):
            return n
        if isinstance(n, list):
            return [self(x) for x in n]
        if not isinstance(n, dict) or len(n) == 0:
            raise CacheEntryError(f"unexpected node {type(n).__name__}")
        tag = next(iter(n))
        if tag == "$f":
            try:
                return float.fromhex(n["$f"])
            except (TypeError, ValueError):
                raise CacheEntryError("bad float") from None
        if tag == "$a":
            return self.array(n).copy()
        if tag == "$ao":
            vals = [self(x) for x in _list(n["$ao"])]
            out = np.empty(len(vals), dtype=object)
            out[:] = vals
            try:
                return out.reshape(tuple(_list(n.get("shape"))))
            except (TypeError, ValueError):
                raise CacheEntryError("bad object array shape") from None
        if tag == "$np":
            a = self.array(n.get("v"))
            if a.shape != () or a.dtype.str != n["$np"]:
                raise CacheEntryError("bad numpy scalar")
            return a[()]
        if tag == "$t":
            return tuple(self(x) for x in _list(n["$t"]))
        if tag == "$d":
            out = {}
            for kv in _list(n["$d"]):
                if not isinstance(kv, list) or len(kv) != 2:
                    raise CacheEntryError("bad dict item")
                k = self(kv[0])
                try:
                    out[k] = self(kv[1])
                except TypeError:
                    raise CacheEntryError("unhashable dict key") from None
            return out
        if tag in ("$s", "$fs"):
            try:
                items = [self(x) for x in _list(n[tag])]
                return set(items) if tag == "$s" else frozenset(items)
            except TypeError:
                raise CacheEntryError("unhashable set item") from None
        if tag == "$dc":
            cls = _resolve(n["$dc"], "dc")
            fields = n.get("f")
            names = [f.name for f in dataclasses.fields(cls)]
            if not isinstance(fields, dict) or sorted(fields) != sorted(names):
                raise CacheEntryError(f"fields of {n['$dc']} do not match the class")
            obj = object.__new__(cls)
            for name in names:  # as pickle does: no __init__, frozen dataclasses included
                object.__setattr__(obj, name, self(fields[name]))
            return obj
        if tag == "$nt":
            cls = _resolve(n["$nt"], "nt")
            vals = [self(x) for x in _list(n.get("v"))]
            if len(vals) != len(cls._fields):
                raise CacheEntryError(f"fields of {n['$nt']} do not match the class")
            return cls(*vals)
        if tag == "$df":
            return self.frame(n["$df"])
        if tag == "$pa":
            import pyarrow as pa

            try:
                return pa.ipc.open_stream(pa.py_buffer(self.array(n["$pa"]).tobytes())).read_all()
            except (pa.ArrowException, ValueError) as e:
                raise CacheEntryError(f"bad Arrow table ({e})") from None
        raise CacheEntryError(f"unknown tag {tag!r}")

    def frame(self, f: Any):
        import pandas as pd

        if not isinstance(f, dict):
            raise CacheEntryError("bad DataFrame")
        cols = [self(c) for c in _list(f.get("columns"))]
        data = _list(f.get("data"))
        if len(cols) != len(data):
            raise CacheEntryError("DataFrame columns and data differ in length")
        series = [self.column(c) for c in data]
        lengths = {len(s) for s in series}
        index = f.get("index")
        if not isinstance(index, dict):
            raise CacheEntryError("bad DataFrame index")
        if "range" in index:
            r = _list(index["range"])
            if len(r) != 3 or not all(type(x) is int for x in r) or r[2] == 0:
                raise CacheEntryError("bad RangeIndex")
            idx = pd.RangeIndex(*r)
        else:
            idx = pd.Index(self.column(index.get("values")), name=self(index.get("name")))
        if lengths - {len(idx)}:
            raise CacheEntryError("DataFrame columns differ in length")
        try:
            df = pd.DataFrame({k: pd.Series(s, index=idx, copy=False) for k, s in zip(range(len(cols)), series)},
                              index=idx)
            df.columns = pd.Index(cols, dtype=f.get("columns_dtype"))
        except (TypeError, ValueError) as e:
            raise CacheEntryError(f"bad DataFrame ({e})") from None
        return df

    def column(self, c: Any):
        import pandas as pd

        if not isinstance(c, dict) or not isinstance(c.get("dtype"), str):
            raise CacheEntryError("bad DataFrame column")
        dt = c["dtype"]
        if dt == "object":
            vals = [self(x) for x in _list(c.get("v"))]
            out = np.empty(len(vals), dtype=object)
            out[:] = vals
            return out
        if dt in ("str", "string"):
            vals = _list(c.get("v")) if "arrow" not in c else _arrow_text(self.array(c["arrow"]))
            if not all(v is None or isinstance(v, str) for v in vals):
                raise CacheEntryError("bad text column")
            return pd.array(vals, dtype=dt)
        a = self.array(c.get("v"))
        if a.ndim != 1 or a.dtype.str != dt:
            raise CacheEntryError("bad numeric column")
        return a.copy()


def _list(x: Any) -> list:
    if not isinstance(x, list):
        raise CacheEntryError("expected a list")
    return x


def _payload(obj: Any) -> io.BytesIO:
    enc = _Encoder()
    tree = json.dumps(enc(obj), separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()
    buf = io.BytesIO()
    np.savez(buf, tree=np.frombuffer(tree, dtype=np.uint8), **enc.arrays)
    return buf


def encode(obj: Any) -> bytes:
    """The NPZ payload of ``obj`` (TypeError for a value the cache cannot store exactly)."""
    return _payload(obj).getvalue()


def decode(payload: bytes) -> Any:
    """The object an :func:`encode` payload holds; :class:`CacheEntryError` if it does not decode."""
    try:
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:  # never unpickles: object arrays fail
            arrays = {name: z[name] for name in z.files}
    except (ValueError, OSError, EOFError, KeyError, zipfile.BadZipFile, zipfile.LargeZipFile) as e:
        raise CacheEntryError(f"payload is not a readable NPZ archive ({type(e).__name__})") from None
    if not all(isinstance(a, np.ndarray) for a in arrays.values()):
        raise CacheEntryError("payload has members that are not arrays")
    tree = arrays.pop("tree", None)
    if tree is None or tree.dtype != np.uint8 or tree.ndim != 1:
        raise CacheEntryError("payload has no tree")
    try:
        node = json.loads(tree.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise CacheEntryError("tree is not JSON") from None
    try:
        return _Decoder(arrays)(node)
    except CacheEntryError:
        raise
    except Exception as e:  # noqa: BLE001 - a verified payload that still does not decode is a miss
        raise CacheEntryError(f"payload does not decode ({type(e).__name__})") from None


# --- entries --------------------------------------------------------------------------------
BIG_ENTRY_BYTES = 8 << 20
"""An entry at least this large gives its encoding's memory back once written (:func:`planner.io.memory.give_back`)."""


def pack(kind: str, key: str, obj: Any) -> bytes:
    """The bytes of one entry: magic line, header (kind, key, payload length and SHA-256), payload."""
    return b"".join(_entry(kind, key, obj))


def _entry(kind: str, key: str, obj: Any) -> list:
    """:func:`pack`'s bytes in two pieces, the payload a view of the buffer it was written to: an entry is written
    from them without copying it twice more (a line's conflict report is tens of megabytes)."""
    payload = _payload(obj).getbuffer()
    header = {"kind": kind, "key": key, "payload_bytes": payload.nbytes,
              "payload_sha256": hashlib.sha256(payload).hexdigest()}
    return [MAGIC + json.dumps(header, sort_keys=True, separators=(",", ":")).encode() + b"\n", payload]


def unpack(data: bytes, kind: str | None = None, key: str | None = None) -> tuple[dict, bytes]:
    """(header, payload) of an entry's bytes, checked; :class:`CacheEntryError` says why not."""
    if not data:
        raise CacheEntryError("empty file")
    if not data.startswith(MAGIC):
        raise CacheEntryError("not a planner cache entry (bad magic line)")
    end = data.find(b"\n", len(MAGIC), len(MAGIC) + MAX_HEADER_BYTES)
    if end < 0:
        raise CacheEntryError("truncated or oversized header")
    try:
        header = json.loads(data[len(MAGIC):end].decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise CacheEntryError("header is not JSON") from None
    if not isinstance(header, dict) or set(header) != {"kind", "key", "payload_bytes", "payload_sha256"}:
        raise CacheEntryError("header fields are wrong")
    if kind is not None and header["kind"] != kind:
        raise CacheEntryError(f"entry is of kind {header['kind']!r}, expected {kind!r}")
    if key is not None and header["key"] != key:
        raise CacheEntryError("entry holds another key (copied or swapped)")
    payload = data[end + 1:]
    if len(payload) != header["payload_bytes"]:
        raise CacheEntryError(f"payload has {len(payload)} bytes, header says {header['payload_bytes']} (truncated?)")
    if hashlib.sha256(payload).hexdigest() != header["payload_sha256"]:
        raise CacheEntryError("payload digest mismatch (damaged)")
    return header, payload


def check_name(kind: str, key: str) -> None:
    """Refuse a kind or key that could step outside the cache folder (they become path parts)."""
    if not KIND_RE.match(kind):
        raise ValueError(f"cache kind {kind!r} must match {KIND_RE.pattern}")
    if not KEY_RE.match(key):
        raise ValueError(f"cache key {key!r} must be 64 lowercase hex digits")


@dataclass
class VerifyReport:
    """What :meth:`Cache.verify` found: good entries, bad ones (path, why) and foreign files."""

    good: int = 0
    bad: list[tuple[Path, str]] = field(default_factory=list)
    foreign: list[Path] = field(default_factory=list)
    removed: int = 0


class Cache:
    """Results keyed by the digest of exactly the inputs they depend on (see the module doc).

    ``hits`` and ``misses`` count look-ups, which is how tests prove that an
    unchanged re-run recomputes nothing; ``rejected`` counts entries that were
    present but failed verification (each also counted as a miss), with the
    reasons in ``rejected_why``. ``enabled=False`` (``planner run --no-cache``)
    reads nothing and still writes fresh entries.
    """

    def __init__(self, root: Path, *, enabled: bool = True):
        self.root = Path(root)
        self.enabled = enabled
        self.hits = 0
        self.misses = 0
        self.rejected = 0
        self.rejected_why: list[tuple[str, str, str]] = []

    def path(self, kind: str, key: str) -> Path:
        check_name(kind, key)
        return self.root / kind / key[:2] / f"{key}{SUFFIX}"

    def get(self, kind: str, key: str) -> Any | None:
        """The stored result, or None: a missing, damaged, swapped or undecodable entry is a miss."""
        p = self.path(kind, key)
        if not self.enabled:
            self.misses += 1
            return None
        try:
            data = p.read_bytes()
        except FileNotFoundError:
            self.misses += 1
            return None
        except OSError as e:  # a folder in its place, unreadable, ...: not trusted, recomputed
            return self._reject(kind, key, f"unreadable ({e.strerror or type(e).__name__})")
        try:
            _, payload = unpack(data, kind, key)
            obj = decode(payload)
        except CacheEntryError as e:
            return self._reject(kind, key, str(e))
        self.hits += 1
        return obj

    def _reject(self, kind: str, key: str, why: str) -> None:
        self.misses += 1
        self.rejected += 1
        self.rejected_why.append((kind, key, why))
        return None

    def rejected_note(self) -> str:
        """One line for the run summary: how many entries were rejected, why (first reasons), where."""
        reasons: dict[str, int] = {}
        for _, _, why in self.rejected_why:
            reasons[why] = reasons.get(why, 0) + 1
        top = "; ".join(f"{n} × {why}" for why, n in sorted(reasons.items(), key=lambda kv: -kv[1])[:3])
        more = "; ..." if len(reasons) > 3 else ""
        s = "y" if self.rejected == 1 else "ies"
        return (f"{self.rejected} cache entr{s} in {self.root} failed verification and "
                f"{'was' if self.rejected == 1 else 'were'} recomputed and replaced ({top}{more}); "
                "if this repeats, check the disk or run `planner cache verify`")

    def put(self, kind: str, key: str, obj: Any) -> None:
        """Store ``obj`` (atomically: a killed run leaves the old entry or none, never half of one).

        Not flushed to disk one by one: an entry that a power cut leaves empty or torn fails
        its digest on the next read and is recomputed (:meth:`get`), so a flush per entry
        would buy nothing but time.
        """
        p = self.path(kind, key)
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        parts = _entry(kind, key, obj)
        big = parts[1].nbytes >= BIG_ENTRY_BYTES
        write_chunks_atomic(p, parts, fsync=False)
        del parts
        if big:  # its encoding's buffers, a few times its size, are given back before the next one is made
            give_back()

    # --- maintenance: `planner cache verify` and `planner cache clear`
    def entries(self) -> Iterator[Path]:
        """Every file under the cache root (entries and anything else), sorted."""
        if self.root.is_dir():
            yield from sorted(p for p in self.root.rglob("*") if p.is_file() or p.is_symlink())

    def verify(self, *, remove_bad: bool = False) -> VerifyReport:
        """Check every entry as :meth:`get` would (name, kind, key, digest, decoding)."""
        rep = VerifyReport()
        for p in self.entries():
            rel = p.relative_to(self.root).parts
            ok_name = (len(rel) == 3 and KIND_RE.match(rel[0]) and p.suffix == SUFFIX
                       and KEY_RE.match(p.stem) and rel[1] == p.stem[:2] and not p.is_symlink())
            if not ok_name:
                rep.foreign.append(p)
                continue
            try:
                _, payload = unpack(p.read_bytes(), rel[0], p.stem)
                decode(payload)
            except (CacheEntryError, OSError) as e:
                rep.bad.append((p, str(e)))
                if remove_bad:
                    p.unlink(missing_ok=True)
                    rep.removed += 1
                continue
            rep.good += 1
        if remove_bad:
            for p in rep.foreign:
                p.unlink(missing_ok=True)
                rep.removed += 1
        return rep

    def clear(self) -> int:
        """Remove the whole cache; returns how many files were removed."""
        n = sum(1 for _ in self.entries())
        if self.root.is_symlink():
            self.root.unlink()
        elif self.root.exists():
            shutil.rmtree(self.root)
        return n


__all__ = ["Cache", "CacheEntryError", "VerifyReport", "decode", "encode", "pack", "unpack"]
