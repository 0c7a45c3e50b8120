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

Stations are the ``operationControlPoints/ocp`` that a crossSection puts on the line, and
any ``[stations.X] position_m`` of the ``--extra`` TOML. Every track runs begin → end, so
railML ``up`` is the planner's ``down``. Chainage is the railway's own kilometre posts:
``absPos`` of the trackBegin plus ``pos`` from it, when every track of the line has an
``absPos`` on both ends that runs on continuously (so stations, beacons and timetables
given by km post land where the railway's documents put them); otherwise it starts at 0
at the first track's begin and adds the tracks' lengths (said in a note).

Exports in the wild deviate from the schema; what is unambiguous is accepted with a
note each: ``<trackRef id=…>`` for ``ref``; a trackEnd whose connection names no track
of the line, bridged where the absPos runs on (or the missing track found through its
connections and inserted); an element whose ``pos`` lies past its track's end, placed by
its ``absPos``; a file whose speedChanges are all for one direction (the limits hold for
both). Per-train-category speeds (a speedChange's ``profileRef`` to
``infraAttrGroups/infraAttributes/speeds/speed[@trainCategory, @vMax]``) become
per-train-type limits through ``--category TYPE=CATEGORY``. Every element-level problem
of a file is reported in one run. railML 3.x (a different topology model, netElements
and linear locations) is not read.
"""
from __future__ import annotations

import contextlib
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd

from planner.errors import SourceError
from planner.line.schema import MAX_GRADIENT_PERMIL, TABLES
from planner.line.importers.common import (
    ImportSummary,
    Problems,
    beacon_table,
    category_map,
    check_categories,
    line_table,
    load_extras,
    number,
    path_id,
    station_table,
    write_line,
)
from planner.line.importers.railml_group import connected, stations_on, through_route
from planner.line.importers.stock import rolling_stock_tables
from planner.line.importers.timetable import railml_or_toml_timetable

END_SPEEDS = {"end", "999.9"}
"""vMax values that end a (temporary) restriction rather than set a limit."""
_DIRS = {"up": "down", "down": "up"}  # railML dir (track orientation) → planner direction (chainage)
ABS_TOL_M = 0.001
"""absPos and pos agree to this [m] (exports write whole metres or millimetres)."""


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
        self.problems = Problems(p.name)
        self.past_end: list[str] = []  # elements placed by absPos although their pos lies past their track
        self.off_line: list[str] = []  # elements that pos and absPos both put beyond the line's ends
        try:
            self.root = ET.parse(p).getroot()
        except FileNotFoundError:
            raise SourceError(f"{p}: file does not exist") from None
        except ET.ParseError as e:
            line, col = e.position
            raise SourceError(f"{p.name} line {line} column {col + 1}: not well-formed XML ({e.msg if hasattr(e, 'msg') else e})") \
                from None
        ns = self.root.tag[1:].split("}")[0] if self.root.tag.startswith("{") else ""
        if _local(self.root.tag).lower() == "railml" and ("railml.org/schemas/3" in ns
                                                          or self.root.get("version", "").startswith("3")):
            raise SourceError(f"{p.name}: railML 3.x is not supported (netElements); export railML 2.x")
        if _local(self.root.tag) != "railml":
            raise SourceError(f"{p.name}: root element <{_local(self.root.tag)}> is not <railml>")
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

    @contextlib.contextmanager
    def each(self):
        """Context for reading one element: a problem is collected, the file read on (all reported at once);
        an element that lies off the line by its own absPos is skipped and counted."""
        with self.problems.each():
            try:
                yield
            except _OffLine as e:
                self.off_line.append(str(e))


class _OffLine(Exception):
    """An element whose pos runs past its track and whose absPos (consistent with it) lies off the line."""


class _Track:
    def __init__(self, doc: _Doc, el: ET.Element):
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
        ab, ae = self.begin_el.get("absPos"), self.end_el.get("absPos")
        self.abs_begin = number(ab, doc.where(self.begin_el, "absPos"), "metres (km post)") if ab is not None else None
        self.abs_end = number(ae, doc.where(self.end_el, "absPos"), "metres (km post)") if ae is not None else None
        self.offset = 0.0
        self.line: "_Line | None" = None

    @property
    def length(self) -> float:
        return self.end - self.begin

    @property
    def abs_ok(self) -> bool:
        """absPos on both ends, increasing with pos and as far apart as the pos values."""
        return (self.abs_begin is not None and self.abs_end is not None
                and abs((self.abs_end - self.abs_begin) - self.length) <= ABS_TOL_M)

    def chainage(self, el: ET.Element) -> float:
        pos = self.doc.num(el, "pos", "metres from the track begin")
        if self.begin <= pos <= self.end:
            return round(self.offset + pos - self.begin, 9)
        ab = el.get("absPos")
        line = self.line
        if ab is not None and line is not None and line.by_abs:
            a = number(ab, self.doc.where(el, "absPos"), "metres (km post)")
            if line.start <= a <= line.end:
                self.doc.past_end.append(f"{el.get('id')} ({self.id} pos {pos:g} → absPos {a:g})")
                return round(a, 9)
            if abs(a - (self.offset + pos - self.begin)) <= ABS_TOL_M:  # pos and absPos agree: beyond the line
                raise _OffLine(f"{el.get('id')} (absPos {a:g})")
        raise SourceError(f"{self.doc.where(el, 'pos')}: {pos!r} is outside track {self.id!r} "
                          f"[{self.begin!r}, {self.end!r}] (pos is in metres from the track begin)"
                          + ("" if ab is None else f" and its absPos {ab} is off the line"))

    def items(self, *path: str) -> list[ET.Element]:
        return _children(self.el, *path)


class _Line:
    """The line's tracks in running order, and its chainage: absPos (km posts) or from 0."""

    def __init__(self, tracks: list[_Track], by_abs: bool):
        self.tracks, self.by_abs = tracks, by_abs
        offset = tracks[0].abs_begin if by_abs else 0.0
        for t in tracks:
            t.offset, t.line = (t.abs_begin if by_abs else offset), self
            offset += t.length
        self.start = round(tracks[0].offset, 9)
        self.end = round(tracks[-1].offset + tracks[-1].length, 9)


_connected = connected


def _bridges(doc: _Doc, a: _Track, b: _Track, all_tracks, in_line: set) -> list[_Track]:
    """The tracks outside the line whose begin ``a``'s end connects to and whose end connects to ``b``'s begin."""
    out = []
    for el in (e for e in all_tracks if e.get("id") is not None and e.get("id") not in in_line):
        try:
            t = _Track(doc, el)
        except SourceError:
            continue
        out += [t] if _connected(a, t) and _connected(t, b) else []
    return out


def _line_tracks(doc: _Doc, line_id: str, s: ImportSummary) -> tuple[ET.Element, _Line]:
    from planner.line.model import did_you_mean

    lines = [ln for ln in _children(doc.infra, "trackGroups", "line")]
    found = [ln for ln in lines if ln.get("id") == line_id]
    if not found:
        ids = sorted(str(ln.get("id")) for ln in lines)
        raise SourceError(f"{doc.fname}: --line: no <line id={line_id!r}> in <trackGroups>{did_you_mean(line_id, ids)} "
                          f"(lines: {', '.join(ids) or 'none'})")
    line = found[0]
    refs = _children(line, "trackRef")
    if not refs:
        raise SourceError(f"{doc.where(line)}: has no <trackRef>; list the line's tracks in sequence")
    all_tracks = _children(doc.infra, "tracks", "track")
    by_id = {t.get("id"): t for t in all_tracks if t.get("id") is not None}
    order, by_id_attr = [], []
    for r in refs:
        with doc.each():
            ref = r.get("ref")
            if ref is None and r.get("id") in by_id:  # exporters that write id= where the schema has ref=
                ref = r.get("id")
                by_id_attr.append(ref)
            if ref is None:
                raise SourceError(f"{doc.where(r, 'ref')}: missing (the id of a <track> of the line)")
            if ref not in by_id:
                raise SourceError(f"{doc.where(line)} <trackRef ref={ref!r}>: no <track id={ref!r}> in "
                                  f"<tracks>{did_you_mean(ref, by_id)}")
            seq = r.get("sequence")
            order.append((number(seq, doc.where(r, "sequence")) if seq is not None else len(order), ref))
    if by_id_attr:
        s.notes.append(f"{len(by_id_attr)} <trackRef> of line {line_id!r} name their track with @id instead of "
                       f"@ref (the schema's attribute): taken as ref")
    order.sort(key=lambda o: o[0])
    tracks = []
    for _, ref in order:
        with doc.each():
            tracks.append(_Track(doc, by_id[ref]))
    doc.problems.check()
    in_line = {t.id for t in tracks}
    runs_on = lambda ts: all(t.abs_ok for t in ts) and all(  # noqa: E731
        abs(b.abs_begin - a.abs_end) <= ABS_TOL_M for a, b in zip(ts[:-1], ts[1:]))
    by_abs = runs_on(tracks)
    if not by_abs and not all(_connected(a, b) or len(_bridges(doc, a, b, all_tracks, in_line)) == 1
                              for a, b in zip(tracks[:-1], tracks[1:])):
        route = through_route(tracks)
        on_route = set().union(*(stations_on(t) for t in route)) if route else set()
        left_out = set().union(*(stations_on(t) for t in tracks if t not in route))
        # a station area's tracks listed as a group: its through route is the line; a chain with a gap (a
        # station on a track left out) is not, and is refused below as before
        if route and left_out <= on_route:
            rest = [t.id for t in tracks if t not in route]
            s.notes.append(f"line {line_id!r} lists {len(tracks)} tracks that do not run on one from the next (a "
                           f"station area's tracks as a group): its through route {' → '.join(t.id for t in route)}"
                           f" is the line, the other tracks ({', '.join(rest)}) the network around it")
            tracks, in_line = route, {t.id for t in route}
            by_abs = runs_on(tracks)
    if not by_abs:
        why = next((f"track {t.id!r} has no absPos on both ends, or one that disagrees with its length"
                    for t in tracks if not t.abs_ok), "the absPos values do not run on from track to track")
        s.notes.append(f"chainage from 0 at the first trackBegin, adding the tracks' lengths ({why}); km posts "
                       f"(absPos) are not used")
    seq: list[_Track] = [tracks[0]]
    for b in tracks[1:]:
        a = seq[-1]
        with doc.each():
            if _connected(a, b):
                seq.append(b)
                continue
            if by_abs:  # the absPos runs on: the sequence is unambiguous whatever the connection says
                seq.append(b)
                refs_out = ", ".join(sorted(str(c.get("ref")) for c in _children(a.end_el, "connection"))) or "none"
                s.notes.append(f"track {a.id!r}'s trackEnd connects to {refs_out}, not to the next track of line "
                               f"{line_id!r}, {b.id!r}; joined because absPos runs on ({a.abs_end:g} m = "
                               f"{b.abs_begin:g} m)")
                continue
            between = _bridges(doc, a, b, all_tracks, in_line)
            if len(between) == 1:
                seq += between + [b]
                s.notes.append(f"track {between[0].id!r} (not a trackRef of line {line_id!r}) joins {a.id!r} and "
                               f"{b.id!r} through their connections: inserted")
                continue
            raise SourceError(f"{doc.where(a.end_el)}: track {a.id!r} is not connected to the next track of line "
                              f"{line_id!r}, {b.id!r}: its trackEnd <connection ref> must name the <connection> "
                              f"in {b.id!r}'s trackBegin (no absPos runs on, and no single track joins them)")
        seq.append(b)  # reached only after a problem: check the rest of the sequence too
    doc.problems.check()
    return line, _Line(seq, by_abs)


def _profile(doc: _Doc, line: _Line, kind: str, s: ImportSummary) -> list[tuple]:
    """Gradient or radius segments (start_m, end_m, value) over the line."""
    group, elem, attr = {"gradient": ("gradientChanges", "gradientChange", "slope"),
                         "radius": ("radiusChanges", "radiusChange", "radius")}[kind]
    rows = []
    for t in line.tracks:
        changes = []
        for el in t.items("trackElements", group, elem):
            with doc.each():
                d = el.get("dir")
                if kind == "gradient" and d not in (None, "up", "both"):
                    raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give slopes in track orientation "
                                      f"(dir up or no dir), positive = rising towards the trackEnd")
                v = doc.num(el, attr, "‰" if kind == "gradient" else "metres")
                if kind == "gradient" and abs(v) > MAX_GRADIENT_PERMIL:
                    raise SourceError(f"{doc.where(el, attr)}: {v!r} is steeper than {MAX_GRADIENT_PERMIL:g}; "
                                      f"railML slopes are in ‰ (per mille), not % or m/m")
                changes.append((t.chainage(el), v, el))
        changes.sort(key=lambda c: c[0])
        for (c1, v1, e1), (c2, v2, e2) in zip(changes[:-1], changes[1:]):
            if c1 == c2 and v1 != v2:
                with doc.each():
                    raise SourceError(f"{doc.where(e2, 'pos')}: {kind} changes {e1.get('id')!r} and "
                                      f"{e2.get('id')!r} overlap at the same pos with {v1!r} and {v2!r}; keep one")
        end = round(t.offset + t.length, 9)
        if not changes:
            if kind == "gradient":
                g = number(s.default("missing_gradient", t.id), "[defaults] missing_gradient")
                if g != 0:
                    rows.append((round(t.offset, 9), end, g))
            continue
        if kind == "gradient" and changes[0][0] != round(t.offset, 9):
            with doc.each():
                raise SourceError(f"{doc.where(changes[0][2], 'pos')}: the first gradientChange of track {t.id!r} "
                                  f"must be at its trackBegin (pos {t.begin!r}): the gradient before it is unknown "
                                  f"(a gap)")
        for k, (c, v, _) in enumerate(changes):
            nxt = changes[k + 1][0] if k + 1 < len(changes) else end
            if nxt > c and v != 0:
                rows.append((c, nxt, abs(v) if kind == "radius" else v))
    return rows


def _category_speeds(doc: _Doc) -> dict[str, dict[str, float]]:
    """Speed profiles by id: ``infraAttrGroups/infraAttributes[@id]/speeds/speed[@trainCategory, @vMax]`` [km/h].
    A speed with an ``etcsTrainCategory`` instead (railML 2.2 allows either; CAD exports write ETCS ones) is
    category ``etcsN``; one with neither holds for every train (category ``""``)."""
    out: dict[str, dict[str, float]] = {}
    for grp in _children(doc.infra, "infraAttrGroups", "infraAttributes"):
        for sp in _children(grp, "speeds", "speed"):
            with doc.each():
                etcs = sp.get("etcsTrainCategory")
                cat = sp.get("trainCategory") or (f"etcs{etcs}" if etcs is not None else "")
                out.setdefault(doc.ident(grp), {})[cat] = doc.num(sp, "vMax", "km/h", positive=True)
    return out


def _speed_limits(doc: _Doc, line: _Line, s: ImportSummary, categories: dict[str, str]) -> tuple[pd.DataFrame, set]:
    """speed_limits rows (general and per mapped train type), and the train categories the line's profiles name."""
    profiles = _category_speeds(doc)
    changes, unread, lowered = {"down": [], "up": []}, set(), []
    for t in line.tracks:
        for el in t.items("trackElements", "speedChanges", "speedChange"):
            with doc.each():
                d = doc.attr(el, "dir")
                if d not in _DIRS:
                    raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give one speedChange per direction, dir up "
                                      f"or down (the direction of travel it applies to)")
                raw = doc.attr(el, "vMax")
                v = None if raw.strip() in END_SPEEDS else doc.num(el, "vMax", "km/h, or 'end'", positive=True)
                ref = el.get("profileRef")
                if ref is not None and ref not in profiles:
                    unread.add(ref)  # e.g. a railML <speedProfile>: its vMax is used, its details are not
                one = set(profiles.get(ref, {}).values())
                if len(one) == 1 and v is not None and min(one) < v:  # the profile's one speed is every train's
                    lowered.append(f"{el.get('id')} {v:g} → {min(one):g}")
                    v = min(one)
                changes[_DIRS[d]].append((t.chainage(el), v, el, profiles.get(ref, {})))
    given = [d for d, ch in changes.items() if ch]
    labels = {"down": "down", "up": "up"}
    if len(given) == 1:  # a file with one direction only: the stretches are the railway's, not one way's
        (d,) = given
        other = "down" if d == "up" else "up"
        labels[d] = "both"
        s.notes.append(f"every speedChange is for railML dir={other!r} (planner direction {d}); none for the other "
                       f"direction: the limits are taken for both directions")
    offered = {c for ch in changes.values() for *_, cats in ch for c in cats}
    rows, higher = [], 0
    for direction, ch in changes.items():
        ch.sort(key=lambda c: c[0], reverse=direction == "up")
        for (c1, _, e1, _), (c2, _, e2, _) in zip(ch[:-1], ch[1:]):
            if c1 == c2:
                with doc.each():
                    raise SourceError(f"{doc.where(e2, 'pos')}: speedChanges {e1.get('id')!r} and {e2.get('id')!r} "
                                      f"for the same direction at the same position; keep one")
        for k, (c, v, el, cats) in enumerate(ch):
            nxt = ch[k + 1][0] if k + 1 < len(ch) else (line.end if direction == "down" else line.start)
            if nxt == c:
                continue
            base = dict(start_m=min(c, nxt), end_m=max(c, nxt), direction=labels[direction],
                        kind=s.default("speed_limit_kind", el.get("id")),
                        has_beacon=s.default("has_beacon", el.get("id")))
            if v is not None:
                rows.append(dict(base, limit_kmh=v, train_type=None))
            for typ, cat in categories.items():
                vc = cats.get(cat)
                if vc is None:
                    continue
                if v is not None and vc >= v:
                    higher += vc > v
                    continue
                rows.append(dict(base, limit_kmh=vc, train_type=typ))
    if unread:
        s.unused.append(f"speed profiles {', '.join(sorted(unread)[:5])}{' …' if len(unread) > 5 else ''} named by "
                        f"speedChange profileRef (only infraAttrGroups/infraAttributes speeds are read; vMax holds)")
    if lowered:
        s.notes.append(f"{len(lowered)} speedChanges whose profile gives every train category it names one speed, "
                       f"below the speedChange's vMax: that speed is the limit for every train ("
                       f"{', '.join(lowered[:4])}{' …' if len(lowered) > 4 else ''} km/h)")
    if higher:
        s.notes.append(f"{higher} category speeds above their speedChange's vMax: the lower (vMax) holds")
    if categories:
        s.notes.append("per-train-type speed limits from train categories: "
                       + ", ".join(f"{typ} = {cat}" for typ, cat in sorted(categories.items())))
    rows.sort(key=lambda r: (r["start_m"], r["end_m"], r["direction"], r["train_type"] or ""))
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["speed_limits"].schema]), offered


def _direction(doc: _Doc, el: ET.Element) -> str:
    d = doc.attr(el, "dir")
    if d not in _DIRS:
        raise SourceError(f"{doc.where(el, 'dir')}: {d!r}; give up or down (the trains it applies to)")
    return _DIRS[d]


_READ = {"trackElements": {"gradientChanges", "radiusChanges", "speedChanges", "platformEdges"},
         "ocsElements": {"signals", "balises", "trainDetectionElements", "stopPosts"}}
"""Element groups of a track that the line database takes; the others are named as not used."""


def _not_read(line: _Line) -> list[str]:
    count: dict[str, int] = {}
    for t in line.tracks:
        for part, read in _READ.items():
            for grp in t.items(part):
                for g in grp:
                    if _local(g.tag) not in read:
                        key = f"{part}/{_local(g.tag)}"
                        count[key] = count.get(key, 0) + len(list(g))
    return [f"{k} ({n} elements)" for k, n in sorted(count.items()) if n]


def _stations(doc: _Doc, line: _Line, line_id: str, s: ImportSummary) -> dict[str, dict]:
    ocps = {o.get("id"): o for o in _children(doc.infra, "operationControlPoints", "ocp")}
    found: dict[str, dict] = {}
    for t in line.tracks:
        for el in t.items("trackTopology", "crossSections", "crossSection"):
            with doc.each():
                ref = el.get("ocpRef")
                if ref is None:
                    continue
                if ref not in ocps:
                    raise SourceError(f"{doc.where(el, 'ocpRef')}: no <ocp id={ref!r}> in <operationControlPoints>")
                if ref not in found:
                    found[ref] = dict(source_id=ref, name=ocps[ref].get("name") or ref, position_m=t.chainage(el))
    by_position = [k for k, v in (s.extra.stations if s.extra else {}).items() if "position_m" in v and k not in found]
    if len(found) + len(by_position) < 2:
        what = ("this file has no OCPs (operationControlPoints)" if not ocps
                else f"fewer than two OCPs on line {line_id!r} (crossSection ocpRef)")
        km = ", absPos km posts" if line.by_abs else ""
        with doc.each():
            raise SourceError(f"{doc.fname}: {what}; add stations with [stations.X] position_m in --extra "
                              f"(chainage {line.start:g} … {line.end:g} m{km})")
    for t in line.tracks:
        for el in t.items("trackElements", "platformEdges", "platformEdge"):
            with doc.each():
                ref = el.get("ocpRef")
                if ref in found and el.get("length") is not None:
                    found[ref].setdefault("platform_length_m", doc.num(el, "length", "metres", positive=True))
        for el in t.items("ocsElements", "stopPosts", "stopPost"):
            with doc.each():
                ref = el.get("ocpStationRef")
                if ref is None:
                    continue
                if ref not in found:
                    raise SourceError(f"{doc.where(el, 'ocpStationRef')}: {ref!r} is not an OCP on line {line_id!r}")
                key = "stop_down_m" if _direction(doc, el) == "down" else "stop_up_m"
                found[ref].setdefault(key, t.chainage(el))
    return found


def import_railml(file: str | Path, line_id: str, rolling_stock: list, out: str | Path, *,
                  extra: str | Path | None = None, force: bool = False, new_line_id: str | None = None,
                  categories: list[str] | None = None) -> ImportSummary:
    """Import the railML 2.x ``<line id=line_id>`` of ``file`` into the line database ``out``.

    ``new_line_id`` names the imported line (default: ``[line] line_id`` of the TOML, else the
    railML line id); ``categories`` are ``TYPE=CATEGORY`` mappings (``--category``).
    """
    doc = _Doc(file)
    s = ImportSummary(source=str(file), extra=load_extras(extra))
    cats = category_map(s, categories)
    line_el, line = _line_tracks(doc, line_id, s)
    located: dict[str, float] = {}

    gradients = pd.DataFrame(_profile(doc, line, "gradient", s), columns=["start_m", "end_m", "gradient_permil"])
    curves = pd.DataFrame(_profile(doc, line, "radius", s), columns=["start_m", "end_m", "radius_m"])
    limits, offered = _speed_limits(doc, line, s, cats)

    signals, skipped = [], 0
    for t in line.tracks:
        for el in t.items("ocsElements", "signals", "signal"):
            with doc.each():
                located[doc.ident(el)] = c = t.chainage(el)
                if el.get("type", "main") not in ("main", "combined"):
                    skipped += 1
                    continue
                signals.append((doc.ident(el), c, _direction(doc, el)))
    if skipped:
        s.notes.append(f"{skipped} signals not of type main/combined (distant, repeater, shunting) are not block "
                       f"boundaries: not imported")
    balises = []
    for t in line.tracks:
        for el in t.items("ocsElements", "balises", "balise"):
            with doc.each():
                bid = doc.ident(el)
                located[bid] = c = t.chainage(el)
                balises.append(dict(beacon_id=bid, position_m=c, direction=_direction(doc, el)))
        for el in t.items("ocsElements", "trainDetectionElements", "trainDetector"):
            with doc.each():
                located[doc.ident(el)] = t.chainage(el)
    found = _stations(doc, line, line_id, s)
    doc.problems.check()  # every element-level problem of the file, at once
    located.update({k: v["position_m"] for k, v in found.items()})
    if doc.past_end:
        s.notes.append(f"{len(doc.past_end)} elements with pos past their track's end placed by their absPos "
                       f"(km post): {', '.join(doc.past_end[:5])}{' …' if len(doc.past_end) > 5 else ''}")
    if doc.off_line:
        s.notes.append(f"{len(doc.off_line)} elements whose pos and absPos both lie beyond the line's ends (on "
                       f"track the file does not export): skipped: {', '.join(doc.off_line[:5])}"
                       f"{' …' if len(doc.off_line) > 5 else ''}")
    if line.by_abs:
        s.notes.append(f"chainage = the railway's km posts (absPos): {line.start:g} … {line.end:g} m")
    s.unused += _not_read(line)

    rs, traction = rolling_stock_tables(rolling_stock, s)
    check_categories(cats, rs, offered, "train category", s)
    lid = new_line_id or (s.extra.line.get("line_id") if s.extra else None)
    if lid is None:
        lid = path_id(line_id)
        s.default("line_id", lid)
        if lid != line_id:
            s.notes.append(f"line id {lid!r} from railML line {line_id!r} (a line id names files: A-Z a-z 0-9 . _ -)")
    tables = {
        "line": line_table(str(lid), line.start, line.end, s),
        "stations": station_table(list(found.values()), line.start, line.end, s,
                                  float(rs["length_m"].max()) if len(rs) else 0.0),
        "gradients": gradients,
        "curves": curves,
        "speed_limits": limits,
        "beacons": beacon_table(located, s, balises),
        "signals": pd.DataFrame(sorted(signals, key=lambda r: (r[1], r[0])),
                                columns=["signal_id", "position_m", "direction"]),
        "rolling_stock": rs,
        "traction": traction,
        "timetable": railml_or_toml_timetable(doc.root, doc.fname, found, [str(x) for x in rs["train_type"]], s),
    }
    from planner.line.importers.network import railml_network, stops_of

    tables["nodes"], tables["edges"] = railml_network(doc, line.tracks, found, s.extra, str(lid), s.notes,
                                                      stops_of(tables["stations"]))
    return write_line(tables, out, s, force=force)
