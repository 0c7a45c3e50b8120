"""The signed manifest of an on-board DB bundle: what a bundle is for, which release, what it holds.

Takes a target (line, direction, train type), a :class:`Release` and the table
members; gives the manifest's one byte form (:func:`canonical_json`), its strict
reading and schema check (:func:`parse_manifest`, :func:`check_manifest`) and
:class:`BundleInfo`. Also the format's names, bounds and time form, and
:func:`fail`, the one error helper of the bundle package.

Freshness and reproducibility
-----------------------------
The version, build time and validity are *inputs* of a build (:class:`Release`),
like ``SOURCE_DATE_EPOCH`` for reproducible builds: the same tables, key and
release give the same bytes. :func:`Release.issue` derives the version from the
build time (UTC ``YYYYMMDDHHMMSS`` as an integer), so versions increase with
build time for every target, on any build host, without state to keep.
"""
from __future__ import annotations

import json
import math
import os
import re
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping

from planner import __version__
from planner.errors import BundleError
from planner.line.model import DIRECTIONS
from planner.io.paths import PATH_ID_RE, PATH_ID_RULE, is_path_id

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
"""Expected tables that exist only for one cruise mode: table (d) for sawtooth vehicles (docs/design.md §3)."""


def expected_tables(cruise: str | None = None) -> tuple[str, ...]:
    """The tables a complete bundle for a vehicle with this cruise mode holds (None: every one)."""
    return tuple(t for t in EXPECTED_TABLES if cruise is None or VEHICLE_TABLES.get(t, cruise) == cruise)


MEMBER_NAME_RE = re.compile(r"[a-z][a-z0-9_]{0,63}\.parquet")
"""A table member's name: the only member names besides the manifest and its signature."""
SHA256_RE = re.compile(r"[0-9a-f]{64}")


def fail(where: str, msg: str) -> BundleError:
    """The error refusing bundle ``where`` (a path, ``<bytes>`` or ``build``): ``bundle WHERE: MSG``."""
    return BundleError(f"bundle {where}: {msg}")


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


# --- the operating day a bundle is for -------------------------------------------
@dataclass(frozen=True)
class BundleDay:
    """The operating day a bundle is built for: its window and the temporary restrictions in force.

    Signed in the manifest as ``operating_day``; a vehicle (``planner bundle verify --at``) refuses the
    bundle outside [start_s, end_s). ``restrictions``: (feed id, valid from, valid until [UTC epoch s]) of
    every temporary restriction in force that day on the line; each bundle lists those it includes (its
    direction and train type).
    """

    day: str
    time_zone: str
    start_s: int
    end_s: int
    restrictions: tuple[tuple[str, int, int], ...] = ()

    def validity(self) -> dict[str, tuple[int, int]]:
        """Bundle restriction id (``T.<feed id>``) → its window, for the ATS-P data."""
        return {f"T.{rid}": (a, b) for rid, a, b in self.restrictions}

    def record(self, included) -> dict:
        """The manifest's ``operating_day``: day, zone, window (UTC), the feed ids of ``included``."""
        return {"day": self.day, "time_zone": self.time_zone, "valid_from": format_time(self.start_s),
                "valid_until": format_time(self.end_s), "restrictions": sorted(included)}


_DAY_KEYS = {"day": str, "time_zone": str, "valid_from": str, "valid_until": str, "restrictions": list}


def _check_day(d, where: str) -> None:
    """The manifest's optional ``operating_day``: keys, types, a window of two times in order."""
    if not isinstance(d, dict) or set(d) != set(_DAY_KEYS) or not all(_is(d[k], t) for k, t in _DAY_KEYS.items()):
        raise fail(where, f"manifest operating_day must have exactly the keys {sorted(_DAY_KEYS)}")
    for k in ("valid_from", "valid_until"):
        if not _TIME_RE.fullmatch(d[k]):
            raise fail(where, f"manifest operating_day {k} {d[k]!r} is not a time of the form YYYY-MM-DDTHH:MM:SSZ")
    if not d["valid_until"] > d["valid_from"]:
        raise fail(where, f"manifest operating_day valid_until {d['valid_until']} is not after valid_from")
    r = d["restrictions"]
    if not all(isinstance(x, str) and PATH_ID_RE.fullmatch(x) for x in r) or r != sorted(set(r)):
        raise fail(where, "manifest operating_day restrictions must be a sorted list of unique restriction ids")


# --- target: what a bundle is for -----------------------------------------------
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


# --- what a bundle holds --------------------------------------------------------
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
    operating_day: dict | None = None
    """The manifest's ``operating_day`` (:class:`BundleDay`), or None for a bundle not bound to a day."""
    no_stop: tuple = ()
    """The manifest's ``no_stop``: the stops it has no stopping pattern for, at which adhesion levels."""

    @property
    def target(self) -> str:
        """``LINE/DIRECTION/TYPE``: what the bundle is for."""
        return f"{self.line_id}/{self.direction}/{self.train_type}"

    @property
    def complete(self) -> bool:
        """True when every expected table is present and every stop has its stopping patterns at every adhesion
        level (a bundle that cannot stop its train at a station is not complete)."""
        return not self.missing and not self.no_stop

    def incomplete_text(self) -> str:
        """What the bundle lacks, in one line (empty when complete)."""
        parts = ([f"missing {', '.join(self.missing)}"] if self.missing else []) + (
            [f"no stopping pattern at {no_stop_text(self.no_stop)}"] if self.no_stop else [])
        return "; ".join(parts)

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
        d = self.operating_day
        if d is not None:
            out.insert(2, f"operating day {d['day']} ({d['time_zone']}), valid {d['valid_from']} to "
                          f"{d['valid_until']}; temporary restrictions: {', '.join(d['restrictions']) or 'none'}")
        for f in self.files:
            out.append(f"  {f.name:<24} {f.rows:>9} rows {f.size:>11} bytes")
        out.append("complete" if self.complete else "PARTIAL: " + self.incomplete_text())
        return out


def manifest_info(path: str, m: dict, size_digest: tuple[int, str]) -> BundleInfo:
    """The :class:`BundleInfo` of a checked manifest ``m`` of the file ``path`` (its size and SHA-256)."""
    size, digest = size_digest
    return BundleInfo(
        path=path, line_id=m["line_id"], direction=m["direction"], train_type=m["train_type"],
        schema_version=m["schema_version"], software_version=m["software_version"],
        line_digest=m["line_digest"], key_id=m["key_id"],
        files=tuple(FileEntry(e["name"], e["size"], e["sha256"], e["rows"]) for e in m["files"]),
        missing=tuple(m["missing"]), size_bytes=size, sha256=digest, key_kind=m["key_kind"],
        bundle_version=m["bundle_version"], built_at=m["built_at"], expires=m["expires"],
        operating_day=m.get("operating_day"), no_stop=tuple(m.get("no_stop", ())),
    )


# --- the manifest's byte form and schema ----------------------------------------
def canonical_json(obj) -> bytes:
    """The one byte form of a manifest: sorted keys, no whitespace, ASCII."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


def parse_manifest(data: bytes, where: str):
    """The manifest object of signed bytes ``data``: refuses duplicate keys, non-integers, non-canonical form."""
    def no_dupes(pairs):
        d = {}
        for k, v in pairs:
            if k in d:
                raise fail(where, f"manifest has duplicate key {k!r}")
            d[k] = v
        return d

    def no_float(s):
        raise fail(where, f"manifest holds a non-integer number {s}")

    try:
        obj = json.loads(data.decode("ascii"), object_pairs_hook=no_dupes, parse_float=no_float,
                         parse_constant=no_float)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise fail(where, f"manifest is not valid JSON ({e})") from None
    if canonical_json(obj) != data:
        raise fail(where, "manifest is not in canonical form")
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


def check_manifest(m, where: str) -> None:
    """Manifest schema: keys, types, supported version, well-formed values."""
    if not isinstance(m, dict):
        raise fail(where, "manifest is not a JSON object")
    if "schema_version" in m and _is(m["schema_version"], int) and m["schema_version"] not in SUPPORTED_SCHEMA_VERSIONS:
        raise fail(where, f"bundle schema version {m['schema_version']} not supported by planner {__version__} "
                          f"(supports {sorted(SUPPORTED_SCHEMA_VERSIONS)}); update the vehicle-side software")
    missing = sorted(set(_MANIFEST_KEYS) - set(m))
    extra = sorted(set(m) - set(_MANIFEST_KEYS) - {"operating_day", "no_stop"})  # optional keys
    if missing or extra:
        raise fail(where, f"manifest keys wrong (missing {missing}, unknown {extra})")
    for k, typ in _MANIFEST_KEYS.items():
        if not _is(m[k], typ):
            raise fail(where, f"manifest {k!r} must be {typ.__name__}, found {type(m[k]).__name__}")
    if m["format"] != FORMAT:
        raise fail(where, f"manifest format {m['format']!r} is not {FORMAT!r}")
    if m["direction"] not in DIRECTIONS:
        raise fail(where, f"manifest direction {m['direction']!r} is not 'down' or 'up'")
    for k in ("line_id", "train_type"):
        if not PATH_ID_RE.fullmatch(m[k]):
            raise fail(where, f"manifest {k} {m[k]!r} is not a valid id")
    if m["line_digest"] and not SHA256_RE.fullmatch(m["line_digest"]):
        raise fail(where, "manifest line_digest is not a SHA-256 hex digest")
    if not SHA256_RE.fullmatch(m["key_id"]):
        raise fail(where, "manifest key_id is not a SHA-256 hex digest")
    if m["key_kind"] not in KEY_KINDS:
        raise fail(where, f"manifest key_kind {m['key_kind']!r} is not one of {list(KEY_KINDS)}")
    if m["bundle_version"] < 1:
        raise fail(where, f"manifest bundle_version {m['bundle_version']} is not a positive integer")
    for k in ("built_at", "expires"):
        try:
            ok = bool(_TIME_RE.fullmatch(m[k])) and bool(datetime.strptime(m[k], _TIME_FORMAT))
        except ValueError:
            ok = False
        if not ok:
            raise fail(where, f"manifest {k} {m[k]!r} is not a time of the form YYYY-MM-DDTHH:MM:SSZ")
    if not m["expires"] > m["built_at"]:  # same fixed-width form: text order is time order
        raise fail(where, f"manifest expires {m['expires']} is not after built_at {m['built_at']}")
    if "operating_day" in m:
        _check_day(m["operating_day"], where)
    if "no_stop" in m:
        _check_no_stop(m["no_stop"], where)
    _check_files(m, where)


_NO_STOP_KEYS = {"station_id": str, "origin": str, "adhesion_kmh_s": list}
_LEVEL_RE = re.compile(r"[0-9]+(\.[0-9]+)?")
"""An adhesion level in the manifest: its decimal text (the manifest holds no non-integer number)."""


def _check_no_stop(rows, where: str) -> None:
    """The manifest's optional ``no_stop``: the stops the bundle has no stopping pattern for, at which adhesion
    levels (:func:`no_stop_rows`); present only when there is one, sorted, each with its levels sorted."""
    ok = isinstance(rows, list) and rows and all(
        isinstance(r, dict) and set(r) == set(_NO_STOP_KEYS) and all(_is(r[k], t) for k, t in _NO_STOP_KEYS.items())
        and PATH_ID_RE.fullmatch(r["station_id"]) and PATH_ID_RE.fullmatch(r["origin"]) and r["adhesion_kmh_s"]
        and all(isinstance(a, str) and _LEVEL_RE.fullmatch(a) for a in r["adhesion_kmh_s"])
        and r["adhesion_kmh_s"] == sorted(set(r["adhesion_kmh_s"]), key=float) for r in rows)
    if not ok or [(r["station_id"], r["origin"]) for r in rows] != sorted({(r["station_id"], r["origin"]) for r in rows}):
        raise fail(where, "manifest no_stop must be a non-empty sorted list of {station_id, origin, adhesion_kmh_s} "
                          "with the levels sorted")


def no_stop_rows(stop_summary) -> list[dict]:
    """The stops a ``stop_summary`` table has no stopping pattern for: per arrival station and departure station
    of the approach, the adhesion levels [km/h/s, as decimal text] without a feasible pattern, sorted (the manifest's
    ``no_stop``: a bundle that lacks them cannot stop its train there at those levels)."""
    cols = ("station_id", "origin", "adhesion_kmh_s", "feasible")
    if stop_summary is None or not stop_summary.num_rows or not set(cols) <= set(stop_summary.column_names):
        return []  # (a table without these columns is refused by the cross-checks, naming them)
    miss: dict[tuple[str, str], set[float]] = {}
    for sid, org, a, ok in zip(*(stop_summary.column(c).to_pylist() for c in cols)):
        if not ok:
            miss.setdefault((str(sid), str(org)), set()).add(float(a))
    return [{"station_id": s, "origin": o, "adhesion_kmh_s": [repr(a) for a in sorted(v)]}
            for (s, o), v in sorted(miss.items())]


def no_stop_text(rows) -> str:
    """``MDR from TKD at 2.5…3.2 km/h/s (8 levels)``, the stops of a manifest's ``no_stop``, for one line."""
    def levels(a):
        a = [float(x) for x in a]
        return f"{a[0]:g} km/h/s" if len(a) == 1 else f"{a[0]:g}…{a[-1]:g} km/h/s ({len(a)} levels)"
    return "; ".join(f"{r['station_id']} from {r['origin']} at {levels(r['adhesion_kmh_s'])}" for r in rows)


def _check_files(m: dict, where: str) -> None:
    """The manifest's ``files`` and ``missing``: well formed, sorted, core tables present, missing ones listed."""
    names = []
    for e in m["files"]:
        if not isinstance(e, dict) or set(e) != set(_FILE_KEYS):
            raise fail(where, f"manifest file entry {e!r} must have exactly the keys {sorted(_FILE_KEYS)}")
        for k, typ in _FILE_KEYS.items():
            if not _is(e[k], typ):
                raise fail(where, f"manifest file entry {e.get('name')!r}: {k} must be {typ.__name__}")
        if not MEMBER_NAME_RE.fullmatch(e["name"]) or not SHA256_RE.fullmatch(e["sha256"]):
            raise fail(where, f"manifest file entry {e['name']!r} has a bad name or sha256")
        if not (0 <= e["size"] <= MAX_MEMBER_BYTES and e["rows"] >= 0):
            raise fail(where, f"manifest file entry {e['name']!r} has a bad size or row count")
        names.append(e["name"])
    if names != sorted(set(names)):
        raise fail(where, "manifest files must be sorted and unique")
    tables = {n.removesuffix(".parquet") for n in names}
    absent_core = [t for t in CORE_TABLES if t not in tables]
    if absent_core:
        raise fail(where, f"manifest lacks the core table(s) {', '.join(absent_core)}")
    mis = m["missing"]
    if not all(isinstance(x, str) for x in mis) or mis != sorted(set(mis)):
        raise fail(where, "manifest 'missing' must be a sorted list of unique table names")
    # every expected table absent must be listed, except those that exist only for another cruise
    # mode (VEHICLE_TABLES): the signer, who knew the vehicle, left them out of 'missing'
    absent = {t for t in EXPECTED_TABLES if t not in tables}
    if not set(mis) <= absent or not absent - set(VEHICLE_TABLES) <= set(mis):
        raise fail(where, f"manifest 'missing' {mis} does not match the tables it lists")
