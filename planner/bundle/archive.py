"""The bundle's archive: a canonical POSIX ustar file, written byte for byte and read strictly.

Takes named members (bytes); gives the archive bytes (:func:`pack`). Takes a
file or bytes; gives the members (:func:`read_members`), refusing anything but
the canonical form :func:`pack` writes.

Members are sorted by name, every header canonical: mode 0644, uid/gid 0, empty
uname/gname, mtime 0, type regular file, no prefix/link fields; data padded with
zeros to 512-byte blocks; the archive ends with exactly two zero blocks (no
record padding), so the bytes depend on the contents only. Any standard ``tar``
can list and extract a bundle.
"""
from __future__ import annotations

import hashlib
import io
import os
import re
import stat
from typing import Mapping

from planner.bundle.manifest import (MANIFEST, MAX_MANIFEST_BYTES, MAX_MEMBER_BYTES, MAX_MEMBERS,
                                     MAX_TOTAL_BYTES, MEMBER_NAME_RE, SIGNATURE, fail)
from planner.errors import BundleError

_BLOCK = 512


# --- writing -----------------------------------------------------------------
def _octal(value: int, width: int) -> bytes:
    digits = format(value, "o").encode("ascii")
    if len(digits) > width - 1:
        raise BundleError(f"value {value} does not fit a {width}-byte tar field")
    return digits.rjust(width - 1, b"0") + b"\0"


def tar_header(name: str, size: int) -> bytes:
    """The canonical ustar header of a regular-file member (POSIX.1-1988 layout)."""
    h = bytearray(_BLOCK)
    raw = name.encode("ascii")
    h[0:len(raw)] = raw
    h[100:108] = _octal(0o644, 8)  # mode
    h[108:116] = _octal(0, 8)  # uid
    h[116:124] = _octal(0, 8)  # gid
    h[124:136] = _octal(size, 12)
    h[136:148] = _octal(0, 12)  # mtime
    h[148:156] = b" " * 8  # checksum is computed with its own field as spaces
    h[156:157] = b"0"  # regular file
    h[257:263] = b"ustar\0"
    h[263:265] = b"00"
    # devmajor/devminor stay NUL for a regular file, as Python's tarfile writes them.
    h[148:156] = format(sum(h), "06o").encode("ascii") + b"\0 "
    return bytes(h)


def _pad(n: int) -> int:
    return -n % _BLOCK


def pack(members: Mapping[str, bytes]) -> bytes:
    """A canonical tar of ``members`` (sorted by name)."""
    out = bytearray()
    for name in sorted(members):
        data = members[name]
        out += tar_header(name, len(data)) + data + b"\0" * _pad(len(data))
    out += b"\0" * (2 * _BLOCK)
    return bytes(out)


# --- reading -----------------------------------------------------------------
_TYPEFLAGS = {b"1": "a hard link", b"2": "a symbolic link", b"3": "a character device",
              b"4": "a block device", b"5": "a directory", b"6": "a FIFO", b"7": "a contiguous file",
              b"x": "a pax header", b"g": "a pax global header", b"L": "a GNU long name",
              b"K": "a GNU long link name"}


def _parse_octal(field_: bytes, what: str, where: str) -> int:
    digits = field_.rstrip(b"\0 ")
    if not digits or not re.fullmatch(rb"[0-7]+", digits):
        raise fail(where, f"{what} field {field_!r} is not a plain octal number")
    return int(digits, 8)


class _HashingReader:
    """Reads from ``f`` and hashes every byte read, so the file digest costs no second pass."""

    def __init__(self, f):
        self._f, self.sha256 = f, hashlib.sha256()

    def read(self, n: int) -> bytes:
        data = self._f.read(n)
        self.sha256.update(data)
        return data


def _member_name(h: bytes, members: Mapping[str, bytes], where: str) -> str:
    """The checked name of the member whose header is ``h``: a regular file, a plain allowed name, new."""
    raw_name = h[0:100].split(b"\0", 1)[0]
    shown = raw_name.decode("ascii", "backslashreplace")
    kind = _TYPEFLAGS.get(h[156:157])
    if kind is not None:
        raise fail(where, f"member {shown!r} is {kind}; only regular files are allowed")
    if h[156:157] not in (b"0", b"\0"):
        raise fail(where, f"member {shown!r} has unknown type {h[156:157]!r}; only regular files are allowed")
    if raw_name.startswith(b"/") or b".." in raw_name or b"/" in raw_name or b"\\" in raw_name:
        raise fail(where, f"member name {shown!r} is a path; only plain file names are allowed")
    try:
        name = raw_name.decode("ascii")
    except UnicodeDecodeError:
        raise fail(where, f"member name {shown!r} is not ASCII") from None
    if not (MEMBER_NAME_RE.fullmatch(name) or name in (MANIFEST, SIGNATURE)):
        raise fail(where, f"member name {name!r} not allowed")
    if name in members:
        raise fail(where, f"duplicate member {name!r}")
    if len(members) >= MAX_MEMBERS:
        raise fail(where, f"more than {MAX_MEMBERS} members")
    return name


def unpack(f, file_size: int, where: str) -> dict[str, bytes]:
    """Members of a canonical bundle tar, read into memory; refuse anything else.

    Checks every header before reading its data: type regular file, a name of
    the allowed form (no '/', no '..', no absolute path), size within the
    bounds and the file, no duplicate; then that the header is byte-identical
    to the canonical one for that name and size, that padding is zero, and that
    the archive ends with exactly two zero blocks.
    """
    members: dict[str, bytes] = {}
    total = 0
    pos = 0
    while True:
        h = f.read(_BLOCK)
        if len(h) < _BLOCK:
            raise fail(where, f"truncated at byte {pos}: no end-of-archive marker")
        pos += _BLOCK
        if h == b"\0" * _BLOCK:
            second = f.read(_BLOCK)
            if second != b"\0" * _BLOCK:
                raise fail(where, f"malformed end-of-archive marker at byte {pos}")
            pos += _BLOCK
            if f.read(1):
                raise fail(where, f"unexpected data after the end of the archive at byte {pos}")
            break
        if h[257:262] != b"ustar":  # not a tar header at all (POSIX or GNU): say so, never show what the file holds
            raise fail(where, f"not a bundle: no tar header at byte {pos - _BLOCK} (a bundle is the .pdb file "
                              "planner bundle build or planner run writes)" if not members else
                       f"no tar header at byte {pos - _BLOCK} after member {next(reversed(members))!r} "
                       "(damaged or not written by planner)")
        name = _member_name(h, members, where)
        size = _parse_octal(h[124:136], f"member {name!r} size", where)
        bound = MAX_MANIFEST_BYTES if name in (MANIFEST, SIGNATURE) else MAX_MEMBER_BYTES
        if size > bound:
            raise fail(where, f"member {name!r} declares {size} bytes, above the {bound}-byte bound")
        total += size
        if total > MAX_TOTAL_BYTES:
            raise fail(where, f"members total more than the {MAX_TOTAL_BYTES}-byte bound")
        if pos + size + _pad(size) > file_size:
            raise fail(where, f"member {name!r} declares {size} bytes but the file ends first (truncated)")
        if h != tar_header(name, size):
            raise fail(where, f"member {name!r} has a non-canonical header (altered or not written by planner)")
        data = f.read(size)
        pad = f.read(_pad(size))
        if len(data) != size or len(pad) != _pad(size):
            raise fail(where, f"member {name!r} is truncated")
        if pad.strip(b"\0"):
            raise fail(where, f"member {name!r} has non-zero padding")
        pos += size + len(pad)
        members[name] = data
    if [n for n in members] != sorted(members):
        raise fail(where, "members are not in sorted order (not written by planner)")
    return members


def read_members(path: str | os.PathLike | bytes) -> tuple[dict[str, bytes], tuple[int, str]]:
    """The members of the bundle file ``path`` (or its bytes), and the file's size and SHA-256.

    The file is opened without blocking (a FIFO is refused, never waited on)
    and must be a regular file within the size bound.
    """
    if isinstance(path, (bytes, bytearray, memoryview)):
        reader = _HashingReader(io.BytesIO(path))
        return unpack(reader, len(path), "<bytes>"), (len(path), reader.sha256.hexdigest())
    where = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO must not block us
    except FileNotFoundError:
        raise BundleError(f"bundle {where} not found") from None
    except OSError as e:
        raise fail(where, f"cannot open ({e.strerror})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise fail(where, "not a regular file")
    with os.fdopen(fd, "rb") as f:
        bound = MAX_TOTAL_BYTES + (MAX_MEMBERS + 2) * 2 * _BLOCK
        if st.st_size > bound:
            raise fail(where, f"{st.st_size} bytes, above the {bound}-byte bound")
        reader = _HashingReader(f)
        members = unpack(reader, st.st_size, where)
        return members, (st.st_size, reader.sha256.hexdigest())
