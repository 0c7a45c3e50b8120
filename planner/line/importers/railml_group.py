"""A railML ``<line>`` that lists a station area's tracks as a group (CAD exports): its through route.

A CAD tool (e.g. RailCOMPLETE) exports the tracks of a drawing under one ``<line>``: main tracks, the
crossovers between them and sidings, in no running order. The line is then the group's through route:
the longest chain of its tracks (in metres) in which each track's end connects to the next one's begin.
Where no two tracks chain that way (each main runs from open end to open end and the crossovers join
it by switches along it), the through route is the longest track that switches join to others of the
group; a group whose tracks are neither chained nor switched together is a broken listing, not a
station area, and stays refused.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET


def _conns(el: ET.Element) -> list[ET.Element]:
    return [c for c in el.iter() if c.tag.rsplit("}", 1)[-1] == "connection"]


def connected(a, b) -> bool:
    """``a``'s trackEnd connects to ``b``'s trackBegin."""
    out_ids = {c.get("ref") for c in _conns(a.end_el)}
    in_ids = {c.get("id") for c in _conns(b.begin_el)}
    return bool(out_ids & in_ids)


def switched(a, others) -> bool:
    """A ``<switch>`` on track ``a`` connects to one of ``others`` (a crossover, a loop, a siding)."""
    refs = {c.get("ref") for sw in a.el.iter() if sw.tag.rsplit("}", 1)[-1] == "switch" for c in _conns(sw)}
    return any(refs & {c.get("id") for c in _conns(b.el)} for b in others if b is not a)


def stations_on(t) -> set[str]:
    """The operational points a track's elements name (cross sections, platform edges, stop posts)."""
    return {v for el in t.el.iter() for k in ("ocpRef", "ocpStationRef") if (v := el.get(k))}


def through_route(tracks: list) -> list:
    """The longest chain of ``tracks`` (in metres), each track's end connected to the next one's begin: the
    through route of a group of tracks (a station area's main track, loops and sidings); on a tie the first
    found in the group's order. Tracks joined to the chain by switches along them are not on it. A chain of
    one track is the route only if switches on it join it to the rest of the group (else: [])."""
    nxt = {id(a): [b for b in tracks if b is not a and connected(a, b)] for a in tracks}
    best: list = []

    def walk(path: list) -> None:
        nonlocal best
        best = list(path) if sum(t.length for t in path) > sum(t.length for t in best) else best
        for b in (b for b in nxt[id(path[-1])] if b not in path):
            walk(path + [b])

    entered = {id(b) for bs in nxt.values() for b in bs}
    for a in [t for t in tracks if id(t) not in entered] or tracks:
        walk([a])
    if len(best) == 1:
        singles = sorted((t for t in tracks if switched(t, tracks)), key=lambda t: -t.length)
        best = singles[:1]
    return best
