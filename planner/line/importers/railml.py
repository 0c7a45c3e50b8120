"""railML 2.x → line database: the tracks of one ``<line>`` of ``<trackGroups>``, in sequence.

railML 2 (the European XML exchange format, schema namespaces
``http://www.railml.org/schemas/20xx``) locates everything on ``<track>`` elements by
``pos`` [m] from the track's ``<trackBegin>`` towards its ``<trackEnd>``; ``dir="up"``
means valid for trains running that way (increasing ``pos``), ``dir="down"`` the other
way. What this reader takes, per track of the line:

- ``trackTopology``: ``trackBegin``/``trackEnd`` (their ``pos`` give the length; the
  ``trackEnd``'s ``<connection ref>`` must name the ``<connection>`` in the next track's
  ``trackBegin``), ``crossSections/crossSection[@ocpRef]`` (where an OCP lies);
- ``trackElements``: ``gradientChanges/gradientChange[@pos, @slope ‰]`` (the slope holds
  from ``pos`` to the next change; the first change must be at the track begin, a track
  without any is level and listed as a default), ``radiusChanges/radiusChange[@pos,
  @radius m]`` (0 = straight; before the first change straight), ``speedChanges/
  speedChange[@pos, @dir, @vMax km/h]`` (the limit holds in ``dir`` until the next change
  met in that direction, across track boundaries; ``vMax="end"`` or 999.9 ends a
  restriction), ``platformEdges/platformEdge[@ocpRef, @length]``;
- ``ocsElements``: ``signals/signal[@dir]`` of ``type`` main or combined (block
  boundaries; others are counted in the notes), ``balises/balise[@dir]`` (beacons; kind,
  telegram and evaluation point from the TOML or defaults), ``trainDetectionElements/
  trainDetector`` (positions for ``[[beacons]] at``), ``stopPosts/stopPost[@dir,
  @ocpStationRef]`` (stop markers).

Stations are the ``operationControlPoints/ocp`` that a crossSection puts on the line.
Chainage starts at 0 at the first track's begin and adds the tracks' lengths; every
track runs begin → end, so railML ``up`` is the planner's ``down``. railML 3.x (a
different topology model, netElements and linear locations) is not read.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd

from planner.errors import SourceError
from planner.line.schema import MAX_GRADIENT_PERMIL, TABLES
from planner.line.importers.common import (
    ImportSummary,
    beacon_table,
    line_table,
    load_extras,
    number,
    station_table,
    timetable_table,
    write_line,
)
from planner.line.importers.railjson import rolling_stock_tables

END_SPEEDS = {"end", "999.9"}
"""vMax values that end a (temporary) restriction rather than set a limit."""
_DIRS = {"up": "down", "down": "up"}  # railML dir (track orientation) → planner direction (chainage)


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _children(el: ET.Element | None, *path: str) -> list[ET.Element]:
    """Descendants along ``path`` of local names (namespace-agnostic)."""
    level = [el] if el is not None else []
    for name in path:
        level = [c for e in level for c in e if _local(c.tag) == name]
    return level


class _Doc:
    def __init__(self, path: str | Path):
        p = Path(path)
        self.fname = p.name
        try:
            self.root = ET.parse(p).getroot()
        except FileNotFoundError:
            raise SourceError(f"{p}: file does not exist") from None
        except ET.ParseError as e:
            line, col = e.position
            raise SourceError(f"{p.name} line {line} column {col + 1}: not well-formed XML ({e.msg if hasattr(e, 'msg') else e})") \
                from None
        if _local(self.root.tag) != "railml":
            raise SourceError(f"{p.name}: root element <{_local(self.root.tag)}> is not <railml>")
        ns = self.root.tag[1:].split("}")[0] if self.root.tag.startswith("{") else ""
        if "railml.org/schemas/3" in ns or self.root.get("version", "").startswith("3"):
            raise SourceError(f"{p.name}: railML 3.x is not supported (netElements); export railML 2.x")
        infra = _children(self.root, "infrastructure")
        if not infra:
            raise SourceError(f"{p.name}: <infrastructure> is missing")
        self.infra = infra[0]

    def where(self, el: ET.Element, attr: str = "") -> str:
        ident = el.get("id")
        s = f"{self.fname}: <{_local(el.tag)}{' id=' + repr(ident) if ident else ''}>"
        return f"{s} @{attr}" if attr else s

    def attr(self, el: ET.Element, name: str) -> str:
        v = el.get(name)
        if v is None:
            raise SourceError(f"{self.where(el, name)}: missing")
        return v

    def num(self, el: ET.Element, name: str, fix: str = "", **kw) -> float:
        return number(self.attr(el, name), self.where(el, name), fix, **kw)

    def ident(self, el: ET.Element) -> str:
        return self.attr(el, "id")


class _Track:
    def __init__(self, doc: _Doc, el: ET.Element, offset: float):
        self.doc, self.el, self.id = doc, el, doc.ident(el)
        begin = _children(el, "trackTopology", "trackBegin")
        end = _children(el, "trackTopology", "trackEnd")
        if not begin or not end:
            raise SourceError(f"{doc.where(el)}: trackTopology needs a trackBegin and a trackEnd")
        self.begin_el, self.end_el = begin[0], end[0]
        self.begin = doc.num(self.begin_el, "pos", "metres from the track begin")
        self.end = doc.num(self.end_el, "pos", "metres from the track begin")
        if not self.end > self.begin:
            raise SourceError(f"{doc.where(self.end_el, 'pos')}: {self.end!r} must be greater than the trackBegin's "
                              f"pos {self.begin!r}")
        self.offset = offset

    @property
    def length(self) -> float:
        return self.end - self.begin

    def chainage(self, el: ET.Element) -> float:
        pos = self.doc.num(el, "pos", "metres from the track begin")
        if not self.begin <= pos <= self.end:
            raise SourceError(f"{self.doc.where(el, 'pos')}: {pos!r} is outside track {self.id!r} "
                              f"[{self.begin!r}, {self.end!r}] (pos is in metres from the track begin)")
        return round(self.offset + pos - self.begin, 9)

    def items(self, *path: str) -> list[ET.Element]:
        return _children(self.el, *path)


def _line_tracks(doc: _Doc, line_id: str) -> tuple[ET.Element, list[_Track]]:
    lines = [ln for ln in _children(doc.infra, "trackGroups", "line")]
    found = [ln for ln in lines if ln.get("id") == line_id]
    if not found:
        ids = ", ".join(sorted(str(ln.get("id")) for ln in lines)) or "none"
        raise SourceError(f"{doc.fname}: --line: no <line id={line_id!r}> in <trackGroups> (lines: {ids})")
    line = found[0]
    refs = _children(line, "trackRef")
    if not refs:
        raise SourceError(f"{doc.where(line)}: has no <trackRef>; list the line's tracks in sequence")
    by_id = {doc.ident(t): t for t in _children(doc.infra, "tracks", "track")}
    order = []
    for r in refs:
        ref = doc.attr(r, "ref")
        if ref not in by_id:
            raise SourceError(f"{doc.where(line)} <trackRef ref={ref!r}>: no <track id={ref!r}> in <tracks>")
        seq = r.get("sequence")
        order.append((number(seq, doc.where(r, "sequence")) if seq is not None else len(order), ref))
    order.sort()
    tracks, offset = [], 0.0
    for _, ref in order:
        t = _Track(doc, by_id[ref], offset)
        tracks.append(t)
        offset += t.length
    for a, b in zip(tracks[:-1], tracks[1:]):
        out_ids = {c.get("ref") for c in _children(a.end_el, "connection")}
        in_ids = {c.get("id") for c in _children(b.begin_el, "connection")}
        if not out_ids & in_ids:
            raise SourceError(f"{doc.where(a.end_el)}: track {a.id!r} is not connected to the next track of line "
                              f"{line_id!r}, {b.id!r}: its trackEnd <connection ref> must name the <connection> "
                              f"in {b.id!r}'s trackBegin")
    return line, tracks


def _profile(doc: _Doc, tracks: list[_Track], kind: str, s: ImportSummary) -> list[tuple]:
    """Gradient or radius segments (start_m, end_m, value) over the line."""
    group, elem, attr = {"gradient": ("gradientChanges", "gradientChange", "slope"),
                         "radius": ("radiusChanges", "radiusChange", "radius")}[kind]
    rows = []
    for t in tracks:
        changes = []
        for el in t.items("trackElements", group, elem):
            d = el.get("dir")
            if kind == "gradient" and d not in (None, "up", "both"):
                raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give slopes in track orientation "
                                  f"(dir up or no dir), positive = rising towards the trackEnd")
            v = doc.num(el, attr, "‰" if kind == "gradient" else "metres")
            if kind == "gradient" and abs(v) > MAX_GRADIENT_PERMIL:
                raise SourceError(f"{doc.where(el, attr)}: {v!r} is steeper than {MAX_GRADIENT_PERMIL:g}; railML "
                                  f"slopes are in ‰ (per mille), not % or m/m")
            changes.append((t.chainage(el), v, el))
        changes.sort(key=lambda c: c[0])
        for (c1, v1, e1), (c2, v2, e2) in zip(changes[:-1], changes[1:]):
            if c1 == c2 and v1 != v2:
                raise SourceError(f"{doc.where(e2, 'pos')}: {kind} changes {e1.get('id')!r} and {e2.get('id')!r} "
                                  f"overlap at the same pos with {v1!r} and {v2!r}; keep one")
        end = round(t.offset + t.length, 9)
        if not changes:
            if kind == "gradient":
                g = number(s.default("missing_gradient", t.id), "[defaults] missing_gradient")
                if g != 0:
                    rows.append((round(t.offset, 9), end, g))
            continue
        if kind == "gradient" and changes[0][0] != round(t.offset, 9):
            raise SourceError(f"{doc.where(changes[0][2], 'pos')}: the first gradientChange of track {t.id!r} must "
                              f"be at its trackBegin (pos {t.begin!r}): the gradient before it is unknown (a gap)")
        for k, (c, v, _) in enumerate(changes):
            nxt = changes[k + 1][0] if k + 1 < len(changes) else end
            if nxt > c and v != 0:
                rows.append((c, nxt, abs(v) if kind == "radius" else v))
    return rows


def _speed_limits(doc: _Doc, tracks: list[_Track], length: float, s: ImportSummary) -> pd.DataFrame:
    changes = {"down": [], "up": []}
    for t in tracks:
        for el in t.items("trackElements", "speedChanges", "speedChange"):
            d = doc.attr(el, "dir")
            if d not in _DIRS:
                raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give one speedChange per direction, dir up or "
                                  f"down (the direction of travel it applies to)")
            raw = doc.attr(el, "vMax")
            v = None if raw.strip() in END_SPEEDS else doc.num(el, "vMax", "km/h, or 'end'", positive=True)
            changes[_DIRS[d]].append((t.chainage(el), v, el))
    rows = []
    for direction, ch in changes.items():
        ch.sort(key=lambda c: c[0], reverse=direction == "up")
        for (c1, _, e1), (c2, _, e2) in zip(ch[:-1], ch[1:]):
            if c1 == c2:
                raise SourceError(f"{doc.where(e2, 'pos')}: speedChanges {e1.get('id')!r} and {e2.get('id')!r} "
                                  f"for the same direction at the same position; keep one")
        for k, (c, v, el) in enumerate(ch):
            nxt = ch[k + 1][0] if k + 1 < len(ch) else (length if direction == "down" else 0.0)
            if v is None or nxt == c:
                continue
            rows.append(dict(start_m=min(c, nxt), end_m=max(c, nxt), limit_kmh=v, direction=direction,
                             train_type=None, kind=s.default("speed_limit_kind", el.get("id")),
                             has_beacon=s.default("has_beacon", el.get("id"))))
    rows.sort(key=lambda r: (r["start_m"], r["end_m"], r["direction"]))
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["speed_limits"].schema])


def _direction(doc: _Doc, el: ET.Element) -> str:
    d = doc.attr(el, "dir")
    if d not in _DIRS:
        raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give up or down (the trains it applies to)")
    return _DIRS[d]


def import_railml(file: str | Path, line_id: str, rolling_stock: list, out: str | Path, *,
                  extra: str | Path | None = None, force: bool = False) -> ImportSummary:
    """Import the railML 2.x ``<line id=line_id>`` of ``file`` into the line database ``out``."""
    doc = _Doc(file)
    s = ImportSummary(source=str(file), extra=load_extras(extra))
    line_el, tracks = _line_tracks(doc, line_id)
    length = round(sum(t.length for t in tracks), 9)
    located: dict[str, float] = {}

    gradients = pd.DataFrame(_profile(doc, tracks, "gradient", s), columns=["start_m", "end_m", "gradient_permil"])
    curves = pd.DataFrame(_profile(doc, tracks, "radius", s), columns=["start_m", "end_m", "radius_m"])
    limits = _speed_limits(doc, tracks, length, s)

    signals, skipped = [], 0
    for t in tracks:
        for el in t.items("ocsElements", "signals", "signal"):
            located[doc.ident(el)] = c = t.chainage(el)
            if el.get("type", "main") not in ("main", "combined"):
                skipped += 1
                continue
            signals.append((doc.ident(el), c, _direction(doc, el)))
    if skipped:
        s.notes.append(f"{skipped} signals not of type main/combined (distant, repeater, shunting) are not block "
                       f"boundaries: not imported")
    balises = []
    for t in tracks:
        for el in t.items("ocsElements", "balises", "balise"):
            bid = doc.ident(el)
            located[bid] = c = t.chainage(el)
            balises.append(dict(beacon_id=bid, position_m=c, direction=_direction(doc, el)))
        for el in t.items("ocsElements", "trainDetectionElements", "trainDetector"):
            located[doc.ident(el)] = t.chainage(el)

    ocps = {doc.ident(o): o for o in _children(doc.infra, "operationControlPoints", "ocp")}
    found: dict[str, dict] = {}
    for t in tracks:
        for el in t.items("trackTopology", "crossSections", "crossSection"):
            ref = el.get("ocpRef")
            if ref is None:
                continue
            if ref not in ocps:
                raise SourceError(f"{doc.where(el, 'ocpRef')}: no <ocp id={ref!r}> in <operationControlPoints>")
            if ref not in found:
                found[ref] = dict(source_id=ref, name=ocps[ref].get("name") or ref, position_m=t.chainage(el))
    if len(found) < 2:
        raise SourceError(f"{doc.where(line_el)}: fewer than two OCPs on the line (crossSection ocpRef); a line "
                          f"needs at least two stations")
    for t in tracks:
        for el in t.items("trackElements", "platformEdges", "platformEdge"):
            ref = el.get("ocpRef")
            if ref in found and el.get("length") is not None:
                found[ref].setdefault("platform_length_m", doc.num(el, "length", "metres", positive=True))
        for el in t.items("ocsElements", "stopPosts", "stopPost"):
            ref = el.get("ocpStationRef")
            if ref is None:
                continue
            if ref not in found:
                raise SourceError(f"{doc.where(el, 'ocpStationRef')}: {ref!r} is not an OCP on line {line_id!r}")
            key = "stop_down_m" if _direction(doc, el) == "down" else "stop_up_m"
            found[ref].setdefault(key, t.chainage(el))
    located.update({k: v["position_m"] for k, v in found.items()})

    rs, traction = rolling_stock_tables(rolling_stock, s)
    lid = (s.extra.line.get("line_id") if s.extra else None) or line_id
    tables = {
        "line": line_table(str(lid), 0.0, length, s),
        "stations": station_table(list(found.values()), 0.0, length, s),
        "gradients": gradients,
        "curves": curves,
        "speed_limits": limits,
        "beacons": beacon_table(located, s, balises),
        "signals": pd.DataFrame(sorted(signals, key=lambda r: (r[1], r[0])),
                                columns=["signal_id", "position_m", "direction"]),
        "rolling_stock": rs,
        "traction": traction,
        "timetable": timetable_table(s),
    }
    return write_line(tables, out, s, force=force)
