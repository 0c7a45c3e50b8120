"""The bundle container: signed, reproducible on-board DB bundles (docs/design.md §7, issue 7).

Takes a bundle's tables (:mod:`planner.bundle.assemble`), a signing key and a
:class:`~planner.bundle.manifest.Release`; gives one file per line × direction
× train type, ``<line>_<direction>_<train_type>.pdb``, that the vehicle loads
(:func:`build_line`, :func:`build_bundle`, :func:`bundle_bytes`).

Format
------
An uncompressed POSIX ustar archive (:mod:`planner.bundle.archive`) of:

* one Parquet file per table (``restrictions``, ``max_profile``, ``atsp``,
  ``beacons``, ``timetable`` always; ``eval_points`` (beacon points and the
  odometer points: departure, after departure, regular interval), ``table_a``,
  ``table_b``, ``table_c``, ``table_d``, ``stop_summary``, ``stop_samples``
  when they were built), written with fixed
  pyarrow settings and no pandas metadata, so the same table gives the same
  bytes;
* ``manifest.json``: canonical JSON (sorted keys, no whitespace, ASCII, only
  strings/integers/lists) with the bundle schema version, line, direction,
  train type, software version, the digest of the input line DB, the signing
  key's id and kind (``production`` or ``development``), the bundle version,
  build time and expiry (:class:`~planner.bundle.manifest.Release`), the tables
  expected but missing, and for every other member its name, size, SHA-256 and
  row count (:mod:`planner.bundle.manifest`);
* ``manifest.sig``: the 64-byte Ed25519 signature of the exact manifest bytes.

The same tables, key and release give the same bytes. The builder runs the
verifier's manifest and table checks before signing. :mod:`planner.bundle.verify`
reads a bundle back.

Writes are atomic: the bundle is written to a temporary file in the output
folder, fsynced and renamed over the final name, so an interrupted build
leaves either no bundle or the complete previous one under that name.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import re
from pathlib import Path
from typing import Callable, Mapping, Sequence

import pyarrow as pa
import pyarrow.parquet as pq

from planner import __version__
from planner.bundle import signing
from planner.bundle.archive import pack, unpack
from planner.bundle.assemble import TABLE_SOURCES, Partition, assemble
from planner.bundle.contents import (CORE_SCHEMAS, STREAMED, Streamed, check_keys, check_schema, check_tables,
                                     streamed)
from planner.bundle.manifest import (CORE_TABLES, BundleDay, EXPECTED_TABLES, FORMAT, MANIFEST, MAX_MEMBER_BYTES,
                                     MAX_TOTAL_BYTES, SCHEMA_VERSION, SHA256_RE, SIGNATURE, VEHICLE_TABLES,
                                     BundleInfo, Release, bundle_name, canonical_json, check_manifest,
                                     expected_tables, format_time, manifest_info, no_stop_rows)
from planner.errors import BundleError
from planner.io.atomic import write_bytes_atomic
from planner.io.memory import give_back
from planner.io.parquet import without_pandas_metadata
from planner.line.model import DIRECTIONS, Line

_TABLE_NAME = re.compile(r"[a-z][a-z0-9_]{0,63}")
_PARQUET_OPTIONS = dict(compression="zstd", use_dictionary=True, write_statistics=True, store_schema=False)
"""Fixed Parquet writer settings. ``store_schema=False`` leaves out the serialised Arrow
schema (with the column descriptions, about 2-3 KB per file, two thirds of a small
bundle): the vehicle needs names and types, which Parquet's own schema carries; the
descriptions are declared in :mod:`planner.bundle.contents`."""


STEP_TABLES = TABLE_SOURCES["tables"] + TABLE_SOURCES["stops"]
"""The tables a bundle takes from the tables' and stops' datasets; those :func:`build_line` may be given as bytes."""
DECODED_GIVEN = ("eval_points", "stop_summary")
"""Given tables decoded all the same: the beacon check reads the evaluation points, the manifest's ``no_stop`` the
stop summary (both small)."""


# --- writing -----------------------------------------------------------------
def parquet_bytes(table: pa.Table) -> bytes:
    """Deterministic Parquet bytes of ``table`` (fixed writer settings, no pandas metadata)."""
    buf = io.BytesIO()
    pq.write_table(without_pandas_metadata(table), buf, **_PARQUET_OPTIONS)
    return buf.getvalue()


def streamed_bytes(name: str, part: Partition, target: tuple[str, str, str]) -> tuple[bytes, Streamed]:
    """Deterministic Parquet bytes of a dataset's partition (fixed writer settings, no pandas metadata), written a
    file of it at a time (a row group or more each, in the files' order), each checked as it is read
    (:func:`planner.bundle.contents.streamed`); and what the cross-checks need of it. A table of millions of rows
    (table (d) on a long line) is encoded holding one file's rows, not the whole table's."""
    buf = io.BytesIO()
    writer: list[pq.ParquetWriter] = []

    def write(piece: pa.Table) -> None:
        piece = without_pandas_metadata(piece)
        if not writer:
            writer.append(pq.ParquetWriter(buf, piece.schema, **_PARQUET_OPTIONS))
        writer[0].write_table(piece)

    summary = streamed(name, part.pieces(), target, "build", write)
    if writer:
        writer[0].close()
    return buf.getvalue(), summary


def _private_key(key) -> "signing.Ed25519PrivateKey":
    if isinstance(key, signing.Ed25519PrivateKey):
        return key
    if key is None or str(key) == "":
        raise BundleError(f"no signing key: give --key FILE or set {signing.ENV_SIGNING_KEY} to its path")
    return signing.load_private_key(key)


def bundle_bytes(tables: Mapping[str, pa.Table], *, line_id: str, direction: str, train_type: str,
                 private_key, release: Release, line_digest: str = "", line_schema_version: int = 1,
                 expected: Sequence[str] | None = None, day: BundleDay | None = None,
                 given: Mapping[str, bytes] | None = None) -> bytes:
    """The bytes of a signed bundle holding ``tables`` (no file is written).

    Parameters
    ----------
    tables : mapping of name -> pyarrow.Table or Partition
        Must hold every name in :data:`CORE_TABLES`; may hold those in
        :data:`EXPECTED_TABLES` and other names ``[a-z][a-z0-9_]*``. Core
        tables must match their declared schema. A step's table may be given as its dataset's
        :class:`~planner.bundle.assemble.Partition`: it is then read, checked and encoded a file at a time
        (:func:`streamed_bytes`).
    line_id, direction, train_type : str
        What the bundle is for; every row of a table with a ``line``,
        ``direction`` or ``train_type`` column must carry these values.
    private_key : Ed25519PrivateKey or path
        Signing key (a path is loaded with :func:`planner.bundle.signing.load_private_key`).
    release : Release
        Version, build time, validity and key kind, signed in the manifest.
    line_digest : str
        SHA-256 hex of the input line DB (``Line.source_digest``), or "".
    line_schema_version : int
        Schema version of the input line DB.
    expected : sequence of str, optional
        The expected tables for this vehicle (:func:`expected_tables` of its cruise mode);
        those absent are listed as missing. Default every :data:`EXPECTED_TABLES`.
    day : BundleDay, optional
        The operating day the bundle is for: its window and the temporary restrictions it includes
        (those of ``day`` named ``T.<id>`` in its restrictions table) go into the manifest.
    given : mapping of name -> bytes, optional
        Members of the steps' tables (:data:`STEP_TABLES`) as the Parquet bytes of a bundle signed before
        from the same datasets with the same code (:func:`build_line`'s ``reused``): taken as they are, not
        encoded again; a given table is not in ``tables`` but for ``eval_points`` and ``stop_summary``, which
        the cross-checks and the manifest's ``no_stop`` read (decoded from these bytes). The tables were
        checked against each other when those bytes were first signed; here the given eval points are checked
        against this bundle's beacons again, the rest against the line's own tables as always.
    """
    key = _private_key(private_key)
    given = dict(given or {})
    if not set(given) <= set(STEP_TABLES):
        raise BundleError(f"only the steps' tables may be given as bytes, not {sorted(set(given) - set(STEP_TABLES))}")
    if not isinstance(release, Release):
        raise BundleError("a bundle needs a Release (version, build time, validity); see Release.issue")
    expected = EXPECTED_TABLES if expected is None else tuple(expected)
    if not set(expected) <= set(EXPECTED_TABLES) or not set(EXPECTED_TABLES) - set(expected) <= set(VEHICLE_TABLES):
        raise BundleError(f"expected tables {list(expected)}: only {', '.join(VEHICLE_TABLES)} may be left out")
    bundle_name(line_id, direction, train_type)  # validates the ids
    if line_digest and not SHA256_RE.fullmatch(line_digest):
        raise BundleError(f"line digest {line_digest!r} is not a SHA-256 hex digest")
    absent = [t for t in CORE_TABLES if t not in tables]
    if absent:
        raise BundleError(f"cannot build a bundle without the {', '.join(absent)} table(s)")
    members: dict[str, bytes] = {}
    files = []
    total = 0
    checked = dict(tables)  # what the cross-checks read: a streamed table's summary in place of its partition
    for name in sorted(set(tables) | set(given)):
        if not _TABLE_NAME.fullmatch(name):
            raise BundleError(f"table name {name!r} not allowed: use lower-case letters, digits and '_'")
        if name in given:
            data = given[name]
            rows = pq.read_metadata(pa.BufferReader(data)).num_rows
        elif isinstance(tables[name], Partition):  # read, checked and encoded a file at a time
            data, checked[name] = streamed_bytes(name, tables[name], (line_id, direction, train_type))
            rows = checked[name].num_rows
        else:
            t = tables[name]
            if name in CORE_SCHEMAS:
                check_schema(name, t.schema, CORE_SCHEMAS[name], "build")
            check_keys(name, t, line_id, direction, train_type, "build")
            data, rows = parquet_bytes(t), t.num_rows
        if len(data) > MAX_MEMBER_BYTES:
            raise BundleError(f"table {name} is {len(data)} bytes, above the {MAX_MEMBER_BYTES}-byte member bound")
        total += len(data)
        fname = f"{name}.parquet"
        members[fname] = data
        files.append({"name": fname, "size": len(data), "sha256": hashlib.sha256(data).hexdigest(), "rows": rows})
    if total > MAX_TOTAL_BYTES:
        raise BundleError(f"bundle tables total {total} bytes, above the {MAX_TOTAL_BYTES}-byte bound")
    manifest = {
        "format": FORMAT,
        "schema_version": SCHEMA_VERSION,
        "line_id": line_id,
        "direction": direction,
        "train_type": train_type,
        "software_version": __version__,
        "writer": f"pyarrow {pa.__version__}",
        "line_digest": line_digest,
        "line_schema_version": int(line_schema_version),
        "key_id": signing.public_key_id(key.public_key()),
        "key_kind": "development" if release.development else "production",
        "bundle_version": release.version,
        "built_at": format_time(release.built_at_s),
        "expires": format_time(release.expires_s),
        "files": files,
        "missing": sorted(t for t in expected if t not in tables and t not in given),
    }
    if day is not None:
        have = set(tables["restrictions"].column("restriction_id").to_pylist())
        manifest["operating_day"] = day.record(rid for rid, _, _ in day.restrictions if f"T.{rid}" in have)
    no_stop = no_stop_rows(tables.get("stop_summary"))
    if no_stop:  # signed: the vehicle knows where the bundle cannot stop it (never only a smaller stop_samples)
        manifest["no_stop"] = no_stop
    check_manifest(manifest, "build")
    check_tables(checked, manifest, "build")  # never sign what verify would refuse
    mbytes = canonical_json(manifest)
    members[MANIFEST] = mbytes
    members[SIGNATURE] = signing.sign(key, mbytes)
    return pack(members)


def write_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` so that the name only ever holds a complete file.

    A temporary file ``.<name>.*.tmp`` in the same folder is written, fsynced
    and renamed over ``path`` (:func:`planner.io.atomic.atomic_path`); bundles are
    signed, public data (0644). After a kill the temporary file stays behind
    under its hidden name, never under the final one.
    """
    write_bytes_atomic(path, data)


def build_bundle(tables: Mapping[str, pa.Table], *, line_id: str, direction: str, train_type: str,
                 out_dir: str | os.PathLike, private_key, release: Release, line_digest: str = "",
                 line_schema_version: int = 1, expected: Sequence[str] | None = None,
                 day: BundleDay | None = None, given: Mapping[str, bytes] | None = None) -> BundleInfo:
    """Build, sign and atomically write one bundle into ``out_dir``; see :func:`bundle_bytes`.

    Returns
    -------
    BundleInfo
        What was written (path ``out_dir/<line>_<direction>_<train_type>.pdb``).

    Raises
    ------
    OSError
        The file cannot be written (a full disk, no permission), with its errno and the path that
        failed; nothing is left under the bundle's name. Each caller names its own fix: ``planner
        bundle build`` its ``--out``, the nightly job its output root.
    """
    out = Path(out_dir)
    data = bundle_bytes(tables, line_id=line_id, direction=direction, train_type=train_type,
                        private_key=private_key, release=release, line_digest=line_digest,
                        line_schema_version=line_schema_version, expected=expected, day=day, given=given)
    path = out / bundle_name(line_id, direction, train_type)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(path, data)
    members = unpack(io.BytesIO(data), len(data), str(path))
    return manifest_info(str(path), json.loads(members[MANIFEST]), (len(data), hashlib.sha256(data).hexdigest()))


def _read_given(given: Mapping[str, bytes]) -> dict[str, pa.Table]:
    """The given tables a bundle's checks and manifest read (:data:`DECODED_GIVEN`), decoded from their bytes."""
    return {name: pq.read_table(pa.BufferReader(given[name])) for name in DECODED_GIVEN if name in given}


def build_line(line: Line, out_dir: str | os.PathLike, private_key, *, release: Release, tables_dir=None,
               stops_dir=None, directions: Sequence[str] | None = None, train_types: Sequence[str] | None = None,
               on_built: Callable[[BundleInfo], None] | None = None, day: BundleDay | None = None,
               reused: Callable[[str, str], Mapping[str, bytes] | None] | None = None) -> list[BundleInfo]:
    """Build every bundle of a line (each direction × train type, or the ones asked for).

    ``day``: the operating day the bundles are for (``line`` is then the day's line, its temporary
    restrictions among its speed limits): the manifest names it, and each DB-fed pattern of a temporary
    restriction carries its window.

    ``reused(direction, train_type)``: some of that bundle's steps' tables as the member bytes of a bundle signed
    before from the same datasets' files with the same code (the nightly job's previous run,
    :mod:`planner.job.bundle_reuse`), or None; the others are read from ``tables_dir`` and ``stops_dir`` and
    encoded. The line's own tables are always made again and the manifest signed anew (its release and line
    digest are this build's).

    The key is loaded once; every bundle gets the same ``release``; each is
    written atomically as soon as it is complete. ``on_built`` is called after
    each (for progress display).
    """
    key = _private_key(private_key)
    dirs = list(directions) if directions else list(DIRECTIONS)
    for d in dirs:
        if d not in DIRECTIONS:
            raise BundleError(f"--direction must be 'down' or 'up', not {d!r}")
    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    for t in types:
        line.train_type(t)  # UnknownNameError names the known types
    done = []
    for d in dirs:
        for t in types:
            given = reused(d, t) if reused is not None else None
            tables = assemble(line, d, t, tables_dir=tables_dir, stops_dir=stops_dir,
                              validity=day.validity() if day is not None else None, streamed=STREAMED,
                              given=given or ())
            if given is not None:
                tables.update(_read_given(given))
            info = build_bundle(tables, line_id=line.line_id, direction=d, train_type=t, out_dir=out_dir,
                                private_key=key, release=release, line_digest=line.source_digest,
                                line_schema_version=line.schema_version,
                                expected=expected_tables(line.train_type(t).cruise), day=day, given=given)
            done.append(info)
            del tables  # a bundle's tables (a partition's table (d) on a long line) before the next bundle's
            give_back()
            if on_built is not None:
                on_built(info)
    return done


