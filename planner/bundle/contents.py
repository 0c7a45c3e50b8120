"""What a bundle's tables must hold: the declared schemas of the tables built from the line DB,
the columns the vehicle relies on in the other steps' tables, and the consistency between tables.

Takes a bundle's tables by name (pyarrow tables) and its target (line,
direction, train type); returns nothing when they hold and raises
:class:`planner.errors.BundleError` naming the first failed check. The builder
(:mod:`planner.bundle.container`) runs the same checks as the verifier
(:mod:`planner.bundle.verify`), so it never signs what a vehicle would refuse.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from planner.bundle import atsp
from planner.bundle.manifest import CORE_TABLES, fail, no_stop_rows
from planner.io.parquet import declare
from planner.line.model import sign
from planner.tables.eval_points import KINDS as EVAL_POINT_KINDS


# --- declared schemas of the tables built from the line DB ----------------------
def _key_fields() -> list[tuple[str, pa.DataType, str]]:
    return [
        ("line", pa.string(), "line id"),
        ("direction", pa.string(), "running direction, 'down' or 'up'"),
        ("train_type", pa.string(), "train type the bundle is for"),
    ]


RESTRICTIONS_SCHEMA = declare(
    _key_fields() + [
        ("seq", pa.int32(), "running order of the restriction entry, from 0"),
        ("restriction_id", pa.string(), "'R<row>', row = 0-based row in speed_limits.parquet; 'T.<id>' for "
                                    "a temporary restriction of the daily feed"),
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
        ("valid_from_utc_s", pa.int64(), "a temporary restriction (kind temporary, id T.<feed id>): in force "
                                         "from [UTC epoch s]; null for the line's own"),
        ("valid_until_utc_s", pa.int64(), "a temporary restriction: in force until (exclusive) [UTC epoch s]; "
                                          "null for the line's own"),
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
        ("valid_from_utc_s", pa.int64(), "a temporary restriction's pattern: fed from [UTC epoch s]; null: "
                                         "always (the line's own)"),
        ("valid_until_utc_s", pa.int64(), "a temporary restriction's pattern: fed until (exclusive) [UTC epoch "
                                          "s]; null: always"),
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


# --- checks ---------------------------------------------------------------------
def check_schema(name: str, got: pa.Schema, want: pa.Schema, where: str) -> None:
    """Table ``name`` has exactly the declared columns and types of ``want``, in order."""
    g = [(f.name, f.type) for f in got]
    w = [(f.name, f.type) for f in want]
    if g != w:
        gd, wd = dict(g), dict(w)
        diff = [f"{n}: expected {t}, found {gd.get(n, 'nothing')}" for n, t in w if gd.get(n) != t]
        diff += [f"{n}: not declared" for n in gd if n not in wd]
        raise fail(where, f"table {name} does not match its declared schema ({'; '.join(diff) or 'column order'})")


def check_keys(name: str, t: pa.Table, line_id: str, direction: str, train_type: str, where: str) -> None:
    """Every row of ``t`` that carries a line, direction or train type carries the bundle's target."""
    for col, want in (("line", line_id), ("line_id", line_id), ("direction", direction),
                      ("train_type", train_type)):
        if col not in t.column_names or t.num_rows == 0:
            continue
        c = t.column(col)
        if c.null_count or not _only(c, want):
            found = sorted({str(x) for x in c.to_pylist()} - {want})
            raise fail(where, f"table {name} column {col} holds {found}, expected only {want!r}")


def _only(c: pa.ChunkedArray, want: str) -> bool:
    """Whether every value of the column ``c`` (no nulls) is ``want``; a dictionary-encoded column (a bundle's
    member read for verifying, :func:`planner.bundle.verify._row_groups`) by the dictionary values its rows use."""
    if pa.types.is_dictionary(c.type):
        used = [ch.dictionary.take(pc.unique(ch.indices)) for ch in c.chunks]
        return all(u.null_count == 0 and pc.all(pc.equal(u.cast(pa.string()), want)).as_py() is not False
                   for u in used)
    return bool(pc.all(pc.equal(c.cast(pa.string()), want)).as_py())


def _col(t: pa.Table, name: str) -> list:
    return t.column(name).to_pylist()


def _distinct(t, *names: str) -> set:
    """The distinct rows of columns ``names`` of ``t`` (a table, or the :class:`Streamed` summary of one) as a set
    of tuples, made from the distinct rows only (not from a Python object per row and column: tables (b) to (d)
    have millions of rows on a long line)."""
    if isinstance(t, Streamed):
        return t.distinct[names]
    sel = t.select(list(names))
    if all(pa.types.is_dictionary(f.type) for f in sel.schema) and not any(c.null_count for c in sel.columns):
        # dictionary-encoded (a member read for verifying): the distinct rows of the columns' indices, as one
        # number each (index by index, in the base of each dictionary's size), each then its values (one Python
        # object per distinct value, not per row)
        rows: set = set()
        for batch in sel.to_batches():
            values = [c.dictionary.to_pylist() for c in batch.columns]
            sizes = [max(len(v), 1) for v in values]
            if float(np.prod(sizes, dtype=float)) >= 2.0 ** 62:  # not one int64 each: by the rows' values
                return _distinct(pa.table([c.cast(c.type.value_type) for c in sel.columns], names=list(names)),
                                 *names)
            code = np.zeros(batch.num_rows, dtype=np.int64)
            for c, n in zip(batch.columns, sizes):
                code = code * n + np.asarray(c.indices, dtype=np.int64)
            found = []
            for n in reversed(sizes):
                code, r = np.divmod(np.unique(code) if not found else code, n)
                found.append(r)
            rows |= set(zip(*(map(v.__getitem__, r.tolist()) for v, r in zip(values, reversed(found)))))
        return rows
    plain = [c.cast(c.type.value_type) if pa.types.is_dictionary(c.type) else c for c in sel.columns]
    u = pa.table(plain, names=list(names)).group_by(list(names), use_threads=False).aggregate([])
    return set(zip(*(u.column(c).to_pylist() for c in names)))


STREAMED = ("table_a", "table_b", "table_c", "table_d", "stop_samples")
"""The steps' tables that are checked a piece at a time, never held whole, where a bundle is built from the
datasets or only verified (:func:`streamed`): on a long line tables (b) to (d) and the stop samples have millions
of rows each. The evaluation points and the stop summary, which the checks read row by row, are read whole."""

CROSS_KEYS = {
    "table_a": (("origin", "destination", "ratio"),),
    "table_b": (("origin", "destination", "ratio_before"), ("origin", "destination", "ratio_after"),
                ("origin", "destination", "eval_point_id")),
    "table_c": (("origin", "destination", "ratio"),),
    "table_d": (("origin", "destination", "eval_point_id"),),
}
"""The columns of each step table whose distinct rows the cross-checks compare (:func:`_check_step_tables`)."""


@dataclass
class Streamed:
    """What the checks need of a table that is read, checked and encoded a piece at a time and never held whole
    (:func:`streamed`): its schema, its rows and the distinct rows of its :data:`CROSS_KEYS`."""

    schema: pa.Schema
    num_rows: int = 0
    distinct: dict = field(default_factory=dict)

    @property
    def column_names(self) -> list[str]:
        return list(self.schema.names)


def streamed(name: str, pieces: Iterable[pa.Table], target: tuple[str, str, str], where: str,
             each: Callable[[pa.Table], None] | None = None) -> Streamed | None:
    """Check ``pieces`` of table ``name`` one at a time (each piece's rows carry the bundle's ``target``: line,
    direction, train type; all pieces have the first one's columns), give each to ``each`` (the builder encodes
    it) and gather what the cross-checks compare; None when there is no piece. A table of millions of rows is
    then checked holding one piece of it, not all."""
    out = None
    for piece in pieces:
        if out is None:
            out = Streamed(piece.schema, distinct={k: set() for k in CROSS_KEYS.get(name, ())
                                                   if set(k) <= set(piece.column_names)})
        elif piece.schema != out.schema:
            raise fail(where, f"table {name}: its pieces differ in their columns ({out.schema.names} and "
                              f"{piece.schema.names})")
        check_keys(name, piece, *target, where)
        for k, seen in out.distinct.items():
            seen |= _distinct(piece, *k)
        out.num_rows += piece.num_rows
        if each is not None:
            each(piece)
    return out


_REQUIRED_COLUMNS = {
    "eval_points": ("origin", "destination", "eval_point_id"),
    "table_a": ("origin", "destination", "ratio", "running_time_s"),
    "table_b": ("origin", "destination", "eval_point_id", "ratio_before", "ratio_after", "remaining_time_s"),
    "table_c": ("origin", "destination", "eval_point_id", "ratio", "remaining_time_s", "remaining_time_ref_s"),
    "table_d": ("origin", "destination", "eval_point_id", "speed_kmh", "powering", "ratio_after",
                "remaining_time_s", "remaining_time_ref_s"),
    "stop_summary": ("station_id", "origin", "adhesion_kmh_s", "feasible"),
}
"""Columns the cross-checks (and the vehicle) rely on in the tables step's datasets."""


def check_tables(tables: Mapping[str, pa.Table], m: dict, where: str) -> None:
    """Cross-table consistency of a bundle whose bytes are already proven."""
    for name, cols in _REQUIRED_COLUMNS.items():
        if name in tables:
            lost = [c for c in cols if c not in tables[name].column_names]
            if lost:
                raise fail(where, f"table {name} lacks column(s) {', '.join(lost)}")
    for name, t in tables.items():
        if not isinstance(t, Streamed):  # a streamed table's pieces were checked as they were read
            check_keys(name, t, m["line_id"], m["direction"], m["train_type"], where)
        if name in CORE_SCHEMAS:
            check_schema(name, t.schema, CORE_SCHEMAS[name], where)
    _check_core(tables, sign(m["direction"]), where)
    _check_step_tables(tables, where)
    # a bundle signed before the manifest named them has no no_stop: what its stop_summary says counts (manifest_info)
    if "no_stop" in m and m["no_stop"] != no_stop_rows(tables.get("stop_summary")):
        raise fail(where, "manifest no_stop does not list the stops that stop_summary has no pattern for")


def _check_core(tables: Mapping[str, pa.Table], sg: int, where: str) -> None:
    """The tables built from the line DB: sequence numbers, ATS-P rows, running order, beacon flags."""
    r, a, b = tables["restrictions"], tables["atsp"], tables["beacons"]
    for name in CORE_TABLES:
        t = tables[name]
        if "seq" in t.column_names and name != "timetable" and _col(t, "seq") != list(range(t.num_rows)):
            raise fail(where, f"table {name} seq is not 0..{t.num_rows - 1}")
    rid = _col(r, "restriction_id")
    if len(set(rid)) != len(rid):
        raise fail(where, "restrictions has duplicate restriction_id")
    fed = [i for i, x in zip(rid, _col(r, "db_fed")) if x]
    if sorted(fed) != sorted(_col(a, "restriction_id")):
        raise fail(where, "atsp rows do not match the restrictions marked db_fed")
    for tname, t in (("restrictions", r), ("atsp", a)):
        bad = [x for x in _col(t, "overwrites") if x is not None and x not in rid]
        if bad:
            raise fail(where, f"{tname} overwrites unknown restriction(s) {bad}")
    entry = np.array(_col(r, "entry_m"), dtype=float) * sg
    if np.any(np.diff(entry) < 0):
        raise fail(where, "restrictions are not in running order")
    feed = np.array(_col(a, "feed_m"), dtype=float) * sg
    if np.any(np.diff(feed) < 0):
        raise fail(where, "atsp telegrams are not in running order")
    pos = np.array(_col(b, "position_m"), dtype=float) * sg
    if np.any(np.diff(pos) < 0):
        raise fail(where, "beacons are not in running order")
    if _col(b, "correction_usable") != atsp.correction_usable(_col(b, "telegram")).tolist():
        raise fail(where, "beacons correction_usable flags do not match their telegrams")
    mp = tables["max_profile"]
    fr, to = (np.array(_col(mp, c), dtype=float) * sg for c in ("from_m", "to_m"))
    if mp.num_rows == 0 or np.any(fr[1:] != to[:-1]) or np.any(to <= fr):
        raise fail(where, "max_profile segments are not contiguous in running order")


CROSS_CHECKED = (("table_a", "table_b"), ("table_a", "table_c"), ("eval_points", "table_b"),
                 ("eval_points", "table_d"))
"""The pairs of steps' tables :func:`_check_step_tables` checks against each other (the ratios of (b) and (c) are
(a)'s, the evaluation points of (b) and (d) are in ``eval_points``): a nightly build that takes one of a pair from
the previous bundle takes the other too, or decodes it (:func:`planner.job.bundle_reuse.taken`)."""


def _check_step_tables(tables: Mapping[str, pa.Table], where: str) -> None:
    """The tables and stopping steps' tables: ratios and evaluation points they share, beacon points."""
    ta, tb, ep = tables.get("table_a"), tables.get("table_b"), tables.get("eval_points")
    if ta is not None and tb is not None:
        have = _distinct(ta, "origin", "destination", "ratio")
        for c in ("ratio_before", "ratio_after"):
            need = _distinct(tb, "origin", "destination", c)
            lost = sorted(need - have, key=str)
            if lost:
                raise fail(where, f"table_b {c} {lost[0][2]} for {lost[0][0]}->{lost[0][1]} is not in table_a")
    tc = tables.get("table_c")
    if ta is not None and tc is not None:  # the adaptive on-board mode reads table (c) beside (a) and (b)
        have = _distinct(ta, "origin", "destination", "ratio")
        lost = sorted(_distinct(tc, "origin", "destination", "ratio") - have, key=str)
        if lost:
            raise fail(where, f"table_c ratio {lost[0][2]} for {lost[0][0]}->{lost[0][1]} is not in table_a")
    if ep is not None:
        pts = _distinct(ep, "origin", "destination", "eval_point_id")
        for name in ("table_b", "table_d"):
            t = tables.get(name)
            if t is None:
                continue
            lost = _distinct(t, "origin", "destination", "eval_point_id") - pts
            if lost:
                o, d, x = sorted(lost)[0]
                raise fail(where, f"{name} evaluation point {x!r} for {o}->{d} is not in eval_points")
        # beacon points must be beacons of this bundle; odometer points (departure, after departure,
        # regular interval) are named dep / dep+<m> and are found by running distance, not by beacon
        ids = _col(ep, "eval_point_id")
        kinds = _col(ep, "eval_point_kind") if "eval_point_kind" in ep.column_names else \
            ["departure" if x.startswith("dep") else "beacon" for x in ids]
        bad = sorted({k for k in kinds} - set(EVAL_POINT_KINDS), key=str)
        if bad:
            raise fail(where, f"eval_points eval_point_kind {bad[0]!r} is not one of {', '.join(EVAL_POINT_KINDS)}")
        beacon_ids = set(_col(tables["beacons"], "beacon_id"))
        strays = sorted({x for x, k in zip(ids, kinds) if k == "beacon" and x not in beacon_ids})
        if strays:
            raise fail(where, f"eval_points name beacon(s) {strays} that are not in beacons")
        odo = sorted({x for x, k in zip(ids, kinds) if k != "beacon" and not (x == "dep" or x.startswith("dep+"))})
        if odo:
            raise fail(where, f"eval_points odometer point(s) {odo} are not named 'dep' or 'dep+<m>'")
