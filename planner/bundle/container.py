"""Signed, reproducible on-board DB bundles (DESIGN.md §7, issue 7).

One bundle per line × direction × train type, a single file
``<line>_<direction>_<train_type>.pdb`` that the vehicle loads.

Format
------
An uncompressed POSIX ustar archive written by this module, byte for byte:

* members sorted by name, every header canonical: mode 0644, uid/gid 0, empty
  uname/gname, mtime 0, type regular file, no prefix/link fields; data padded
  with zeros to 512-byte blocks; the archive ends with exactly two zero blocks
  (no record padding), so the bytes depend on the contents only;
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
  build time and expiry (:class:`Release`), the tables expected but missing,
  and for every other member its name, size, SHA-256 and row count;
* ``manifest.sig``: the 64-byte Ed25519 signature of the exact manifest bytes.

Any standard ``tar`` can list and extract a bundle; this module reads it with
its own strict parser (see :func:`verify_bundle`), which accepts nothing but
the canonical form it writes.

Trust
-----
Reading checks, in this order, and parses nothing else before the signature is
proven: archive structure (member names ``[a-z0-9_]+.parquet`` or the two
manifest files, regular files only, no duplicates, sizes within bounds, every
header and padding byte canonical, nothing after the end); the signature of
``manifest.json``; the manifest's schema; that its ``key_id`` is the id of the
verifying key; then what the vehicle asked for (:func:`verify_bundle`: the
expected line/direction/train type, a production key unless development keys
are allowed, a version not below the installed one, not expired); that the
members are exactly the files it lists, each with its size and SHA-256; then
the tables themselves: declared columns and types, the line/direction/train
type in every row, and cross-table consistency (ATS-P rows ↔ restrictions,
beacon order and flags, table (b) ratios and points present in table (a) and
the evaluation points, beacon evaluation points present in the beacons). ``docs/bundles.md`` explains each check and the attack
it stops.

Freshness and reproducibility
-----------------------------
The version, build time and validity are *inputs* of a build (:class:`Release`),
like ``SOURCE_DATE_EPOCH`` for reproducible builds: the same tables, key and
release give the same bytes. :func:`Release.issue` derives the version from the
build time (UTC ``YYYYMMDDHHMMSS`` as an integer), so versions increase with
build time for every target, on any build host, without state to keep.

Writes are atomic: the bundle is written to a temporary file in the output
folder, fsynced and renamed over the final name, so an interrupted build
leaves either no bundle or the complete previous one under that name.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import stat
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from planner import __version__
from planner.bundle import atsp, signing
from planner.io.atomic import write_bytes_atomic
from planner.io.parquet import declare
from planner.tables.eval_points import KINDS as EVAL_POINT_KINDS
from planner.errors import BundleError
from planner.line.model import DIRECTIONS, Line, sign
from planner.line.schema import PATH_ID_RE, PATH_ID_RULE, is_path_id
from planner.physics.speed_profile import onboard_max_ms, restriction_spans
from planner.line.units import kmh

# --- format constants ----------------------------------------------------------
FORMAT = "planner-onboard-db"
SCHEMA_VERSION = 2
SUPPORTED_SCHEMA_VERSIONS = frozenset({2})
"""Version 1 had no target binding, version, expiry or key kind: refused, as it cannot be kept fresh."""
KEY_KINDS = ("production", "development")
DEFAULT_VALID_DAYS = 30
"""Default validity of a bundle [days]: a vehicle refuses it this long after its build time."""
ENV_BUILD_TIME = "SOURCE_DATE_EPOCH"
"""Environment variable fixing the build time [Unix seconds] (reproducible-builds.org convention)."""
_TIME_FORMAT = "%Y-%m-%dT%H:%M:%SZ"
_TIME_RE = re.compile(r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z")
SUFFIX = ".pdb"
MANIFEST = "manifest.json"
SIGNATURE = "manifest.sig"
MAX_MEMBER_BYTES = 256 * 1024**2
"""Largest member accepted or written [bytes] (256 MiB)."""
MAX_TOTAL_BYTES = 1024**3
"""Largest sum of member sizes accepted or written [bytes] (1 GiB)."""
MAX_MEMBERS = 64
MAX_MANIFEST_BYTES = 1024**2

CORE_TABLES = ("restrictions", "max_profile", "atsp", "beacons", "timetable")
"""Tables every bundle holds: built from the line DB itself."""
EXPECTED_TABLES = ("eval_points", "table_a", "table_b", "table_c", "table_d", "stop_summary", "stop_samples")
"""Tables a complete bundle holds, built by the tables and stopping steps; absent ones are listed in the manifest."""
VEHICLE_TABLES = {"table_d": "sawtooth"}
"""Expected tables that exist only for one cruise mode: table (d) for sawtooth vehicles (DESIGN §3)."""


def expected_tables(cruise: str | None = None) -> tuple[str, ...]:
    """The tables a complete bundle for a vehicle with this cruise mode holds (None: every one)."""
    return tuple(t for t in EXPECTED_TABLES if cruise is None or VEHICLE_TABLES.get(t, cruise) == cruise)


TABLE_SOURCES = {"tables": ("eval_points", "table_a", "table_b", "table_c", "table_d"),
                 "stops": ("stop_summary", "stop_samples")}
"""Which output folder (``--tables`` / ``--stops``) each expected table is read from."""

_BLOCK = 512
_TABLE_NAME = re.compile(r"[a-z][a-z0-9_]{0,63}")
_MEMBER_NAME = re.compile(r"[a-z][a-z0-9_]{0,63}\.parquet")
_ID = PATH_ID_RE  # the one rule for ids that name files (planner.line.schema)
_SHA256 = re.compile(r"[0-9a-f]{64}")
_PARTITION_COLS = ("line", "direction", "train_type")
_PARQUET_OPTIONS = dict(compression="zstd", use_dictionary=True, write_statistics=True, store_schema=False)
"""Fixed Parquet writer settings. ``store_schema=False`` leaves out the serialised Arrow
schema (with the column descriptions, about 2-3 KB per file, two thirds of a small
bundle): the vehicle needs names and types, which Parquet's own schema carries; the
descriptions are declared in this module."""


# --- declared schemas of the tables built here ---------------------------------
def _key_fields() -> list[tuple[str, pa.DataType, str]]:
    return [
        ("line", pa.string(), "line id"),
        ("direction", pa.string(), "running direction, 'down' or 'up'"),
        ("train_type", pa.string(), "train type the bundle is for"),
    ]


RESTRICTIONS_SCHEMA = declare(
    _key_fields() + [
        ("seq", pa.int32(), "running order of the restriction entry, from 0"),
        ("restriction_id", pa.string(), "'R<row>', row = 0-based row in speed_limits.parquet"),
        ("kind", pa.string(), "curve, turnout, civil, station, ..."),
        ("start_m", pa.float64(), "start chainage of the restricted stretch [m]"),
        ("end_m", pa.float64(), "end chainage of the restricted stretch [m]"),
        ("entry_m", pa.float64(), "chainage where the train front enters the restriction [m]"),
        ("clear_m", pa.float64(), "chainage of the front when the tail has left the restriction [m]"),
        ("limit_kmh", pa.float64(), "restriction speed [km/h]"),
        ("onboard_max_kmh", pa.float64(), "on-board maximum in it: min(limit, line, vehicle max) - margin [km/h]"),
        ("has_beacon", pa.bool_(), "a ground beacon sends this restriction's ATS-P pattern"),
        ("pattern_needed", pa.bool_(), "limit below the approach speed: an ATS-P pattern is needed"),
        ("pattern_distance_m", pa.float64(), "(v_high^2 - v_limit^2) / (2 b_ATS-P): pattern length [m]"),
        ("pattern_start_m", pa.float64(), "chainage where the pattern must begin [m]"),
        ("db_fed", pa.bool_(), "the on-board logic feeds this telegram (a row in atsp)"),
        ("overwrite_conflict", pa.bool_(), "its pattern and another's would overwrite each other"),
        ("overwrites", pa.string(), "restriction_id whose pattern this one's telegram overwrites, or null"),
    ],
    name="restrictions",
    description="Speed restrictions for the direction and train type, in running order, with ATS-P data.",
)
MAX_PROFILE_SCHEMA = declare(
    _key_fields() + [
        ("seq", pa.int32(), "running order, from 0"),
        ("from_m", pa.float64(), "chainage where the segment begins in the running direction [m]"),
        ("to_m", pa.float64(), "chainage where the segment ends in the running direction [m]"),
        ("limit_kmh", pa.float64(), "lowest of line, vehicle and held restriction speeds [km/h]"),
        ("onboard_max_kmh", pa.float64(), "on-board maximum speed = limit_kmh - speed margin [km/h]"),
    ],
    name="max_profile",
    description="On-board maximum-speed profile over the whole line, restrictions held until the tail clears.",
)
ATSP_SCHEMA = declare(
    _key_fields() + [
        ("seq", pa.int32(), "running order of the feed point, from 0"),
        ("restriction_id", pa.string(), "restriction the telegram protects (see restrictions)"),
        ("feed_m", pa.float64(), "chainage where the telegram is fed to the ATS-P unit [m]"),
        ("pattern_start_m", pa.float64(), "chainage where the pattern must begin [m] (feed_m unless clipped)"),
        ("entry_m", pa.float64(), "chainage of the restriction start in the running direction [m]"),
        ("distance_m", pa.float64(), "distance from the feed point to the restriction start [m]"),
        ("hold_m", pa.float64(), "restriction length + train length: speed held over it [m]"),
        ("limit_kmh", pa.float64(), "restriction speed [km/h]"),
        ("telegram", pa.string(), "telegram to feed: P<limit km/h:3>D<distance m:5>L<hold m:5>"),
        ("feed_clipped", pa.bool_(), "pattern start lies before the line start; fed at the line start"),
        ("overwrite_conflict", pa.bool_(), "this telegram and another's would overwrite each other"),
        ("overwrites", pa.string(), "restriction_id whose pattern this telegram overwrites, or null"),
    ],
    name="atsp",
    description="ATS-P telegrams fed from the DB for restrictions without a ground beacon.",
)
BEACONS_SCHEMA = declare(
    _key_fields() + [
        ("seq", pa.int32(), "running order, from 0"),
        ("beacon_id", pa.string(), "beacon id"),
        ("position_m", pa.float64(), "chainage [m]"),
        ("kind", pa.string(), "signal, pattern_update, tasc, other"),
        ("telegram", pa.string(), "telegram as received on board"),
        ("evaluation_point", pa.bool_(), "running time is re-evaluated here"),
        ("correction_usable", pa.bool_(), "telegram differs from both neighbours: may correct the position"),
    ],
    name="beacons",
    description="Beacons read in the direction, in running order, with position-correction flags.",
)
TIMETABLE_SCHEMA = declare(
    _key_fields() + [
        ("train_id", pa.string(), "train number"),
        ("seq", pa.int32(), "order of calls along the run, from 0"),
        ("station_id", pa.string(), "station"),
        ("arrival_s", pa.float64(), "arrival, seconds after midnight; null at the origin [s]"),
        ("departure_s", pa.float64(), "departure, seconds after midnight; null at the terminus [s]"),
        ("stops", pa.bool_(), "false for a pass"),
    ],
    name="timetable",
    description="Timetable slice: trains of the train type and direction, calls in order.",
)
CORE_SCHEMAS = {
    "restrictions": RESTRICTIONS_SCHEMA,
    "max_profile": MAX_PROFILE_SCHEMA,
    "atsp": ATSP_SCHEMA,
    "beacons": BEACONS_SCHEMA,
    "timetable": TIMETABLE_SCHEMA,
}


# --- release: version, build time, expiry ---------------------------------------
def format_time(t_s: int) -> str:
    """``YYYY-MM-DDTHH:MM:SSZ`` (UTC) of Unix seconds ``t_s``: the manifest's time form."""
    return time.strftime(_TIME_FORMAT, time.gmtime(int(t_s)))


def parse_time(text: str, what: str = "time") -> int:
    """Unix seconds of an ISO 8601 time; a time without a zone is UTC. Raises BundleError."""
    s = str(text).strip()
    try:
        t = datetime.fromisoformat(s[:-1] + "+00:00" if s.endswith(("Z", "z")) else s)
    except ValueError:
        raise BundleError(f"{what} {text!r} is not an ISO 8601 time such as 2026-11-23T04:00:00Z") from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return int(t.timestamp())


def build_time_s(env: Mapping[str, str] | None = None) -> int:
    """The build time [Unix seconds]: ``$SOURCE_DATE_EPOCH`` when set, else the clock now (whole seconds)."""
    env = os.environ if env is None else env
    raw = env.get(ENV_BUILD_TIME, "")
    if raw == "":
        return int(time.time())
    if not raw.isdigit():
        raise BundleError(f"{ENV_BUILD_TIME}={raw!r} must be a whole number of seconds since 1970-01-01 UTC")
    return int(raw)


@dataclass(frozen=True)
class Release:
    """How a bundle is issued: version, build time, validity, and whether the key is a development key.

    All four are signed in the manifest. They are build *inputs*, so a build is
    a pure function of tables, key and release (byte-reproducible).

    Attributes
    ----------
    version : int
        Bundle version, ≥ 1; a vehicle refuses one below the version it has installed.
    built_at_s : int
        Build time [Unix seconds, UTC].
    valid_s : int
        Validity [s]; the bundle expires at ``built_at_s + valid_s``.
    development : bool
        Signed with a development key: vehicles in service refuse it.
    """

    version: int
    built_at_s: int
    valid_s: int = DEFAULT_VALID_DAYS * 86400
    development: bool = False

    def __post_init__(self):
        for name in ("version", "built_at_s", "valid_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int):
                raise BundleError(f"bundle {name} must be an integer, found {v!r}")
        if self.version < 1:
            raise BundleError(f"bundle version must be at least 1, found {self.version}")
        if not 0 <= self.built_at_s < 253402300800:  # year 10000: the manifest's time form has 4 digits
            raise BundleError(f"bundle build time {self.built_at_s} is outside 1970..9999")
        if self.valid_s < 1:
            raise BundleError(f"bundle validity must be at least 1 s, found {self.valid_s}")

    @classmethod
    def issue(cls, built_at_s: int | None = None, *, valid_days: float = DEFAULT_VALID_DAYS,
              development: bool = False, version: int | None = None) -> "Release":
        """A release built at ``built_at_s`` (default :func:`build_time_s`), version from the build time.

        The version is the build time in UTC as the integer ``YYYYMMDDHHMMSS``
        (e.g. 20261123040000): it grows with the build time for every target,
        on every build host, without a counter to keep, and reads as a date.
        """
        t = build_time_s() if built_at_s is None else int(built_at_s)
        if not (isinstance(valid_days, (int, float)) and math.isfinite(valid_days) and valid_days > 0):
            raise BundleError(f"bundle validity must be a positive number of days, found {valid_days!r}")
        v = int(time.strftime("%Y%m%d%H%M%S", time.gmtime(t))) if version is None else version
        return cls(v, t, int(round(valid_days * 86400)), development)

    @property
    def expires_s(self) -> int:
        return self.built_at_s + self.valid_s


# --- public results ------------------------------------------------------------
@dataclass(frozen=True)
class FileEntry:
    """One table member as the manifest lists it."""

    name: str
    size: int
    sha256: str
    rows: int


@dataclass(frozen=True)
class BundleInfo:
    """What a verified (or just built) bundle holds.

    Attributes
    ----------
    path : str
        The bundle file.
    line_id, direction, train_type : str
    schema_version : int
        Bundle format version.
    software_version : str
        ``planner.__version__`` of the build.
    line_digest : str
        SHA-256 of the input line DB (``Line.source_digest``; "" for an in-memory line).
    key_id : str
        SHA-256 of the signing public key (raw bytes).
    key_kind : str
        ``production`` or ``development``.
    bundle_version : int
        Release version (monotonic per target).
    built_at, expires : str
        Build time and expiry, ``YYYY-MM-DDTHH:MM:SSZ``.
    files : tuple of FileEntry
        Table members, sorted by name.
    missing : tuple of str
        Expected tables the bundle does not hold (empty for a complete bundle).
    size_bytes : int
        Size of the bundle file.
    sha256 : str
        SHA-256 of the whole bundle file.
    """

    path: str
    line_id: str
    direction: str
    train_type: str
    schema_version: int
    software_version: str
    line_digest: str
    key_id: str
    files: tuple[FileEntry, ...]
    missing: tuple[str, ...]
    size_bytes: int
    sha256: str
    key_kind: str = "production"
    bundle_version: int = 0
    built_at: str = ""
    expires: str = ""

    @property
    def target(self) -> str:
        """``LINE/DIRECTION/TYPE``: what the bundle is for."""
        return f"{self.line_id}/{self.direction}/{self.train_type}"

    @property
    def complete(self) -> bool:
        """True when every expected table is present."""
        return not self.missing

    @property
    def tables(self) -> tuple[str, ...]:
        return tuple(f.name.removesuffix(".parquet") for f in self.files)

    def summary(self) -> list[str]:
        """Human-readable lines: what the bundle holds."""
        out = [
            f"{Path(self.path).name}: line {self.line_id}, {self.direction}, train type {self.train_type}; "
            f"bundle schema v{self.schema_version}, planner {self.software_version}",
            f"version {self.bundle_version}, built {self.built_at}, expires {self.expires}",
            f"line DB sha256 {self.line_digest or '(in-memory line)'}; signed by {self.key_kind} key {self.key_id[:16]}"
            + ("  (DEVELOPMENT KEY: not for service)" if self.key_kind != "production" else ""),
            f"{self.size_bytes} bytes, sha256 {self.sha256}",
        ]
        for f in self.files:
            out.append(f"  {f.name:<24} {f.rows:>9} rows {f.size:>11} bytes")
        out.append("complete" if self.complete else "PARTIAL: missing " + ", ".join(self.missing))
        return out


@dataclass(frozen=True, eq=False)
class Bundle:
    """A verified bundle read into memory: its info and its tables by name."""

    info: BundleInfo
    tables: Mapping[str, pa.Table] = field(repr=False)


# --- tables built from the line DB ---------------------------------------------
def check_id(value: str, what: str) -> str:
    """A line id / train type safe to put in a file name and a manifest."""
    if not is_path_id(value):
        raise BundleError(f"{what} {value!r} cannot name a bundle: {PATH_ID_RULE}")
    return value


def bundle_name(line_id: str, direction: str, train_type: str) -> str:
    """File name of a bundle: ``<line>_<direction>_<train_type>.pdb``."""
    if direction not in DIRECTIONS:
        raise BundleError(f"direction must be 'down' or 'up', not {direction!r}")
    return f"{check_id(line_id, 'line id')}_{direction}_{check_id(train_type, 'train type')}{SUFFIX}"


def _keys(n: int, line_id: str, direction: str, train_type: str) -> dict[str, list]:
    return {"line": [line_id] * n, "direction": [direction] * n, "train_type": [train_type] * n}


def _table(cols: dict[str, list], schema: pa.Schema) -> pa.Table:
    return pa.Table.from_arrays([pa.array(cols[f.name], type=f.type) for f in schema], schema=schema)


def line_tables(line: Line, direction: str, train_type: str) -> dict[str, pa.Table]:
    """The tables built from the line DB alone: restrictions, max_profile, atsp, beacons, timetable.

    Parameters
    ----------
    line : Line
        Validated line (SI).
    direction : {'down', 'up'}
    train_type : str
        A train type of ``line``.

    Notes
    -----
    The ATS-P approach speed ``v_high`` is min(line maximum, vehicle maximum):
    the fastest a train of this type can approach any restriction. Every
    restriction with a pattern (limit < v_high) takes part in the overwrite
    check, also those with a ground beacon (their telegram replaces the held
    pattern too; their beacon is assumed at the computed pattern start). A
    pattern must be held from its feed point until the train's tail has left
    the restriction, so a telegram fed anywhere in that window overwrites it.
    """
    train = line.train_type(train_type)
    sg = sign(direction)
    lid = line.line_id
    x0 = line.start_m if direction == "down" else line.end_m  # s = 0 at the line end the train enters
    length = line.end_m - line.start_m
    to_chain = lambda s: x0 + sg * np.asarray(s, dtype=float)  # noqa: E731

    # Restrictions in running order.
    rows = {r.row: r for r in line.limits_for(direction, train_type)}
    spans = sorted(restriction_spans(line, train, direction, x0),
                   key=lambda sp: (sp.s_from_m, sp.s_to_m, sp.limit_ms, sp.row))
    n = len(spans)
    s_from = np.array([sp.s_from_m for sp in spans], dtype=float)
    s_to = np.array([sp.s_to_m for sp in spans], dtype=float)
    limit = np.array([sp.limit_ms for sp in spans], dtype=float)
    v_high = min(line.max_speed_ms, train.max_speed_ms)
    dist = np.atleast_1d(atsp.pattern_distance_m(v_high, limit, train.atsp_pattern_ms2)) if n else np.zeros(0)
    needed = limit < v_high
    s_start = s_from - dist
    s_feed = np.maximum(s_start, 0.0)  # cannot feed before the train is on the line
    has_beacon = np.array([rows[sp.row].has_beacon for sp in spans], dtype=bool)
    db_fed = needed & ~has_beacon
    overwrites, conflict = atsp.overwrite_conflicts(s_feed, s_to, needed)
    rid = [f"R{sp.row}" for sp in spans]
    ow = [rid[i] if i >= 0 else None for i in overwrites]
    restrictions = _table({
        **_keys(n, lid, direction, train_type),
        "seq": list(range(n)),
        "restriction_id": rid,
        "kind": [rows[sp.row].kind for sp in spans],
        "start_m": [rows[sp.row].start_m for sp in spans],
        "end_m": [rows[sp.row].end_m for sp in spans],
        "entry_m": to_chain(s_from).tolist(),
        "clear_m": to_chain(s_to).tolist(),
        "limit_kmh": kmh(limit).tolist(),
        "onboard_max_kmh": kmh(np.minimum(limit, v_high) - train.speed_margin_ms).tolist(),
        "has_beacon": has_beacon.tolist(),
        "pattern_needed": needed.tolist(),
        "pattern_distance_m": dist.tolist(),
        "pattern_start_m": to_chain(s_start).tolist(),
        "db_fed": db_fed.tolist(),
        "overwrite_conflict": conflict.tolist(),
        "overwrites": ow,
    }, RESTRICTIONS_SCHEMA)

    # DB-fed telegrams, in order of their feed points.
    idx = sorted(np.flatnonzero(db_fed), key=lambda i: (s_feed[i], i))
    m = len(idx)
    hold = [float(s_to[i] - s_from[i]) for i in idx]
    atsp_table = _table({
        **_keys(m, lid, direction, train_type),
        "seq": list(range(m)),
        "restriction_id": [rid[i] for i in idx],
        "feed_m": [float(to_chain(s_feed[i])) for i in idx],
        "pattern_start_m": [float(to_chain(s_start[i])) for i in idx],
        "entry_m": [float(to_chain(s_from[i])) for i in idx],
        "distance_m": [float(s_from[i] - s_feed[i]) for i in idx],
        "hold_m": hold,
        "limit_kmh": [float(kmh(limit[i])) for i in idx],
        "telegram": [atsp.restriction_telegram(float(kmh(limit[i])), float(s_from[i] - s_feed[i]), h)
                     for i, h in zip(idx, hold)],
        "feed_clipped": [bool(s_start[i] < 0.0) for i in idx],
        "overwrite_conflict": [bool(conflict[i]) for i in idx],
        "overwrites": [ow[i] for i in idx],
    }, ATSP_SCHEMA)

    # On-board maximum profile: constant between span ends; evaluate at midpoints.
    edges = np.unique(np.clip(np.concatenate([[0.0, length], s_from, s_to]), 0.0, length))
    vmax = onboard_max_ms(0.5 * (edges[:-1] + edges[1:]), spans, line.max_speed_ms, train.max_speed_ms,
                          train.speed_margin_ms)
    keep = np.concatenate([[True], np.diff(vmax) != 0.0])  # merge equal neighbours
    starts = edges[:-1][keep]
    ends = np.append(starts[1:], edges[-1])
    v = vmax[keep]
    k = len(v)
    max_profile = _table({
        **_keys(k, lid, direction, train_type),
        "seq": list(range(k)),
        "from_m": to_chain(starts).tolist(),
        "to_m": to_chain(ends).tolist(),
        "limit_kmh": kmh(v + train.speed_margin_ms).tolist(),
        "onboard_max_kmh": kmh(v).tolist(),
    }, MAX_PROFILE_SCHEMA)

    # Beacons in running order with the correction flag.
    bs = line.beacons_for(direction)
    usable = atsp.correction_usable([b.telegram for b in bs])
    nb = len(bs)
    beacons = _table({
        **_keys(nb, lid, direction, train_type),
        "seq": list(range(nb)),
        "beacon_id": [b.beacon_id for b in bs],
        "position_m": [b.position_m for b in bs],
        "kind": [b.kind for b in bs],
        "telegram": [b.telegram for b in bs],
        "evaluation_point": [b.evaluation_point for b in bs],
        "correction_usable": usable.tolist(),
    }, BEACONS_SCHEMA)

    # Timetable slice, trains ordered by first departure then number.
    def first_dep(t):
        deps = [c.departure_s for c in t.calls if not math.isnan(c.departure_s)]
        return min(deps) if deps else math.inf

    trains = sorted((t for t in line.trains if t.train_type == train_type and t.direction == direction),
                    key=lambda t: (first_dep(t), t.train_id))
    calls = [(t, c) for t in trains for c in sorted(t.calls, key=lambda c: c.seq)]
    nan_none = lambda x: None if math.isnan(x) else float(x)  # noqa: E731
    timetable = _table({
        **_keys(len(calls), lid, direction, train_type),
        "train_id": [t.train_id for t, _ in calls],
        "seq": [c.seq for _, c in calls],
        "station_id": [c.station_id for _, c in calls],
        "arrival_s": [nan_none(c.arrival_s) for _, c in calls],
        "departure_s": [nan_none(c.departure_s) for _, c in calls],
        "stops": [c.stops for _, c in calls],
    }, TIMETABLE_SCHEMA)
    return {"restrictions": restrictions, "max_profile": max_profile, "atsp": atsp_table,
            "beacons": beacons, "timetable": timetable}


# --- reading the other steps' datasets -----------------------------------------
def read_partition(root: str | os.PathLike, dataset: str, line_id: str, direction: str,
                   train_type: str) -> pa.Table | None:
    """One partition of a hive dataset ``root/dataset/line=/direction=/train_type=``, or None if absent.

    Files are read in sorted name order and concatenated, so the row order is
    the writer's; the partition columns are added as plain strings.
    """
    folder = Path(root) / dataset / f"line={line_id}" / f"direction={direction}" / f"train_type={train_type}"
    files = sorted(folder.glob("*.parquet"), key=lambda p: p.name) if folder.is_dir() else []
    if not files:
        return None
    try:
        parts = [pq.read_table(f, partitioning=None) for f in files]
        t = pa.concat_tables(parts) if len(parts) > 1 else parts[0]
    except (pa.ArrowInvalid, OSError) as e:
        raise BundleError(f"cannot read {folder}: {e}; rebuild the {dataset} dataset") from None
    for col, val in zip(_PARTITION_COLS, (line_id, direction, train_type)):
        if col in t.column_names:  # hive files normally leave it out; if stored, it must agree
            _check_keys(dataset, t.select([col]), line_id, direction, train_type, str(folder))
            t = t.drop_columns([col])
        t = t.append_column(pa.field(col, pa.string()), pa.array([val] * t.num_rows, type=pa.string()))
    return t


def assemble(line: Line, direction: str, train_type: str, *, tables_dir=None,
             stops_dir=None) -> dict[str, pa.Table]:
    """Every table of one bundle that exists: the line's own tables plus the datasets found.

    ``tables_dir`` is the output folder of ``planner tables`` (``eval_points``,
    ``table_a``, ``table_b``), ``stops_dir`` that of the stopping step
    (``stop_summary``, ``stop_samples``). Tables not found are left out; the
    builder records them as missing in the manifest.
    """
    tables = line_tables(line, direction, train_type)
    for key, root in (("tables", tables_dir), ("stops", stops_dir)):
        if root is None:
            continue
        if not Path(root).is_dir():
            raise BundleError(f"--{key} {root} is not a folder; give the output folder of that step")
        for name in TABLE_SOURCES[key]:
            t = read_partition(root, name, line.line_id, direction, train_type)
            if t is not None:
                tables[name] = t
    return tables


# --- writing -----------------------------------------------------------------
def parquet_bytes(table: pa.Table) -> bytes:
    """Deterministic Parquet bytes of ``table`` (fixed writer settings, no pandas metadata)."""
    meta = dict(table.schema.metadata or {})
    meta.pop(b"pandas", None)
    table = table.replace_schema_metadata(meta or None)
    buf = io.BytesIO()
    pq.write_table(table, buf, **_PARQUET_OPTIONS)
    return buf.getvalue()


def canonical_json(obj) -> bytes:
    """The one byte form of a manifest: sorted keys, no whitespace, ASCII."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


def _octal(value: int, width: int) -> bytes:
    digits = format(value, "o").encode("ascii")
    if len(digits) > width - 1:
        raise BundleError(f"value {value} does not fit a {width}-byte tar field")
    return digits.rjust(width - 1, b"0") + b"\0"


def _tar_header(name: str, size: int) -> bytes:
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
        out += _tar_header(name, len(data)) + data + b"\0" * _pad(len(data))
    out += b"\0" * (2 * _BLOCK)
    return bytes(out)


def _private_key(key) -> "signing.Ed25519PrivateKey":
    if isinstance(key, signing.Ed25519PrivateKey):
        return key
    if key is None or str(key) == "":
        raise BundleError(f"no signing key: give --key FILE or set {signing.ENV_SIGNING_KEY} to its path")
    return signing.load_private_key(key)


def bundle_bytes(tables: Mapping[str, pa.Table], *, line_id: str, direction: str, train_type: str,
                 private_key, release: Release, line_digest: str = "", line_schema_version: int = 1,
                 expected: Sequence[str] | None = None) -> bytes:
    """The bytes of a signed bundle holding ``tables`` (no file is written).

    Parameters
    ----------
    tables : mapping of name -> pyarrow.Table
        Must hold every name in :data:`CORE_TABLES`; may hold those in
        :data:`EXPECTED_TABLES` and other names ``[a-z][a-z0-9_]*``. Core
        tables must match their declared schema.
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
    """
    key = _private_key(private_key)
    if not isinstance(release, Release):
        raise BundleError("a bundle needs a Release (version, build time, validity); see Release.issue")
    expected = EXPECTED_TABLES if expected is None else tuple(expected)
    if not set(expected) <= set(EXPECTED_TABLES) or not set(EXPECTED_TABLES) - set(expected) <= set(VEHICLE_TABLES):
        raise BundleError(f"expected tables {list(expected)}: only {', '.join(VEHICLE_TABLES)} may be left out")
    bundle_name(line_id, direction, train_type)  # validates the ids
    if line_digest and not _SHA256.fullmatch(line_digest):
        raise BundleError(f"line digest {line_digest!r} is not a SHA-256 hex digest")
    absent = [t for t in CORE_TABLES if t not in tables]
    if absent:
        raise BundleError(f"cannot build a bundle without the {', '.join(absent)} table(s)")
    members: dict[str, bytes] = {}
    files = []
    total = 0
    for name in sorted(tables):
        if not _TABLE_NAME.fullmatch(name):
            raise BundleError(f"table name {name!r} not allowed: use lower-case letters, digits and '_'")
        t = tables[name]
        if name in CORE_SCHEMAS:
            _check_schema(name, t.schema, CORE_SCHEMAS[name], "build")
        _check_keys(name, t, line_id, direction, train_type, "build")
        data = parquet_bytes(t)
        if len(data) > MAX_MEMBER_BYTES:
            raise BundleError(f"table {name} is {len(data)} bytes, above the {MAX_MEMBER_BYTES}-byte member bound")
        total += len(data)
        fname = f"{name}.parquet"
        members[fname] = data
        files.append({"name": fname, "size": len(data), "sha256": hashlib.sha256(data).hexdigest(),
                      "rows": t.num_rows})
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
        "missing": sorted(t for t in expected if t not in tables),
    }
    _check_manifest(manifest, "build")
    _check_tables(tables, manifest, "build")  # never sign what verify would refuse
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
                 line_schema_version: int = 1, expected: Sequence[str] | None = None) -> BundleInfo:
    """Build, sign and atomically write one bundle into ``out_dir``; see :func:`bundle_bytes`.

    Returns
    -------
    BundleInfo
        What was written (path ``out_dir/<line>_<direction>_<train_type>.pdb``).
    """
    out = Path(out_dir)
    data = bundle_bytes(tables, line_id=line_id, direction=direction, train_type=train_type,
                        private_key=private_key, release=release, line_digest=line_digest,
                        line_schema_version=line_schema_version, expected=expected)
    path = out / bundle_name(line_id, direction, train_type)
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_atomic(path, data)
    except OSError as e:
        raise BundleError(f"cannot write {path}: {e.strerror or e}; check --out (space, permissions)") from None
    members = _unpack(io.BytesIO(data), len(data), str(path))
    return _info(str(path), json.loads(members[MANIFEST]), data)


def build_line(line: Line, out_dir: str | os.PathLike, private_key, *, release: Release, tables_dir=None,
               stops_dir=None, directions: Sequence[str] | None = None, train_types: Sequence[str] | None = None,
               on_built: Callable[[BundleInfo], None] | None = None) -> list[BundleInfo]:
    """Build every bundle of a line (each direction × train type, or the ones asked for).

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
            tables = assemble(line, d, t, tables_dir=tables_dir, stops_dir=stops_dir)
            info = build_bundle(tables, line_id=line.line_id, direction=d, train_type=t, out_dir=out_dir,
                                private_key=key, release=release, line_digest=line.source_digest,
                                line_schema_version=line.schema_version,
                                expected=expected_tables(line.train_type(t).cruise))
            done.append(info)
            if on_built is not None:
                on_built(info)
    return done


# --- reading -----------------------------------------------------------------
def _fail(where: str, msg: str) -> BundleError:
    return BundleError(f"bundle {where}: {msg}")


_TYPEFLAGS = {b"1": "a hard link", b"2": "a symbolic link", b"3": "a character device",
              b"4": "a block device", b"5": "a directory", b"6": "a FIFO", b"7": "a contiguous file",
              b"x": "a pax header", b"g": "a pax global header", b"L": "a GNU long name",
              b"K": "a GNU long link name"}


def _parse_octal(field_: bytes, what: str, where: str) -> int:
    digits = field_.rstrip(b"\0 ")
    if not digits or not re.fullmatch(rb"[0-7]+", digits):
        raise _fail(where, f"{what} field {field_!r} is not a plain octal number")
    return int(digits, 8)


class _HashingReader:
    """Reads from ``f`` and hashes every byte read, so the file digest costs no second pass."""

    def __init__(self, f):
        self._f, self.sha256 = f, hashlib.sha256()

    def read(self, n: int) -> bytes:
        data = self._f.read(n)
        self.sha256.update(data)
        return data


def _unpack(f, file_size: int, where: str) -> dict[str, bytes]:
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
            raise _fail(where, f"truncated at byte {pos}: no end-of-archive marker")
        pos += _BLOCK
        if h == b"\0" * _BLOCK:
            second = f.read(_BLOCK)
            if second != b"\0" * _BLOCK:
                raise _fail(where, f"malformed end-of-archive marker at byte {pos}")
            pos += _BLOCK
            if f.read(1):
                raise _fail(where, f"unexpected data after the end of the archive at byte {pos}")
            break
        raw_name = h[0:100].split(b"\0", 1)[0]
        shown = raw_name.decode("ascii", "backslashreplace")
        kind = _TYPEFLAGS.get(h[156:157])
        if kind is not None:
            raise _fail(where, f"member {shown!r} is {kind}; only regular files are allowed")
        if h[156:157] not in (b"0", b"\0"):
            raise _fail(where, f"member {shown!r} has unknown type {h[156:157]!r}; only regular files are allowed")
        if raw_name.startswith(b"/") or b".." in raw_name or b"/" in raw_name or b"\\" in raw_name:
            raise _fail(where, f"member name {shown!r} is a path; only plain file names are allowed")
        try:
            name = raw_name.decode("ascii")
        except UnicodeDecodeError:
            raise _fail(where, f"member name {shown!r} is not ASCII") from None
        if not (_MEMBER_NAME.fullmatch(name) or name in (MANIFEST, SIGNATURE)):
            raise _fail(where, f"member name {name!r} not allowed")
        if name in members:
            raise _fail(where, f"duplicate member {name!r}")
        if len(members) >= MAX_MEMBERS:
            raise _fail(where, f"more than {MAX_MEMBERS} members")
        size = _parse_octal(h[124:136], f"member {name!r} size", where)
        bound = MAX_MANIFEST_BYTES if name in (MANIFEST, SIGNATURE) else MAX_MEMBER_BYTES
        if size > bound:
            raise _fail(where, f"member {name!r} declares {size} bytes, above the {bound}-byte bound")
        total += size
        if total > MAX_TOTAL_BYTES:
            raise _fail(where, f"members total more than the {MAX_TOTAL_BYTES}-byte bound")
        if pos + size + _pad(size) > file_size:
            raise _fail(where, f"member {name!r} declares {size} bytes but the file ends first (truncated)")
        if h != _tar_header(name, size):
            raise _fail(where, f"member {name!r} has a non-canonical header (altered or not written by planner)")
        data = f.read(size)
        pad = f.read(_pad(size))
        if len(data) != size or len(pad) != _pad(size):
            raise _fail(where, f"member {name!r} is truncated")
        if pad.strip(b"\0"):
            raise _fail(where, f"member {name!r} has non-zero padding")
        pos += size + len(pad)
        members[name] = data
    if [n for n in members] != sorted(members):
        raise _fail(where, "members are not in sorted order (not written by planner)")
    return members


def _read_members(path: str | os.PathLike | bytes) -> tuple[dict[str, bytes], tuple[int, str]]:
    if isinstance(path, (bytes, bytearray, memoryview)):
        reader = _HashingReader(io.BytesIO(path))
        return _unpack(reader, len(path), "<bytes>"), (len(path), reader.sha256.hexdigest())
    where = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO must not block us
    except FileNotFoundError:
        raise BundleError(f"bundle {where} not found") from None
    except OSError as e:
        raise BundleError(f"bundle {where}: cannot open ({e.strerror})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise _fail(where, "not a regular file")
    with os.fdopen(fd, "rb") as f:
        bound = MAX_TOTAL_BYTES + (MAX_MEMBERS + 2) * 2 * _BLOCK
        if st.st_size > bound:
            raise _fail(where, f"{st.st_size} bytes, above the {bound}-byte bound")
        reader = _HashingReader(f)
        members = _unpack(reader, st.st_size, where)
        return members, (st.st_size, reader.sha256.hexdigest())


def _strict_json(data: bytes, where: str):
    def no_dupes(pairs):
        d = {}
        for k, v in pairs:
            if k in d:
                raise _fail(where, f"manifest has duplicate key {k!r}")
            d[k] = v
        return d

    def no_float(s):
        raise _fail(where, f"manifest holds a non-integer number {s}")

    try:
        obj = json.loads(data.decode("ascii"), object_pairs_hook=no_dupes, parse_float=no_float,
                         parse_constant=no_float)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _fail(where, f"manifest is not valid JSON ({e})") from None
    if canonical_json(obj) != data:
        raise _fail(where, "manifest is not in canonical form")
    return obj


_MANIFEST_KEYS = {
    "format": str, "schema_version": int, "line_id": str, "direction": str, "train_type": str,
    "software_version": str, "writer": str, "line_digest": str, "line_schema_version": int,
    "key_id": str, "files": list, "missing": list, "key_kind": str, "bundle_version": int, "built_at": str,
    "expires": str,
}
_FILE_KEYS = {"name": str, "size": int, "sha256": str, "rows": int}


def _is(v, typ) -> bool:
    return isinstance(v, typ) and not (typ is int and isinstance(v, bool))


def _check_manifest(m, where: str) -> None:
    """Manifest schema: keys, types, supported version, well-formed values."""
    if not isinstance(m, dict):
        raise _fail(where, "manifest is not a JSON object")
    if "schema_version" in m and _is(m["schema_version"], int) and m["schema_version"] not in SUPPORTED_SCHEMA_VERSIONS:
        raise _fail(where, f"bundle schema version {m['schema_version']} not supported by planner {__version__} "
                           f"(supports {sorted(SUPPORTED_SCHEMA_VERSIONS)}); update the vehicle-side software")
    missing = sorted(set(_MANIFEST_KEYS) - set(m))
    extra = sorted(set(m) - set(_MANIFEST_KEYS))
    if missing or extra:
        raise _fail(where, f"manifest keys wrong (missing {missing}, unknown {extra})")
    for k, typ in _MANIFEST_KEYS.items():
        if not _is(m[k], typ):
            raise _fail(where, f"manifest {k!r} must be {typ.__name__}, found {type(m[k]).__name__}")
    if m["format"] != FORMAT:
        raise _fail(where, f"manifest format {m['format']!r} is not {FORMAT!r}")
    if m["direction"] not in DIRECTIONS:
        raise _fail(where, f"manifest direction {m['direction']!r} is not 'down' or 'up'")
    for k in ("line_id", "train_type"):
        if not _ID.fullmatch(m[k]):
            raise _fail(where, f"manifest {k} {m[k]!r} is not a valid id")
    if m["line_digest"] and not _SHA256.fullmatch(m["line_digest"]):
        raise _fail(where, "manifest line_digest is not a SHA-256 hex digest")
    if not _SHA256.fullmatch(m["key_id"]):
        raise _fail(where, "manifest key_id is not a SHA-256 hex digest")
    if m["key_kind"] not in KEY_KINDS:
        raise _fail(where, f"manifest key_kind {m['key_kind']!r} is not one of {list(KEY_KINDS)}")
    if m["bundle_version"] < 1:
        raise _fail(where, f"manifest bundle_version {m['bundle_version']} is not a positive integer")
    for k in ("built_at", "expires"):
        try:
            ok = bool(_TIME_RE.fullmatch(m[k])) and bool(datetime.strptime(m[k], _TIME_FORMAT))
        except ValueError:
            ok = False
        if not ok:
            raise _fail(where, f"manifest {k} {m[k]!r} is not a time of the form YYYY-MM-DDTHH:MM:SSZ")
    if not m["expires"] > m["built_at"]:  # same fixed-width form: text order is time order
        raise _fail(where, f"manifest expires {m['expires']} is not after built_at {m['built_at']}")
    names = []
    for e in m["files"]:
        if not isinstance(e, dict) or set(e) != set(_FILE_KEYS):
            raise _fail(where, f"manifest file entry {e!r} must have exactly the keys {sorted(_FILE_KEYS)}")
        for k, typ in _FILE_KEYS.items():
            if not _is(e[k], typ):
                raise _fail(where, f"manifest file entry {e.get('name')!r}: {k} must be {typ.__name__}")
        if not _MEMBER_NAME.fullmatch(e["name"]) or not _SHA256.fullmatch(e["sha256"]):
            raise _fail(where, f"manifest file entry {e['name']!r} has a bad name or sha256")
        if not (0 <= e["size"] <= MAX_MEMBER_BYTES and e["rows"] >= 0):
            raise _fail(where, f"manifest file entry {e['name']!r} has a bad size or row count")
        names.append(e["name"])
    if names != sorted(set(names)):
        raise _fail(where, "manifest files must be sorted and unique")
    tables = {n.removesuffix(".parquet") for n in names}
    absent_core = [t for t in CORE_TABLES if t not in tables]
    if absent_core:
        raise _fail(where, f"manifest lacks the core table(s) {', '.join(absent_core)}")
    mis = m["missing"]
    if not all(isinstance(x, str) for x in mis) or mis != sorted(set(mis)):
        raise _fail(where, "manifest 'missing' must be a sorted list of unique table names")
    # every expected table absent must be listed, except those that exist only for another cruise
    # mode (VEHICLE_TABLES): the signer, who knew the vehicle, left them out of 'missing'
    absent = {t for t in EXPECTED_TABLES if t not in tables}
    if not set(mis) <= absent or not absent - set(VEHICLE_TABLES) <= set(mis):
        raise _fail(where, f"manifest 'missing' {mis} does not match the tables it lists")


def _check_schema(name: str, got: pa.Schema, want: pa.Schema, where: str) -> None:
    g = [(f.name, f.type) for f in got]
    w = [(f.name, f.type) for f in want]
    if g != w:
        gd, wd = dict(g), dict(w)
        diff = [f"{n}: expected {t}, found {gd.get(n, 'nothing')}" for n, t in w if gd.get(n) != t]
        diff += [f"{n}: not declared" for n in gd if n not in wd]
        raise _fail(where, f"table {name} does not match its declared schema ({'; '.join(diff) or 'column order'})")


def _check_keys(name: str, t: pa.Table, line_id: str, direction: str, train_type: str, where: str) -> None:
    for col, want in (("line", line_id), ("line_id", line_id), ("direction", direction),
                      ("train_type", train_type)):
        if col not in t.column_names or t.num_rows == 0:
            continue
        c = t.column(col)
        if c.null_count or not pc.all(pc.equal(c.cast(pa.string()), want)).as_py():
            found = sorted({str(x) for x in c.to_pylist()} - {want})
            raise _fail(where, f"table {name} column {col} holds {found}, expected only {want!r}")


def _col(t: pa.Table, name: str) -> list:
    return t.column(name).to_pylist()


_REQUIRED_COLUMNS = {
    "eval_points": ("origin", "destination", "eval_point_id"),
    "table_a": ("origin", "destination", "ratio", "running_time_s"),
    "table_b": ("origin", "destination", "eval_point_id", "ratio_before", "ratio_after", "remaining_time_s"),
    "table_c": ("origin", "destination", "eval_point_id", "ratio", "remaining_time_s", "remaining_time_ref_s"),
    "table_d": ("origin", "destination", "eval_point_id", "speed_kmh", "powering", "ratio_after",
                "remaining_time_s", "remaining_time_ref_s"),
}
"""Columns the cross-checks (and the vehicle) rely on in the tables step's datasets."""


def _check_tables(tables: Mapping[str, pa.Table], m: dict, where: str) -> None:
    """Cross-table consistency of a bundle whose bytes are already proven."""
    for name, cols in _REQUIRED_COLUMNS.items():
        if name in tables:
            lost = [c for c in cols if c not in tables[name].column_names]
            if lost:
                raise _fail(where, f"table {name} lacks column(s) {', '.join(lost)}")
    for name, t in tables.items():
        _check_keys(name, t, m["line_id"], m["direction"], m["train_type"], where)
        if name in CORE_SCHEMAS:
            _check_schema(name, t.schema, CORE_SCHEMAS[name], where)
    r, a, b = tables["restrictions"], tables["atsp"], tables["beacons"]
    sg = sign(m["direction"])
    for name in CORE_TABLES:
        t = tables[name]
        if "seq" in t.column_names and name != "timetable" and _col(t, "seq") != list(range(t.num_rows)):
            raise _fail(where, f"table {name} seq is not 0..{t.num_rows - 1}")
    rid = _col(r, "restriction_id")
    if len(set(rid)) != len(rid):
        raise _fail(where, "restrictions has duplicate restriction_id")
    fed = [i for i, x in zip(rid, _col(r, "db_fed")) if x]
    if sorted(fed) != sorted(_col(a, "restriction_id")):
        raise _fail(where, "atsp rows do not match the restrictions marked db_fed")
    for tname, t in (("restrictions", r), ("atsp", a)):
        bad = [x for x in _col(t, "overwrites") if x is not None and x not in rid]
        if bad:
            raise _fail(where, f"{tname} overwrites unknown restriction(s) {bad}")
    entry = np.array(_col(r, "entry_m"), dtype=float) * sg
    if np.any(np.diff(entry) < 0):
        raise _fail(where, "restrictions are not in running order")
    feed = np.array(_col(a, "feed_m"), dtype=float) * sg
    if np.any(np.diff(feed) < 0):
        raise _fail(where, "atsp telegrams are not in running order")
    pos = np.array(_col(b, "position_m"), dtype=float) * sg
    if np.any(np.diff(pos) < 0):
        raise _fail(where, "beacons are not in running order")
    if _col(b, "correction_usable") != atsp.correction_usable(_col(b, "telegram")).tolist():
        raise _fail(where, "beacons correction_usable flags do not match their telegrams")
    beacon_ids = set(_col(b, "beacon_id"))
    mp = tables["max_profile"]
    fr, to = (np.array(_col(mp, c), dtype=float) * sg for c in ("from_m", "to_m"))
    if mp.num_rows == 0 or np.any(fr[1:] != to[:-1]) or np.any(to <= fr):
        raise _fail(where, "max_profile segments are not contiguous in running order")
    ta, tb, ep = tables.get("table_a"), tables.get("table_b"), tables.get("eval_points")
    if ta is not None and tb is not None:
        have = set(zip(_col(ta, "origin"), _col(ta, "destination"), _col(ta, "ratio")))
        for c in ("ratio_before", "ratio_after"):
            need = set(zip(_col(tb, "origin"), _col(tb, "destination"), _col(tb, c)))
            lost = sorted(need - have, key=str)
            if lost:
                raise _fail(where, f"table_b {c} {lost[0][2]} for {lost[0][0]}->{lost[0][1]} is not in table_a")
    tc = tables.get("table_c")
    if ta is not None and tc is not None:  # the adaptive on-board mode reads table (c) beside (a) and (b)
        have = set(zip(_col(ta, "origin"), _col(ta, "destination"), _col(ta, "ratio")))
        lost = sorted(set(zip(_col(tc, "origin"), _col(tc, "destination"), _col(tc, "ratio"))) - have, key=str)
        if lost:
            raise _fail(where, f"table_c ratio {lost[0][2]} for {lost[0][0]}->{lost[0][1]} is not in table_a")
    if ep is not None:
        pts = set(zip(_col(ep, "origin"), _col(ep, "destination"), _col(ep, "eval_point_id")))
        for name in ("table_b", "table_d"):
            t = tables.get(name)
            if t is None:
                continue
            lost = set(zip(_col(t, "origin"), _col(t, "destination"), _col(t, "eval_point_id"))) - pts
            if lost:
                o, d, x = sorted(lost)[0]
                raise _fail(where, f"{name} evaluation point {x!r} for {o}->{d} is not in eval_points")
        # beacon points must be beacons of this bundle; odometer points (departure, after departure,
        # regular interval) are named dep / dep+<m> and are found by running distance, not by beacon
        ids = _col(ep, "eval_point_id")
        kinds = _col(ep, "eval_point_kind") if "eval_point_kind" in ep.column_names else \
            ["departure" if x.startswith("dep") else "beacon" for x in ids]
        bad = sorted({k for k in kinds} - set(EVAL_POINT_KINDS), key=str)
        if bad:
            raise _fail(where, f"eval_points eval_point_kind {bad[0]!r} is not one of {', '.join(EVAL_POINT_KINDS)}")
        strays = sorted({x for x, k in zip(ids, kinds) if k == "beacon" and x not in beacon_ids})
        if strays:
            raise _fail(where, f"eval_points name beacon(s) {strays} that are not in beacons")
        odo = sorted({x for x, k in zip(ids, kinds) if k != "beacon" and not (x == "dep" or x.startswith("dep+"))})
        if odo:
            raise _fail(where, f"eval_points odometer point(s) {odo} are not named 'dep' or 'dep+<m>'")


def _info(path: str, m: dict, data_or_digest) -> BundleInfo:
    if isinstance(data_or_digest, (bytes, bytearray)):
        size, digest = len(data_or_digest), hashlib.sha256(data_or_digest).hexdigest()
    else:
        size, digest = data_or_digest
    return BundleInfo(
        path=path, line_id=m["line_id"], direction=m["direction"], train_type=m["train_type"],
        schema_version=m["schema_version"], software_version=m["software_version"],
        line_digest=m["line_digest"], key_id=m["key_id"],
        files=tuple(FileEntry(e["name"], e["size"], e["sha256"], e["rows"]) for e in m["files"]),
        missing=tuple(m["missing"]), size_bytes=size, sha256=digest, key_kind=m["key_kind"],
        bundle_version=m["bundle_version"], built_at=m["built_at"], expires=m["expires"],
    )


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
    """

    target: str | None = None
    min_version: int = 0
    at_s: int | None = None
    allow_dev: bool = False

    @staticmethod
    def parse_target(text: str) -> str:
        """Check ``LINE/DIRECTION/TYPE`` and return it; raise BundleError naming the fix."""
        parts = str(text).split("/")
        if len(parts) != 3 or parts[1] not in DIRECTIONS or not all(_ID.fullmatch(p) for p in parts[::2]):
            raise BundleError(f"--expect {text!r}: give LINE/DIRECTION/TYPE, e.g. sample/down/E10 "
                              "(direction 'down' or 'up')")
        return "/".join(parts)


def _check_expect(m: dict, expect: Expect, pub_id: str, where: str) -> None:
    """Provenance and freshness of a proven manifest; one reason per refusal."""
    if m["key_id"] != pub_id:
        raise _fail(where, f"manifest names signing key {m['key_id'][:16]}, but it was verified with key "
                           f"{pub_id[:16]}: the manifest lies about its signer (refused)")
    target = f"{m['line_id']}/{m['direction']}/{m['train_type']}"
    if expect.target is not None and target != Expect.parse_target(expect.target):
        raise _fail(where, f"bundle is for {target}, not the expected {expect.target} (renamed or mixed up; refused)")
    if m["key_kind"] != "production" and not expect.allow_dev:
        raise _fail(where, f"signed with a {m['key_kind']} key: not for service (refused; --allow-dev on a test "
                           "bench only)")
    if m["bundle_version"] < expect.min_version:
        raise _fail(where, f"bundle version {m['bundle_version']} is older than the installed version "
                           f"{expect.min_version} (rollback refused)")
    now = int(time.time()) if expect.at_s is None else int(expect.at_s)
    if now >= parse_time(m["expires"]):
        raise _fail(where, f"bundle expired at {m['expires']} (checked at {format_time(now)}; built "
                           f"{m['built_at']}): a fresh bundle is needed (refused)")


def _verified(path, public_key, expect: Expect | None = None
              ) -> tuple[BundleInfo, dict[str, bytes], dict[str, pa.Table]]:
    expect = Expect() if expect is None else expect
    where = "<bytes>" if isinstance(path, (bytes, bytearray, memoryview)) else str(path)
    pub = signing.load_public_key(public_key)
    members, size_digest = _read_members(path)
    if MANIFEST not in members:
        raise _fail(where, f"{MANIFEST} is missing")
    if SIGNATURE not in members:
        raise _fail(where, f"{SIGNATURE} is missing (unsigned bundle)")
    mbytes = members[MANIFEST]
    try:
        signing.verify(pub, mbytes, members[SIGNATURE])
    except BundleError as e:
        raise _fail(where, str(e)) from None
    m = _strict_json(mbytes, where)
    _check_manifest(m, where)
    _check_expect(m, expect, signing.public_key_id(pub), where)
    listed = {e["name"]: e for e in m["files"]}
    present = set(members) - {MANIFEST, SIGNATURE}
    if present - set(listed):
        raise _fail(where, f"extra member(s) not in the manifest: {', '.join(sorted(present - set(listed)))}")
    if set(listed) - present:
        raise _fail(where, f"missing member(s) listed in the manifest: {', '.join(sorted(set(listed) - present))}")
    for name, e in listed.items():
        data = members[name]
        if len(data) != e["size"]:
            raise _fail(where, f"{name} is {len(data)} bytes, the manifest says {e['size']}")
        if hashlib.sha256(data).hexdigest() != e["sha256"]:
            raise _fail(where, f"{name} SHA-256 does not match the manifest (altered)")
    tables = {}
    for name, e in listed.items():
        try:
            t = pq.read_table(pa.BufferReader(members[name]))
        except (pa.ArrowException, OSError) as err:
            raise _fail(where, f"{name} is not a readable Parquet file ({err})") from None
        if t.num_rows != e["rows"]:
            raise _fail(where, f"{name} has {t.num_rows} rows, the manifest says {e['rows']}")
        tables[name.removesuffix(".parquet")] = t
    _check_tables(tables, m, where)
    return _info(where, m, size_digest), members, tables


def _expect(expect, min_version, at, allow_dev) -> Expect:
    if isinstance(expect, Expect):
        return expect
    at_s = parse_time(at, "--at") if isinstance(at, str) else at
    if isinstance(min_version, bool) or not isinstance(min_version, int) or min_version < 0:
        raise BundleError(f"--min-version must be a whole number >= 0, found {min_version!r}")
    return Expect(None if expect is None else Expect.parse_target(expect), min_version, at_s, bool(allow_dev))


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
    return _verified(path, public_key, _expect(expect, min_version, at, allow_dev))[0]


def read_bundle(path: str | os.PathLike | bytes, public_key, *, expect: str | Expect | None = None,
                min_version: int = 0, at: int | str | None = None, allow_dev: bool = False) -> Bundle:
    """Verify a bundle (as :func:`verify_bundle`) and return its tables in memory (nothing written to disk)."""
    info, _, tables = _verified(path, public_key, _expect(expect, min_version, at, allow_dev))
    return Bundle(info, tables)


def open_bundle(path: str | os.PathLike, dest_dir: str | os.PathLike, public_key, *,
                expect: str | Expect | None = None, min_version: int = 0, at: int | str | None = None,
                allow_dev: bool = False) -> BundleInfo:
    """Verify a bundle, then write its members into ``dest_dir`` (created if missing).

    Nothing is written unless the whole bundle verifies. Members are plain file
    names (checked while reading), created relative to an open handle of
    ``dest_dir`` with ``O_EXCL | O_NOFOLLOW``, so a file or symlink already in
    ``dest_dir`` is never followed or overwritten.
    """
    info, members, _ = _verified(path, public_key, _expect(expect, min_version, at, allow_dev))
    dest = Path(dest_dir)
    dest.mkdir(parents=True, exist_ok=True)
    dfd = os.open(dest, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        for name in sorted(members):
            try:
                fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                             0o644, dir_fd=dfd)
            except FileExistsError:
                raise BundleError(f"{dest / name} already exists; open the bundle into an empty folder") from None
            with os.fdopen(fd, "wb") as f:
                f.write(members[name])
    finally:
        os.close(dfd)
    return info
