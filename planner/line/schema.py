"""Line database schema v1: one pyarrow schema per table, declared once.

This module is the machine-readable form of ``docs/line-database.md``: the table files,
their columns (units in the column names), the column types, which columns may
hold nulls, which tables must exist and how many rows they need. The loader
(:mod:`planner.line.loader`) and the validator (:mod:`planner.line.validate`) read it;
nothing else restates the column list.

Every field carries a ``description`` metadata entry, and every schema the
metadata ``table`` and ``schema_version``. Users may add their own columns and
tables (docs/line-database.md); columns not declared here are ignored on load. Columns
listed in :attr:`TableSpec.optional_columns` may be absent.

Ids that become file names or partition values
----------------------------------------------
``line.line_id`` and ``rolling_stock.train_type`` become folder and file
names (``line=<line_id>/``, ``train_type=<train_type>/`` partitions,
``<line_id>_<direction>_<train_type>.pdb`` bundles, ``<line_id>_margins.html``).
One rule, :data:`planner.io.paths.PATH_ID_RE`, holds for each of them (:data:`PATH_ID_COLUMNS`)
and for the job file's closed-loop scenario names (a partition too): **1 to 64
characters, letters A-Z a-z, digits, ``.``, ``_`` or ``-``, the first a letter
or digit**. So an id can never be ``..``, hold a ``/``, a ``=`` or a ``%``
(hive partition syntax), a space or a control character. The validator
refuses other values up front and the writers check again where they build a
path (:func:`planner.io.paths.check_path_id`).

Examples
--------
>>> from planner.line.schema import TABLES
>>> TABLES["gradients"].schema.field("gradient_permil").type
DataType(double)
"""
from __future__ import annotations

from dataclasses import dataclass

import pyarrow as pa

SCHEMA_VERSION = 2
"""Version of the line-database contract described by this module and docs/line-database.md."""

DIRECTIONS = ("down", "up")
"""Running directions: ``down`` towards increasing chainage, ``up`` towards decreasing."""
LIMIT_DIRECTIONS = ("both", "down", "up")
BEACON_KINDS = ("signal", "pattern_update", "tasc", "other")
CRUISE_MODES = ("constant", "sawtooth")
NODE_KINDS = ("switch", "stop", "boundary", "end")
TRACK_DIRECTIONS = ("down", "up", "both")
"""The direction trains normally run a track (``edges.direction``); ``both``: single track, a main signalled
alike both ways, a crossover."""
RUNNING_SIDES = ("right", "left")
"""The side of a double line trains normally run on (``line.running_side``)."""
PATH_ID_COLUMNS = {"line": ("line_id",), "rolling_stock": ("train_type",)}
"""The line-database columns whose values become file names or partition values."""


MAX_GRADIENT_PERMIL = 40.0
"""Steepest gradient accepted [‰]; steeper is outside adhesion railway practice and a likely typo."""


@dataclass(frozen=True)
class Range:
    """The values a numeric column accepts: ``lo <= x <= hi`` (``lo < x`` when ``lo_open``), and why.

    Declared with the column (field metadata ``range`` and ``range_why``), checked
    by stage 1 of validation (:mod:`planner.line.conform`) on every value that is
    not null, and listed by ``planner schema``. The bounds are generous on
    purpose: they refuse what no railway has (a unit slip, a missing decimal
    point, 1e308), never a heavy freight train or a high-speed line.
    """

    lo: float
    hi: float
    why: str
    """Why the bounds are where they are (said in the error message and the docs)."""
    lo_open: bool = False

    def __str__(self) -> str:
        return f"{'(' if self.lo_open else '['}{fmt_bound(self.lo)}, {fmt_bound(self.hi)}]"

    def below(self, x):
        """True where ``x`` is under the lower bound (numpy arrays or floats)."""
        return x <= self.lo if self.lo_open else x < self.lo

    def above(self, x):
        """True where ``x`` is over the upper bound."""
        return x > self.hi


def fmt_bound(x: float) -> str:
    """A bound as written in messages and docs: ``600``, ``0.05``, ``-10000000``."""
    return str(int(x)) if float(x).is_integer() else repr(float(x))


# ---- the bounds, each with the railway fact that puts it there
MAX_CHAINAGE_M = 10_000_000.0
MAX_SPEED_KMH = 600.0
MAX_TRAIN_LENGTH_M = 8_000.0
MAX_MASS_T = 100_000.0
MIN_ACCEL_KMH_S, MAX_ACCEL_KMH_S = 0.05, 18.0
MAX_DAVIS_AT_100_KN = 10_000.0
MAX_EFFORT_KN = 20_000.0
MAX_TIME_S = 7 * 86_400.0
MAX_ROWS_PER_M = 1.0
"""Densest gradient, curve or speed-limit table accepted [rows per metre of line]: a surveyed
profile changes every few tens to hundreds of metres; a row per metre or more is a sampled
curve, not a table of segments, and costs memory and time in every step that reads it."""

CHAINAGE = Range(-MAX_CHAINAGE_M, MAX_CHAINAGE_M,
                 "a chainage is within 10,000 km of the line's origin (the longest railway line, Moscow-Vladivostok, "
                 "is 9,289 km)")
SPEED = Range(0.0, MAX_SPEED_KMH, "600 km/h is above every train ever run on rails (record 574.8 km/h, 2007)",
              lo_open=True)
LENGTH = Range(1.0, MAX_TRAIN_LENGTH_M, "a rail vehicle is at least 1 m long and no train has been longer than "
                                        "7,353 m (BHP iron ore, 2001)")
PLATFORM = Range(0.0, MAX_TRAIN_LENGTH_M, "a platform (or loop) longer than the longest train ever run (7,353 m) "
                                          "holds no train a shorter one would not", lo_open=True)
MASS = Range(1.0, MAX_MASS_T, "a rail vehicle weighs at least a tonne (a track trolley); the heaviest train ever "
                              "run weighed 99,734 t (BHP iron ore, 2001)")
LOAD = Range(0.0, MAX_MASS_T, "the heaviest train ever run weighed 99,734 t (BHP iron ore, 2001)")
ACCEL = Range(MIN_ACCEL_KMH_S, MAX_ACCEL_KMH_S,
              "18 km/h/s is 5 m/s², above what wheel-on-rail adhesion transmits (about 4 m/s² on dry rail); "
              "0.05 km/h/s is below the weakest brake or start of a 100,000 t freight train (about 0.15 km/h/s)")
DAVIS = ("each Davis term at most 10,000 kN at 100 km/h, about four times the whole running resistance of a "
         "100,000 t train at that speed (about 2,500 kN)")
GRADIENT = Range(-MAX_GRADIENT_PERMIL, MAX_GRADIENT_PERMIL,
                 f"steeper than {MAX_GRADIENT_PERMIL:g} ‰ is outside adhesion railway practice (and this planner's "
                 f"adhesion model); a rack section is not modelled")
RADIUS = Range(10.0, 1_000_000.0, "the sharpest railway curves have radii of about 15 m (tramways, Darjeeling "
                                   "18 m); over 1,000 km a curve is straight track (leave it out of curves.parquet)")
LIMIT = Range(1.0, MAX_SPEED_KMH, "a restriction is between walking pace (1 km/h) and 600 km/h, above every train "
                                  "ever run on rails (record 574.8 km/h, 2007)")
ROTATING = Range(0.0, 1.0, "rotating parts add 3-30 % to a train's inertia; 100 % would double it")
JERK = Range(0.0, 100.0, "100 km/h/s² (28 m/s³) reaches a full brake in under 0.05 s, faster than any brake "
                         "builds up (ride comfort is 1-5 km/h/s²)", lo_open=True)
MARGIN = Range(0.0, 50.0, "on-board speed margins are a few km/h; 50 km/h would leave no speed below most "
                          "restrictions")
BAND = Range(0.0, 100.0, "a sawtooth band of 5-20 km/h is usual; over 100 km/h the train would coast to a stop")
TRACTION_SPEED = Range(0.0, 1_000.0, "a traction curve may run past the train's maximum speed, but not past "
                                     "1,000 km/h")
EFFORT = Range(0.0, MAX_EFFORT_KN, "twice the starting effort of ten of the strongest locomotives (about "
                                   "1,000 kN each); the 99,734 t record train had eight")
TIME = Range(0.0, MAX_TIME_S, "seconds after the service day's midnight, at most 7 days (604800 s): longer than "
                              "the longest scheduled run (Moscow-Vladivostok, about 6 days); a train of the evening "
                              "before belongs to that day's timetable")


@dataclass(frozen=True)
class TableSpec:
    """One table of the line database.

    Attributes
    ----------
    name : str
        Table name; the file is ``<name>.parquet``.
    schema : pyarrow.Schema
        Declared columns with types, nullability and descriptions.
    required : bool
        The file must exist (it may still be empty when ``min_rows`` is 0).
    min_rows, max_rows : int, int or None
        Row-count bounds (``max_rows`` None = unbounded).
    row_id : tuple of str
        Columns that identify a row in messages, e.g. ``("station_id",)``.
    optional_columns : frozenset of str
        Declared columns that may be absent from the file.
    """

    name: str
    schema: pa.Schema
    required: bool
    min_rows: int = 0
    max_rows: int | None = None
    row_id: tuple[str, ...] = ()
    optional_columns: frozenset[str] = frozenset()

    @property
    def file(self) -> str:
        """The table's file name inside the line folder."""
        return f"{self.name}.parquet"


def _schema(table: str, fields: list[tuple]) -> pa.Schema:
    """Build a schema from ``(name, type, description[, nullable][, Range])`` tuples."""
    out = []
    for f in fields:
        name, typ, desc = f[:3]
        nullable = next((x for x in f[3:] if isinstance(x, bool)), False)
        meta = {"description": desc}
        rng = next((x for x in f[3:] if isinstance(x, Range)), None)
        if rng is not None:
            meta.update(range=str(rng), range_why=rng.why)
        out.append(pa.field(name, typ, nullable=nullable, metadata=meta))
    return pa.schema(out, metadata={"table": table, "schema_version": str(SCHEMA_VERSION)})


def column_range(field: pa.Field) -> Range | None:
    """The declared :class:`Range` of a numeric column, read back from its metadata (None: unbounded)."""
    meta = field.metadata or {}
    if b"range" not in meta:
        return None
    text = meta[b"range"].decode()
    lo, hi = (float(x) for x in text[1:-1].split(","))
    return Range(lo, hi, meta[b"range_why"].decode(), lo_open=text.startswith("("))


S, D, I32, B = pa.string(), pa.float64(), pa.int32(), pa.bool_()
NULLABLE = True

_SPECS = [
    TableSpec("line", _schema("line", [
        ("line_id", S, "line identifier, used in every output; the folder may have any name; names files (PATH_ID_RE)"),
        ("name", S, "display name"),
        ("start_m", D, "first chainage covered by the database [m]", CHAINAGE),
        ("end_m", D, "last chainage covered by the database [m]", CHAINAGE),
        ("max_speed_kmh", D, "line maximum speed [km/h]; null: none, so where no restriction applies each train "
                             "runs at its own maximum (OSRD's meaning)", NULLABLE, SPEED),
        ("schema_version", I32, "line-database schema version, 2; a folder of an earlier version (1: "
                                "rolling_stock's brake_comfort_kmh_s was comfort_accel_kmh_s) is read as 2, and "
                                "`planner line upgrade DIR` rewrites it"),
        ("approach_m", D, "stopping-pattern start before the stop marker where no TASC beacon is [m] (optional "
                          "column); null or absent: where the train must start braking, plus 10 %", NULLABLE,
         Range(10.0, MAX_CHAINAGE_M, "an approach is at least one grid step of the coarsest step and lies on the "
                                     "line")),
        ("running_side", S, "the side trains normally run on, right or left (optional column): an importer "
                            "names a main track signalled alike both ways down or up by it; null or absent: "
                            "from the source's signals where they tell", NULLABLE),
    ]), required=True, min_rows=1, max_rows=1, row_id=("line_id",),
        optional_columns=frozenset({"approach_m", "running_side"})),
    TableSpec("stations", _schema("stations", [
        ("station_id", S, "unique station identifier"),
        ("name", S, "display name"),
        ("position_m", D, "chainage of the centre of the platform [m]", CHAINAGE),
        ("stop_down_m", D, "stop marker for the train front, direction down [m]", CHAINAGE),
        ("stop_up_m", D, "stop marker for the train front, direction up [m]", CHAINAGE),
        ("platform_length_m", D, "platform length [m]", PLATFORM),
    ]), required=True, min_rows=2, row_id=("station_id",)),
    TableSpec("gradients", _schema("gradients", [
        ("start_m", D, "segment start chainage [m]", CHAINAGE),
        ("end_m", D, "segment end chainage [m]; > start_m", CHAINAGE),
        ("gradient_permil", D, "gradient [‰], positive = rising towards increasing chainage", GRADIENT),
    ]), required=True, row_id=("start_m",)),
    TableSpec("curves", _schema("curves", [
        ("start_m", D, "curve start chainage [m]", CHAINAGE),
        ("end_m", D, "curve end chainage [m]; > start_m", CHAINAGE),
        ("radius_m", D, "curve radius [m]; > 0", RADIUS),
    ]), required=True, row_id=("start_m",)),
    TableSpec("speed_limits", _schema("speed_limits", [
        ("start_m", D, "restricted stretch start chainage [m]", CHAINAGE),
        ("end_m", D, "restricted stretch end chainage [m]; > start_m", CHAINAGE),
        ("limit_kmh", D, "speed limit [km/h]; > 0", LIMIT),
        ("direction", S, "both, down or up"),
        ("train_type", S, "train type it applies to; null = every train type", NULLABLE),
        ("kind", S, "curve, turnout, civil, station, ..."),
        ("has_beacon", B, "an ATS-P ground beacon already sends this restriction's pattern"),
    ]), required=True, row_id=("start_m",)),
    TableSpec("beacons", _schema("beacons", [
        ("beacon_id", S, "unique beacon identifier"),
        ("position_m", D, "beacon chainage [m]", CHAINAGE),
        ("direction", S, "down or up: trains that read it"),
        ("kind", S, "signal, pattern_update, tasc or other"),
        ("telegram", S, "telegram content as received on board"),
        ("evaluation_point", B, "running time is re-evaluated here"),
    ]), required=True, row_id=("beacon_id",)),
    TableSpec("signals", _schema("signals", [
        ("signal_id", S, "unique signal identifier"),
        ("position_m", D, "signal chainage (block boundary) [m]", CHAINAGE),
        ("direction", S, "down or up"),
    ]), required=False, row_id=("signal_id",)),
    TableSpec("rolling_stock", _schema("rolling_stock", [
        ("train_type", S, "unique train type; names files (PATH_ID_RE)"),
        ("length_m", D, "train length [m]", LENGTH),
        ("empty_mass_t", D, "empty train mass [t]", MASS),
        ("full_load_mass_t", D, "passenger mass added at 100 % load [t]", LOAD),
        ("rotating_mass_factor", D, "rotating-mass allowance, e.g. 0.08 [-]", ROTATING),
        ("max_speed_kmh", D, "vehicle maximum speed [km/h]", SPEED),
        ("max_accel_kmh_s", D, "acceleration cap when powering: the vehicle's maximum or its traction comfort "
                               "limit, whichever is lower [km/h/s]", ACCEL),
        ("davis_a_kN", D, "Davis resistance constant term A [kN]", Range(0.0, MAX_DAVIS_AT_100_KN, DAVIS)),
        ("davis_b_kN_per_kmh", D, "Davis resistance linear term B [kN/(km/h)]", Range(0.0, MAX_DAVIS_AT_100_KN / 100, DAVIS)),
        ("davis_c_kN_per_kmh2", D, "Davis resistance quadratic term C [kN/(km/h)^2]", Range(0.0, MAX_DAVIS_AT_100_KN / 100**2, DAVIS)),
        ("service_brake_kmh_s", D, "intermediate (restriction) braking deceleration [km/h/s]", ACCEL),
        ("stop_brake_kmh_s", D, "the train's own stopping brake: the deceleration achieved at station stops "
                                "in the run curves, and the most any stopping pattern asks for or achieves "
                                "[km/h/s]", ACCEL),
        ("atsp_pattern_kmh_s", D, "deceleration of ATS-P speed-check patterns [km/h/s]", ACCEL),
        ("brake_comfort_kmh_s", D, "ride-comfort limit on the braking of a stop (the stopping pattern's "
                                   "comfort limit, e.g. 3.3); not a limit on acceleration [km/h/s]", ACCEL),
        ("jerk_limit_kmh_s2", D, "ride-comfort jerk limit [km/h/s^2]", JERK),
        ("speed_margin_kmh", D, "on-board maximum speed = limit - margin [km/h]", MARGIN),
        ("cruise", S, "constant (constant-speed control) or sawtooth"),
        ("coast_band_kmh", D, "sawtooth speed band [km/h]", BAND),
    ]), required=True, min_rows=1, row_id=("train_type",)),
    TableSpec("traction", _schema("traction", [
        ("train_type", S, "train type (references rolling_stock)"),
        ("speed_kmh", D, "speed of this curve point [km/h]; strictly increasing per train type from 0", TRACTION_SPEED),
        ("effort_kN", D, "full-notch tractive effort of the whole train [kN]; >= 0", EFFORT),
    ]), required=True, min_rows=1, row_id=("train_type", "speed_kmh")),
    TableSpec("timetable", _schema("timetable", [
        ("train_id", S, "train identifier"),
        ("train_type", S, "train type (references rolling_stock)"),
        ("direction", S, "down or up"),
        ("seq", I32, "order of the call along the run, from 0"),
        ("station_id", S, "station (references stations)"),
        ("arrival_s", D, "arrival [s after midnight, may exceed 86400]; null at the origin", NULLABLE, TIME),
        ("departure_s", D, "departure [s after midnight, may exceed 86400]; null at the terminus",
         NULLABLE, TIME),
        ("stops", B, "false for a pass"),
    ]), required=True, row_id=("train_id", "seq")),
    TableSpec("nodes", _schema("nodes", [
        ("node_id", S, "unique node identifier"),
        ("kind", S, "switch, stop, boundary or end"),
        ("position_m", D, "node chainage [m]", CHAINAGE),
        ("interlocking", S, "interlocking that controls the node"),
        ("station_id", S, "station a stop node belongs to (optional column)", NULLABLE),
        ("track", S, "track the node lies on (optional column)", NULLABLE),
    ]), required=False, row_id=("node_id",), optional_columns=frozenset({"station_id", "track"})),
    TableSpec("edges", _schema("edges", [
        ("edge_id", S, "unique edge identifier"),
        ("from_node", S, "node id at one end"),
        ("to_node", S, "node id at the other end"),
        ("length_m", D, "track length between the nodes [m]; > 0", Range(0.0, 2 * MAX_CHAINAGE_M, 'an edge is no longer than the line can be', lo_open=True)),
        ("track", S, "track name"),
        ("direction", S, "the direction trains normally run this track: down, up or both (optional column); "
                         "null or absent: from the track name (D… down, U… up, anything else both)", NULLABLE),
    ]), required=False, row_id=("edge_id",), optional_columns=frozenset({"direction"})),
]

TABLES: dict[str, TableSpec] = {t.name: t for t in _SPECS}
"""Every table of schema v1 by name, in docs/line-database.md order."""

RENAMED_COLUMNS: dict[tuple[str, str], tuple[str, str]] = {
    ("rolling_stock", "brake_comfort_kmh_s"): (
        "comfort_accel_kmh_s",
        "the ride-comfort limit on stop braking it held under its old name (schema 1); a line imported by an "
        "earlier planner had the source's comfort acceleration there, which belongs in max_accel_kmh_s: "
        "re-import such a line"),
}
"""Columns that had another name in older line folders (schema 1): (table, new name) → (old name, what it was).
A folder with the old name is read under the new one with a note (:mod:`planner.line.upgrade`), and
``planner line upgrade DIR`` rewrites it."""


def missing_column_hint(table: str, column: str, present) -> str:
    """The fix for a missing required column when a folder still has its old name ("" if none)."""
    old = RENAMED_COLUMNS.get((table, column))
    if old is None or old[0] not in set(present):
        return ""
    return f"; found {old[0]}: {old[1]}"


def describe(table: str) -> list[tuple[str, str, bool, str]]:
    """``(column, type, nullable, description)`` for each declared column of ``table``."""
    return [
        (f.name, str(f.type), f.nullable, f.metadata[b"description"].decode())
        for f in TABLES[table].schema
    ]


def declared_table(name: str, table: pa.Table) -> pa.Table:
    """``table`` in the one form every writer of a line database gives its file ``<name>.parquet``.

    The declared columns in declared order (an optional one only when present), each with its
    declared type, nullability and description; then the user's own columns as they are; the
    schema metadata of the declaration (``table``, ``schema_version``). A line database written in
    this form by :func:`write_line_table` (the importers, ``lines/sample/build.py``) comes back from
    ``planner export csv`` → ``planner import csv`` in the same bytes, so its source digest, and so
    every cached result of it, stays the same.
    """
    spec = TABLES[name]
    fields, arrays = [], []
    for f in spec.schema:
        if f.name in table.column_names:
            fields.append(f)
            arrays.append(table.column(f.name).cast(f.type).combine_chunks())
    for f in table.schema:
        if f.name not in spec.schema.names:
            fields.append(f)
            arrays.append(table.column(f.name).combine_chunks())
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=spec.schema.metadata))


def write_line_table(name: str, table: pa.Table, path) -> None:
    """Write table ``name`` of a line database to ``path`` in its declared form (:func:`declared_table`),
    with the planner's one deterministic Parquet writer, atomically."""
    from planner.io.parquet import write_parquet_atomic

    write_parquet_atomic(declared_table(name, table), path)
