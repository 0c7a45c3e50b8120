"""The work cache's pickle-free codec: a result as a JSON tree and numeric arrays, laid out in one payload.

:func:`encode` stores dataclasses, named tuples, containers, numbers, text, numpy arrays, DataFrames
(column by column: numeric columns as arrays, text columns as one Arrow stream each, list columns in
the JSON) and Arrow tables exactly, and refuses anything else (TypeError). :func:`decode` rebuilds
them from a payload (:func:`payload_pieces`) whose arrays are plain numbers or text only: dataclasses
and named tuples only when the JSON names a class of the ``planner`` package of that kind, with
exactly its fields, so nothing read back can import or run anything else; anything unexpected is a
:class:`CacheEntryError`. The entries around the payload (header, digest) and the cache itself are
:mod:`planner.job.cache`'s.
"""
from __future__ import annotations

import dataclasses
import importlib
import json
import math
import re
import struct
from typing import Any

import numpy as np


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


_PLAIN = (str, int, bool)


def _float(h: Any) -> float:
    try:
        return float.fromhex(h)
    except (TypeError, ValueError):
        raise CacheEntryError("bad float") from None


class _Decoder:
    """(tree, arrays) → Python object; every node is checked, anything unexpected is a CacheEntryError."""

    def __init__(self, arrays: dict[str, np.ndarray]) -> None:
        self.arrays = arrays
        self.depth = 0

    def array(self, ref: Any) -> np.ndarray:
        if not isinstance(ref, dict) or set(ref) != {"$a"} or ref["$a"] not in self.arrays:
            raise CacheEntryError("bad array reference")
        return self.arrays[ref["$a"]]

    def items(self, xs: list) -> list:
        """The nodes of a list, its plain values and floats (the bulk of a long one) read in place."""
        return [x if x is None or type(x) in _PLAIN else _float(x["$f"]) if type(x) is dict and len(x) == 1
                and "$f" in x else self(x) for x in xs]

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
            return self.items(n)
        if not isinstance(n, dict) or len(n) == 0:
            raise CacheEntryError(f"unexpected node {type(n).__name__}")
        tag = next(iter(n))
        if tag == "$f":
            return _float(n["$f"])
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
            return tuple(self.items(_list(n["$t"])))
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
            if "arrow" in c:  # a large_string Arrow column (checked): str or None each
                return pd.array(_arrow_text(self.array(c["arrow"])), dtype=dt)
            vals = _list(c.get("v"))
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


def members(obj: Any) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The payload's members: the tree (UTF-8 JSON as bytes) and the arrays it refers to (TypeError for a value
    the cache cannot store exactly)."""
    enc = _Encoder()
    tree = json.dumps(enc(obj), separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()
    return np.frombuffer(tree, dtype=np.uint8), enc.arrays


PAYLOAD_MAGIC = b"PCP1"
"""First bytes of a payload (planner cache payload, layout 1)."""
ALIGN = 64
"""Every array's bytes start at a multiple of this from the start of the data section."""
_LENGTHS = struct.Struct("<QQ")
_NAME = re.compile(r"a[0-9]{1,9}")


def payload_pieces(tree: np.ndarray, arrays: dict[str, np.ndarray]) -> list:
    """The payload of :func:`members` as pieces to be written one after another, each array's piece a view of its
    own memory (nothing is copied, however large)::

        PCP1 | directory length, tree length (two little-endian uint64) | directory (JSON) | tree (JSON)
        | zero bytes to a multiple of ALIGN | the arrays' bytes, each starting at a multiple of ALIGN

    The directory is ``{"arrays": [[name, dtype, shape, offset], ...]}``: ``dtype`` numpy's string for it
    (``"<f8"``), ``offset`` from the start of the data section. One NPZ member per array cost a zip entry and
    a header parsed with ``ast`` each; this layout is read with one JSON parse and a view per array."""
    directory, pieces, offset = [], [], 0
    for name, a in arrays.items():
        raw = a.reshape(-1).view(np.uint8)  # C-contiguous (the encoder made it so): a view
        pad = -offset % ALIGN
        if pad:
            pieces.append(bytes(pad))
            offset += pad
        directory.append([name, a.dtype.str, list(a.shape), offset])
        pieces.append(memoryview(raw))
        offset += raw.nbytes
    head = json.dumps({"arrays": directory}, separators=(",", ":")).encode()
    tree = memoryview(tree).cast("B")
    lead = PAYLOAD_MAGIC + _LENGTHS.pack(len(head), tree.nbytes) + head
    start = len(lead) + tree.nbytes
    return [lead, tree, bytes(-start % ALIGN), *pieces]


def _arrays(payload: memoryview) -> tuple[bytes, dict[str, np.ndarray]]:
    """(tree, arrays) of a payload, every part checked: the arrays read-only views of ``payload``."""
    lead = len(PAYLOAD_MAGIC) + _LENGTHS.size
    if len(payload) < lead or bytes(payload[:len(PAYLOAD_MAGIC)]) != PAYLOAD_MAGIC:
        raise CacheEntryError("payload is not a planner cache payload (bad magic)")
    head_len, tree_len = _LENGTHS.unpack_from(payload, len(PAYLOAD_MAGIC))
    tree_at = lead + head_len
    data = tree_at + tree_len + (-(tree_at + tree_len) % ALIGN)
    if data > len(payload):
        raise CacheEntryError("payload is shorter than its lengths say")
    try:
        head = json.loads(bytes(payload[lead:tree_at]))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise CacheEntryError("payload directory is not JSON") from None
    if not isinstance(head, dict) or set(head) != {"arrays"} or not isinstance(head["arrays"], list):
        raise CacheEntryError("bad payload directory")
    arrays: dict[str, np.ndarray] = {}
    for item in head["arrays"]:
        if not (isinstance(item, list) and len(item) == 4 and isinstance(item[0], str) and _NAME.fullmatch(item[0])
                and item[0] not in arrays and isinstance(item[1], str) and isinstance(item[2], list)
                and all(type(n) is int and 0 <= n < 2**40 for n in item[2]) and len(item[2]) <= 32
                and type(item[3]) is int and 0 <= item[3] and item[3] % ALIGN == 0):
            raise CacheEntryError("bad array in the payload directory")
        name, dt, shape, offset = item
        try:
            dtype = np.dtype(dt)
        except (TypeError, ValueError, SyntaxError):
            raise CacheEntryError(f"bad dtype {dt!r}") from None
        if dtype.hasobject or dtype.kind not in "biufcSUMm" or dtype.fields is not None or dtype.str != dt \
                or dtype.subdtype is not None:
            raise CacheEntryError(f"dtype {dt!r} is not a plain numeric or text dtype")
        count = math.prod(shape)
        start = data + offset
        if start + count * dtype.itemsize > len(payload):
            raise CacheEntryError("an array runs past the end of the payload")
        if count == 0 or dtype.itemsize == 0:
            arrays[name] = np.zeros(shape, dtype=dtype)
        else:
            arrays[name] = np.frombuffer(payload, dtype=dtype, count=count, offset=start).reshape(shape)
    return bytes(payload[tree_at:tree_at + tree_len]), arrays


def encode(obj: Any) -> bytes:
    """The payload of ``obj``, whole (TypeError for a value the cache cannot store exactly)."""
    return b"".join(payload_pieces(*members(obj)))


def decode(payload: bytes | memoryview) -> Any:
    """The object an :func:`encode` payload holds (its arrays views of it); :class:`CacheEntryError` if it does
    not decode."""
    try:
        tree, arrays = _arrays(memoryview(payload).toreadonly().cast("B"))
    except CacheEntryError:
        raise
    except Exception as e:  # noqa: BLE001 - e.g. a shape numpy refuses to make: a miss, never a crash
        raise CacheEntryError(f"payload directory does not decode ({type(e).__name__})") from None
    try:
        node = json.loads(tree.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise CacheEntryError("tree is not JSON") from None
    try:
        return _Decoder(arrays)(node)
    except CacheEntryError:
        raise
    except Exception as e:  # noqa: BLE001 - a verified payload that still does not decode is a miss
        raise CacheEntryError(f"payload does not decode ({type(e).__name__})") from None


__all__ = ["ALIGN", "CacheEntryError", "PAYLOAD_MAGIC", "decode", "encode", "members", "payload_pieces"]
