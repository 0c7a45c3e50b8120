"""Temporary speed restrictions from outside → a daily feed's ``restrictions.parquet``.

Two source formats:

- **CSV**: the columns of ``restrictions.parquet`` (docs/operating-day.md), one
  restriction per row, ``#`` comment lines before the header, ``true``/``false``
  for ``has_beacon``, an empty ``train_type`` for every train type, validity as
  local date-times without offset (``2026-11-30T01:00``).
- **OSRD temporary speed limits** (JSON): the body OSRD's editoast takes to
  create a temporary speed limit group, ``{"speed_limit_group_name": ...,
  "speed_limits": [{"obj_id", "start_date_time", "end_date_time", "speed_limit"
  [m/s], "track_ranges": [{"track", "begin", "end", "direction":
  "START_TO_STOP"|"STOP_TO_START"}]}]}`` (a bare list of such items is accepted
  too). Track ranges are located on the line with the railjson infrastructure
  and ``--path`` the line was imported with (:mod:`planner.line.importers.railjson`):
  a range run in the path's own direction is ``down``. Date-times without
  offset are local; with an offset (newer OSRD versions write UTC) they are
  converted to the line's time zone. OSRD has no beacons: ``has_beacon`` is
  false (a default listed in the summary).

The rows are validated against the line with the feed's own rules
(:func:`planner.line.daily.check_restrictions`); then, ``replace`` or
``append`` (an id that already exists is refused), the feed's
restrictions.parquet is written atomically: a failed import changes nothing.
"""
from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pyarrow as pa

from planner.errors import InputError, LineValidationError, SourceError, Violation
from planner.io.parquet import write_parquet_atomic
from planner.line.conform import conform
from planner.line.daily import FEED_TABLES, check_restrictions, read_feed_tables, restriction_rows, \
    restrictions_table, check_feed
from planner.line.importers.common import ImportSummary, number
from planner.line.importers.csv import read_table_csv
from planner.line.model import Line
from planner.line.operating_day import zone

SPEC = FEED_TABLES["restrictions"]
OSRD_DIRECTIONS = ("START_TO_STOP", "STOP_TO_START")


def read_csv(path: Path) -> tuple[pa.Table, list[str]]:
    """The CSV's rows as a restrictions table and, per row, how messages name it (``file line N``)."""
    table, line_no = read_table_csv(path, SPEC.name, SPEC)
    return table, [f"{path.name} line {n}" for n in line_no]


def _local(text, where: str, tz: str) -> str:
    """An OSRD date-time as local text without offset (converted to ``tz`` when it has an offset)."""
    if not isinstance(text, str):
        raise SourceError(f"{where}: expected a date-time string, found {text!r}")
    try:
        t = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise SourceError(f"{where}: {text!r} is not an ISO 8601 date-time") from None
    if t.tzinfo is not None:
        t = t.astimezone(zone(tz)).replace(tzinfo=None)
    return t.isoformat(timespec="seconds")


def read_osrd(path: Path, infra: Path, path_ops: list[str], tz: str, s: ImportSummary,
              running_side: str | None = None) -> tuple[pa.Table, list[str]]:
    """OSRD temporary speed limits located on the line along ``path_ops`` of the railjson ``infra`` (imported
    with ``running_side``: the line's)."""
    from planner.line.importers.railjson import MAX_SPEED_MS, _Network, _ops, _Src, build_path, load_json

    fname, data = load_json(path)
    items = data.get("speed_limits") if isinstance(data, dict) else data
    group = str(data.get("speed_limit_group_name", "")) if isinstance(data, dict) else ""
    if not isinstance(items, list):
        raise SourceError(f"{fname}: expected {{\"speed_limit_group_name\", \"speed_limits\": [...]}} or a list "
                          f"of temporary speed limits")
    from planner.line.importers.network import path_chainage, railjson_topology

    iname, idata = load_json(infra)
    src = _Src(iname, idata)
    net = _Network(src)
    line_path, _ = build_path(src, net, _ops(src, net, path_ops))
    # every track of the line's network, as the line import placed it: the other main, loops, platform tracks
    places = track_places(railjson_topology(src, net, {}), path_chainage(line_path.pieces), running_side)
    rows, names = [], []
    for i, it in enumerate(items):
        w = f"{fname}: speed_limits[{i}]"
        if not isinstance(it, dict):
            raise SourceError(f"{w}: must be an object")
        oid = it.get("obj_id")
        if not isinstance(oid, str) or not oid:
            raise SourceError(f"{w}.obj_id: missing; every temporary speed limit needs its id")
        v = number(it.get("speed_limit"), f"{w}.speed_limit", positive=True)
        if v > MAX_SPEED_MS:
            raise SourceError(f"{w}.speed_limit: {v!r} m/s is {v * 3.6:.0f} km/h; OSRD speeds are in m/s: "
                              f"was it given in km/h?")
        frm = _local(it.get("start_date_time"), f"{w}.start_date_time", tz)
        until = _local(it.get("end_date_time"), f"{w}.end_date_time", tz)
        ranges = it.get("track_ranges")
        if not isinstance(ranges, list) or not ranges:
            raise SourceError(f"{w}.track_ranges: expected a non-empty list of {{track, begin, end, direction}}")
        pieces: dict[tuple[float, float, str], set[str]] = {}
        for k, r in enumerate(ranges):
            wr = f"{w}.track_ranges[{k}]"
            if not isinstance(r, dict):
                raise SourceError(f"{wr}: must be an object {{\"track\", \"begin\", \"end\", \"direction\"}}")
            b, e = number(r.get("begin"), f"{wr}.begin"), number(r.get("end"), f"{wr}.end")
            rd = r.get("direction", "START_TO_STOP")
            if rd not in OSRD_DIRECTIONS:
                raise SourceError(f"{wr}.direction: {rd!r} is not {' or '.join(OSRD_DIRECTIONS)}")
            track = str(r.get("track"))
            for ca, cb, dirn in _on_network(places, track, min(b, e), max(b, e), rd):
                ca, cb = max(ca, 0.0), min(cb, line_path.length)  # a track the path runs along only in part
                if cb > ca:
                    pieces.setdefault((ca, cb, places[track][2]), set()).add(dirn)
            if track not in places:
                s.notes.append(f"temporary speed limit {oid}: track range {track} {min(b, e):g}–{max(b, e):g} m lies "
                               "on no track of the line's network: that piece not imported")
        if not pieces:
            s.notes.append(f"temporary speed limit {oid}: none of its track ranges lies on the line: not imported")
            continue
        merged = _merge(pieces)
        for n, (a, b, dirn, track) in enumerate(merged):
            rid = oid if len(merged) == 1 else f"{oid}.{n + 1}"
            rows.append(dict(restriction_id=rid, start_m=a, end_m=b, limit_kmh=round(v * 3.6, 9), direction=dirn,
                             track=track, train_type=None, valid_from=frm, valid_until=until,
                             reason=f"OSRD temporary speed limit group {group}".strip() if group else
                             "OSRD temporary speed limit",
                             has_beacon=s.default("has_beacon", rid)))
            names.append(f"{fname} speed_limits[{i}] (obj_id {oid})")
    return restrictions_table(rows), names


def track_places(topo, on_line: dict[str, tuple[float, int]],
                 running_side: str | None = None) -> dict[str, tuple[float, float, str, float]]:
    """Where each source track of the imported network lies: ``track id → (chainage at its position 0, chainage
    at its end, the track's name in edges.parquet, its length)``, for the tracks :func:`network_tables` keeps; a
    position ``p`` on it is at ``c0 + (c1 - c0) · p / length``, as its points are placed there (exactly the line's
    chainage on the line's own tracks). For what lies on a track off the line's path (a temporary restriction
    on the other main or a loop)."""
    from planner.line.importers.network import _key, _track_groups, placed
    from planner.line.importers.sides import track_labels

    uf, pos, keep = placed(topo, on_line)
    label, _, _ = track_labels(topo, on_line, _track_groups(topo, None), _track_groups(topo, on_line), pos, uf,
                               running_side, [])
    return {t: (pos[uf.find(_key(t, 0.0))], pos[uf.find(_key(t, topo.lengths[t]))], label[t], topo.lengths[t])
            for t in sorted(keep)}


def _on_network(places: dict, track: str, begin: float, end: float, osrd_dir: str):
    """``(chainage start, chainage end, direction)`` of a track range on the line's network
    (:func:`track_places`: a position ``p`` of a track of length ``L`` lies at
    ``c0 + (c1 - c0) · p / L``); a range run towards increasing chainage is ``down``. Nothing when the track is
    not on the network or the range is empty there."""
    if track not in places:
        return
    c0, c1, _, length = places[track]
    lo, hi = max(begin, 0.0), min(end, length)
    if hi <= lo or c1 == c0:
        return
    at = lambda p: round(c0 + (c1 - c0) * p / length, 6)  # noqa: E731
    a, b = sorted((at(lo), at(hi)))
    yield a, b, ("down" if (osrd_dir == "START_TO_STOP") == (c1 > c0) else "up")


def _merge(pieces: dict[tuple[float, float, str], set[str]]) -> list[tuple[float, float, str, str]]:
    """Touching chainage pieces of one limit on one track with the same directions become one stretch; both
    directions of one stretch are ``both``."""
    out: list[list] = []
    for (a, b, track), dirs in sorted(pieces.items(), key=lambda kv: (kv[0][2], kv[0][0], kv[0][1])):
        d = "both" if dirs == {"down", "up"} else next(iter(dirs))
        if out and out[-1][2] == d and out[-1][3] == track and abs(out[-1][1] - a) < 1e-6:
            out[-1][1] = b
        else:
            out.append([a, b, d, track])
    return [tuple(x) for x in sorted(out, key=lambda x: (x[0], x[1], x[3]))]


def _validated(table: pa.Table, names: list[str], line: Line, tz: str, source: str) -> None:
    """Refuse the source (every problem, named by the source's own row) when a row breaks a rule."""
    view, bad = conform(SPEC, table)
    if view is not None:
        bad += check_restrictions(view, line, tz)[1]
    if bad:
        raise LineValidationError(source, [Violation(names[v.row] if v.row is not None else source, None,
                                                     v.column, v.message) for v in bad])


def import_restrictions(src: str | Path, line: Line, feed: str | Path, *, tz: str, replace: bool = False,
                        infra: str | Path | None = None, path_ops: list[str] | None = None) -> ImportSummary:
    """Import restrictions from a CSV or OSRD JSON file into the daily feed ``feed`` of ``line``.

    ``replace``: the feed's restrictions become the source's; else they are appended (a restriction id
    already in the feed is refused). The rest of the feed is validated too, so the written feed loads.
    """
    src, feed = Path(src), Path(feed)
    try:
        zone(tz)
    except ValueError as e:
        raise InputError(f"--time-zone: {e}") from None
    if not src.is_file():
        raise SourceError(f"{src}: file does not exist")
    s = ImportSummary(source=str(src))
    if src.suffix.lower() == ".json":
        if infra is None or not path_ops:
            raise InputError("an OSRD temporary speed limit file locates its limits on track sections: give the "
                             "railjson infrastructure (--infra) and the --path the line was imported with")
        table, names = read_osrd(src, Path(infra), path_ops, tz, s, line.running_side)
    else:
        table, names = read_csv(src)
    _validated(table, names, line, tz, src.name)
    views, bad = read_feed_tables(feed) if feed.is_dir() else ({}, [])
    old, more = check_feed(feed, line, tz, views)
    # the rest of the feed must load with the new restrictions; the old restrictions only when they stay
    bad = [v for v in bad + more if replace is False or v.file != SPEC.file]
    if bad:
        raise LineValidationError(str(feed), bad)
    rows = table.to_pylist()
    if not replace:
        have = {r.restriction_id for r in old.restrictions}
        dup = [(n, r["restriction_id"]) for n, r in zip(names, rows) if r["restriction_id"] in have]
        if dup:
            raise LineValidationError(src.name, [Violation(n, None, "restriction_id", f"{rid!r} is already in "
                                      f"{feed / SPEC.file}; give a new id, or --replace the feed's restrictions")
                                      for n, rid in dup])
        rows = restriction_rows(old) + rows
    write_parquet_atomic(restrictions_table(rows), feed / SPEC.file)
    s.out, s.line_id, s.rows = feed / SPEC.file, line.line_id, {"imported": len(table), "in the feed": len(rows)}
    s.notes.append(f"the source's restrictions {'replace the feed' if replace else 'are appended to the feed'}")
    return s


__all__ = ["import_restrictions", "read_csv", "read_osrd"]


# --------------------------------------------------------------------------- the feed's restrictions, edited
def feed_rows(line: Line, feed: str | Path, tz: str) -> list[dict]:
    """The restrictions of the daily feed ``feed`` of ``line`` (validated), as rows of restrictions.parquet."""
    from planner.line.daily import load_feed

    return restriction_rows(load_feed(feed, line, tz))


def _find(rows: list[dict], rid: str, feed: Path) -> dict:
    row = next((r for r in rows if r["restriction_id"] == rid), None)
    if row is None:
        ids = ", ".join(r["restriction_id"] for r in rows[:8]) or "none"
        raise InputError(f"{feed / SPEC.file}: no restriction {rid!r} (the feed has {ids}); "
                         "`planner restrictions list` shows them")
    return row


def write_rows(rows: list[dict], line: Line, feed: str | Path, tz: str, source: str) -> Path:
    """Validate ``rows`` as the feed's restrictions (every rule of an import) and write them atomically: on any
    problem nothing is written."""
    feed = Path(feed)
    table = restrictions_table(rows)
    _validated(table, [f"{source} {r['restriction_id']}" for r in rows], line, tz, source)
    write_parquet_atomic(table, feed / SPEC.file)
    return feed / SPEC.file


def lift(line: Line, feed: str | Path, tz: str, rid: str, at: str) -> tuple[dict, dict]:
    """End restriction ``rid`` early, at the local time ``at`` (``YYYY-MM-DDTHH:MM``, the line's time zone):
    its ``valid_until`` becomes ``at``. ``at`` must fall inside its validity (one that has not started yet is
    removed instead). Returns the row before and after."""
    from planner.line.daily import parse_local

    feed = Path(feed)
    rows = feed_rows(line, feed, tz)
    row = _find(rows, rid, feed)
    at_s, err = parse_local(at, late=True, tz=tz)
    if err:
        raise InputError(f"--at {at!r}: {err}")
    from_s, _ = parse_local(row["valid_from"], late=False, tz=tz)
    until_s, _ = parse_local(row["valid_until"], late=True, tz=tz)
    if not from_s < at_s < until_s:
        raise InputError(f"--at {at}: restriction {rid} is in force from {row['valid_from']} until "
                         f"{row['valid_until']}; lift it inside that time, or `planner restrictions remove` it")
    new = {**row, "valid_until": at}
    write_rows([new if r is row else r for r in rows], line, feed, tz, f"lift {rid}")
    return row, new


def remove(line: Line, feed: str | Path, tz: str, rid: str) -> dict:
    """Delete restriction ``rid`` from the feed; returns its row."""
    feed = Path(feed)
    rows = feed_rows(line, feed, tz)
    row = _find(rows, rid, feed)
    write_rows([r for r in rows if r is not row], line, feed, tz, f"remove {rid}")
    return row


def export_csv(line: Line, feed: str | Path, tz: str, out: str | Path) -> Path:
    """The feed's restrictions as a CSV file ``out`` that ``planner restrictions import`` reads back (atomic)."""
    from planner.io.atomic import write_bytes_atomic
    from planner.line.importers.csv import table_csv

    text = table_csv(SPEC.name, restrictions_table(feed_rows(line, feed, tz)), spec=SPEC)
    write_bytes_atomic(out, text.encode("utf-8"))
    return Path(out)

