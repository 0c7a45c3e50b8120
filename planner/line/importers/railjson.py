"""OSRD railjson → line database: the line along a path of operational points, and OSRD rolling stock.

railjson (the infrastructure format of OSRD, the open-source railway planner) locates
everything on *track sections*: ``{"id", "length" [m], "slopes": [{"begin", "end",
"gradient" [m/km = ‰]}], "curves": [{"begin", "end", "radius" [m]}]}``, joined by
``switches`` whose ``ports`` name track ends (``{"track", "endpoint": "BEGIN"|"END"}``;
the built-in ``switch_type`` values ``link``, ``point_switch``, ``crossing``,
``single_slip_switch``, ``double_slip_switch`` and the file's ``extended_switch_types``
say which ports connect). ``speed_sections`` carry ``speed_limit`` [m/s] over
``track_ranges`` with ``applicable_directions`` (``START_TO_STOP``, ``STOP_TO_START``,
``BOTH``); ``signals`` and ``detectors`` sit at ``{"track", "position"}`` (signals with a
``direction``); ``operational_points`` have ``parts`` at track positions.

The line is the shortest connected route through the named operational points in
order, without reversing, extended to the whole first and last track sections. Its
chainage starts at 0 where the first track section is entered; direction ``down`` is
the running order of ``--path``. A track section run against its own orientation
(``STOP_TO_START``) has its gradients negated and its directional objects swapped.

OSRD rolling stock (``{"name", "length" [m], "mass" [kg], "max_speed" [m/s],
"inertia_coefficient", "comfort_acceleration" [m/s²], "const_gamma" or "gamma":
{"value"} [m/s²], "rolling_resistance": {"type": "davis", "A" [N], "B" [N/(m/s)],
"C" [N/(m/s)²]}, "effort_curves": {"default_mode", "modes": {mode: {"default_curve":
{"speeds" [m/s], "max_efforts" [N]}}}}}``) becomes one rolling_stock row and its
traction curve. Converted values are rounded to 1e-9 of the target unit (so that
22.2222… m/s is written 80.0 km/h). The braking mapping is explicit (and printed in the
import summary): ``comfort_acceleration``, OSRD's traction comfort limit, caps acceleration
(``max_accel_kmh_s``) and never braking; ``gamma`` is the train's own brake (``service_brake_kmh_s``,
``stop_brake_kmh_s``, ``atsp_pattern_kmh_s``); OSRD has no ride-comfort limit on braking, so
``brake_comfort_kmh_s`` takes the documented default (3.3 km/h/s) unless the TOML gives one.
"""
from __future__ import annotations

import heapq
from pathlib import Path

import pandas as pd

from planner.errors import SourceError
from planner.line.schema import MAX_GRADIENT_PERMIL, TABLES
from planner.line.importers.common import (
    ImportSummary,
    beacon_table,
    category_map,
    check_categories,
    line_table,
    load_extras,
    load_json,
    number,
    path_id,
    station_table,
    timetable_table,
    write_line,
)
from planner.line.importers.stock import MAX_SPEED_MS, rolling_stock_tables

SWITCH_LINKS = {
    "link": [("A", "B")],
    "point_switch": [("A", "B1"), ("A", "B2")],
    "crossing": [("A1", "B1"), ("A2", "B2")],
    "single_slip_switch": [("A1", "B1"), ("A2", "B2"), ("A1", "B2")],
    "double_slip_switch": [("A1", "B1"), ("A1", "B2"), ("A2", "B1"), ("A2", "B2")],
}
"""Built-in OSRD switch types: which ports a train can run between."""

INC, DEC = "START_TO_STOP", "STOP_TO_START"


def _r(x: float) -> float:
    return round(x, 9)


class _Src:
    """Element lookup with error messages of the form ``file: list[i] (id X): field: problem``."""

    def __init__(self, fname: str, data: object):
        if not isinstance(data, dict):
            raise SourceError(f"{fname}: the top level must be a JSON object (railjson infrastructure)")
        self.fname, self.data = fname, data

    def items(self, key: str, required: bool = False) -> list[dict]:
        v = self.data.get(key)
        if v is None:
            if required:
                raise SourceError(f"{self.fname}: {key}: missing; a railjson infrastructure lists its {key}")
            return []
        if not isinstance(v, list):
            raise SourceError(f"{self.fname}: {key}: must be a list")
        for i, x in enumerate(v):
            if not isinstance(x, dict):
                raise SourceError(f"{self.fname}: {key}[{i}]: must be an object")
        return v

    def where(self, key: str, i: int, obj: dict, field: str = "") -> str:
        ident = f" (id {obj.get('id')})" if obj.get("id") is not None else ""
        return f"{self.fname}: {key}[{i}]{ident}{': ' + field if field else ''}"

    def get(self, key: str, i: int, obj: dict, field: str):
        if field not in obj:
            raise SourceError(f"{self.where(key, i, obj, field)}: missing")
        return obj[field]


# --------------------------------------------------------------------------- topology and path
class _Network:
    def __init__(self, src: _Src):
        self.src = src
        self.tracks: dict[str, tuple[int, dict]] = {}
        for i, t in enumerate(src.items("track_sections", required=True)):
            tid = src.get("track_sections", i, t, "id")
            if tid in self.tracks:
                raise SourceError(f"{src.where('track_sections', i, t, 'id')}: duplicate track section id")
            number(src.get("track_sections", i, t, "length"), src.where("track_sections", i, t, "length"),
                   "the length of a track section in metres", positive=True)
            self.tracks[str(tid)] = (i, t)
        self.adj: dict[tuple[str, str], list[tuple[str, str]]] = {}
        types = {k: list(v) for k, v in SWITCH_LINKS.items()}
        for i, st in enumerate(src.items("extended_switch_types")):
            groups = st.get("groups") or {}
            try:
                types[str(st.get("id"))] = [(c["src"], c["dst"]) for g in groups.values() for c in g]
            except (AttributeError, KeyError, TypeError):
                raise SourceError(f"{src.where('extended_switch_types', i, st, 'groups')}: must map group names "
                                  f"to lists of {{\"src\": port, \"dst\": port}}") from None
        for i, sw in enumerate(src.items("switches")):
            kind = src.get("switches", i, sw, "switch_type")
            if kind not in types:
                raise SourceError(f"{src.where('switches', i, sw, 'switch_type')}: unknown switch type {kind!r}; "
                                  f"known: {', '.join(sorted(types))}")
            ports = src.get("switches", i, sw, "ports")
            for a, b in types[kind]:
                ea = self._endpoint(ports, a, src.where("switches", i, sw, f"ports.{a}"))
                eb = self._endpoint(ports, b, src.where("switches", i, sw, f"ports.{b}"))
                self.adj.setdefault(ea, []).append(eb)
                self.adj.setdefault(eb, []).append(ea)
        for i, ln in enumerate(src.items("track_section_links")):  # railjson before switch type "link"
            ea = self._endpoint(ln, "src", src.where("track_section_links", i, ln, "src"))
            eb = self._endpoint(ln, "dst", src.where("track_section_links", i, ln, "dst"))
            self.adj.setdefault(ea, []).append(eb)
            self.adj.setdefault(eb, []).append(ea)

    def _endpoint(self, ports: dict, port: str, where: str) -> tuple[str, str]:
        if not isinstance(ports, dict) or not isinstance(ports.get(port), dict):
            raise SourceError(f"{where}: missing; give {{\"track\": ..., \"endpoint\": \"BEGIN\"|\"END\"}}")
        p = ports[port]
        if p.get("track") not in self.tracks:
            raise SourceError(f"{where}.track: unknown track section {p.get('track')!r}")
        if p.get("endpoint") not in ("BEGIN", "END"):
            raise SourceError(f"{where}.endpoint: {p.get('endpoint')!r} is not BEGIN or END")
        return str(p["track"]), p["endpoint"]

    def length(self, track: str) -> float:
        return float(self.tracks[track][1]["length"])

    def locate(self, key: str, i: int, obj: dict) -> tuple[str, float]:
        track = self.src.get(key, i, obj, "track")
        if track not in self.tracks:
            raise SourceError(f"{self.src.where(key, i, obj, 'track')}: unknown track section {track!r}")
        pos = number(self.src.get(key, i, obj, "position"), self.src.where(key, i, obj, "position"),
                      "an offset in metres from the track section's BEGIN")
        if not 0 <= pos <= self.length(track):
            raise SourceError(f"{self.src.where(key, i, obj, 'position')}: {pos!r} is outside track section "
                              f"{track!r} (length {self.length(track)!r} m)")
        return track, pos

    def route(self, starts: list[tuple[str, float, str | None]], targets: list[tuple[str, float]]):
        """Shortest run from any start (track, pos, direction or None = either) to any target, no reversal.

        Returns (pieces, target, direction): pieces are (track, direction, from_pos, to_pos) in order.
        """
        heap: list = []
        prev: dict = {}
        best: dict = {}
        for track, pos, d in starts:
            for dd in ([d] if d else [INC, DEC]):
                heapq.heappush(heap, (0.0, len(prev), (track, dd, pos), None))
        count = 0
        while heap:
            cost, _, state, parent = heapq.heappop(heap)
            if state in best:
                continue
            best[state] = cost
            prev[state] = parent
            track, d, entry = state
            ahead = [(t, p) for t, p in targets if t == track and (p >= entry if d == INC else p <= entry)]
            if ahead:
                t, p = min(ahead, key=lambda tp: abs(tp[1] - entry))
                pieces = [(track, d, entry, p)]
                s = parent
                while s is not None:
                    (tr, dd, en), ex = s
                    pieces.append((tr, dd, en, ex))
                    s = prev[(tr, dd, en)]
                return pieces[::-1], (t, p), d
            exit_pos = self.length(track) if d == INC else 0.0
            end = (track, "END" if d == INC else "BEGIN")
            for t2, ep in self.adj.get(end, []):
                d2 = INC if ep == "BEGIN" else DEC
                nxt = (t2, d2, 0.0 if d2 == INC else self.length(t2))
                if nxt not in best:
                    count += 1
                    heapq.heappush(heap, (cost + abs(exit_pos - entry), len(prev) + count, nxt,
                                          (state, exit_pos)))
        return None


class _Path:
    """The line's track pieces in running order, and the chainage of any track position on them."""

    def __init__(self, pieces: list[tuple[str, str, float, float]]):
        self.pieces = []
        c = 0.0
        for track, d, a, b in pieces:
            self.pieces.append((track, d, a, b, c))
            c += abs(b - a)
        self.length = c

    def chainage(self, track: str, pos: float) -> float | None:
        for t, d, a, b, c0 in self.pieces:
            if t == track and min(a, b) <= pos <= max(a, b):
                return _r(c0 + (pos - a if d == INC else a - pos))
        return None

    def ranges(self, track: str, begin: float, end: float):
        """(chainage start, chainage end, direction) of the parts of [begin, end] on the path."""
        for t, d, a, b, c0 in self.pieces:
            if t != track:
                continue
            lo, hi = max(begin, min(a, b)), min(end, max(a, b))
            if hi > lo:
                ca, cb = (c0 + lo - a, c0 + hi - a) if d == INC else (c0 + a - hi, c0 + a - lo)
                yield _r(ca), _r(cb), d


def _ops(src: _Src, net: _Network, names: list[str]):
    """The --path points: (id, name, locations, is an operational point); a track section id stands for its
    whole section (a waypoint, not a station)."""
    from planner.line.model import did_you_mean

    by_id = {}
    for i, op in enumerate(src.items("operational_points")):
        by_id[str(op.get("id"))] = (i, op)
    out = []
    for n in names:
        if n not in by_id and n in net.tracks:
            out.append((n, n, [(n, 0.0), (n, net.length(n))], False))
            continue
        if n not in by_id:
            if not by_id:
                raise SourceError(f"{src.fname}: --path: {n!r}: this file has no operational points; name track "
                                  f"sections in --path{did_you_mean(n, net.tracks)} (track_sections ids) and add "
                                  f"stations with [stations.X] position_m in --extra")
            ids = sorted(by_id)
            listed = ", ".join(ids[:30]) + (f" … ({len(ids)} in all)" if len(ids) > 30 else "")
            raise SourceError(f"{src.fname}: --path: unknown operational point {n!r}{did_you_mean(n, ids)} "
                              f"(operational_points ids: {listed}; or a track section id)")
        i, op = by_id[n]
        parts = src.get("operational_points", i, op, "parts")
        if not isinstance(parts, list) or not parts:
            raise SourceError(f"{src.where('operational_points', i, op, 'parts')}: needs at least one part "
                              f"(track, position)")
        for k, p in enumerate(parts):
            if not isinstance(p, dict):
                raise SourceError(f"{src.fname}: operational_points[{i}].parts[{k}]: must be an object "
                                  f"{{\"track\", \"position\"}}")
        locs = [net.locate(f"operational_points[{i}].parts", k, p) for k, p in enumerate(parts)]
        name = ((op.get("extensions") or {}).get("identifier") or {}).get("name") or n
        out.append((n, str(name), locs, True))
    return out


def build_path(src: _Src, net: _Network, ops) -> tuple[_Path, dict[str, float]]:
    if len(ops) < 2:
        raise SourceError(f"{src.fname}: --path: name at least two operational points, in running order")
    seen = set()
    for n, *_ in ops:
        if n in seen:
            raise SourceError(f"{src.fname}: --path: operational point {n!r} appears twice")
        seen.add(n)
    pieces: list = []
    first = ops[0][2]
    starts = [(t, p, None) for t, p in first]
    at: dict[str, tuple[str, float]] = {}
    direction = None
    for (n1, *_), (n2, _, locs2, _) in zip(ops[:-1], ops[1:]):
        found = net.route(starts, locs2)
        if found is None:
            raise SourceError(f"{src.fname}: --path: no connected route from operational point {n1!r} to "
                              f"{n2!r} (without reversing); check the switches joining their track sections "
                              f"and the order of --path")
        run, target, direction = found
        if not pieces:
            t0, d0, a0, _ = run[0]
            at[n1] = (t0, a0)
            entry = 0.0 if d0 == INC else net.length(t0)
            run[0] = (t0, d0, entry, run[0][3])
        elif run[0][2] == pieces[-1][3] and run[0][0] == pieces[-1][0]:
            t, d, a, _ = pieces.pop()
            run[0] = (t, d, a, run[0][3])
        pieces += run
        at[n2] = target
        starts = [(target[0], target[1], direction)]
    t, d, a, _ = pieces[-1]
    pieces[-1] = (t, d, a, net.length(t) if d == INC else 0.0)
    tracks = [p[0] for p in pieces]
    for tr in tracks:
        if tracks.count(tr) > 1:
            raise SourceError(f"{src.fname}: --path: the route runs over track section {tr!r} twice; "
                              f"name operational points that make a simple line")
    path = _Path([p for p in pieces if p[2] != p[3] or len(pieces) == 1])
    return path, {n: path.chainage(*loc) for n, loc in at.items()}


# --------------------------------------------------------------------------- infrastructure tables
def _segments(src: _Src, net: _Network, path: _Path, key: str, value: str, s: ImportSummary) -> list[tuple]:
    rows = []
    for track, _, _, _, _ in path.pieces:
        i, t = net.tracks[track]
        items = t.get(key) or []
        if not isinstance(items, list):
            raise SourceError(f"{src.where('track_sections', i, t, key)}: must be a list")
        spans = []
        for k, it in enumerate(items):
            w = f"{src.where('track_sections', i, t, f'{key}[{k}]')}"
            if not isinstance(it, dict):
                raise SourceError(f"{w}: must be an object {{\"begin\", \"end\", \"{value}\"}}")
            b = number(it.get("begin"), f"{w}.begin", "an offset in metres")
            e = number(it.get("end"), f"{w}.end", "an offset in metres")
            v = number(it.get(value), f"{w}.{value}")
            if not 0 <= b < e <= net.length(track):
                raise SourceError(f"{w}: [{b!r}, {e!r}] must satisfy 0 <= begin < end <= the track section's "
                                  f"length {net.length(track)!r} m (offsets in metres)")
            if key == "slopes" and abs(v) > MAX_GRADIENT_PERMIL:
                raise SourceError(f"{w}.gradient: {v!r} is steeper than {MAX_GRADIENT_PERMIL:g}; railjson "
                                  f"gradients are in m/km (‰), not % or m/m")
            spans.append((b, e, k))
        spans.sort()
        for (b1, e1, k1), (b2, e2, k2) in zip(spans[:-1], spans[1:]):
            if b2 < e1:
                raise SourceError(f"{src.where('track_sections', i, t, f'{key}[{k2}]')}: [{b2!r}, {e2!r}] "
                                  f"overlaps {key}[{k1}] [{b1!r}, {e1!r}]; a track section has one "
                                  f"{value} at each offset")
        for k, it in enumerate(items):
            v = float(it[value])
            if key == "curves":
                if v == 0:
                    continue  # a radius of 0 marks straight track in some exports
                v = abs(v)  # the sign gives the side of the curve
            for ca, cb, d in path.ranges(track, float(it["begin"]), float(it["end"])):
                rows.append((ca, cb, (-v if d == DEC else v) if key == "slopes" else v))
    rows.sort()
    return rows


def _speed_limits(src: _Src, path: _Path, s: ImportSummary, categories: dict[str, str]) -> tuple[pd.DataFrame, set]:
    """speed_limits rows (general, and per train type through ``categories`` from speed_limit_by_tag), and the
    tags of the sections on the path."""
    rows, tags, higher = [], set(), 0
    for i, sec in enumerate(src.items("speed_sections")):
        by_tag = sec.get("speed_limit_by_tag") if isinstance(sec.get("speed_limit_by_tag"), dict) else {}
        v = sec.get("speed_limit")
        ranges = src.get("speed_sections", i, sec, "track_ranges")
        if not isinstance(ranges, list):
            raise SourceError(f"{src.where('speed_sections', i, sec, 'track_ranges')}: must be a list")
        on_path = []
        for k, r in enumerate(ranges):
            w = src.where("speed_sections", i, sec, f"track_ranges[{k}]")
            if not isinstance(r, dict):
                raise SourceError(f"{w}: must be an object {{\"track\", \"begin\", \"end\", ...}}")
            b, e = number(r.get("begin"), f"{w}.begin"), number(r.get("end"), f"{w}.end")
            ad = r.get("applicable_directions", "BOTH")
            if ad not in ("BOTH", INC, DEC):
                raise SourceError(f"{w}.applicable_directions: {ad!r} is not BOTH, {INC} or {DEC}")
            for ca, cb, d in path.ranges(str(r.get("track")), b, e):
                dirn = "both" if ad == "BOTH" else ("down" if ad == d else "up")
                on_path.append((ca, cb, dirn))
        if not on_path:
            continue
        tags |= set(by_tag)
        limits = {None: v} if v is not None else {}  # train type (None = every one) -> m/s
        limits.update({typ: by_tag[tag] for typ, tag in categories.items() if tag in by_tag})
        for typ, x in limits.items():
            field = "speed_limit" if typ is None else f"speed_limit_by_tag.{categories[typ]}"
            x = number(x, src.where("speed_sections", i, sec, field), positive=True)
            if x > MAX_SPEED_MS:
                raise SourceError(f"{src.where('speed_sections', i, sec, field)}: {x!r} m/s is "
                                  f"{x * 3.6:.0f} km/h; railjson speeds are in m/s: was it given in km/h?")
            if typ is not None and v is not None and x >= float(v):
                higher += x > float(v)
                continue
            for ca, cb, dirn in on_path:
                rows.append(dict(start_m=ca, end_m=cb, limit_kmh=_r(x * 3.6), direction=dirn, train_type=typ,
                                 kind=s.default("speed_limit_kind", str(sec.get("id"))),
                                 has_beacon=s.default("has_beacon", str(sec.get("id")))))
    if higher:
        s.notes.append(f"{higher} tag speeds above their section's speed_limit: the lower (speed_limit) holds")
    pairs = ", ".join(sorted(f"{t} = {g}" for t, g in categories.items()))
    s.notes += [f"per-train-type speed limits from speed_limit_by_tag: {pairs}"] if categories else []
    rows.sort(key=lambda r: (r["start_m"], r["end_m"], r["train_type"] or ""))
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["speed_limits"].schema]), tags


def _points(src: _Src, net: _Network, path: _Path, key: str, located: dict[str, float]) -> list[tuple]:
    out = []
    for i, obj in enumerate(src.items(key)):
        track, pos = net.locate(key, i, obj)
        c = path.chainage(track, pos)
        if c is None:
            continue
        d = None
        if key == "signals":
            sd = src.get(key, i, obj, "direction")
            if sd not in (INC, DEC):
                raise SourceError(f"{src.where(key, i, obj, 'direction')}: {sd!r} is not {INC} or {DEC}")
            piece_dir = next(p[1] for p in path.pieces if p[0] == track)
            d = "down" if sd == piece_dir else "up"
        oid = str(src.get(key, i, obj, "id"))
        located[oid] = c
        out.append((oid, c, d))
    return out


# --------------------------------------------------------------------------- rolling stock
def import_railjson(infra: str | Path, path_ops: list[str], rolling_stock: list, out: str | Path, *,
                    extra: str | Path | None = None, line_id: str | None = None,
                    force: bool = False, categories: list[str] | None = None) -> ImportSummary:
    """Import the line along ``path_ops`` of the railjson ``infra`` into the line database ``out``.

    ``categories`` are ``TYPE=TAG`` mappings (``--category``): train type TYPE takes the
    ``speed_limit_by_tag`` limits of TAG.
    """
    fname, data = load_json(infra)
    s = ImportSummary(source=str(infra), extra=load_extras(extra))
    cats = category_map(s, categories)
    src = _Src(fname, data)
    net = _Network(src)
    ops = _ops(src, net, path_ops)
    path, at = build_path(src, net, ops)
    op_at = {n: at[n] for n, _, _, is_op in ops if is_op}
    located: dict[str, float] = dict(op_at)
    gradients = pd.DataFrame(_segments(src, net, path, "slopes", "gradient", s),
                             columns=["start_m", "end_m", "gradient_permil"])
    curves = pd.DataFrame(_segments(src, net, path, "curves", "radius", s), columns=["start_m", "end_m", "radius_m"])
    limits, tags = _speed_limits(src, path, s, cats)
    signals = pd.DataFrame(_points(src, net, path, "signals", located),
                           columns=["signal_id", "position_m", "direction"]).sort_values(
                               ["position_m", "signal_id"], kind="stable")
    detectors = _points(src, net, path, "detectors", located)
    if detectors:
        s.notes.append(f"{len(detectors)} detectors on the path: schema v1 has no train-detection table; "
                       f"name them in [[beacons]] at = ... where an ATS-P beacon stands")
    rs, traction = rolling_stock_tables(rolling_stock, s)
    stations = station_table([dict(source_id=n, name=name, position_m=op_at[n]) for n, name, _, is_op in ops
                              if is_op], 0.0, path.length, s, float(rs["length_m"].max()) if len(rs) else 0.0)
    if len(stations) < 2:
        raise SourceError(f"{src.fname}: --path: {len(stations)} operational point(s) on the path; a line needs two "
                          f"stations: add stations with [stations.X] position_m in --extra (chainage 0 … "
                          f"{path.length:g} m from the first track section's entry)")
    check_categories(cats, rs, tags, "speed tag", s)
    default_id = line_id or (s.extra.line.get("line_id") if s.extra else None)
    if default_id is None:  # two paths of one file never share an id
        default_id = path_id(f"{Path(infra).stem}_{path_ops[0]}_{path_ops[-1]}")
        s.default("line_id", default_id)
    tables = {
        "line": line_table(str(default_id), 0.0, _r(path.length), s),
        "stations": stations,
        "gradients": gradients,
        "curves": curves,
        "speed_limits": limits,
        "beacons": beacon_table(located, s),
        "signals": signals,
        "rolling_stock": rs,
        "traction": traction,
        "timetable": timetable_table(s),
    }
    from planner.line.importers.network import railjson_network, stops_of

    tables["nodes"], tables["edges"] = railjson_network(src, net, path.pieces, [n for n, *_, is_op in ops if is_op],
                                                        s.extra, str(default_id), s.notes, stops_of(stations))
    return write_line(tables, out, s, force=force)
