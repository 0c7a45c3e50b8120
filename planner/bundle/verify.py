"""Verification of an on-board DB bundle: what a vehicle checks before it loads one.

Takes a bundle file (or its bytes), the public key the vehicle was provisioned
with and what the vehicle expects (:class:`Expect`: target, installed version,
its clock, development keys allowed or not); gives the bundle's
:class:`~planner.bundle.manifest.BundleInfo` (:func:`verify_bundle`), its tables
in memory (:func:`read_bundle`) or its members written to a folder
(:func:`open_bundle`), or refuses with one :class:`~planner.errors.BundleError` line.

Trust
-----
Reading checks, in this order, and parses nothing else before the signature is
proven: archive structure (member names ``[a-z0-9_]+.parquet`` or the two
manifest files, regular files only, no duplicates, sizes within bounds, every
header and padding byte canonical, nothing after the end:
:mod:`planner.bundle.archive`); the signature of ``manifest.json``; the
manifest's schema; that its ``key_id`` is the id of the verifying key; then what
the vehicle asked for (the expected line/direction/train type, a production key
unless development keys are allowed, a version not below the installed one, not
expired); that the members are exactly the files it lists, each with its size
and SHA-256; then the tables themselves (:mod:`planner.bundle.contents`):
declared columns and types, the line/direction/train type in every row, and
cross-table consistency (ATS-P rows ↔ restrictions, beacon order and flags,
table (b) ratios and points present in table (a) and the evaluation points,
beacon evaluation points present in the beacons). ``docs/bundles.md`` explains
each check and the attack it stops.
"""
from __future__ import annotations

import dataclasses
import errno
import hashlib
import os
import stat
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import pyarrow as pa
import pyarrow.parquet as pq

from planner.bundle import signing
from planner.bundle.archive import read_members
from planner.bundle.contents import STREAMED, check_tables, streamed
from planner.bundle.manifest import (MANIFEST, SIGNATURE, BundleInfo, check_manifest, fail, format_time, no_stop_rows,
                                     manifest_info, parse_manifest, parse_time)
from planner.errors import BundleError
from planner.io.atomic import folder_in_place
from planner.line.model import DIRECTIONS
from planner.io.paths import PATH_ID_RE


@dataclass(frozen=True, eq=False)
class Bundle:
    """A verified bundle read into memory: its info and its tables by name."""

    info: BundleInfo
    tables: Mapping[str, pa.Table] = field(repr=False)


@dataclass(frozen=True)
class Expect:
    """What the vehicle asks of a bundle beyond a good signature (see ``docs/bundles.md``).

    Attributes
    ----------
    target : str or None
        ``LINE/DIRECTION/TYPE`` the vehicle wants; None: any (no identity check).
    min_version : int
        Lowest acceptable bundle version (the version installed on the vehicle;
        an equal version is the same release and is accepted).
    at_s : int or None
        The vehicle's time [Unix seconds] for the expiry check; None: the clock now.
    allow_dev : bool
        Accept a bundle signed with a development key (test benches only).
    check_time : bool
        Check expiry and the operating day's window at ``at_s``. False only for reading a bundle that is not
        loaded onto a vehicle (comparing two runs' bundles: yesterday's is outside its day by design).
    """

    target: str | None = None
    min_version: int = 0
    at_s: int | None = None
    allow_dev: bool = False
    check_time: bool = True
    at_local: str = ""
    """``--at`` given without an offset: a local time of the bundle's operating day (its time zone), read once
    the manifest is proven; a bundle not bound to a day takes it as UTC."""

    @staticmethod
    def parse_target(text: str) -> str:
        """Check ``LINE/DIRECTION/TYPE`` and return it; raise BundleError naming the fix."""
        parts = str(text).split("/")
        if len(parts) != 3 or parts[1] not in DIRECTIONS or not all(PATH_ID_RE.fullmatch(p) for p in parts[::2]):
            raise BundleError(f"--expect {text!r}: give LINE/DIRECTION/TYPE, e.g. sample/down/E10 "
                              "(direction 'down' or 'up')")
        return "/".join(parts)


def _check_expect(m: dict, expect: Expect, pub_id: str, where: str) -> None:
    """Provenance and freshness of a proven manifest; one reason per refusal."""
    if m["key_id"] != pub_id:
        raise fail(where, f"manifest names signing key {m['key_id'][:16]}, but it was verified with key "
                          f"{pub_id[:16]}: the manifest lies about its signer (refused)")
    target = f"{m['line_id']}/{m['direction']}/{m['train_type']}"
    if expect.target is not None and target != Expect.parse_target(expect.target):
        raise fail(where, f"bundle is for {target}, not the expected {expect.target} (renamed or mixed up; refused)")
    if m["key_kind"] != "production" and not expect.allow_dev:
        raise fail(where, f"signed with a {m['key_kind']} key: not for service (refused; --allow-dev on a test "
                          "bench only)")
    if m["bundle_version"] < expect.min_version:
        raise fail(where, f"bundle version {m['bundle_version']} is older than the installed version "
                          f"{expect.min_version} (rollback refused)")
    if not expect.check_time:
        return
    d = m.get("operating_day")
    now = int(time.time()) if expect.at_s is None else int(expect.at_s)
    if expect.at_local:
        now = local_time_s(expect.at_local, d["time_zone"] if d is not None else "UTC")
    if now >= parse_time(m["expires"]):
        raise fail(where, f"bundle expired at {m['expires']} (checked at {format_time(now)}; built "
                          f"{m['built_at']}): a fresh bundle is needed (refused)")
    if d is not None and not parse_time(d["valid_from"]) <= now < parse_time(d["valid_until"]):
        raise fail(where, f"bundle is for operating day {d['day']} ({d['valid_from']} to {d['valid_until']}), "
                          f"checked at {format_time(now)}: outside its window, that day's bundle is needed (refused)")


def read_signed(path, public_key, *, expect: Expect | None = None) -> tuple[BundleInfo, dict[str, bytes]]:
    """A bundle's signed manifest and its members' bytes, each checked against the manifest's size and SHA-256, the
    tables not decoded: for a reader that decodes only the members it needs (the comparison of two runs' bundles,
    which decodes the tables whose digests differ). What :func:`read_bundle` checks beyond this (the tables'
    contents against each other) is not checked: nothing read this way may be loaded onto a vehicle."""
    where, m, members, size_digest = _signed(path, public_key, expect)
    return manifest_info(where, m, size_digest), members


def _signed(path, public_key, expect: Expect | None) -> tuple[str, dict, dict[str, bytes], str]:
    """The signature, the manifest, the expectations and every member's size and digest checked."""
    expect = Expect() if expect is None else expect
    where = "<bytes>" if isinstance(path, (bytes, bytearray, memoryview)) else str(path)
    pub = signing.load_public_key(public_key)
    members, size_digest = read_members(path)
    if MANIFEST not in members:
        raise fail(where, f"{MANIFEST} is missing")
    if SIGNATURE not in members:
        raise fail(where, f"{SIGNATURE} is missing (unsigned bundle)")
    mbytes = members[MANIFEST]
    try:
        signing.verify(pub, mbytes, members[SIGNATURE])
    except BundleError as e:
        raise fail(where, str(e)) from None
    m = parse_manifest(mbytes, where)
    check_manifest(m, where)
    _check_expect(m, expect, signing.public_key_id(pub), where)
    listed = {e["name"]: e for e in m["files"]}
    present = set(members) - {MANIFEST, SIGNATURE}
    if present - set(listed):
        raise fail(where, f"extra member(s) not in the manifest: {', '.join(sorted(present - set(listed)))}")
    if set(listed) - present:
        raise fail(where, f"missing member(s) listed in the manifest: {', '.join(sorted(set(listed) - present))}")
    for name, e in listed.items():
        data = members[name]
        if len(data) != e["size"]:
            raise fail(where, f"{name} is {len(data)} bytes, the manifest says {e['size']}")
        if hashlib.sha256(data).hexdigest() != e["sha256"]:
            raise fail(where, f"{name} SHA-256 does not match the manifest (altered)")
    return where, m, members, size_digest


def _row_groups(name: str, data: bytes, where: str):
    """The row groups of member ``name`` one at a time, its text columns dictionary-encoded (every value decoded and
    checked, but a few distinct strings made, not one per row: tables (b) to (d) have millions of rows)."""
    try:
        text = [f.name for f in pq.ParquetFile(pa.BufferReader(data)).schema_arrow
                if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)]
        f = pq.ParquetFile(pa.BufferReader(data), read_dictionary=text)
        for i in range(f.num_row_groups):
            yield f.read_row_group(i)
    except (pa.ArrowException, OSError) as err:
        raise fail(where, f"{name} is not a readable Parquet file ({err})") from None


def _verified(path, public_key, expect: Expect | None = None, keep: bool = True
              ) -> tuple[BundleInfo, dict[str, bytes], dict]:
    """The bundle's info, members and tables, every check passed; ``keep`` False: the large step tables
    (:data:`planner.bundle.contents.STREAMED`) are checked a row group at a time and given as their summaries."""
    where, m, members, size_digest = _signed(path, public_key, expect)
    listed = {e["name"]: e for e in m["files"]}
    tables = {}
    target = (m["line_id"], m["direction"], m["train_type"])
    for name, e in listed.items():
        table = name.removesuffix(".parquet")
        if not keep and table in STREAMED:
            t = streamed(table, _row_groups(name, members[name], where), target, where)
            if t is None:  # no row group: the table as it is, empty
                t = pq.read_table(pa.BufferReader(members[name]))
        else:
            try:
                t = pq.read_table(pa.BufferReader(members[name]))
            except (pa.ArrowException, OSError) as err:
                raise fail(where, f"{name} is not a readable Parquet file ({err})") from None
        if t.num_rows != e["rows"]:
            raise fail(where, f"{name} has {t.num_rows} rows, the manifest says {e['rows']}")
        tables[table] = t
    check_tables(tables, m, where)
    # the stops without a pattern from the signed stop_summary itself, also where the manifest predates no_stop
    info = dataclasses.replace(manifest_info(where, m, size_digest),
                               no_stop=tuple(no_stop_rows(tables.get("stop_summary"))))
    return info, members, tables


def _expect(expect, min_version, at, allow_dev) -> Expect:
    if isinstance(expect, Expect):
        return expect
    at_s = parse_time(at, "--at") if isinstance(at, str) else at  # (checks the text, also one without offset)
    local = at if isinstance(at, str) and not _has_zone(at) else ""
    if isinstance(min_version, bool) or not isinstance(min_version, int) or min_version < 0:
        raise BundleError(f"--min-version must be a whole number >= 0, found {min_version!r}")
    return Expect(None if expect is None else Expect.parse_target(expect), min_version, at_s, bool(allow_dev),
                  at_local=local)


def _has_zone(text: str) -> bool:
    """Whether an ISO 8601 time names its zone (``Z`` or an offset)."""
    from datetime import datetime

    s = str(text).strip()
    return s.endswith(("Z", "z")) or datetime.fromisoformat(s).tzinfo is not None


def local_time_s(text: str, tz: str) -> int:
    """Unix seconds of an ISO 8601 time without offset read in the IANA zone ``tz`` (a vehicle's clock on the
    line: the operating day's local time, as every time a person types about that day)."""
    from datetime import datetime
    from zoneinfo import ZoneInfo

    return int(datetime.fromisoformat(str(text).strip()).replace(tzinfo=ZoneInfo(tz)).timestamp())


def verify_bundle(path: str | os.PathLike | bytes, public_key, *, expect: str | Expect | None = None,
                  min_version: int = 0, at: int | str | None = None, allow_dev: bool = False) -> BundleInfo:
    """Prove a bundle complete, untampered, signed by ``public_key``, fresh and meant for service.

    Parameters
    ----------
    path : path or bytes
        The bundle file (only read, never extracted), or its bytes already in memory.
    public_key : path, PEM bytes, 32 raw bytes or Ed25519PublicKey
        The signer's public key; the manifest's ``key_id`` must be its id.
    expect : str ``LINE/DIRECTION/TYPE`` or Expect, optional
        The target the vehicle wants; None accepts any target (a vehicle must give it).
    min_version : int
        Refuse a bundle version below this (the installed version: rollback).
    at : Unix seconds or ISO 8601 str, optional
        Time of the expiry check; default the clock now.
    allow_dev : bool
        Accept a bundle signed with a development key.

    Returns
    -------
    BundleInfo

    Raises
    ------
    BundleError
        With one line naming the first failed check: structure (names, links,
        sizes, canonical headers), signature, manifest schema and version, key
        id, target, key kind, rollback, expiry, extra or missing members, size
        and SHA-256 of each, row counts, table schemas, line/direction/train
        type in every row, cross-table consistency.
    """
    return _verified(path, public_key, _expect(expect, min_version, at, allow_dev), keep=False)[0]


def read_bundle(path: str | os.PathLike | bytes, public_key, *, expect: str | Expect | None = None,
                min_version: int = 0, at: int | str | None = None, allow_dev: bool = False) -> Bundle:
    """Verify a bundle (as :func:`verify_bundle`) and return its tables in memory (nothing written to disk)."""
    info, _, tables = _verified(path, public_key, _expect(expect, min_version, at, allow_dev))
    return Bundle(info, tables)


def open_bundle(path: str | os.PathLike, dest_dir: str | os.PathLike, public_key, *,
                expect: str | Expect | None = None, min_version: int = 0, at: int | str | None = None,
                allow_dev: bool = False) -> BundleInfo:
    """Verify a bundle, then write its members as the folder ``dest_dir``: all of them or nothing.

    ``dest_dir`` must be missing or an empty folder, not a symbolic link. Nothing is written unless
    the whole bundle verifies. The members are then written into a fresh temporary folder beside
    ``dest_dir`` (the same file system), each a plain file name created with ``O_EXCL | O_NOFOLLOW``;
    read back and compared there with the verified bytes; and the folder becomes ``dest_dir`` by one
    rename (:func:`planner.io.atomic.folder_in_place`). A refusal or a failure at any member (a full
    disk) leaves ``dest_dir`` exactly as it was, and no temporary folder behind.
    """
    info, members, _ = _verified(path, public_key, _expect(expect, min_version, at, allow_dev))
    dest = Path(dest_dir)
    try:
        _check_destination(dest, members)
        with folder_in_place(dest) as tmp:
            _write_members(tmp, members)
    except OSError as e:
        if e.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR):  # the rename: dest changed meanwhile
            raise BundleError(f"{dest} is no longer missing or empty (it changed while the bundle was opened); "
                              "nothing was written: open the bundle into a new or empty folder") from None
        what = f"{e.strerror or e}" + (f" ({e.filename})" if e.filename else "")
        raise BundleError(f"cannot open the bundle into {dest}: {what}; nothing was written: check the space "
                          "and permissions there") from None
    return info


def _check_destination(dest: Path, members: Mapping[str, bytes]) -> None:
    """Refuse a destination that is not a missing or empty real folder, before anything is written."""
    try:
        st = os.lstat(dest)
    except FileNotFoundError:
        return
    if stat.S_ISLNK(st.st_mode):
        raise BundleError(f"{dest} is a symbolic link; open the bundle into a new or empty folder")
    if not stat.S_ISDIR(st.st_mode):
        raise BundleError(f"{dest} is not a folder; open the bundle into a new or empty folder")
    present = sorted(os.listdir(dest))
    clash = [n for n in present if n in members]
    if clash:
        raise BundleError(f"{dest / clash[0]} already exists; open the bundle into a new or empty folder")
    if present:
        raise BundleError(f"{dest} is not empty (it holds {present[0]!r}); open the bundle into a new or "
                          "empty folder")


def _write_members(folder: Path, members: Mapping[str, bytes]) -> None:
    """Write the members into the fresh ``folder``, then check that it holds exactly them, byte for byte."""
    nofollow = getattr(os, "O_NOFOLLOW", 0)
    dfd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        for name in sorted(members):
            fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | nofollow, 0o644, dir_fd=dfd)
            with os.fdopen(fd, "wb") as f:
                f.write(members[name])
        if sorted(os.listdir(dfd)) != sorted(members):
            raise BundleError(f"{folder} holds {sorted(os.listdir(dfd))} after writing, not the bundle's "
                              f"members {sorted(members)}; nothing was opened")
        for name in sorted(members):
            with os.fdopen(os.open(name, os.O_RDONLY | nofollow, dir_fd=dfd), "rb") as f:
                if f.read() != members[name]:
                    raise BundleError(f"{folder / name} reads back different from the verified member; "
                                      "nothing was opened: check the disk")
    finally:
        os.close(dfd)
