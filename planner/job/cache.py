"""The work cache of the nightly job: verified, pickle-free entries.

A cache entry is trusted no more than the inputs it stands for. Each entry is
one file ``OUTPUT_ROOT/.cache/<kind>/<ab>/<key>.pce`` (``ab`` = the first two
hex digits of the key) laid out as::

    PLANNER-CACHE 2\\n                   magic line (format version)
    {"kind": ..., "key": ..., "payload_bytes": N, "payload_sha256": ...}\\n
    <payload: N bytes>

The payload (:func:`planner.job.codec.payload_pieces`) holds the result's structure as UTF-8 JSON (the tree)
and its arrays' raw bytes, each named in a directory by its numeric dtype and shape; nothing in it can
hold a Python object. DataFrames are stored column by
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

What the nightly job keeps of a unit's result, when that is small, is an entry of its own beside the
result's (kind ``<kind>_kept``, the same key: :func:`planner.job.units.kept_beside`), checked the same way;
one that is missing or rejected is made again from the result, which is checked and decoded then.

The digest guards against damage, not against someone who can write the
output root: such a person could also write the published runs. Protect the
output root like the signing key's folder.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from planner.io.atomic import write_chunks_atomic
from planner.io.memory import give_back
from planner.job.codec import CacheEntryError, decode, encode, members, payload_pieces  # noqa: F401 (re-exported)

MAGIC = b"PLANNER-CACHE 2\n"
"""First line of every entry; bump the number when the layout changes (old entries then miss)."""
SUFFIX = ".pce"
"""Entry file suffix (planner cache entry)."""
MAX_HEADER_BYTES = 4096
KEY_RE = re.compile(r"^[0-9a-f]{64}$")
KIND_RE = re.compile(r"^[a-z][a-z0-9_]{0,31}$")


# --- entries --------------------------------------------------------------------------------
BIG_ENTRY_BYTES = 8 << 20
"""An entry whose members are at least this large gives its encoding's memory back once written
(:func:`planner.io.memory.give_back`)."""


def pack(kind: str, key: str, obj: Any) -> bytes:
    """The bytes of one entry: magic line, header (kind, key, payload length and SHA-256), payload."""
    return b"".join(_entry(kind, key, *members(obj)))


def _entry(kind: str, key: str, tree: np.ndarray, arrays: dict[str, np.ndarray]) -> list:
    """:func:`pack`'s bytes of the members ``tree`` and ``arrays`` as pieces: the header, then the payload's pieces,
    each array's a view of its own memory. The payload is hashed piece by piece and written the same way, so an
    entry is never held whole (a line's conflict report is 66 MB on a line ten times the sample)."""
    pieces = payload_pieces(tree, arrays)
    h, size = hashlib.sha256(), 0
    for p in pieces:
        h.update(p)
        size += memoryview(p).nbytes
    return [_header(kind, key, size, h.hexdigest()), *pieces]


def _header(kind: str, key: str, payload_bytes: int, payload_sha256: str) -> bytes:
    """The magic line and the header line of an entry."""
    header = {"kind": kind, "key": key, "payload_bytes": payload_bytes, "payload_sha256": payload_sha256}
    return MAGIC + json.dumps(header, sort_keys=True, separators=(",", ":")).encode() + b"\n"


def _header_of(data, kind: str | None, key: str | None) -> tuple[dict, int]:
    """The header of an entry whose first bytes are ``data`` (at least the magic and header lines, when the entry
    has them), checked (kind, key, fields), and where its payload starts; :class:`CacheEntryError` says why not."""
    if not data:
        raise CacheEntryError("empty file")
    if bytes(data[:len(MAGIC)]) != MAGIC:
        raise CacheEntryError("not a planner cache entry (bad magic line)")
    end = bytes(data[len(MAGIC):len(MAGIC) + MAX_HEADER_BYTES]).find(b"\n")
    if end < 0:
        raise CacheEntryError("truncated or oversized header")
    end += len(MAGIC)
    try:
        header = json.loads(bytes(data[len(MAGIC):end]).decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise CacheEntryError("header is not JSON") from None
    if not isinstance(header, dict) or set(header) != {"kind", "key", "payload_bytes", "payload_sha256"}:
        raise CacheEntryError("header fields are wrong")
    if kind is not None and header["kind"] != kind:
        raise CacheEntryError(f"entry is of kind {header['kind']!r}, expected {kind!r}")
    if key is not None and header["key"] != key:
        raise CacheEntryError("entry holds another key (copied or swapped)")
    return header, end + 1


def _payload_checked(header: dict, size: int, sha256: str) -> None:
    """A payload of ``size`` bytes with digest ``sha256`` against what its header says."""
    if size != header["payload_bytes"]:
        raise CacheEntryError(f"payload has {size} bytes, header says {header['payload_bytes']} (truncated?)")
    if sha256 != header["payload_sha256"]:
        raise CacheEntryError("payload digest mismatch (damaged)")


def unpack(data: bytes, kind: str | None = None, key: str | None = None) -> tuple[dict, memoryview]:
    """(header, payload) of an entry's bytes, checked; :class:`CacheEntryError` says why not. The payload is a
    view of ``data`` (a large entry is not copied)."""
    header, start = _header_of(data, kind, key)
    payload = memoryview(data)[start:]
    _payload_checked(header, payload.nbytes, hashlib.sha256(payload).hexdigest())
    return header, payload


CHECK_BLOCK_BYTES = 1 << 20
"""What :meth:`Cache.check` reads at a time: a larger entry is checked through one buffer of this size, never held
whole."""


def check_file(path: Path, kind: str | None = None, key: str | None = None) -> None:
    """:func:`unpack`'s checks of the entry file at ``path`` (kind, key, length, digest), read a block at a time
    into one buffer no larger than the entry: an entry that is not decoded is never held whole (about three times
    as fast as reading it whole and slicing out its payload on entries of tens of MB: no fresh pages to fault in,
    nothing copied)."""
    h, size = hashlib.sha256(), 0
    with open(path, "rb", buffering=0) as f:
        buf = bytearray(min(CHECK_BLOCK_BYTES, max(os.fstat(f.fileno()).st_size, 1)))  # a small entry: its size
        view = memoryview(buf)
        n = f.readinto(buf)
        header, start = _header_of(view[:n], kind, key)
        if start > n:
            raise CacheEntryError("truncated or oversized header")
        h.update(view[start:n])
        size = n - start
        while n := f.readinto(buf):
            h.update(view[:n])
            size += n
    _payload_checked(header, size, h.hexdigest())


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
        payload = self._payload(kind, key)
        if payload is None:
            return None
        try:
            obj = decode(payload)
        except CacheEntryError as e:
            return self._reject(kind, key, str(e))
        self.hits += 1
        return obj

    def check(self, kind: str, key: str) -> bool:
        """Whether the entry is there and trusted as :meth:`get` trusts it (kind, key, length, digest) without
        decoding it (:func:`check_file`): for a reader that needs to know the result is there for whoever reads it
        next. A missing or rejected entry counts as :meth:`get` counts it."""
        p = self.path(kind, key)
        if not self.enabled:
            self.misses += 1
            return False
        try:
            check_file(p, kind, key)
        except FileNotFoundError:
            self.misses += 1
            return False
        except OSError as e:  # a folder in its place, unreadable, ...: not trusted, recomputed
            return self._reject(kind, key, f"unreadable ({e.strerror or type(e).__name__})") or False
        except CacheEntryError as e:
            return self._reject(kind, key, str(e)) or False
        self.hits += 1
        return True

    def _payload(self, kind: str, key: str) -> memoryview | None:
        """The entry's payload, checked (:func:`unpack`); None, counted as a miss (a rejection with its reason),
        when it is missing or not trusted."""
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
            return unpack(data, kind, key)[1]
        except CacheEntryError as e:
            return self._reject(kind, key, str(e))

    def present(self, kind: str, key: str) -> bool:
        """Whether an entry is stored under the key (its name only: :meth:`get` reads and checks it); False when
        the cache is not read (``enabled=False``)."""
        return self.enabled and self.path(kind, key).is_file()

    def _reject(self, kind: str, key: str, why: str) -> None:
        self.misses += 1
        self.rejected += 1
        self.rejected_why.append((kind, key, why))
        return None

    def why_missed(self) -> str:
        """Why the last :meth:`get` found nothing it could trust: the rejection's reason, else ``missing``."""
        return self.rejected_why[-1][2] if self.rejected_why else "missing"

    def rejected_elsewhere(self, kind: str, key: str, why: str) -> None:
        """Count an entry of this cache that a reader elsewhere (a worker's own :class:`Cache` on the same root)
        rejected, so the run's one warning counts it."""
        self._reject(kind, key, why)

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
        tree, arrays = members(obj)
        big = tree.nbytes + sum(a.nbytes for a in arrays.values()) >= BIG_ENTRY_BYTES
        write_chunks_atomic(p, _entry(kind, key, tree, arrays), fsync=False)
        if big:
            del tree, arrays
            give_back()  # its encoding's buffers (text columns' Arrow streams), before the next one is made

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
