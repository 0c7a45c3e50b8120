"""The track network of an imported line: ``nodes.parquet`` and ``edges.parquet`` from a source's topology.

Both railjson and railML describe tracks joined by switches, crossings and
links, with points on the tracks (detectors, buffer stops, platforms). Each
importer reduces its source to a :class:`Topology` (tracks with lengths, the
joins between track positions, the points on tracks, the signals) and calls
:func:`network_tables` with the chainage of the imported line's own tracks.

What becomes what (the conflict check's model, docs/line-database.md):

- a **switch**, crossing or slip (every track position it joins) → one
  ``switch`` node, a resource claimed by one train at a time;
- a **link** (two track ends joined end to end) → no node: the two track
  pieces become one edge;
- a **detector** (train-detection, block and route boundary) → a
  ``boundary`` node, so the edges between them are the detection sections;
- a **platform** of a station on the line (an operational-point part, a railML
  platform edge or crossSection) → a ``stop`` node with its ``station_id``;
- an unconnected track end or a buffer stop → an ``end`` node.

Positions on the line's own tracks take its chainage exactly. A track off the
line (a loop, the second main, a crossover, a dead-end platform) is placed by
dead reckoning through the joins at track ends (:func:`_orient`), its points
between the chainages of its two end nodes in proportion to their offsets (a
loop longer than the main it bypasses stays monotone). Tracks no join at a
track end connects to the line, or wholly beyond its ends, are left out with a
note. A crossing is one node (a diamond's straight legs are not told apart).

Track directions: each edge's ``direction`` (down, up, both) and its track's name (``D:``/``U:``/``B:`` and the
first track id of its group) from the source's direction attributes, signals and running side
(:func:`planner.line.importers.sides.track_labels`).
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import pandas as pd

from planner.line.importers.sides import track_labels
from planner.line.importers.stop_nodes import stops_on_line
from planner.line.schema import TABLES


@dataclass
class Topology:
    """A source's track network, reduced to what the conflict check needs.

    Attributes
    ----------
    lengths : dict
        track id → length [m]; positions run 0 … length along the track.
    joins : list of (id, kind, members)
        ``kind`` ``switch`` (switch, crossing, slip) or ``link``; ``members``
        the track ends ``(track, pos, side)`` it joins into one node, ``side`` 0 or 1: a
        train runs through the join from a member on one side to a member on the other.
    points : list of (id, kind, track, pos, station_id)
        ``kind`` ``stop``, ``boundary`` or ``end``; ``station_id`` for stops.
    signals : list of (track, pos, along)
        ``along`` True for a signal facing trains that run with increasing pos.
    """

    lengths: dict[str, float]
    joins: list[tuple[str, str, list[tuple[str, float, int]]]] = field(default_factory=list)
    points: list[tuple[str, str, str, float, str | None]] = field(default_factory=list)
    signals: list[tuple[str, float, bool]] = field(default_factory=list)
    main_dir: dict[str, str] = field(default_factory=dict)
    """track id → the source's own direction of it: ``along`` (increasing pos), ``against`` or ``both``."""
    geo: dict[str, list] = field(default_factory=dict)
    """track id → its coordinates from pos 0 to its length (``(x, y)`` pairs; longitude, latitude allowed)."""
    given_dir: dict[str, str] = field(default_factory=dict)
    """source track id → down, up or both: the import's ``[track_directions]``."""


class _UF:
    def __init__(self):
        self.p: dict = {}

    def find(self, x):
        self.p.setdefault(x, x)
        while self.p[x] != x:
            self.p[x] = self.p[self.p[x]]
            x = self.p[x]
        return x

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.p[max(ra, rb)] = min(ra, rb)


def _key(track: str, pos: float) -> tuple[str, float]:
    return track, round(float(pos), 6)


def network_tables(topo: Topology, on_line: dict[str, tuple[float, int]], interlocking: str,
                   notes: list[str], running_side: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """nodes and edges tables of the network of ``topo`` that trains along the line can run. The running side
    (``running_side`` where given, else the data's; :mod:`planner.line.importers.sides`) is the edges'
    ``attrs["running_side"]`` (None: not known).

    Parameters
    ----------
    on_line : dict
        track id → ``(offset, sign)`` for the line's own tracks: chainage = offset + sign·pos.
    interlocking : str
        Interlocking of every node (the sources name none).
    notes : list of str
        Appended: what was left out and why.
    """
    uf = _UF()
    kind_of: dict = {}
    ident: dict = {}
    for jid, kind, members in topo.joins:
        keys = [_key(t, p) for t, p, _ in members]
        for k in keys:
            uf.find(k)
        for k in keys[1:]:
            uf.union(keys[0], k)
        for k in keys:
            if kind == "switch" or kind_of.get(k) != "switch":
                kind_of[k], ident[k] = kind, jid
    at: dict[str, set] = defaultdict(set)
    for t, length in topo.lengths.items():
        at[t] |= {_key(t, 0.0), _key(t, length)}
    for _, _, members in topo.joins:
        for t, p, _ in members:
            at[t].add(_key(t, p))
    # node of each key: the group root; its kind and id
    node_kind: dict = {}
    node_id: dict = {}
    station: dict = {}
    for _, _, members in topo.joins:
        for t, p, _ in members:
            k = _key(t, p)
            r = uf.find(k)
            if kind_of[k] == "switch" or r not in node_kind:
                node_kind[r], node_id[r] = kind_of[k], ident[k]
    skipped = 0
    for pid, kind, t, p, sid in topo.points:
        k = _key(t, p)
        r = uf.find(k)
        if node_kind.get(r) == "link" and kind != "end":  # a detector or platform where two tracks meet
            node_kind[r], node_id[r], station[r] = kind, pid, sid
            continue
        if r in node_kind or k in node_kind:
            if kind == "end" and node_kind.get(r) == "end":
                node_id[r] = pid
            elif kind == "stop" and node_kind.get(r) in ("boundary", "end"):  # a platform at a detector or a
                node_kind[r], node_id[r], station[r] = kind, pid, sid  # buffer stop: trains are routed to its station
            else:
                skipped += kind != "end"
            continue
        node_kind[r], node_id[r], station[r] = kind, pid, sid
        at[t].add(k)
    for t, length in topo.lengths.items():
        for k in (_key(t, 0.0), _key(t, length)):
            r = uf.find(k)
            if r not in node_kind:
                node_kind[r], node_id[r] = "end", f"{t}.{'BEGIN' if k[1] == 0 else 'END'}"
    if skipped:
        notes.append(f"track network: {skipped} detectors or platforms at a switch are that switch's node")
    # edges along each track between consecutive positions
    edges: list[list] = []  # [edge_id, node_a, node_b, length, track]
    for t in sorted(at):
        ks = sorted(at[t], key=lambda k: k[1])
        for j, (a, b) in enumerate(zip(ks[:-1], ks[1:])):
            if b[1] - a[1] > 1e-6:
                edges.append([f"{t}:{j + 1}", uf.find(a), uf.find(b), b[1] - a[1], t])
    pos, keep = _chainage(topo, on_line, uf, notes)
    edges = _contract_links([e for e in edges if e[4] in keep], node_kind)
    label, way, side = track_labels(topo, on_line, _track_groups(topo, None), _track_groups(topo, on_line), pos, uf,
                                    running_side, notes)
    used = {n for e in edges for n in e[1:3]}
    nodes = [dict(node_id=node_id[r], kind=node_kind[r], position_m=round(pos[r], 6), interlocking=interlocking,
                  station_id=station.get(r), track=label[r[0]] if node_kind[r] in ("stop", "boundary") else None)
             for r in sorted(used, key=lambda r: (pos[r], node_id[r]))]
    rows = [dict(edge_id=e[0], from_node=node_id[e[1]], to_node=node_id[e[2]], length_m=round(e[3], 6),
                 track=label[e[4]], direction=way[e[4]]) for e in edges]
    cols = lambda t: [f.name for f in TABLES[t].schema]  # noqa: E731
    out = pd.DataFrame(rows, columns=cols("edges"))
    out.attrs["running_side"] = side
    return pd.DataFrame(nodes, columns=cols("nodes")), out


def _track_groups(topo: Topology, on_line: dict | None) -> _UF:
    """Tracks joined end to end by links are one track; so are the line's own tracks (``on_line``; None: not)."""
    tuf = _UF()
    for t in sorted(on_line or ()):
        tuf.union(min(on_line), t)
    for _, kind, members in topo.joins:
        for t, _, _ in (members[1:] if kind == "link" else ()):
            tuf.union(members[0][0], t)
    return tuf


def _contract_links(edges: list[list], node_kind: dict) -> list[list]:
    """Merge the two edges at every link node into one (a link is no resource and no point of its own)."""
    inc: dict = defaultdict(list)
    for e in edges:
        inc[e[1]].append(e)
        inc[e[2]].append(e)
    for r, kind in list(node_kind.items()):
        if kind != "link" or len(inc[r]) != 2:
            if kind == "link":
                node_kind[r] = "end" if len(inc[r]) < 2 else "switch"
            continue
        e1, e2 = inc[r]
        a = e1[1] if e1[2] == r else e1[2]
        b = e2[1] if e2[2] == r else e2[2]
        merged = [e1[0], a, b, e1[3] + e2[3], e1[4]]
        for n, old in ((a, e1), (b, e2)):
            inc[n] = [merged if x is old else x for x in inc[n]]
        inc[r] = []
        del node_kind[r]
    seen, out = set(), []
    for lst in inc.values():
        for e in lst:
            if id(e) not in seen:
                seen.add(id(e))
                out.append(e)
    return sorted(out, key=lambda e: e[0])


def _orient(topo: Topology, on_line: dict) -> dict[str, tuple[float, int]]:
    """(offset, sign) of every track reachable from the line through joins at track ends: chainage = offset + sign·pos.

    Dead reckoning that follows the geometry of each join: a train crosses a join from one side to
    the other, so a track joined on the other side than the one it came from continues in the same
    direction of chainage, a track on the same side runs back.
    """
    orient = dict(on_line)
    by_track: dict = defaultdict(list)
    for j, (_, _, members) in enumerate(topo.joins):
        for m in members:
            by_track[m[0]].append(j)
    queue = sorted(on_line)
    while queue:
        t = queue.pop(0)
        off, sg = orient[t]
        length = topo.lengths[t]
        for j in by_track[t]:
            members = topo.joins[j][2]
            mine = [m for m in members if m[0] == t and m[1] in (0.0, length)]
            if not mine:
                continue
            _, p, side = mine[0]
            c = off + sg * p
            d = sg * (1 if p == length else -1)  # chainage direction of running out of t into the join
            for t2, p2, s2 in members:
                if t2 in orient or p2 not in (0.0, topo.lengths[t2]):
                    continue
                sg2 = (d if s2 != side else -d) * (1 if p2 == 0.0 else -1)
                orient[t2] = (c - sg2 * p2, sg2)
                queue.append(t2)
    return orient


def placed(topo: Topology, on_line: dict) -> tuple[_UF, dict, set]:
    """The joins' union-find, the chainage of every node (:func:`_chainage`) and the tracks
    :func:`network_tables` keeps, before any point is placed: where each source track lies."""
    uf = _UF()
    for _, _, members in topo.joins:
        keys = [_key(t, p) for t, p, _ in members]
        for k in keys[1:]:
            uf.union(keys[0], k)
    pos, keep = _chainage(topo, on_line, uf, [])
    return uf, pos, keep


def _chainage(topo: Topology, on_line: dict, uf: _UF, notes: list[str]) -> tuple[dict, set]:
    """Chainage of every node, and the tracks kept: exact on the line, off it between the track's end nodes.

    A junction takes the chainage of a member on the line, else the dead-reckoned one (:func:`_orient`);
    a point on a track off the line lies between the chainages of the track's two end nodes in
    proportion to its position, so a loop longer than the main line it bypasses stays monotone.
    """
    orient = _orient(topo, on_line)
    line_end = max(off + sg * p for t, (off, sg) in on_line.items() for p in (0.0, topo.lengths[t]))
    pos: dict = {}
    for t in sorted(orient, key=lambda t: (t not in on_line, t)):
        off, sg = orient[t]
        for p in (0.0, topo.lengths[t]):
            pos.setdefault(uf.find(_key(t, p)), off + sg * p)
    keep = set()
    for t, (off, sg) in orient.items():
        c0, c1 = pos[uf.find(_key(t, 0.0))], pos[uf.find(_key(t, topo.lengths[t]))]
        if t in on_line or (max(c0, c1) > 0.0 and min(c0, c1) < line_end):
            keep.add(t)
    for t in keep:
        if t in on_line:
            continue
        c0, c1 = pos[uf.find(_key(t, 0.0))], pos[uf.find(_key(t, topo.lengths[t]))]
        for k in _positions(topo, t):
            r = uf.find(k)
            if r not in pos:
                pos[r] = c0 + (c1 - c0) * k[1] / topo.lengths[t]
    for t in on_line:
        off, sg = on_line[t]
        for k in _positions(topo, t):
            pos.setdefault(uf.find(k), off + sg * k[1])
    left = sorted(set(topo.lengths) - keep)
    if left:
        notes.append(f"track network: {len(left)} track(s) not connected to the line or wholly beyond its ends "
                     f"left out ({', '.join(left[:6])}{' …' if len(left) > 6 else ''})")
    return pos, keep


def _positions(topo: Topology, t: str) -> list[tuple[str, float]]:
    out = [_key(t, p) for _, _, tt, p, _ in topo.points if tt == t]
    out += [_key(m[0], m[1]) for _, _, ms in topo.joins for m in ms if m[0] == t]
    return out


# --------------------------------------------------------------------------- railjson
def railjson_topology(src, net, stations: dict[str, str]) -> Topology:
    """The :class:`Topology` of a railjson infrastructure (``src``, ``net`` as the railjson importer reads them).

    ``stations``: operational point id → station_id for the stations of the imported line; each of
    their parts is a platform (a ``stop`` node).
    """
    topo = Topology({t: net.length(t) for t in net.tracks},
                    geo={t: _coordinates(obj.get("geo")) for t, (_, obj) in net.tracks.items()})
    end = lambda tr, ep, side: (tr, 0.0 if ep == "BEGIN" else net.length(tr), side)  # noqa: E731
    for sw in src.items("switches"):
        ports = sorted((k, p) for k, p in (sw.get("ports") or {}).items() if isinstance(p, dict))
        kind = "link" if sw.get("switch_type") == "link" else "switch"
        # ports A, A1, A2 on one side, B, B1, B2 on the other (OSRD's built-in types; extended types by name)
        topo.joins.append((str(sw.get("id")), kind,
                           [end(p["track"], p["endpoint"], 0 if k.upper().startswith("A") else 1) for k, p in ports]))
    for i, ln in enumerate(src.items("track_section_links")):
        topo.joins.append((str(ln.get("id", f"link{i}")), "link",
                           [end(ln[k]["track"], ln[k]["endpoint"], s) for s, k in enumerate(("src", "dst"))]))
    for key, kind in (("detectors", "boundary"), ("buffer_stops", "end")):
        for i, obj in enumerate(src.items(key)):
            track, p = net.locate(key, i, obj)
            topo.points.append((str(obj.get("id")), kind, track, p, None))
    for i, op in enumerate(src.items("operational_points")):
        sid = stations.get(str(op.get("id")))
        if sid is None:
            continue
        for k, part in enumerate(op.get("parts") or []):
            track, p = net.locate(f"operational_points[{i}].parts", k, part)
            topo.points.append((f"STOP-{sid}-{track}", "stop", track, p, sid))
    for i, sg in enumerate(src.items("signals")):
        track, p = net.locate("signals", i, sg)
        topo.signals.append((track, p, sg.get("direction") == "START_TO_STOP"))
    return topo


def _coordinates(geo) -> list | None:
    """A railjson ``geo`` LineString's coordinates (None: no usable geometry)."""
    c = geo.get("coordinates") if isinstance(geo, dict) else None
    ok = isinstance(c, list) and len(c) >= 2 and all(
        isinstance(p, list) and len(p) >= 2 and all(isinstance(x, (int, float)) for x in p[:2]) for p in c)
    return [p[:2] for p in c] if ok else None


def path_chainage(pieces) -> dict[str, tuple[float, int]]:
    """track → (offset, sign) of the railjson importer's path pieces ``(track, dir, from, to, chainage)``."""
    out = {}
    for t, d, a, _, c0 in pieces:
        out[t] = (c0 - a, 1) if d == "START_TO_STOP" else (c0 + a, -1)
    return out


def stops_of(stations: pd.DataFrame) -> list[tuple[str, float]]:
    """``(station_id, chainage)`` of each stop marker of a stations table, for :func:`stops_on_line` (a train is
    routed to the stop nearest its marker; markers seldom fall on a source's buffer stop or switch)."""
    out = []
    for sid, c, down, up in zip(stations["station_id"], stations["position_m"], stations["stop_down_m"],
                                stations["stop_up_m"]):
        marks = [float(x) for x in (down, up) if x is not None and x == x] or [float(c)]
        out += [(str(sid), x) for x in dict.fromkeys(marks)]
    return out


def railjson_network(src, net, pieces, op_ids: list[str], extra, line_id: str,
                     notes: list[str], stations=()) -> tuple[pd.DataFrame, pd.DataFrame]:
    """nodes and edges of a railjson import: the line's path ``pieces``, its operational points ``op_ids``;
    ``stations``: ``(station_id, chainage)`` of the imported line's stations (:func:`stops_on_line`)."""
    over = extra.stations if extra is not None else {}
    names = {n: str(over.get(n, {}).get("station_id", n)) for n in op_ids}
    return _network(railjson_topology(src, net, names), path_chainage(pieces), stations, line_id, notes,
                    "switches", "the switches, links, detectors, buffer stops and operational points", extra)


def _network(topo: Topology, on_line: dict, stations, line_id: str, notes: list[str], switches: str,
             sources: str, extra) -> tuple[pd.DataFrame, pd.DataFrame]:
    """nodes and edges of an imported network (stop nodes for every station first), and a note counting them."""
    stops_on_line(topo, on_line, stations, notes)
    topo.given_dir = dict(extra.track_directions) if extra is not None else {}
    given = extra.line.get("running_side") if extra is not None else None
    nodes, edges = network_tables(topo, on_line, str(line_id), notes, given)
    n_sw = int((nodes["kind"] == "switch").sum())
    notes.append(f"track network: {len(nodes)} nodes ({n_sw} {switches}), {len(edges)} edges on "
                 f"{edges['track'].nunique()} tracks, from {sources}")
    return nodes, edges


# --------------------------------------------------------------------------- railML 2.x
def _rl(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _rl_path(el, *names):
    level = [el]
    for n in names:
        level = [c for e in level for c in e if _rl(c.tag) == n]
    return level


def railml_topology(doc, line_tracks, stations: dict[str, str],
                    notes: list[str] | None = None) -> tuple[Topology, dict[str, tuple[float, int]]]:
    """The :class:`Topology` of a railML 2.x ``<infrastructure>``, and the chainage of the line's tracks.

    Every ``<track>`` is cut at its ``<switch>``/``<crossing>`` positions into pieces ``id#k``, so every
    join lies at track ends. A switch joins the piece before it (one side), the piece after it and,
    by its ``<connection ref>``, the branch track's end: on the far side when the connection's
    ``orientation`` is ``outgoing`` (the branch leaves towards the trackEnd), on the near side when
    ``incoming``. A ``<connection>`` in a trackBegin/trackEnd that names another track end is a link.
    ``line_tracks``: the railML importer's tracks of the line (``id``, ``begin``, ``offset``).
    ``stations``: OCP id → station_id for the stations of the line (their crossSections and
    platformEdges on any track are platforms).
    """
    from planner.line.importers.common import number

    notes = [] if notes is None else notes
    tracks = _rl_path(doc.infra, "tracks", "track")
    pos_of = lambda el: number(el.get("pos"), doc.where(el, "pos"), "metres from the track begin")  # noqa: E731
    pieces: dict[str, list[tuple[float, float]]] = {}
    conn_at: dict[str, tuple] = {}  # connection id → ("end", track, BEGIN|END) or ("switch", switch id, orientation)
    conn_ref: dict[str, str] = {}
    switches: dict[str, tuple[str, float]] = {}
    begin_of: dict[str, float] = {}
    topo = Topology({})
    for tr in tracks:
        tid = tr.get("id")
        tb, te = _rl_path(tr, "trackTopology", "trackBegin"), _rl_path(tr, "trackTopology", "trackEnd")
        if tid is None or not tb or not te:
            continue
        b, e = pos_of(tb[0]), pos_of(te[0])
        if not e > b:
            continue
        begin_of[tid] = b
        cuts = set()
        for kind in ("switch", "crossing"):
            for sw in _rl_path(tr, "trackTopology", "connections", kind):
                p = pos_of(sw) - b
                if 0 < p < e - b:
                    cuts.add(round(p, 6))
                switches[sw.get("id")] = (tid, p)
                for c in _rl_path(sw, "connection"):
                    conn_at[c.get("id")] = ("switch", sw.get("id"), c.get("orientation"))
                    conn_ref[c.get("id")] = c.get("ref")
        bounds = [0.0] + sorted(cuts) + [e - b]
        pieces[tid] = list(zip(bounds[:-1], bounds[1:]))
        for k, (lo, hi) in enumerate(pieces[tid]):
            topo.lengths[f"{tid}#{k}"] = hi - lo
        for end_el, which in ((tb[0], "BEGIN"), (te[0], "END")):
            for c in _rl_path(end_el, "connection"):
                conn_at[c.get("id")] = ("end", tid, which)
                conn_ref[c.get("id")] = c.get("ref")
            if not _rl_path(end_el, "connection"):  # a bufferStop, an openEnd: an end node named by it
                named = [x.get("id") for x in _rl_path(end_el, "bufferStop") + _rl_path(end_el, "openEnd")]
                t, p = _piece(pieces, tid, 0.0 if which == "BEGIN" else e - b)
                topo.points.append((next((x for x in named if x), None) or end_el.get("id") or f"{tid}.{which}",
                                    "end", t, p, None))

    track_end = lambda tid, which: _track_end(pieces, tid, which)  # noqa: E731
    branches: dict[str, list] = defaultdict(list)
    linked = set()
    for cid, at in conn_at.items():
        other = conn_at.get(conn_ref.get(cid))
        if at[0] != "end" or other is None or at[1] not in pieces:
            continue
        if other[0] == "end" and other[1] in pieces:
            pair = tuple(sorted((cid, conn_ref[cid])))
            if pair not in linked:
                linked.add(pair)
                (t1, p1), (t2, p2) = track_end(at[1], at[2]), track_end(other[1], other[2])
                topo.joins.append((f"link:{pair[0]}", "link", [(t1, p1, 0), (t2, p2, 1)]))
        elif other[0] == "switch":
            branches[other[1]].append((track_end(at[1], at[2]), other[2]))
    # switch to switch (a crossover without a track between): one node of both switches
    pairs = {tuple(sorted((a[1], conn_at[conn_ref[c]][1]))): (a[2], conn_at[conn_ref[c]][2])
             for c, a in conn_at.items() if a[0] == "switch" and conn_at.get(conn_ref.get(c), ("",))[0] == "switch"}
    joined: dict[str, list] = {}
    for sid, (tid, p) in switches.items():
        if tid not in pieces:
            continue
        ps = pieces[tid]
        k = next((j for j, (lo, _) in enumerate(ps) if abs(lo - p) < 1e-6), None)
        members = []
        if k is None:  # at the track's very begin or end: the track end itself
            members.append((*track_end(tid, "BEGIN" if p <= 0 else "END"), 1 if p <= 0 else 0))
        else:
            members += [(f"{tid}#{k - 1}", ps[k - 1][1] - ps[k - 1][0], 0), (f"{tid}#{k}", 0.0, 1)]
        for (t2, p2), orient in branches.get(sid, []):
            members.append((t2, p2, 0 if orient == "incoming" else 1))
        joined[sid] = members
    for (sa, sb), (oa, ob) in sorted(pairs.items()):
        if sa in joined and sb in joined and sa != sb:
            # the tracks run the same way when one connection is outgoing and the other incoming
            flip = (oa == "incoming") == (ob == "incoming")
            joined[sa] = joined[sa] + [(t, p, 1 - side if flip else side) for t, p, side in joined.pop(sb)]
    for sid, members in joined.items():
        topo.joins.append((sid, "switch", members))
    _railml_points(topo, tracks, pieces, begin_of, pos_of, stations)
    on_line = {}
    for t in line_tracks:
        for k, (lo, _) in enumerate(pieces.get(t.id, [])):
            on_line[f"{t.id}#{k}"] = (t.offset + lo, 1)
    _bridge_gaps(topo, line_tracks, pieces, notes)
    return topo, on_line


def _track_end(pieces: dict, tid: str, which: str) -> tuple[str, float]:
    """(piece, position) of the trackBegin or trackEnd of railML track ``tid``."""
    ps = pieces[tid]
    return (f"{tid}#0", 0.0) if which == "BEGIN" else (f"{tid}#{len(ps) - 1}", ps[-1][1] - ps[-1][0])


def _railml_points(topo: Topology, tracks, pieces: dict, begin_of: dict, pos_of, stations: dict) -> None:
    """trainDetectors, main signals, the track's ``mainDir`` and the platforms of the line's stations on every
    railML track."""
    for tr in tracks:
        tid = tr.get("id")
        if tid not in pieces:
            continue
        b = begin_of[tid]
        main = {"up": "along", "down": "against", "both": "both"}.get(tr.get("mainDir") or "")
        for k in range(len(pieces[tid]) if main else 0):  # the track's own running direction (mainDir)
            topo.main_dir[f"{tid}#{k}"] = main
        for el in _rl_path(tr, "ocsElements", "trainDetectionElements", "trainDetector"):
            topo.points.append((el.get("id"), "boundary", *_piece(pieces, tid, pos_of(el) - b), None))
        for el in _rl_path(tr, "ocsElements", "signals", "signal"):
            if el.get("type", "main") in ("main", "combined") and el.get("dir") in ("up", "down"):
                topo.signals.append((*_piece(pieces, tid, pos_of(el) - b), el.get("dir") == "up"))
        seen = set()
        for el in (_rl_path(tr, "trackTopology", "crossSections", "crossSection")
                   + _rl_path(tr, "trackElements", "platformEdges", "platformEdge")):
            sid = stations.get(el.get("ocpRef"))
            if sid is None or sid in seen:
                continue
            seen.add(sid)
            p = pos_of(el) - b
            if _rl(el.tag) == "platformEdge" and el.get("length") is not None:
                p = min(p + float(el.get("length")) / 2, pieces[tid][-1][1])
            topo.points.append((f"STOP-{sid}-{tid}", "stop", *_piece(pieces, tid, p), sid))


def _bridge_gaps(topo: Topology, line_tracks, pieces: dict, notes: list[str]) -> None:
    """Consecutive tracks of the line that no connection joins (a gap the importer bridged) are joined
    end to end, so the line's own tracks are one piece of network as its chainage is."""
    joined_ends = {(m[0], round(m[1], 6)) for _, _, ms in topo.joins for m in ms}
    for a, b in zip(line_tracks[:-1], line_tracks[1:]):
        if a.id in pieces and b.id in pieces:
            ea, eb = _track_end(pieces, a.id, "END"), _track_end(pieces, b.id, "BEGIN")
            if (ea[0], round(ea[1], 6)) not in joined_ends and (eb[0], round(eb[1], 6)) not in joined_ends:
                topo.joins.append((f"gap:{a.id}:{b.id}", "link", [(*ea, 0), (*eb, 1)]))
                notes.append(f"track network: tracks {a.id} and {b.id} follow each other on the line but no "
                             f"connection joins them: joined end to end")


def _piece(pieces: dict, tid: str, p: float) -> tuple[str, float]:
    """(piece id, position on it) of position ``p`` from the begin of railML track ``tid``."""
    ps = pieces[tid]
    for k, (lo, hi) in enumerate(ps):
        if p <= hi + 1e-9 or k == len(ps) - 1:
            return f"{tid}#{k}", min(max(p - lo, 0.0), hi - lo)
    raise AssertionError


def railml_network(doc, line_tracks, found: dict, extra, line_id: str,
                   notes: list[str], stations=()) -> tuple[pd.DataFrame, pd.DataFrame]:
    """nodes and edges of a railML import: every connected track, cut at its switches; ``stations``:
    ``(station_id, chainage)`` of the imported line's stations (:func:`stops_on_line`)."""
    over = extra.stations if extra is not None else {}
    names = {k: str(over.get(k, {}).get("station_id", k)) for k in found}
    topo, on_line = railml_topology(doc, line_tracks, names, notes)
    return _network(topo, on_line, stations, line_id, notes, "switches and crossings",
                    "the connections, switches, crossings, bufferStops, trainDetectors and platforms", extra)
